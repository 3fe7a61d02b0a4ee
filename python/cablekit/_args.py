"""Argument checking for the Python-level entry points — the same refusals the bindings give,
with cablekit's own errors: a number that is not a real number is a :class:`DTypeError`, one
outside its range (or not finite) a :class:`ParameterError`, a count too large for the work it
asks for a :class:`ParameterError` that says the bound. One helper, used by every Python layer
(``cablekit.cdpr``, ``cablekit.forceps``, the estimators), so that no builtin ``ValueError``,
``IndexError`` or ``ZeroDivisionError`` reaches a user."""

from __future__ import annotations

import collections.abc
import functools
import inspect
import math
import numbers
import os
import types
import typing
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

import numpy as np

from cablekit._arrays import float_array
from cablekit.errors import CablekitError, DTypeError, ParameterError

__all__ = [
    "SIGNAL_LIMIT",
    "Epochs",
    "Range",
    "Seed",
    "Stride",
    "Width",
    "check_value",
    "checked",
    "choice",
    "count",
    "float_array",
    "instance",
    "real",
    "signal",
    "text",
]


def real(
    value: Any,
    name: str,
    *,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    hi_open: bool = False,
) -> float:
    """``value`` as a finite float within ``[lo, hi]`` (``lo_open``/``hi_open``: excluded). A
    bool, a string or any non-real is a :class:`DTypeError`; NaN, ±inf or a value outside the
    range a :class:`ParameterError` naming ``name`` and the range."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise DTypeError(f"{name} must be a real number, got {type(value).__name__} {value!r}")
    try:
        v = float(value)
    except (OverflowError, ValueError, TypeError):
        raise ParameterError(f"{name} must be a finite number, got {value!r}") from None
    if not math.isfinite(v):
        raise ParameterError(f"{name} must be a finite number, got {value!r}")
    below = lo is not None and (v <= lo if lo_open else v < lo)
    above = hi is not None and (v >= hi if hi_open else v > hi)
    if below or above:
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        span = f"{left}{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}{right}"
        raise ParameterError(f"{name} must lie in {span}, got {v:g}")
    return v


def count(value: Any, name: str, *, lo: int = 0, hi: int | None = None) -> int:
    """``value`` as an int within ``[lo, hi]`` (a bool or a float is a :class:`DTypeError`, one
    outside the range a :class:`ParameterError` that names the bound)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise DTypeError(f"{name} must be an integer, got {type(value).__name__} {value!r}")
    v = int(value)
    if v < lo or (hi is not None and v > hi):
        raise ParameterError(f"{name} must lie in [{lo}, {'inf' if hi is None else hi}], got {v}")
    return v


def choice(value: Any, name: str, options: Sequence[Any]) -> Any:
    """``value`` if it is one of ``options`` (compared by equality, not by truthiness); a
    :class:`ParameterError` listing them otherwise."""
    try:
        ok = any(value == o and type(value) is type(o) for o in options)
    except Exception:  # an object whose == raises is not one of the options
        ok = False
    if not ok:
        raise ParameterError(f"{name} must be one of {list(options)}, got {value!r}")
    return value


def instance(value: Any, name: str, kind: type | tuple[type, ...], *, optional: bool = False) -> Any:
    """``value`` if it is a ``kind`` (or ``None`` when ``optional``); a :class:`DTypeError`
    naming the argument and the type it must be otherwise — never an ``AttributeError`` from
    deep inside the function."""
    kinds = kind if isinstance(kind, tuple) else typing.get_args(kind) or (kind,)
    if (optional and value is None) or isinstance(value, kinds):
        return value
    names = " or ".join(getattr(k, "__name__", str(k)) for k in kinds)
    raise DTypeError(f"{name} must be a {names}{' or None' if optional else ''}, got {type(value).__name__}")


def text(value: Any, name: str) -> str:
    """``value`` if it is a ``str``; a :class:`DTypeError` otherwise."""
    return str(instance(value, name, str))


#: the largest magnitude a physical signal may have: beyond it the arithmetic of a filter or a
#: norm overflows (a square of 1e155 is inf), and no sensor reports such a number
SIGNAL_LIMIT = 1e150


def signal(value: Any, name: str, ndim: int | tuple[int, ...] | None = None) -> Any:
    """``value`` as a finite float64 array (:func:`float_array`) whose every sample is within
    ``±SIGNAL_LIMIT``: NaN/inf are a :class:`ParameterError` naming the argument, as are
    magnitudes no measurement has."""
    arr = float_array(value, name, ndim)
    if not np.isfinite(arr).all():
        raise ParameterError(f"{name} has NaN or inf samples")
    if arr.size and float(np.abs(arr).max()) > SIGNAL_LIMIT:
        raise ParameterError(f"{name} has samples beyond ±{SIGNAL_LIMIT:g}: not a physical signal")
    return arr


