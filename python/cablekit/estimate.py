"""Estimation tasks on the square-root UKF (seed 001, chapters 3–5).

``SrUkf`` (the filter itself) is compiled; this module holds the task-level helpers that set it
up for a cable transmission and return results with named fields:

* :func:`estimate_joint_states` — joint angles and velocities of a cable transmission from its
  motor encoders and the applied motor torques (seed 001 ch. 3), with the transmission
  kinematics estimate alongside for comparison;
* :func:`kinematic_joint_angles` — the rigid-cable estimate ``q_l = T⁻¹·q_m``;
* :func:`estimate_parameters` — joint state–parameter estimation of transmission parameters
  (cable stiffness and damping, coupling coefficients, pulley radius, …) as random-walk states
  with bounds (seed 001 §3.3, ch. 4);
* :func:`estimate_external_force` — external joint forces as random-walk states (the UKF
  method of seed 001 §5.3), and :class:`CableStretchForce` — the cable-stretch method with its
  two-Gaussian, four-quadrant classification;
* :func:`estimate_stiffness`, :class:`PretensionMap`, :class:`StringCalibration` — pretension
  from the filter's cable stiffness through a fitted quadratic map, its Low/Mid/High category,
  and the taut-string frequency → tension calibration (seed 001 §5.2).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cablekit._arrays import float_array
from cablekit._cablekit import DualSrUkf, SrUkf
from cablekit.errors import ParameterError, ShapeError
from cablekit.simulation import propose_step, state_indices

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from cablekit._cablekit import CableTransmission

__all__ = [
    "CableStretchForce",
    "ForceEstimate",
    "JointStateEstimate",
    "ParameterEstimate",
    "PretensionEstimate",
    "PretensionMap",
    "StringCalibration",
    "TransmissionParameters",
    "estimate_external_force",
    "estimate_joint_states",
    "estimate_parameters",
    "estimate_pretension",
    "estimate_stiffness",
    "kinematic_joint_angles",
    "stretch_and_rate",
]


@dataclass(frozen=True)
class JointStateEstimate:
    """Result of :func:`estimate_joint_states`; row ``k`` is sample ``k``."""

    q_l: NDArray[np.float64]
    """Estimated joint angles ``(T, n_links)`` (rad; m for prismatic joints)."""
    dq_l: NDArray[np.float64]
    """Estimated joint velocities ``(T, n_links)``."""
    q_l_std: NDArray[np.float64]
    """Filter standard deviation of the joint angles ``(T, n_links)``."""
    q_l_kinematics: NDArray[np.float64]
    """Transmission-kinematics estimate ``T⁻¹·q_m`` from the same encoder readings."""
    x: NDArray[np.float64]
    """Full filtered state ``(T, 4·n_links)`` in the model's state order."""
    nis: NDArray[np.float64]
    """Normalised innovation squared per step (mean ≈ number of encoders when consistent)."""
    recovered: NDArray[np.float64]
    """Downdate recoveries per step (0 in healthy operation)."""
    substeps: int
    """RK4 substeps per sample used by the filter's process model."""


@dataclass(frozen=True)
class _Observations:
    states: list[int]
    y: NDArray[np.float64]
    mask: NDArray[np.bool_] | None
    r: NDArray[np.float64]


