"""External joint forces: the UKF with the forces as random-walk states (seed 001 §5.3) and the
cable-stretch method with its two-Gaussian, four-quadrant classification."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cablekit._cablekit import SrUkf
from cablekit.errors import ParameterError, ShapeError
from cablekit.estimate.common import _observations, _setup, kinematic_joint_angles

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from cablekit._cablekit import CableTransmission


@dataclass(frozen=True)
class ForceEstimate:
    """External forces per estimated link ``(T, k)`` with their filter standard deviations."""

    links: list[int]
    force: NDArray[np.float64]
    std: NDArray[np.float64]
    x: NDArray[np.float64]
    nis: NDArray[np.float64]


def estimate_external_force(
    model: CableTransmission,
    q_m: NDArray[np.float64],
    tau_m: NDArray[np.float64],
    dt: float,
    *,
    links: list[int],
    q_l: NDArray[np.float64] | None = None,
    encoder_noise: float = 1e-4,
    joint_noise: float | None = None,
    force_noise: float = 20.0,
    motor_noise: float = 1.0,
    link_noise: float = 0.1,
    substeps: int | None = None,
    alpha: float = 0.5,
) -> ForceEstimate:
    """The UKF method of seed 001 §5.3: the external force (or torque) on each of ``links``
    (0-based) is a random-walk state feeding the model's external input; ``force_noise`` is
    its random-walk density (N/√s). Observations: the motor encoders, and ``q_l`` ``(T, n)``
    joint encoders where given (NaN: not measured; e.g. only the insertion axis' linear
    encoder, as in the seed).

    ``link_noise`` defaults to 0.1, ten times less than for joint states: the force state is
    what absorbs unmodelled link loads, and a link velocity left free to wander averages its
    dry friction away (on the twin, 1.0 made every basket weight read 7.5 % light: the
    friction's share)."""
    n_links = model.n_links
    if not links or any(not 0 <= i < n_links for i in links) or len(set(links)) != len(links):
        raise ParameterError(f"links must be distinct link indices in [0, {n_links}), got {links}")
    n, k = model.n_states, len(links)
    su = _setup(model, q_m, tau_m, dt, substeps, encoder_noise, motor_noise, link_noise, extra=k)
    q_m, u, x0, p0, q, substeps = su.q_m, su.u, su.x0, su.p0, su.q, su.substeps
    p0[n:, n:] = 100.0 * np.eye(k)
    q[n:, n:] = force_noise**2 * dt * np.eye(k)
    obs = _observations(model, q_m, q_l, encoder_noise, joint_noise, x0)
    ukf = SrUkf.with_input_states(
        model,
        [n_links + i for i in links],
        x0,
        p0,
        q,
        obs.r,
        dt=dt,
        substeps=substeps,
        states=obs.states,
        alpha=alpha,
    )
    res = ukf.run(u, obs.y, obs.mask)
    std = np.sqrt(np.einsum("tij,tij->ti", res.S, res.S))
    return ForceEstimate(list(links), res.x[:, n:], std[:, n:], res.x[:, :n], res.nis)


def _two_gaussians(
    s: NDArray[np.float64], iterations: int = 200
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Means and standard deviations (ascending means) of a two-component Gaussian mixture
    fitted by expectation–maximisation, started from the lower and upper thirds."""
    s = np.asarray(s, dtype=np.float64)
    lo, hi = np.quantile(s, [1 / 6, 5 / 6])
    mu = np.array([lo, hi])
    sd = np.full(2, max(np.std(s) / 2, 1e-12))
    w = np.array([0.5, 0.5])
    for _ in range(iterations):
        dens = w / sd * np.exp(-0.5 * ((s[:, None] - mu) / sd) ** 2)
        resp = dens / np.maximum(dens.sum(axis=1, keepdims=True), 1e-300)
        nk = resp.sum(axis=0)
        mu_new = (resp * s[:, None]).sum(axis=0) / nk
        sd = np.sqrt(np.maximum((resp * (s[:, None] - mu_new) ** 2).sum(axis=0) / nk, 1e-24))
        w = nk / len(s)
        if np.allclose(mu_new, mu, rtol=0, atol=1e-12 * (1 + np.abs(mu).max())):
            mu = mu_new
            break
        mu = mu_new
    order = np.argsort(mu)
    return mu[order], sd[order]


@dataclass
class CableStretchForce:
    """The cable-stretch method of seed 001 §5.3 (eqs 5.3–5.4) for one axis: the external force
    from the stretch ``S`` between the transmission-kinematics and the measured joint position,
    ``F = −(K_s·(S − S_ref) + b·Ṡ)``.

    Without load the stretch is bimodal (friction and pretension hold it at one value per
    direction of motion); :meth:`fit` fits two Gaussians to the stretch of unloaded training
    cycles (lower and upper means, the mid point between them). Each sample is then assigned a
    quadrant: above the upper mean (I) or between the mid point and it (II) take the upper mean
    as the reference; below the lower mean (III) or between it and the mid point (IV) take the
    lower mean; within ±1σ of the mid point the state is unknown and the caller's fallback (the
    UKF estimate) is used.
    """

    stiffness: float
    """``K_s`` (N/m, or N·m/rad): for a cable loop `2·k_e` at the joint."""
    damping: float
    """``b`` (N·s/m): for a cable loop `2·b_e`."""
    lower: float = float("nan")
    upper: float = float("nan")
    sigma: float = float("nan")
    upper_direction: float = float("nan")
    """Sign of the joint velocity at which the unloaded stretch sits at the upper mean (from
    :meth:`fit` with velocities; NaN without)."""

    @property
    def mid(self) -> float:
        return 0.5 * (self.lower + self.upper)

    def fit(
        self, stretch: NDArray[np.float64], velocity: NDArray[np.float64] | None = None
    ) -> CableStretchForce:
        """Fit the unloaded stretch (training cycles); returns ``self``. With the joint
        ``velocity`` of the same samples, also learn which direction of motion holds the
        stretch at the upper mean (friction's side), for ``force(..., velocity=...)``."""
        s = np.asarray(stretch, dtype=np.float64)
        if s.ndim != 1 or len(s) < 20 or not np.isfinite(s).all():
            raise ParameterError("the training stretch must be a finite 1-D array of at least 20 samples")
        mu, sd = _two_gaussians(s)
        self.lower, self.upper = float(mu[0]), float(mu[1])
        self.sigma = float(np.mean(sd))
        if velocity is not None:
            v = np.asarray(velocity, dtype=np.float64)
            if v.shape != s.shape:
                raise ShapeError(f"velocity must have the shape of the stretch {s.shape}, got {v.shape}")
            up, down = s[v > 0], s[v < 0]
            if len(up) < 10 or len(down) < 10:
                raise ParameterError("the training run must move both ways to tell the modes apart")
            self.upper_direction = 1.0 if np.mean(up) > np.mean(down) else -1.0
        return self

    def quadrant(self, stretch: NDArray[np.float64]) -> NDArray[np.int64]:
        """1–4 per sample (I–IV as above), 0 where unknown."""
        s = np.asarray(stretch, dtype=np.float64)
        q = np.where(s > self.upper, 1, np.where(s > self.mid, 2, np.where(s < self.lower, 3, 4)))
        return np.where(np.abs(s - self.mid) < self.sigma, 0, q)

    def force(
        self,
        stretch: NDArray[np.float64],
        stretch_rate: NDArray[np.float64],
        fallback: NDArray[np.float64] | None = None,
        velocity: NDArray[np.float64] | None = None,
    ) -> NDArray[np.float64]:
        """External force per sample; ``fallback`` (e.g. the UKF estimate) where the quadrant is
        unknown (NaN without one).

        The seed's rule picks the reference mean from where the stretch lies, which is right
        while the load's stretch is smaller than the gap between the modes; a larger load
        pushes every sample into quadrant I or III and half of them get the wrong reference
        (an error of ``K_s·(upper − lower)/2``, the friction level). Given the joint
        ``velocity`` (and :meth:`fit` with velocities), the reference follows the direction of
        motion instead — the physical cause of the two modes — and the quadrant is unknown
        only while the joint is at rest within ±1σ of the mid point."""
        if np.isnan(self.mid):
            raise ParameterError("fit() the unloaded training stretch first")
        s = np.asarray(stretch, dtype=np.float64)
        if velocity is None:
            ref = np.where(s > self.mid, self.upper, self.lower)
            unknown = self.quadrant(s) == 0
        else:
            if np.isnan(self.upper_direction):
                raise ParameterError("fit() with velocities to use the direction of motion")
            v = np.asarray(velocity, dtype=np.float64)
            ref = np.where(v * self.upper_direction > 0, self.upper, np.where(v == 0, self.mid, self.lower))
            unknown = (v == 0) & (np.abs(s - self.mid) < self.sigma)
        f = -(self.stiffness * (s - ref) + self.damping * np.asarray(stretch_rate, dtype=np.float64))
        fb = np.full_like(f, np.nan) if fallback is None else np.asarray(fallback, dtype=np.float64)
        return np.where(unknown, fb, f)


def stretch_and_rate(
    model: CableTransmission,
    q_m: NDArray[np.float64],
    q_l: NDArray[np.float64],
    link: int,
    dt: float,
    window: float = 0.01,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Cable stretch of ``link`` — the transmission-kinematics position minus the measured
    joint position, seed 001 eq 5.3 — and its rate by a central difference over ±``window`` s
    (quantised encoders need the window)."""
    s = kinematic_joint_angles(model, q_m)[:, link] - np.asarray(q_l, dtype=np.float64)
    k = max(1, round(window / dt))
    rate = np.zeros_like(s)
    rate[k:-k] = (s[2 * k :] - s[: -2 * k]) / (2 * k * dt)
    return s, rate
