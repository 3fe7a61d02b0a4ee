"""Seed 003's winch as a nonlinear model (eqs 11–20), written from the equations in the module
docs of ``cable_core::dynamics::winch`` and docs/cdpr.md, in NumPy."""

from __future__ import annotations

import numpy as np

NAMES = [
    "torque_constant", "rotor_inertia", "rotor_viscous", "gear_ratio", "gearbox_inertia",
    "drum_inertia", "drum_viscous", "static_friction", "drum_radius", "stiffness_a",
    "stiffness_b", "ee_mass", "kp", "td", "ti", "cutoff",
]  # fmt: skip


class WinchRef:
    def __init__(
        self, values, setup="fixed", lpf=True, pretension=20.0, current_limit=10.0, eps=0.01, damping=0.0
    ):
        self.p = dict(zip(NAMES, np.asarray(values, dtype=float), strict=True))
        self.s = 1.0 if setup == "synchronized" else 0.0
        self.lpf, self.t0, self.imax, self.eps, self.c = lpf, pretension, current_limit, eps, damping

    def rest(self):
        """The working point: the integral holding the current that carries T₀."""
        p = self.p
        hold = min(p["drum_radius"] * self.t0 / (p["torque_constant"] * p["gear_ratio"]), self.imax)
        return np.array([0.0, 0.0, 0.0, 0.0, hold * p["ti"] / p["kp"] if p["kp"] else 0.0, 0.0])

    def tensions(self, x):
        p, r = self.p, self.p["drum_radius"]
        ta = self.t0 + p["stiffness_a"] * (x[2] + r * x[0]) + self.c * (x[3] + r * x[1])
        tb = self.t0 - p["stiffness_b"] * (x[2] + self.s * r * x[0]) - self.c * (x[3] + self.s * r * x[1])
        return max(ta, 0.0), max(tb, 0.0)

    def current(self, x, u):
        p = self.p
        d = x[5] if self.lpf else p["td"] * (u[1] - x[1])
        cmd = p["kp"] * ((u[0] - x[0]) + d + x[4] / p["ti"])
        return cmd, min(max(cmd, -self.imax), self.imax)

    def f(self, x, u):
        p = self.p
        j = p["rotor_inertia"] * p["gear_ratio"] ** 2 + p["gearbox_inertia"] + p["drum_inertia"]
        b = p["rotor_viscous"] * p["gear_ratio"] ** 2 + p["drum_viscous"]
        ta, tb = self.tensions(x)
        cmd, i = self.current(x, u)
        e = u[0] - x[0]
        sign = x[1] / np.sqrt(x[1] ** 2 + self.eps**2)
        torque = p["torque_constant"] * p["gear_ratio"] * i - b * x[1] - p["static_friction"] * sign
        torque -= p["drum_radius"] * ta
        winding = abs(cmd) > self.imax and p["kp"] * e * cmd > 0
        return np.array(
            [
                x[1],
                torque / j,
                x[3],
                (tb - ta) / p["ee_mass"],
                0.0 if winding else e,
                p["cutoff"] * (p["td"] * (u[1] - x[1]) - x[5]) if self.lpf else 0.0,
            ]
        )

    def h(self, x, u):
        p = self.p
        ta, tb = self.tensions(x)
        _, i = self.current(x, u)
        return np.array(
            [x[0], ta, tb, x[2], i, p["torque_constant"] * p["gear_ratio"] * i / p["drum_radius"]]
        )