def _observations(
    model: CableTransmission,
    q_m: NDArray[np.float64],
    q_l: NDArray[np.float64] | None,
    encoder_noise: float,
    joint_noise: float | None,
    x0: NDArray[np.float64],
    name: str = "q_l",
) -> _Observations:
    """Motor encoders always; joint angles ``q_l`` where given (NaN = not measured at that
    sample; a column that is all NaN is not a channel). Joint encoders (not a camera) also start
    ``x0``'s joint angles at their first reading. The measurement noise of the joint channels
    is ``joint_noise``."""
    n_links = q_m.shape[1]
    i_qm, i_ql = state_indices(model, "q_m"), state_indices(model, "q_l")
    states = list(i_qm)
    r = [encoder_noise**2] * n_links
    if q_l is None:
        return _Observations(states, q_m, None, np.diag(r))
    q_l = float_array(q_l, "q_l")
    if q_l.shape != q_m.shape:
        raise ShapeError(f"{name} must have the shape of q_m {q_m.shape}, got {q_l.shape}")
    if np.isinf(q_l).any():
        raise ParameterError(f"{name} holds ±inf; mark missing samples with NaN")
    jn = encoder_noise if joint_noise is None else joint_noise
    if not (np.isfinite(jn) and jn > 0):
        raise ParameterError(
            f"{'camera_noise' if name == 'q_camera' else 'joint_noise'} must be finite and > 0, got {jn}"
        )
    cols = [j for j in range(n_links) if not np.isnan(q_l[:, j]).all()]
    seen = ~np.isnan(q_l[:, cols])
    for c, j in enumerate(cols):
        if name == "q_l" and seen[0, c]:
            x0[i_ql[j]] = q_l[0, j]
    states += [i_ql[j] for j in cols]
    r += [jn**2] * len(cols)
    y = np.ascontiguousarray(np.concatenate([q_m, np.where(seen, q_l[:, cols], 0.0)], axis=1))
    mask = None
    if not seen.all():
        mask = np.ascontiguousarray(np.concatenate([np.ones((len(q_m), n_links), bool), seen], axis=1))
    return _Observations(states, y, mask, np.diag(r))


@dataclass(frozen=True)
class _Setup:
    q_m: NDArray[np.float64]
    u: NDArray[np.float64]
    x0: NDArray[np.float64]
    p0: NDArray[np.float64]
    q: NDArray[np.float64]
    substeps: int


def _setup(
    model: CableTransmission,
    q_m: NDArray[np.float64],
    tau_m: NDArray[np.float64],
    dt: float,
    substeps: int | None,
    encoder_noise: float,
    motor_noise: float,
    link_noise: float,
    extra: int = 0,
    external: NDArray[np.float64] | None = None,
) -> _Setup:
    """What every task helper starts from: checked arrays; the inputs shifted so that the one
    acting over the period ending at sample k is what the servo applied at sample k − 1; the
    start at rest with the motor angles as measured and the joint angles from the kinematics
    (cable stretch unknown, ~1 mrad); the process noise of white random accelerations (velocity
    variance a²·dt; the angles follow through the dynamics). ``extra`` zero rows and columns
    are appended for augmented states, for the caller to fill."""
    n_links = model.n_links
    q_m = float_array(q_m, "q_m")
    tau_m = float_array(tau_m, "tau_m")
    if q_m.ndim != 2 or q_m.shape[1] != n_links:
        raise ShapeError(f"q_m must have shape (T, {n_links}), got {q_m.shape}")
    if tau_m.shape != q_m.shape:
        raise ShapeError(f"tau_m must have the shape of q_m {q_m.shape}, got {tau_m.shape}")
    for name, v in (
        ("dt", dt),
        ("encoder_noise", encoder_noise),
        ("motor_noise", motor_noise),
        ("link_noise", link_noise),
    ):
        if not (np.isfinite(v) and v > 0):
            raise ParameterError(f"{name} must be finite and > 0, got {v}")
    ext = np.zeros_like(tau_m) if external is None else float_array(external, "external")
    if ext.shape != q_m.shape:
        raise ShapeError(f"external must have the shape of q_m {q_m.shape}, got {ext.shape}")
    if substeps is None:
        substeps = propose_step(model, dt).substeps
    u = np.concatenate([tau_m, ext], axis=1)
    u = np.ascontiguousarray(np.vstack([u[:1], u[:-1]]))
    n = model.n_states
    at = {k: state_indices(model, k) for k in ("q_m", "dq_m", "q_l", "dq_l")}
    x0 = np.zeros(n + extra)
    x0[at["q_m"]] = q_m[0]
    x0[at["q_l"]] = kinematic_joint_angles(model, q_m[:1])[0]
    p0_diag, q_diag = np.zeros(n + extra), np.zeros(n + extra)
    for k, p0_k, q_k in (
        ("q_m", encoder_noise**2, 0.0),
        ("dq_m", 1e-2, motor_noise**2 * dt),
        ("q_l", 1e-6, 0.0),
        ("dq_l", 1e-2, link_noise**2 * dt),
    ):
        p0_diag[at[k]], q_diag[at[k]] = p0_k, q_k
    p0, q = np.diag(p0_diag), np.diag(q_diag)
    return _Setup(q_m, u, x0, p0, q, substeps)


