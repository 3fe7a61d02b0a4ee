"""What every estimation task starts from: checked arrays, the shifted inputs, the start state and
noise, the measurement channels, and the rigid-cable kinematics."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cablekit._arrays import float_array
from cablekit._cablekit import CableTransmission
from cablekit.errors import DTypeError, ParameterError, ShapeError
from cablekit.simulation import propose_step, state_indices

if TYPE_CHECKING:
    from numpy.typing import NDArray


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
    if not isinstance(model, CableTransmission):
        raise DTypeError(
            f"model must be a cablekit.CableTransmission (the joint-state, parameter and force "
            f"estimators run on a cable transmission), got {type(model).__name__}; for an "
            "antagonistic joint use cablekit.SrUkf with its own process model"
        )
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