# ---- every argument against its annotation -------------------------------------------------


class Range:
    """The closed range ``[lo, hi]`` an ``Annotated`` number must lie in:
    ``Annotated[int, Range(0, 10)]``; :func:`check_value` says the range when it is left."""

    def __init__(self, lo: float | None = None, hi: float | None = None) -> None:
        self.lo, self.hi = lo, hi

    def __repr__(self) -> str:
        return f"Range({self.lo}, {self.hi})"


#: a random seed: NumPy's generators take the non-negative integers
Seed = typing.Annotated[int, Range(0, 2**63 - 1)]
#: training epochs of a network (bounded: no call runs unboundedly long)
Epochs = typing.Annotated[int, Range(1, 100_000)]
#: the neurons of a hidden layer
Width = typing.Annotated[int, Range(1, 10_000)]
#: a count of things to do or show, or a step through samples (every ``k``-th)
Stride = typing.Annotated[int, Range(1, 1_000_000)]

_Fn = TypeVar("_Fn", bound=Callable[..., Any])


#: the words a message uses for the plain annotations
_WORDS = {type(None): "None", float: "a real number", int: "an integer", bool: "a bool", str: "a string"}


def _describe(tp: Any) -> str:
    """``tp`` in a user's words: "a string", "a path or None", "a list of BenchRun"."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        paths = [a for a in args if a is str or (isinstance(a, type) and issubclass(a, os.PathLike))]
        rest = [_describe(a) for a in args if a not in paths]
        return " or ".join((["a path"] if len(paths) > 1 else [_describe(p) for p in paths]) + rest)
    if origin is typing.Annotated:
        return _describe(args[0])
    if tp in _WORDS:
        return _WORDS[tp]
    if isinstance(tp, type) and issubclass(tp, os.PathLike):
        return "a path"
    if tp is np.ndarray or origin is np.ndarray:
        return "an array"
    if origin in (list, tuple, collections.abc.Sequence):
        return f"a list of {_describe(args[0]).removeprefix('a ').removeprefix('an ')}" if args else "a list"
    if origin in (dict, collections.abc.Mapping):
        return "a mapping"
    if origin is collections.abc.Callable:
        return "a callable"
    return getattr(tp, "__name__", None) or str(tp).replace("typing.", "")


def _wrong(value: Any, name: str, tp: Any) -> DTypeError:
    return DTypeError(f"{name} must be {_describe(tp)}, got {type(value).__name__}")


def _array_like(value: Any, name: str) -> None:
    """An array argument: an ndarray, a (nested) list or tuple of numbers, or a number; a float
    array with NaN or inf samples is a :class:`ParameterError`. Shapes are the function's own."""
    if isinstance(value, str | bytes) or value is None:
        raise DTypeError(f"{name} must be an array, got {type(value).__name__}")
    if not isinstance(value, np.ndarray | list | tuple | numbers.Number | np.generic):
        raise DTypeError(f"{name} must be an array, got {type(value).__name__}")
    try:
        arr = np.asarray(value)
    except (ValueError, TypeError, OverflowError):
        raise DTypeError(f"{name} must be a rectangular array of numbers") from None
    if arr.dtype.kind not in "biuf":
        raise DTypeError(f"{name} must be an array of numbers, got dtype {arr.dtype}")
    if arr.dtype.kind == "f" and not np.isfinite(arr).all():
        raise ParameterError(f"{name} has NaN or inf entries")


