"""Estimation tasks on the square-root UKF (seed 001, chapters 3–5).

``SrUkf`` (the filter itself) is compiled; this module holds the task-level helpers that set it
up for a cable transmission and return results with named fields:

* :func:`estimate_joint_states` — joint angles and velocities of a cable transmission from its
  motor encoders and the applied motor torques (seed 001 ch. 3), with the transmission
  kinematics estimate alongside for comparison;
* :func:`kinematic_joint_angles` — the rigid-cable estimate ``q_l = T⁻¹·q_m``;
* :func:`estimate_parameters` — joint state–parameter estimation of transmission parameters
  (cable stiffness and damping, coupling coefficients, pulley radius, …) as random-walk states
  with bounds (seed 001 §3.3, ch. 4).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cablekit._cablekit import SrUkf
from cablekit.errors import ParameterError, ShapeError
from cablekit.simulation import propose_step

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from cablekit._cablekit import CableTransmission

__all__ = [
    "JointStateEstimate",
    "ParameterEstimate",
    "TransmissionParameters",
    "estimate_joint_states",
    "estimate_parameters",
    "kinematic_joint_angles",
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


def kinematic_joint_angles(model: CableTransmission, q_m: NDArray[np.float64]) -> NDArray[np.float64]:
    """Joint angles from motor angles through the rigid transmission, ``q_l = T⁻¹·q_m``."""
    q_m = np.asarray(q_m, dtype=np.float64)
    tinv = np.linalg.inv(model.transmission_matrix)
    return q_m @ tinv.T


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
    n_links = model.n_links
    q_m = np.ascontiguousarray(q_m, dtype=np.float64)
    tau_m = np.ascontiguousarray(tau_m, dtype=np.float64)
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
    ext = np.zeros_like(tau_m) if external is None else np.ascontiguousarray(external, dtype=np.float64)
    if ext.shape != q_m.shape:
        raise ShapeError(f"external must have the shape of q_m {q_m.shape}, got {ext.shape}")
    n = model.n_states
    if substeps is None:
        substeps = propose_step(model, dt).substeps
    # the input over the period ending at sample k is what the servo applied at sample k − 1
    u = np.concatenate([tau_m, ext], axis=1)
    u = np.ascontiguousarray(np.vstack([u[:1], u[:-1]]))
    q_l0 = kinematic_joint_angles(model, q_m[:1])[0]
    x0 = np.zeros(n)
    x0[0::4], x0[2::4] = q_m[0], q_l0
    # discrete process noise of a white random acceleration a: velocity variance a²·dt (the
    # angles follow through the dynamics)
    q = np.diag(np.tile([0.0, motor_noise**2 * dt, 0.0, link_noise**2 * dt], n_links))
    # start: motor angles as measured, joint angles from the kinematics (cable stretch unknown,
    # ~1 mrad), at rest within ~0.1 rad/s
    p0 = np.diag(np.tile([encoder_noise**2, 1e-2, 1e-6, 1e-2], n_links))
    states = list(range(0, n, 4))
    r = encoder_noise**2 * np.eye(n_links)
    y, mask = q_m, None
    if q_camera is not None:
        cam = np.ascontiguousarray(q_camera, dtype=np.float64)
        if cam.shape != q_m.shape:
            raise ShapeError(f"q_camera must have the shape of q_m {q_m.shape}, got {cam.shape}")
        if not (np.isfinite(camera_noise) and camera_noise > 0):
            raise ParameterError(f"camera_noise must be finite and > 0, got {camera_noise}")
        if np.isinf(cam).any():
            raise ParameterError("q_camera holds ±inf; mark occluded samples with NaN")
        states += list(range(2, n, 4))
        r = np.diag(np.r_[np.full(n_links, encoder_noise**2), np.full(n_links, camera_noise**2)])
        seen = ~np.isnan(cam)
        y = np.ascontiguousarray(np.concatenate([q_m, np.where(seen, cam, 0.0)], axis=1))
        mask = np.ascontiguousarray(np.concatenate([np.ones_like(seen), seen], axis=1))
    ukf = SrUkf(model, x0, p0, q, r, dt=dt, substeps=substeps, states=states, alpha=alpha)
    res = ukf.run(u, y, mask)
    std = np.sqrt(np.einsum("tij,tij->ti", res["S"], res["S"]))  # row norms of S: √diag(S·Sᵀ)
    return JointStateEstimate(
        q_l=res["x"][:, 2::4],
        dq_l=res["x"][:, 3::4],
        q_l_std=std[:, 2::4],
        q_l_kinematics=kinematic_joint_angles(model, q_m),
        x=res["x"],
        nis=res["nis"],
        recovered=res["recovered"],
        substeps=substeps,
    )


#: per-link parameters (one index); ``coupling`` takes two
_KEYS = {"cable_stiffness", "cable_damping", "joint_radius", "link_inertia", "link_coulomb", "link_viscous"}


class TransmissionParameters:
    """Named parameters of a cable transmission (``"cable_stiffness[1]"``,
    ``"coupling[2][0]"``, … — the keyword names of :class:`CableTransmission` with 0-based
    indices): read their values, build the model with new values."""

    def __init__(self, model: CableTransmission, names: list[str]):
        self.base = model
        self.names = list(names)
        self._params = model.params()
        for name in self.names:
            self._locate(name)

    def _locate(self, name: str) -> tuple[str, tuple[int, ...]]:
        key, _, rest = name.partition("[")
        try:
            idx = tuple(int(part) for part in ("[" + rest).replace("]", "").split("[")[1:])
        except ValueError:
            idx = ()
        value = self._params.get(key)
        ok = (key in _KEYS and len(idx) == 1) or (key == "coupling" and len(idx) == 2)
        try:
            for i in idx:
                value = value[i]  # type: ignore[index]
        except (IndexError, TypeError):
            ok = False
        if not ok or (key == "coupling" and idx[1] >= idx[0]):
            raise ParameterError(
                f"unknown transmission parameter {name!r}: use cable_stiffness[i], cable_damping[i], "
                "coupling[i][j] (i > j), joint_radius[i], link_inertia[i], link_coulomb[i], link_viscous[i]"
            )
        return key, idx

    def values(self) -> NDArray[np.float64]:
        """The parameters' values in the base model."""
        out = []
        for name in self.names:
            key, idx = self._locate(name)
            v = self._params[key]
            for i in idx:
                v = v[i]
            out.append(float(v))
        return np.array(out)

    def model(self, values: list[float] | NDArray[np.float64]) -> CableTransmission:
        """The base model with the parameters set to ``values``."""
        from cablekit._cablekit import CableTransmission as _Tx

        p = {
            k: ([list(r) for r in v] if k == "coupling" else (list(v) if isinstance(v, list) else v))
            for k, v in self._params.items()
        }
        for name, v in zip(self.names, values, strict=True):
            key, idx = self._locate(name)
            if key == "coupling":
                p[key][idx[0]][idx[1]] = float(v)
            else:
                p[key][idx[0]] = float(v)
        return _Tx(**p)


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
    """
    q_m = np.ascontiguousarray(q_m, dtype=np.float64)
    tau_m = np.ascontiguousarray(tau_m, dtype=np.float64)
    n_links = model.n_links
    if q_m.ndim != 2 or q_m.shape[1] != n_links or tau_m.shape != q_m.shape:
        raise ShapeError(f"q_m and tau_m must have shape (T, {n_links}), got {q_m.shape} and {tau_m.shape}")
    theta0 = TransmissionParameters(model, params).values()
    n = model.n_states
    p = len(params)
    if substeps is None:
        substeps = propose_step(model, dt).substeps
    u = np.concatenate([tau_m, np.zeros_like(tau_m)], axis=1)
    u = np.ascontiguousarray(np.vstack([u[:1], u[:-1]]))
    scale = np.where(np.abs(theta0) > 0, np.abs(theta0), 1.0)
    x0 = np.zeros(n + p)
    x0[0:n:4] = q_m[0]
    x0[2:n:4] = kinematic_joint_angles(model, q_m[:1])[0] if q_l is None else q_l[0]
    x0[n:] = theta0
    p0 = np.diag(np.r_[np.tile([encoder_noise**2, 1e-2, 1e-6, 1e-2], n_links), (initial_spread * scale) ** 2])
    q = np.diag(
        np.r_[
            np.tile([0.0, motor_noise**2 * dt, 0.0, link_noise**2 * dt], n_links), (drift * scale) ** 2 * dt
        ]
    )
    states = list(range(0, n, 4))
    y, mask = q_m, None
    r = encoder_noise**2 * np.eye(n_links)
    if q_l is not None:
        q_l = np.ascontiguousarray(q_l, dtype=np.float64)
        if q_l.shape != q_m.shape:
            raise ShapeError(f"q_l must have the shape of q_m {q_m.shape}, got {q_l.shape}")
        if np.isinf(q_l).any():
            raise ParameterError("q_l holds ±inf; mark missing samples with NaN")
        jn = encoder_noise if joint_noise is None else joint_noise
        if not (np.isfinite(jn) and jn > 0):
            raise ParameterError(f"joint_noise must be finite and > 0, got {jn}")
        states += list(range(2, n, 4))
        seen = ~np.isnan(q_l)
        y = np.ascontiguousarray(np.concatenate([q_m, np.where(seen, q_l, 0.0)], axis=1))
        if not seen.all():
            mask = np.ascontiguousarray(np.concatenate([np.ones_like(seen), seen], axis=1))
        r = np.diag(np.r_[np.full(n_links, encoder_noise**2), np.full(n_links, jn**2)])
    ukf = SrUkf.with_parameters(
        model, list(params), x0, p0, q, r, dt=dt, substeps=substeps, states=states, bounds=bounds, alpha=alpha
    )
    res = ukf.run(u, y, mask)
    std = np.sqrt(np.einsum("tij,tij->ti", res["S"], res["S"]))
    return ParameterEstimate(
        list(params),
        res["x"][:, n:],
        std[:, n:],
        theta0,
        res["x"][:, :n],
        std[:, :n],
        res["nis"],
        res["recovered"],
    )
