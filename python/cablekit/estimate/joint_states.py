"""Joint states of a cable transmission from its motor encoders (seed 001 ch. 3), with optional
camera fusion under occlusion (ch. 4)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cablekit._cablekit import SrUkf
from cablekit.errors import ParameterError
from cablekit.estimate.common import _observations, _setup, kinematic_joint_angles
from cablekit.simulation import state_indices

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from cablekit._cablekit import CableTransmission


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
