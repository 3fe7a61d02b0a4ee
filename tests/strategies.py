"""Hypothesis strategies shared by the tests: physical parameter sets, states and inputs.

The same names are used for the binding call (keywords) and the NumPy reference (dict), so a
test builds both from one draw and never from the model's own ``params()``.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import strategies as st


def _f(lo, hi):
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


def _logf(lo, hi):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: 10.0**e)


@st.composite
def transmission_params(draw, n=None, law=None, stiffness=(1e3, 1e6), min_length_scale=1e-2):
    n = draw(st.integers(1, 3)) if n is None else n
    law = draw(st.sampled_from(["linear", "exponential"])) if law is None else law
    kinds = draw(st.lists(st.sampled_from(["revolute", "prismatic"]), min_size=n, max_size=n))

    def per(lo, hi, log=False):
        s = _logf(lo, hi) if log else _f(lo, hi)
        return draw(st.lists(s, min_size=n, max_size=n))

    joint_radius = [draw(_f(0.5, 2.0)) if k == "prismatic" else draw(_logf(1e-2, 1e-1)) for k in kinds]
    link_inertia = [draw(_logf(0.05, 2.0)) if k == "prismatic" else draw(_logf(1e-3, 0.5)) for k in kinds]
    coupling = np.zeros((n, n))
    for i in range(n):
        for j in range(i):
            coupling[i, j] = draw(_f(-0.2, 0.2))
    return {
        "motor_inertia": per(1e-5, 1e-3, log=True),
        "gear_ratio": per(1.0, 30.0),
        "capstan_radius": per(2e-3, 2e-2),
        "joint_radius": joint_radius,
        "link_inertia": link_inertia,
        "cable_stiffness": per(*stiffness, log=True),
        "cable_damping": per(0.0, 2000.0),
        "pretension": per(0.0, 100.0),
        "cable_law": law,
        "length_scale": draw(_logf(min_length_scale, 1.0)) if law == "exponential" else 1.0,
        "joint_kind": kinds,
        "motor_coulomb": per(0.0, 0.1),
        "motor_viscous": per(0.0, 1e-3),
        "motor_smoothing": per(0.05, 1.0),
        "link_coulomb": per(0.0, 1.0),
        "link_viscous": per(0.0, 1e-2),
        "link_smoothing": per(1e-2, 0.5),
        "gravity_amplitude": per(-5.0, 5.0),
        "gravity_offset": per(-math.pi, math.pi),
        "coupling": coupling.tolist(),
    }


@st.composite
def transmission_point(draw, params):
    """A state near the rest-length manifold (cable stretch within ±3 mm) and an input."""
    n = len(params["motor_inertia"])
    tr = (
        np.asarray(params["joint_radius"])
        * np.asarray(params["gear_ratio"])
        / np.asarray(params["capstan_radius"])
    )
    t = np.diag(tr) @ (np.eye(n) + np.asarray(params["coupling"]))
    rho = np.asarray(params["capstan_radius"]) / np.asarray(params["gear_ratio"])
    vec = lambda lo, hi: np.array(draw(st.lists(_f(lo, hi), min_size=n, max_size=n)))  # noqa: E731
    ql, wl = vec(-1.0, 1.0), vec(-2.0, 2.0)
    stretch, stretch_rate = vec(-3e-3, 3e-3), vec(-0.05, 0.05)
    qm = t @ ql + stretch / rho
    wm = t @ wl + stretch_rate / rho
    x = np.column_stack([qm, wm, ql, wl]).ravel()
    u = np.concatenate([vec(-1.0, 1.0), vec(-1.0, 1.0)])
    return x, u


@st.composite
def antagonistic_params(draw):
    p = {
        "radius": draw(_logf(1e-3, 1e-2)),
        "stiffness": draw(_logf(1e3, 1e5)),
        "inertia": draw(_logf(1e-6, 1e-3)),
        "damping": draw(_f(0.0, 50.0)),
        "pretension": draw(_f(0.0, 30.0)),
        "cable_law": draw(st.sampled_from(["linear", "exponential"])),
        "length_scale": draw(_logf(1e-2, 1.0)),
        "coulomb": draw(_f(0.0, 1e-2)),
        "viscous": draw(_f(0.0, 1e-3)),
        "smoothing": draw(_logf(1e-2, 1.0)),
        "capstan_mu": draw(_f(0.0, 0.3)),
        "capstan_wrap": draw(_f(0.0, 2 * math.pi)),
        "capstan_smoothing": draw(_logf(1e-4, 1e-2)),
    }
    asym = draw(st.booleans())
    p["stiffness_return"] = draw(_logf(1e3, 1e5)) if asym else p["stiffness"]
    p["damping_return"] = draw(_f(0.0, 50.0)) if asym else p["damping"]
    p["pretension_return"] = draw(_f(0.0, 30.0)) if asym else p["pretension"]
    if draw(st.booleans()):
        p.update(
            static_friction=p["coulomb"] + draw(_f(0.0, 1e-2)),
            stribeck_velocity=draw(_logf(1e-2, 1.0)),
            stribeck_exponent=draw(_f(0.5, 2.5)),
        )
    if draw(st.booleans()):
        p.update(
            dahl_coulomb=draw(_logf(1e-4, 1e-2)),
            dahl_sigma0=draw(_logf(1e-3, 1.0)),
            dahl_exponent=draw(_f(0.5, 2.0)),
        )
    if draw(st.booleans()):
        p.update(creep_fraction=draw(_f(0.0, 0.9)), creep_time_constant=draw(_logf(1e-2, 10.0)))
    if draw(st.booleans()):
        p.update(
            contact_angle=draw(_f(-0.5, 0.5)),
            contact_stiffness=draw(_logf(1e2, 1e4)),
            contact_damping=draw(_f(0.0, 5.0)),
            contact_lever_arm=draw(_logf(1e-3, 2e-2)),
        )
    return p


@st.composite
def antagonistic_point(draw, params):
    theta, omega = draw(_f(-1.0, 1.0)), draw(_f(-10.0, 10.0))
    x_m = params["radius"] * theta + draw(_f(-2e-3, 2e-3))
    x = [theta, omega]
    if "dahl_coulomb" in params:
        x.append(params["dahl_coulomb"] * draw(_f(-0.99, 0.99)))
    if "creep_fraction" in params:
        x += [draw(_f(-20.0, 20.0)), draw(_f(-20.0, 20.0))]
    return np.array(x), np.array([x_m, draw(_f(-0.1, 0.1))])