def kinematic_joint_angles(model: CableTransmission, q_m: NDArray[np.float64]) -> NDArray[np.float64]:
    """Joint angles from motor angles through the rigid transmission, ``q_l = T⁻¹·q_m``, for
    ``(n,)`` or ``(T, n)`` motor angles (the core's forward substitution; non-finite angles are
    a :class:`~cablekit.NotFiniteError` naming the row)."""
    return model.motor_to_joint(float_array(q_m, "q_m", (1, 2)))


def estimate_joint_states(
    model: CableTransmission,
    q_m: NDArray[np.float64],
    tau_m: NDArray[np.float64],
    dt: float,
    *,
    encoder_noise: float = 1e-4,
    motor_noise: float = 1.0,
    link_noise: float = 1.0,
    substeps: int | None = None,
    alpha: float = 1e-3,
    external: NDArray[np.float64] | None = None,
    q_camera: NDArray[np.float64] | None = None,
    camera_noise: float = 1e-2,
) -> JointStateEstimate:
    """Joint states of a cable transmission from motor encoders only (seed 001 ch. 3).

    ``q_m`` ``(T, n)`` are the measured motor angles, ``tau_m`` ``(T, n)`` the motor torques the
    servo applied at each sample (they act over the following period), ``dt`` the sample
    interval. The process model is ``model`` integrated by RK4 (``substeps`` per sample, advised
    from its stiffest mode when not given). The process noise is a white random acceleration of
    every motor and every link, with spectral densities ``motor_noise²`` and ``link_noise²``
    ((rad/s²)²·s; (m/s²)²·s for a prismatic link): the unmodelled torques. They set how far
    the filter trusts the model; on the Raven-II twin (docs/estimation.md) 1.0 for both was the
    best of a 3 × 3 grid over 0.1–10, and 10× larger values let the links drift. The
    measurement noise ``encoder_noise`` is the encoders' standard deviation (rad), quantisation
    included (a step ``Δ`` adds ``Δ/√12``). The filter starts at rest at the kinematic
    estimate of the first sample.

    **Camera fusion** (seed 001 ch. 4): ``q_camera`` ``(T, n)`` are joint angles seen by a
    camera (standard deviation ``camera_noise``), NaN where the joint is occluded. The
    observation model switches per sample: camera and encoders where the camera sees the joint,
    the encoders alone (the transmission kinematics, through the model) where it does not.
    """
    su = _setup(model, q_m, tau_m, dt, substeps, encoder_noise, motor_noise, link_noise, external=external)
    q_m, u, x0, p0, q, substeps = su.q_m, su.u, su.x0, su.p0, su.q, su.substeps
    if q_camera is not None and not (np.isfinite(camera_noise) and camera_noise > 0):
        raise ParameterError(f"camera_noise must be finite and > 0, got {camera_noise}")
    obs = _observations(model, q_m, q_camera, encoder_noise, camera_noise, x0, "q_camera")
    ukf = SrUkf(model, x0, p0, q, obs.r, dt=dt, substeps=substeps, states=obs.states, alpha=alpha)
    res = ukf.run(u, obs.y, obs.mask)
    std = np.sqrt(np.einsum("tij,tij->ti", res.S, res.S))  # row norms of S: √diag(S·Sᵀ)
    i_ql, i_dql = state_indices(model, "q_l"), state_indices(model, "dq_l")
    return JointStateEstimate(
        q_l=res.x[:, i_ql],
        dq_l=res.x[:, i_dql],
        q_l_std=std[:, i_ql],
        q_l_kinematics=kinematic_joint_angles(model, q_m),
        x=res.x,
        nis=res.nis,
        recovered=res.recovered,
        substeps=substeps,
    )


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
