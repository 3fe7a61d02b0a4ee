"""Array arguments of the Python-level entry points, converted or refused with cablekit's own
errors (the compiled core refuses anything but C-contiguous float64; these helpers accept what
NumPy converts losslessly to float64 and say clearly what they cannot)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from cablekit.errors import DTypeError, ShapeError

__all__ = ["float_array"]


def float_array(value: Any, name: str, ndim: int | tuple[int, ...] | None = None) -> NDArray[np.float64]:
    """``value`` as a C-contiguous float64 array: an ndarray or a (nested) list of real numbers
    (bool, integer and float dtypes convert); complex, object, string and other types are a
    :class:`DTypeError`, a rank outside ``ndim`` a :class:`ShapeError` naming ``name``."""
    if isinstance(value, np.ndarray):
        arr = value
    elif isinstance(value, list | tuple):
        try:
            arr = np.asarray(value)
        except (ValueError, TypeError) as exc:
            raise DTypeError(f"{name} must be an array of real numbers ({exc})") from None
    else:
        raise DTypeError(
            f"{name} must be a numpy.ndarray of float64, got {type(value).__name__}; "
            f"pass np.asarray({name}, dtype=np.float64)"
        )
    if arr.dtype.kind not in "biuf":
        raise DTypeError(f"{name} must hold real numbers, got dtype {arr.dtype}")
    if ndim is not None and arr.ndim not in ((ndim,) if isinstance(ndim, int) else ndim):
        raise ShapeError(f"{name} must be {ndim}-D, got shape {arr.shape}")
    return np.ascontiguousarray(arr, dtype=np.float64)
