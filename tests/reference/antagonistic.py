"""Antagonistic joint (seed 000 eq. 9 with elastic cables, optional Stribeck and Dahl joint
friction, optional cable creep), from the equations in docs/models.md."""

from __future__ import annotations

import numpy as np

from tests.reference.friction import dahl_rate, elastic, smooth_sign, stribeck


class AntagonisticRef:
    def __init__(self, p: dict):
        self.p = dict(p)
        self.dahl = "dahl_coulomb" in p
        self.creep = "creep_fraction" in p
        self.i_creep = 2 + int(self.dahl)

    @property
    def n_states(self) -> int:
        return 2 + int(self.dahl) + 2 * int(self.creep)

    def _elastic(self, x, u):
        q = self.p
        s1 = u[0] - q["radius"] * x[0]
        ell = q["length_scale"]
        return (
            s1,
            float(elastic(s1, q["cable_law"], q["stiffness"], ell)),
            float(elastic(-s1, q["cable_law"], q["stiffness_return"], ell)),
        )

    def _joint_tensions(self, x, u):
        q = self.p
        _, f1, f2 = self._elastic(x, u)
        sd1 = u[1] - q["radius"] * x[1]
        w1, w2 = (x[self.i_creep], x[self.i_creep + 1]) if self.creep else (0.0, 0.0)
        t1 = max(0.0, q["pretension"] + f1 + q["damping"] * sd1 - w1)
        t2 = max(0.0, q["pretension_return"] + f2 - q["damping_return"] * sd1 - w2)
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

    def _friction(self, v):
        q = self.p
        fs = q.get("static_friction", q["coulomb"])
        vs, delta = q.get("stribeck_velocity", 1.0), q.get("stribeck_exponent", 2.0)
        return float(stribeck(v, q["coulomb"], fs, vs, delta, q["viscous"], q["smoothing"]))

    def derivative(self, x, u):
        q = self.p
        t1, t2 = self._joint_tensions(x, u)
        fc, lever = self._contact(x)
        torque = q["radius"] * (t1 - t2) - self._friction(x[1]) - lever * fc
        dx = np.zeros(self.n_states)
        if self.dahl:
            torque -= x[2]
            n = q.get("dahl_exponent", 1.0)
            dx[2] = dahl_rate(x[2], x[1], q["dahl_sigma0"], q["dahl_coulomb"], n)
        if self.creep:
            _, f1, f2 = self._elastic(x, u)
            k, tau, i = q["creep_fraction"], q["creep_time_constant"], self.i_creep
            dx[i] = (k * f1 - x[i]) / tau
            dx[i + 1] = (k * f2 - x[i + 1]) / tau
        dx[0] = x[1]
        dx[1] = torque / q["inertia"]
        return dx

    def output(self, x, u):
        q = self.p
        t1, t2 = self._joint_tensions(x, u)
        a = q["capstan_mu"] * q["capstan_wrap"] * smooth_sign(u[1], q["capstan_smoothing"])
        return np.array([t1 * np.exp(a), t2 * np.exp(-a), t1, t2, x[0], self._contact(x)[0]])


def derivative_scale(ref: AntagonisticRef, x, u):
    """Sum of the magnitudes of the terms of each derivative component (tolerance scale)."""
    q = ref.p
    t1, t2 = ref._joint_tensions(x, u)
    fc, lever = ref._contact(x)
    _, f1, f2 = ref._elastic(x, u)
    stretch_terms = q["stiffness"] * np.e * (abs(u[0]) + q["radius"] * abs(x[0]))
    side = abs(t1) + abs(t2) + stretch_terms + q["damping"] * (abs(u[1]) + q["radius"] * abs(x[1]))
    creep_terms = abs(x[ref.i_creep]) + abs(x[ref.i_creep + 1]) if ref.creep else 0.0
    dahl_term = abs(x[2]) if ref.dahl else 0.0
    fric = max(q["coulomb"], q.get("static_friction", 0.0)) + abs(q["viscous"] * x[1])
    s = (q["radius"] * (side + creep_terms) + fric + dahl_term + lever * fc) / q["inertia"]
    out = np.zeros(ref.n_states)
    out[0], out[1] = abs(x[1]), s
    if ref.dahl:
        out[2] = (
            q["dahl_sigma0"]
            * (1.0 + abs(x[2]) / q["dahl_coulomb"]) ** q.get("dahl_exponent", 1.0)
            * abs(x[1])
        )
    if ref.creep:
        i = ref.i_creep
        for j, f in ((i, f1), (i + 1, f2)):
            out[j] = (q["creep_fraction"] * (abs(f) + stretch_terms) + abs(x[j])) / q["creep_time_constant"]
    return out
