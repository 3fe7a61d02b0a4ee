"""NumPy reference of CDPR kinematics and statics, written from the equations (seed 002 eqs 1–5,
10; seed 003 eqs 1–8) and pulley geometry, in matrix form — not a translation of the Rust loops.

Pulleys: the pulley plane holds the swivel axis ``k`` (through the anchor ``d``) and the platform
point ``p``; in that plane (origin at the pulley centre ``c = d + r e``, axes ``e`` and ``k``) the
exit point is the tangent point of ``p`` on the circle reached clockwise from ``d``, found here
with complex numbers: ``z_exit = c + r·exp(i(arg(p − c) + arccos(r/|p − c|)))``.
"""

from __future__ import annotations

import itertools

import numpy as np


def rotation(motion: str, q: np.ndarray) -> np.ndarray:
    def rz(a):
        return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])

    def ry(a):
        return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])

    def rx(a):
        return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])

    if motion == "planar":
        return rz(q[2])
    return rz(q[5]) @ ry(q[4]) @ rx(q[3])


def _exit(d, k, r, p):
    v = p - d
    e = v - (v @ k) * k
    e /= np.linalg.norm(e)
    z = complex(v @ e - r, v @ k)  # p relative to the centre, in the (e, k) plane
    ze = r * np.exp(1j * (np.angle(z) + np.arccos(r / abs(z))))
    exit_ = d + r * e + ze.real * e + ze.imag * k
    wrap = np.mod(np.pi - np.angle(ze), 2 * np.pi)
    return exit_, wrap


def inverse_kinematics(robot: dict, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(lengths (m,), structure matrix Aᵀ (n, m))`` of ``robot`` (a dict of arrays: motion,
    anchors, attachments, pulleys {cable: (radius, axis)}) at pose ``q``."""
    motion = robot["motion"]
    planar = motion == "planar"
    a = np.array(robot["anchors"], dtype=float)
    b = np.array(robot["attachments"], dtype=float)
    rot = rotation(motion, q)
    x = np.array([q[0], q[1], 0.0 if planar else q[2]])
    rb = b @ rot.T
    p = x + rb
    if planar:
        p[:, 2] = 0.0
        a[:, 2] = 0.0
    arcs = np.zeros(len(a))
    for i, (r, k) in robot.get("pulleys", {}).items():
        a[i], wrap = _exit(a[i], np.asarray(k, float), r, p[i])
        arcs[i] = r * wrap
    ell = a - p  # seed 002 eq. 1: l_i = a_i − x − R b_i
    length = np.linalg.norm(ell, axis=1)
    u = ell / length[:, None]
    moment = np.cross(rb, u)
    if planar:
        at = np.vstack([u[:, 0], u[:, 1], moment[:, 2]])
    else:
        at = np.vstack([u.T, moment.T])  # seed 002 eq. 4
    return length + arcs, at


def closed_form(at: np.ndarray, w: np.ndarray, f_min: np.ndarray, f_max: np.ndarray) -> np.ndarray:
    """Seed 002 eq. 10: f = f_ref − A⁺ᵀ (w + Aᵀ f_ref)."""
    f_ref = 0.5 * (f_min + f_max)
    return f_ref - np.linalg.pinv(at) @ (w + at @ f_ref)


def minimum_norm(at: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Seed 003 eq. 8 with the sign of seed 002's eq. 5: f = −A⁺ᵀ w."""
    return -at.T @ np.linalg.solve(at @ at.T, w)


def capacity_margin(
    at: np.ndarray,
    w: np.ndarray,
    f_min: np.ndarray,
    f_max: np.ndarray,
    center: np.ndarray | None = None,
    half_width: np.ndarray | None = None,
    moment_length: float = 1.0,
) -> float:
    """Hyperplane shifting written from its definition: for every set of n − 1 columns of Aᵀ
    (moments divided by the moment length) the unit normal ±c from an SVD, the support
    h(c) = Σ max(f_min c·aᵢ, f_max c·aᵢ), and the margin min (h(c) + c·(w + w_c) − |c|·δ)."""
    n, m = at.shape
    scale = np.ones(n)
    scale[[2] if n == 3 else [3, 4, 5]] = 1.0 / moment_length
    a = at * scale[:, None]
    v = -(w + (0.0 if center is None else center)) * scale
    delta = (np.zeros(n) if half_width is None else half_width) * scale
    best = np.inf
    for cols in itertools.combinations(range(m), n - 1):
        u, s, _ = np.linalg.svd(a[:, cols])
        if s[-1] < 1e-9 * s[0]:
            continue  # dependent columns: no facet
        c = u[:, -1]
        for cc in (c, -c):
            p = cc @ a
            h = np.sum(np.maximum(f_min * p, f_max * p))
            best = min(best, h - cc @ v - np.abs(cc) @ delta)
    return float(best)
