"""Coupled cable transmission (seed 001 eqs 2.3–2.8) in matrix form, from the equations.

T = diag(tr) (I + C), tr = r_l N / r_m, ρ = r_m / N
Δ = ρ ⊙ (q_m − T q_l), Δ̇ = ρ ⊙ (q̇_m − T q̇_l), γ = T_a − T_b
I_m q̈_m = τ − τ_m(q̇_m) − ρ ⊙ γ;   I_l q̈_l = Tᵀ (ρ ⊙ γ) − F_l(q̇_l) − g(q_l) + τ_ext
"""

from __future__ import annotations

import numpy as np

from tests.reference.friction import coulomb_viscous, elastic, run_tension


class TransmissionRef:
    def __init__(self, p: dict):
        self.p = {
            k: (np.asarray(v, dtype=float) if k not in ("cable_law", "joint_kind") else v)
            for k, v in p.items()
        }
        q = self.p
        self.n = len(q["motor_inertia"])
        tr = q["joint_radius"] * q["gear_ratio"] / q["capstan_radius"]
        self.T = np.diag(tr) @ (
            np.eye(self.n) + np.asarray(q["coupling"], dtype=float).reshape(self.n, self.n)
        )
        self.rho = q["capstan_radius"] / q["gear_ratio"]
        self.prismatic = np.array([k == "prismatic" for k in q["joint_kind"]])

    def _split(self, x):
        x = np.asarray(x, dtype=float).reshape(self.n, 4)
        return x[:, 0], x[:, 1], x[:, 2], x[:, 3]

    def tensions(self, x):
        q = self.p
        qm, wm, ql, wl = self._split(x)
        d = self.rho * (qm - self.T @ ql)
        dd = self.rho * (wm - self.T @ wl)
        args = (q["cable_law"], q["cable_stiffness"], q["length_scale"], q["cable_damping"], q["pretension"])
        return run_tension(d, dd, *args), run_tension(-d, -dd, *args)

    def gravity(self, ql):
        q = self.p
        angle = np.where(self.prismatic, 0.0, ql)
        return q["gravity_amplitude"] * np.cos(angle + q["gravity_offset"])

    def derivative(self, x, u):
        q = self.p
        _, wm, ql, wl = self._split(x)
        u = np.asarray(u, dtype=float)
        tau, tau_ext = u[: self.n], u[self.n :]
        ta, tb = self.tensions(x)
        gamma = ta - tb
        acc_m = (
            tau
            - coulomb_viscous(wm, q["motor_coulomb"], q["motor_viscous"], q["motor_smoothing"])
            - self.rho * gamma
        ) / q["motor_inertia"]
        joint_force = self.T.T @ (self.rho * gamma)
        acc_l = (
            joint_force
            - coulomb_viscous(wl, q["link_coulomb"], q["link_viscous"], q["link_smoothing"])
            - self.gravity(ql)
            + tau_ext
        ) / q["link_inertia"]
        return np.column_stack([wm, acc_m, wl, acc_l]).ravel()

    def output(self, x, u):
        qm, _, ql, _ = self._split(x)
        ta, tb = self.tensions(x)
        joint_force = self.T.T @ (self.rho * (ta - tb))
        return np.column_stack([qm, ql, ta, tb, joint_force]).ravel()

    def energy(self, x):
        """½ I_m q̇_m² + ½ I_l q̇_l² + Σ_sides ∫F + gravity potential."""
        q = self.p
        qm, wm, ql, wl = self._split(x)
        d = self.rho * (qm - self.T @ ql)
        k, ell = q["cable_stiffness"], q["length_scale"]
        if q["cable_law"] == "linear":
            cable = k * d * d
        else:
            cable = 2 * k * ell * ell * (np.cosh(d / ell) - 1.0)
        angle = np.where(self.prismatic, 0.0, ql)
        grav = np.where(
            self.prismatic,
            q["gravity_amplitude"] * np.cos(q["gravity_offset"]) * ql,
            q["gravity_amplitude"] * np.sin(angle + q["gravity_offset"]),
        )
        return float(
            np.sum(0.5 * q["motor_inertia"] * wm**2 + 0.5 * q["link_inertia"] * wl**2 + cable + grav)
        )

    def elastic(self, d):
        q = self.p
        return elastic(d, q["cable_law"], q["cable_stiffness"], q["length_scale"])


def tension_scale(ref: TransmissionRef, x):
    """Magnitude of the terms behind each side tension, including the stretch Δ = ρ(q_m − T q_l),
    whose rounding error scales with |q_m| + |T||q_l| (the slope of the law is bounded by k·e at
    the stretches the tests draw)."""
    q = ref.p
    qm, wm, ql, wl = ref._split(x)
    ta, tb = ref.tensions(x)
    k = q["cable_stiffness"] * np.e
    stretch_terms = ref.rho * (np.abs(qm) + np.abs(ref.T) @ np.abs(ql))
    rate_terms = ref.rho * (np.abs(wm) + np.abs(ref.T) @ np.abs(wl))
    return np.abs(ta) + np.abs(tb) + q["pretension"] + k * stretch_terms + q["cable_damping"] * rate_terms


def derivative_scale(ref: TransmissionRef, x, u):
    """Per-component magnitude of the terms summed in f(x, u): the floating-point error of any
    correct evaluation is a few ulps of this, whatever the order of operations."""
    q = ref.p
    _, wm, _, wl = ref._split(x)
    u = np.abs(np.asarray(u, dtype=float))
    side = tension_scale(ref, x)
    s_m = (u[: ref.n] + q["motor_coulomb"] + np.abs(q["motor_viscous"] * wm) + ref.rho * side) / q[
        "motor_inertia"
    ]
    s_l = (
        np.abs(ref.T.T) @ (ref.rho * side)
        + q["link_coulomb"]
        + np.abs(q["link_viscous"] * wl)
        + np.abs(q["gravity_amplitude"])
        + u[ref.n :]
    ) / q["link_inertia"]
    return np.column_stack([np.abs(wm), s_m, np.abs(wl), s_l]).ravel()


def output_scale(ref: TransmissionRef, x):
    qm, _, ql, _ = ref._split(x)
    side = tension_scale(ref, x)
    return np.column_stack([np.abs(qm), np.abs(ql), side, side, np.abs(ref.T.T) @ (ref.rho * side)]).ravel()
