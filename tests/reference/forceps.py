"""NumPy reference of seed 000's joint torque disturbance observer and clamping-force estimator,
written from eqs 8 and 15–17 in matrix form (a selection matrix for the tension differences,
a diagonal of arms) — not a translation of the Rust loop."""

from __future__ import annotations

import numpy as np

#: rows pick ``F¹ − F²`` of forceps A and B from ``[F_A¹, F_A², F_B¹, F_B²]``
DIFFERENCE = np.array([[1.0, -1.0, 0.0, 0.0], [0.0, 0.0, 1.0, -1.0]])


def jtdo(measured, free, r2, arm_a, arm_b, threshold, bias=(0.0, 0.0)):
    """``(F̂_D, τ̂_D, F̂_ext, F̂_CF, contact)`` for rows of ``measured`` and ``free`` ``(T, 4)``."""
    f_d = np.asarray(measured) - np.asarray(free)  # eq. 8
    tau_d = r2 * f_d @ DIFFERENCE.T  # eq. 15
    f_ext = tau_d @ np.diag([1.0 / arm_a, 1.0 / arm_b]) - np.asarray(bias)  # eq. 16
    f_cf = 0.5 * np.abs(f_ext).sum(axis=1)  # eq. 17
    return f_d, tau_d, f_ext, f_cf, np.abs(f_ext) > threshold


def _direction(dx, travel):
    """Rate-independent direction states along motor steps ``dx`` ``(T,)``: each step moves the
    state toward ``sgn dx`` by the fraction ``1 − e^{−|dx|/δ}`` of the way left."""
    out = np.empty_like(dx)
    s = 0.0
    for k, d in enumerate(dx):
        s = s + (np.sign(d) - s) * -np.expm1(-abs(d) / travel)
        out[k] = s
    return out


def physics(motors, measured, losses, r2, arm_a, arm_b, threshold):
    """The physics-informed estimator, per forceps from its motor column pair and tension pair:
    ``(F_f, τ̂_ext, F̂_ext, F̂_CF, contact)`` with ``losses`` ``(2, 9)`` in ``LOSS_NAMES`` order
    (capstan, capstan_travel, pulley_viscous, joint_coulomb, joint_travel, joint_viscous,
    spring, preload, compliance)."""
    motors, measured = np.asarray(motors), np.asarray(measured)
    t = motors.shape[0]
    f_f, tau = np.empty((t, 4)), np.empty((t, 2))
    for j in range(2):
        mu, d_c, c_p, tau_c, d_j, b, k_s, tau_0, comp = losses[j]
        x, v = motors[:, 2 * j], motors[:, 2 * j + 1]
        dx = np.diff(x, prepend=x[0])
        gain = np.exp(mu * _direction(dx, d_c))
        drag = c_p * v
        joint = np.column_stack([(measured[:, 2 * j] - drag) / gain, (measured[:, 2 * j + 1] + drag) * gain])
        diff = joint @ np.array([1.0, -1.0])
        theta = (x - 0.5 * comp * diff) / r2
        tau[:, j] = r2 * diff - tau_c * _direction(dx, d_j) - b * v / r2 - k_s * theta - tau_0
        f_f[:, 2 * j : 2 * j + 2] = measured[:, 2 * j : 2 * j + 2] - joint
    f_ext = tau @ np.diag([1.0 / arm_a, 1.0 / arm_b])
    f_cf = 0.5 * np.abs(f_ext).sum(axis=1)
    return f_f, tau, f_ext, f_cf, np.abs(f_ext) > threshold
