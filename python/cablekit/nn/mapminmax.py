"""MATLAB ``mapminmax``: per-feature affine map of the training range onto [−1, 1].

The same definition as the Rust core (``cable_core::nn::MapMinMax``): ``a = (x − min)·g − 1``
with ``g = 2/(max − min)``, and ``g = 1`` for a feature whose training range is empty.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cablekit.errors import NotFiniteError, ShapeError

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class MapMinMax:
    """Training range per feature, ``min`` and ``max`` of shape ``(n,)``."""

    min: F64
    max: F64

    @classmethod
    def fit(cls, data: F64, name: str = "data") -> MapMinMax:
        """Ranges of the columns of ``data`` ``(N, n)``."""
        data = np.asarray(data, dtype=np.float64)
        if data.ndim != 2 or data.shape[0] == 0:
            raise ShapeError(f"{name} must be a non-empty (N, n) array, got shape {data.shape}")
        if not np.all(np.isfinite(data)):
            raise NotFiniteError(f"{name} contains NaN or inf")
        return cls(data.min(axis=0), data.max(axis=0))

    @property
    def gain(self) -> F64:
        rng = self.max - self.min
        with np.errstate(divide="ignore"):
            return np.where(rng > 0, 2.0 / np.where(rng > 0, rng, 1.0), 1.0)

    def apply(self, x: F64) -> F64:
        """Physical → normalised."""
        return (x - self.min) * self.gain - 1.0

    def reverse(self, a: F64) -> F64:
        """Normalised → physical."""
        return (a + 1.0) / self.gain + self.min
