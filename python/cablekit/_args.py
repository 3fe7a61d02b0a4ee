"""Argument checking for the Python-level entry points — the same refusals the bindings give,
with cablekit's own errors: a number that is not a real number is a :class:`DTypeError`, one
outside its range (or not finite) a :class:`ParameterError`, a count too large for the work it
asks for a :class:`ParameterError` that says the bound. One helper, used by every Python layer
(``cablekit.cdpr``, ``cablekit.forceps``, the estimators), so that no builtin ``ValueError``,
``IndexError`` or ``ZeroDivisionError`` reaches a user."""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from typing import Any

from cablekit._arrays import float_array
from cablekit.errors import DTypeError, ParameterError

__all__ = ["choice", "count", "float_array", "real"]


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
