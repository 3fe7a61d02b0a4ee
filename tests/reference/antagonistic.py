"""Antagonistic joint (seed 000 eq. 9 with elastic cables), from the equations."""

from __future__ import annotations

import numpy as np

from tests.reference.friction import coulomb_viscous, run_tension, smooth_sign


class AntagonisticRef:
    def __init__(self, p: dict):
        self.p = dict(p)

    def _joint_tensions(self, x, u):
        q = self.p
        r = q["radius"]
        s1, sd1 = u[0] - r * x[0], u[1] - r * x[1]
        ell = q["length_scale"]
        t1 = run_tension(s1, sd1, q["cable_law"], q["stiffness"], ell, q["damping"], q["pretension"])
        t2 = run_tension(
            -s1, -sd1, q["cable_law"], q["stiffness_return"], ell, q["damping_return"], q["pretension_return"]
        )
        return float(t1), float(t2)

    def _contact(self, x):
        q = self.p
        if "contact_angle" not in q:
            return 0.0, 0.0
        lever = q["contact_lever_arm"]
        pen = lever * (x[0] - q["contact_angle"])
        if pen <= 0:
            return 0.0, lever
        return max(0.0, q["contact_stiffness"] * pen + q["contact_damping"] * lever * x[1]), lever

    def derivative(self, x, u):
        q = self.p
        t1, t2 = self._joint_tensions(x, u)
        fc, lever = self._contact(x)
        fric = coulomb_viscous(x[1], q["coulomb"], q["viscous"], q["smoothing"])
        return np.array([x[1], (q["radius"] * (t1 - t2) - fric - lever * fc) / q["inertia"]])

    def output(self, x, u):
        q = self.p
        t1, t2 = self._joint_tensions(x, u)
        a = q["capstan_mu"] * q["capstan_wrap"] * smooth_sign(u[1], q["capstan_smoothing"])
        return np.array([t1 * np.exp(a), t2 * np.exp(-a), t1, t2, x[0], self._contact(x)[0]])


def derivative_scale(ref: AntagonisticRef, x, u):
    q = ref.p
    t1, t2 = ref._joint_tensions(x, u)
    fc, lever = ref._contact(x)
    stretch_terms = q["stiffness"] * np.e * (abs(u[0]) + q["radius"] * abs(x[0]))
    side = abs(t1) + abs(t2) + stretch_terms + q["damping"] * (abs(u[1]) + q["radius"] * abs(x[1]))
    s = (q["radius"] * side + q["coulomb"] + abs(q["viscous"] * x[1]) + lever * fc) / q["inertia"]
    return np.array([abs(x[1]), s])
