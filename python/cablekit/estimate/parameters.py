"""Joint state–parameter estimation of transmission parameters as bounded random-walk states
(seed 001 §3.3, ch. 4), single or dual filter."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cablekit._arrays import float_array
from cablekit._cablekit import DualSrUkf, SrUkf
from cablekit.errors import ParameterError
from cablekit.estimate.common import _observations, _setup

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from cablekit._cablekit import CableTransmission


class TransmissionParameters:
    """Named parameters of a cable transmission (``"cable_stiffness[1]"``,
    ``"coupling[2][0]"``, … — the keyword names of :class:`CableTransmission` with 0-based
    indices): read their values, build the model with new values."""

    def __init__(self, model: CableTransmission, names: list[str]):
        self.base = model
        self.names = list(names)
        self.values()  # the core parses and checks every name (ParameterError otherwise)

    def values(self) -> NDArray[np.float64]:
        """The parameters' values in the base model."""
        return self.base.parameter_values(self.names)

    def model(self, values: list[float] | NDArray[np.float64]) -> CableTransmission:
        """The base model with the parameters set to ``values``."""
        return self.base.with_parameter_values(self.names, float_array(values, "values", 1))


@dataclass(frozen=True)
class ParameterEstimate:
    """Result of :func:`estimate_parameters`; row ``k`` is sample ``k``."""

    names: list[str]
    """Parameter names, in column order."""
    values: NDArray[np.float64]
    """Estimated parameters over time ``(T, p)``."""
    std: NDArray[np.float64]
    """Their filter standard deviations ``(T, p)``."""
    initial: NDArray[np.float64]
    """Starting values (the model's)."""
    x: NDArray[np.float64]
    """Filtered transmission states ``(T, 4·n_links)``."""
    x_std: NDArray[np.float64]
    """Their standard deviations."""
    nis: NDArray[np.float64]
    recovered: NDArray[np.float64]

    @property
    def final(self) -> dict[str, float]:
        """The last estimate of every parameter."""
        return {k: float(v) for k, v in zip(self.names, self.values[-1], strict=True)}


def estimate_parameters(
    model: CableTransmission,
    params: list[str],
    q_m: NDArray[np.float64],
    tau_m: NDArray[np.float64],
    dt: float,
    *,
    q_l: NDArray[np.float64] | None = None,
    encoder_noise: float = 1e-4,
    joint_noise: float | None = None,
    initial_spread: float = 0.3,
    drift: float = 1e-4,
    bounds: list[tuple[float, float]] | None = None,
    motor_noise: float = 1.0,
    link_noise: float = 1.0,
    substeps: int | None = None,
    alpha: float = 0.5,
    method: str = "joint",
) -> ParameterEstimate:
    """Joint state–parameter estimation (seed 001 §3.3, ch. 4) of the named transmission
    parameters from motor encoders, applied torques and — offline, as the seed identified its
    coupling coefficients — joint encoders ``q_l``.

    The parameters start at the model's values with a standard deviation of
    ``initial_spread`` × their magnitude and walk randomly at ``drift`` × their magnitude per
    √s; ``bounds`` (``(lower, upper)`` per parameter) are enforced on every sigma point and on
    the mean, on top of the physical ranges (positive stiffness, radius and inertia;
    non-negative damping and friction). ``alpha`` defaults to 0.5: the seed's 1e-3 loses digits
    on stiff cables (docs/estimation.md).

    ``q_l`` may be a camera's joint angles (seed 001 ch. 4): NaN where there is no frame or the
    joint is occluded, with ``joint_noise`` its standard deviation (default ``encoder_noise``).

    ``method="joint"`` augments the state with the parameters (one filter); ``method="dual"``
    runs a state filter and a parameter filter side by side (eqs 3.7–3.8; the parameters'
    measurement is the state filter's last estimate propagated with each parameter sigma
    point). ``x_std`` and ``nis`` are not available from the dual filter (NaN).
    """
    if method not in ("joint", "dual"):
        raise ParameterError(f"method must be 'joint' or 'dual', got {method!r}")
    theta0 = TransmissionParameters(model, params).values()
    n, p = model.n_states, len(params)
    su = _setup(model, q_m, tau_m, dt, substeps, encoder_noise, motor_noise, link_noise, extra=p)
    q_m, u, x0, p0, q, substeps = su.q_m, su.u, su.x0, su.p0, su.q, su.substeps
    scale = np.where(np.abs(theta0) > 0, np.abs(theta0), 1.0)
    x0[n:] = theta0
    p0[n:, n:] = np.diag((initial_spread * scale) ** 2)
    q[n:, n:] = np.diag((drift * scale) ** 2 * dt)
    obs = _observations(model, q_m, q_l, encoder_noise, joint_noise, x0)
    if method == "dual":
        c = np.ascontiguousarray
        dual = DualSrUkf(
            model,
            list(params),
            c(x0[:n]),
            c(p0[:n, :n]),
            c(q[:n, :n]),
            c(p0[n:, n:]),
            c(q[n:, n:]),
            obs.r,
            dt=dt,
            substeps=substeps,
            states=obs.states,
            bounds=bounds,
            alpha=alpha,
        )
        out = dual.run(u, obs.y, obs.mask)
        nan = np.full((len(u), n), np.nan)
        return ParameterEstimate(
            list(params),
            out.theta,
            out.theta_std,
            theta0,
            out.x,
            nan,
            np.full(len(u), np.nan),
            np.zeros(len(u)),
        )
    ukf = SrUkf.with_parameters(
        model,
        list(params),
        x0,
        p0,
        q,
        obs.r,
        dt=dt,
        substeps=substeps,
        states=obs.states,
        bounds=bounds,
        alpha=alpha,
    )
    res = ukf.run(u, obs.y, obs.mask)
    std = np.sqrt(np.einsum("tij,tij->ti", res.S, res.S))
    return ParameterEstimate(
        list(params),
        res.x[:, n:],
        std[:, n:],
        theta0,
        res.x[:, :n],
        std[:, :n],
        res.nis,
        res.recovered,
    )
