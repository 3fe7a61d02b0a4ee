"""Estimation tasks on the square-root UKF (seed 001, chapters 3–5).

``SrUkf`` (the filter itself) is compiled; this module holds the task-level helpers that set it
up for a cable transmission and return results with named fields:

* :func:`estimate_joint_states` — joint angles and velocities of a cable transmission from its
  motor encoders and the applied motor torques (seed 001 ch. 3), with the transmission
  kinematics estimate alongside for comparison;
* :func:`kinematic_joint_angles` — the rigid-cable estimate ``q_l = T⁻¹·q_m``.
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

__all__ = ["JointStateEstimate", "estimate_joint_states", "kinematic_joint_angles"]


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
    r = encoder_noise**2 * np.eye(n_links)
    ukf = SrUkf(model, x0, p0, q, r, dt=dt, substeps=substeps, states=list(range(0, n, 4)), alpha=alpha)
    res = ukf.run(u, q_m)
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
