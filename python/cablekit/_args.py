"""Argument checking for the Python-level entry points — the same refusals the bindings give,
with cablekit's own errors: a number that is not a real number is a :class:`DTypeError`, one
outside its range (or not finite) a :class:`ParameterError`, a count too large for the work it
asks for a :class:`ParameterError` that says the bound. One helper, used by every Python layer
(``cablekit.cdpr``, ``cablekit.forceps``, the estimators), so that no builtin ``ValueError``,
``IndexError`` or ``ZeroDivisionError`` reaches a user."""

from __future__ import annotations

import math
import numbers
import typing
from collections.abc import Sequence
from typing import Any

from cablekit._arrays import float_array
from cablekit.errors import DTypeError, ParameterError

__all__ = ["SIGNAL_LIMIT", "choice", "count", "float_array", "instance", "real", "signal", "text"]


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
    import numpy as np

    arr = float_array(value, name, ndim)
    if not np.isfinite(arr).all():
        raise ParameterError(f"{name} has NaN or inf samples")
    if arr.size and float(np.abs(arr).max()) > SIGNAL_LIMIT:
        raise ParameterError(f"{name} has samples beyond ±{SIGNAL_LIMIT:g}: not a physical signal")
    return arr
