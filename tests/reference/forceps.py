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
