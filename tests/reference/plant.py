"""NumPy reference of ``CdprPlant`` for a planar robot without pulleys, written from the module
docs of ``cable_core::cdpr::plant`` (seed 002 eqs 6, 7, 15; seed 003 eqs 13, 16–19) with
Coulomb pulley friction on both sides of the sensor and a Kelvin–Voigt creep element per cable."""

from __future__ import annotations

import numpy as np


def _sgn(v: float, eps: float) -> float:
    return v / np.sqrt(v * v + eps * eps)


def planar_plant(
    x,
    u,
    *,
    anchors,
    attach,
    ea,
    mass,
    izz,
    com,
    gravity,
    rest,
    winch,
    mu_d,
    wrap_d,
    mu_u,
    wrap_u,
    visc_d,
    visc_u,
    eps_path,
    damping,
    current_limit,
    eps_drum,
    creep_ratio=0.0,
    creep_tau=1.0,
    drum_scale=None,
):
    """``(dx, y)`` of the planar plant; ``winch`` a dict of seed 003's parameters."""
    m = len(anchors)
    q, v = x[:3], x[3:6]
    al, om, zi, dd = x[6 : 6 + m], x[6 + m : 6 + 2 * m], x[6 + 2 * m : 6 + 3 * m], x[6 + 3 * m : 6 + 4 * m]
    crept = x[6 + 6 * m : 6 + 7 * m]
    a_ref, w_ref, i_ff, w_ext = u[:m], u[m : 2 * m], u[2 * m : 3 * m], u[3 * m : 3 * m + 3]
    c, s = np.cos(q[2]), np.sin(q[2])
    rot = np.array([[c, -s], [s, c]])
    w = winch
    r = w["drum_radius"]
    jl = w["rotor_inertia"] * w["gear_ratio"] ** 2 + w["gearbox_inertia"] + w["drum_inertia"]
    bl = w["rotor_viscous"] * w["gear_ratio"] ** 2 + w["drum_viscous"]
    kt = w["torque_constant"] * w["gear_ratio"]
    wrench = np.zeros(3)
    ee, pul, cur = np.zeros(m), np.zeros(m), np.zeros(m)
    dx = np.zeros_like(x)
    for j in range(m):
        rb = rot @ np.asarray(attach[j][:2])
        d = np.asarray(anchors[j][:2]) - (q[:2] + rb)
        length = np.linalg.norm(d)
        e = d / length
        col = np.array([e[0], e[1], rb[0] * e[1] - rb[1] * e[0]])
        l_rate = -col @ v
        unstretched = rest[j] - r * al[j]
        elastic = length - unstretched - crept[j]
        dc = (creep_ratio * max(elastic, 0.0) - crept[j]) / creep_tau if creep_ratio > 0 else 0.0
        t_ee = max(0.0, ea[j] * elastic / unstretched + damping * (l_rate + r * om[j] - dc))
        dx[6 + 6 * m + j] = dc
        vd = -l_rate
        normal = 2 * np.sin(wrap_d / 2)  # no exit pulley: its wrap is 0
        p = max(0.0, t_ee + mu_d * normal * t_ee * _sgn(vd, eps_path) + visc_d * vd)
        vu = r * om[j]
        drum = max(0.0, p + mu_u * 2 * np.sin(wrap_u / 2) * p * _sgn(vu, eps_path) + visc_u * vu)
        err = a_ref[j] - al[j]
        cmd = w["kp"] * (err + dd[j] + zi[j] / w["ti"]) + i_ff[j]
        i = np.clip(cmd, -current_limit, current_limit)
        ee[j], pul[j], cur[j] = t_ee, p, i
        wrench += col * t_ee
        dx[6 + j] = om[j]
        k_st = 1.0 if drum_scale is None else drum_scale[j]
        friction = k_st * w["static_friction"] * _sgn(om[j], eps_drum)
        dx[6 + m + j] = (kt * i - bl * om[j] - friction - r * drum) / jl
        winding = abs(cmd) > current_limit and w["kp"] * err * cmd > 0
        dx[6 + 2 * m + j] = 0.0 if winding else err
        dx[6 + 3 * m + j] = w["cutoff"] * (w["td"] * (w_ref[j] - om[j]) - dd[j])
    rc = rot @ np.asarray(com[:2])
    mg = mass * np.asarray(gravity[:2])
    wrench += np.array([mg[0], mg[1], rc[0] * mg[1] - rc[1] * mg[0]]) + w_ext
    mm = np.array(
        [
            [mass, 0, -mass * rc[1]],
            [0, mass, mass * rc[0]],
            [-mass * rc[1], mass * rc[0], izz + mass * rc @ rc],
        ]
    )
    rhs = wrench + np.array([mass * v[2] ** 2 * rc[0], mass * v[2] ** 2 * rc[1], 0.0])
    dx[:3] = v
    dx[3:6] = np.linalg.solve(mm, rhs)
    y = np.concatenate([q, ee, pul, cur, kt / r * cur, al])
    return dx, y