def check_value(value: Any, tp: Any, name: str) -> None:
    """Check ``value`` against the annotation ``tp``: a value of another type is a
    :class:`DTypeError` naming ``name`` and the type; a ``float`` that is NaN or infinite, and a
    float array with such entries, a :class:`ParameterError`. Containers are checked element by
    element; what an annotation cannot say (shapes, ranges) is the function's own check."""
    if tp is Any or tp is object or isinstance(tp, TypeVar):
        return
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin is typing.Annotated:
        check_value(value, args[0], name)
        for r in (m for m in args[1:] if isinstance(m, Range)):
            if (r.lo is not None and value < r.lo) or (r.hi is not None and value > r.hi):
                raise ParameterError(f"{name} must lie in [{r.lo}, {r.hi}], got {value!r}")
        return
    if origin in (typing.Union, types.UnionType):
        errors: list[CablekitError] = []
        for a in args:
            try:
                check_value(value, a, name)
                return
            except CablekitError as e:
                errors.append(e)
        # a value of the right kind with a bad number says what is wrong with the number
        raise next((e for e in errors if isinstance(e, ParameterError)), _wrong(value, name, tp))
    if tp is type(None):
        if value is not None:
            raise _wrong(value, name, tp)
    elif origin is typing.Literal:
        choice(value, name, args)
    elif tp is float:
        real(value, name)
    elif tp is int:
        if isinstance(value, bool) or not isinstance(value, numbers.Integral):
            raise _wrong(value, name, tp)
    elif tp is bool:
        if not isinstance(value, bool | np.bool_):
            raise _wrong(value, name, tp)
    elif tp is str:
        if not isinstance(value, str):
            raise _wrong(value, name, tp)
    elif tp in (os.PathLike,) or (isinstance(tp, type) and issubclass(tp, os.PathLike)):
        if not isinstance(value, str | os.PathLike):
            raise _wrong(value, name, tp)
    elif tp is np.ndarray or origin is np.ndarray:
        _array_like(value, name)
    elif origin is collections.abc.Callable or tp is collections.abc.Callable:
        if not callable(value):
            raise _wrong(value, name, tp)
    elif origin in (list, tuple, collections.abc.Sequence) or tp in (list, tuple, collections.abc.Sequence):
        if isinstance(value, str | bytes) or not isinstance(value, list | tuple | collections.abc.Sequence):
            raise _wrong(value, name, tp)
        if origin is tuple and args and not (len(args) == 2 and args[1] is Ellipsis):
            if len(value) != len(args):
                raise DTypeError(f"{name} must have {len(args)} entries, got {len(value)}")
            for i, (v, a) in enumerate(zip(value, args, strict=True)):
                check_value(v, a, f"{name}[{i}]")
        elif args:
            for i, v in enumerate(value):
                check_value(v, args[0], f"{name}[{i}]")
    elif origin in (dict, collections.abc.Mapping) or tp in (dict, collections.abc.Mapping):
        if not isinstance(value, collections.abc.Mapping):
            raise _wrong(value, name, tp)
        if len(args) == 2:
            for k, v in value.items():
                check_value(k, args[0], f"a key of {name}")
                check_value(v, args[1], f"{name}[{k!r}]")
    elif isinstance(tp, type):
        if not isinstance(value, tp):
            raise _wrong(value, name, tp)


def _hints(fn: Callable[..., Any]) -> dict[str, Any]:
    """The resolved annotations of ``fn``'s parameters (the return type left out); a name that
    does not resolve is an error here, not an unchecked argument."""
    hints = typing.get_type_hints(fn, include_extras=True)
    hints.pop("return", None)
    return hints


def checked(fn: _Fn) -> _Fn:
    """Check every argument of a public function against its annotation before the body runs
    (:func:`check_value`), so that a wrong type or a NaN is cablekit's own typed error naming the
    argument — never an ``AttributeError`` or ``IndexError`` from deep inside, and never after
    minutes of work. The annotations are resolved on the first call (the module is complete
    by then); ``fn.__cablekit_hints__()`` returns them (the property tests draw against them)."""
    sig = inspect.signature(fn)

    @functools.cache
    def hints() -> dict[str, Any]:
        return _hints(fn)

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        # the arguments given are checked first, then whether any is missing: a bad value is
        # named even in a call that also lacks another argument
        try:
            bound = sig.bind_partial(*args, **kwargs)
        except TypeError as e:
            raise DTypeError(f"{fn.__name__}(): {e}") from None
        h = hints()
        for name, value in bound.arguments.items():
            tp = h.get(name)
            if tp is None:
                continue
            kind = sig.parameters[name].kind
            if kind is inspect.Parameter.VAR_KEYWORD:
                for k, v in value.items():
                    check_value(v, tp, k)
            elif kind is inspect.Parameter.VAR_POSITIONAL:
                for i, v in enumerate(value):
                    check_value(v, tp, f"{name}[{i}]")
            else:
                check_value(value, tp, name)
        try:
            sig.bind(*args, **kwargs)
        except TypeError as e:
            raise DTypeError(f"{fn.__name__}(): {e}") from None
        return fn(*args, **kwargs)

    wrapper.__cablekit_hints__ = hints  # type: ignore[attr-defined]
    return typing.cast(_Fn, wrapper)
