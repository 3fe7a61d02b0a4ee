"""Pretension from the filter's cable stiffness through a fitted quadratic map, its Low/Mid/High
category, and the taut-string frequency → tension calibration (seed 001 §5.2)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cablekit.errors import ParameterError
from cablekit.estimate.parameters import estimate_parameters

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from cablekit._cablekit import CableTransmission


def estimate_stiffness(
    model: CableTransmission,
    link: int,
    q_m: NDArray[np.float64],
    tau_m: NDArray[np.float64],
    dt: float,
    q_l: NDArray[np.float64] | None = None,
    **kwargs: Any,
) -> tuple[float, float]:
    """The cable stiffness of ``link`` (N/m) and its standard deviation at the end of a run, by
    joint state–parameter estimation (:func:`estimate_parameters`; ``kwargs`` pass on). The
    link noise defaults to 0.1 (as for forces: a wandering link velocity averages friction
    away)."""
    kwargs.setdefault("link_noise", 0.1)
    est = estimate_parameters(model, [f"cable_stiffness[{link}]"], q_m, tau_m, dt, q_l=q_l, **kwargs)
    return float(est.values[-1, 0]), float(est.std[-1, 0])


#: seed 001 §5.2's pretension categories (N): Low below 8, Mid 8–14, High above 14
CATEGORY_BOUNDS = (8.0, 14.0)


@dataclass
class PretensionMap:
    """Tension from estimated cable stiffness by a degree-two polynomial (seed 001 §5.2, Fig.
    5.3), fitted on runs of known tension; the stiffness can be biased (friction and inertia
    errors of the model), the fit absorbs a consistent bias."""

    coefficients: NDArray[np.float64] | None = None
    """``(c0, c1, c2)`` of ``T = c0 + c1·k + c2·k²``, k in kN/m."""

    def fit(self, stiffness: NDArray[np.float64], tension: NDArray[np.float64]) -> PretensionMap:
        k = np.asarray(stiffness, dtype=np.float64) / 1e3
        t = np.asarray(tension, dtype=np.float64)
        if (
            k.shape != t.shape
            or k.ndim != 1
            or len(k) < 3
            or not (np.isfinite(k).all() and np.isfinite(t).all())
        ):
            raise ParameterError("fit needs at least 3 finite (stiffness, tension) pairs of equal length")
        self.coefficients = np.polynomial.polynomial.polyfit(k, t, 2)
        return self

    def tension(self, stiffness: NDArray[np.float64] | float) -> NDArray[np.float64]:
        if self.coefficients is None:
            raise ParameterError("fit() the map on runs of known tension first")
        return np.polynomial.polynomial.polyval(
            np.asarray(stiffness, dtype=np.float64) / 1e3, self.coefficients
        )

    @staticmethod
    def category(tension: NDArray[np.float64] | float) -> NDArray[np.str_]:
        """``"low"`` (< 8 N), ``"mid"`` (8–14 N) or ``"high"`` (> 14 N) per value."""
        t = np.asarray(tension, dtype=np.float64)
        lo, hi = CATEGORY_BOUNDS
        return np.where(t < lo, "low", np.where(t > hi, "high", "mid"))


@dataclass
class StringCalibration:
    """Taut-string calibration (seed 001 §5.2): a free span of length ``L`` and linear density
    ``μ`` vibrates at ``f = √(T/μ)/(2L)``, so ``T = a·f²`` with ``a = 4L²μ``; ``a`` is fitted
    (least squares through the origin) on spans whose tension a gauge measured."""

    a: float = float("nan")

    def fit(self, frequency: NDArray[np.float64], tension: NDArray[np.float64]) -> StringCalibration:
        f2 = np.asarray(frequency, dtype=np.float64) ** 2
        t = np.asarray(tension, dtype=np.float64)
        if f2.shape != t.shape or len(t) < 1 or not (np.isfinite(f2).all() and np.isfinite(t).all()):
            raise ParameterError("fit needs finite (frequency, tension) pairs of equal length")
        self.a = float(f2 @ t / (f2 @ f2))
        return self

    def tension(self, frequency: NDArray[np.float64] | float) -> NDArray[np.float64]:
        if np.isnan(self.a):
            raise ParameterError("fit() the string calibration first")
        return self.a * np.asarray(frequency, dtype=np.float64) ** 2


@dataclass(frozen=True)
class PretensionEstimate:
    """Result of :func:`estimate_pretension`."""

    stiffness: float
    """Estimated cable stiffness (N/m)."""
    stiffness_std: float
    tension: float
    """Tension from the map (N)."""
    category: str
    """``"low"``, ``"mid"`` or ``"high"`` (seed 001 §5.2)."""


def estimate_pretension(
    model: CableTransmission,
    link: int,
    tension_map: PretensionMap,
    q_m: NDArray[np.float64],
    tau_m: NDArray[np.float64],
    dt: float,
    q_l: NDArray[np.float64] | None = None,
    **kwargs: Any,
) -> PretensionEstimate:
    """Pretension of ``link``'s cable from one run (seed 001 §5.2): the filter's stiffness
    (:func:`estimate_stiffness`, ``kwargs`` pass on) through a fitted :class:`PretensionMap`."""
    k, sd = estimate_stiffness(model, link, q_m, tau_m, dt, q_l=q_l, **kwargs)
    t = float(tension_map.tension(k))
    return PretensionEstimate(k, sd, t, str(PretensionMap.category(t)))
