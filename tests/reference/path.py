"""Seed 002's path friction (eqs 7–8) in NumPy, from the module docs of
``cable_core::cdpr::path``: speed by central differences of the cable lengths, normal force
``T·(2 sin(θ_g/2) + 2 sin(θ_e/2))``, Coulomb (smoothed sign) or a Dahl state over the hauled
length (n = 1: the exact exponential relaxation)."""

from __future__ import annotations

import numpy as np


def path_friction(lengths, wrap, ee, dt, mu, sv, guide, law="dahl", smoothing=1e-3, presliding=1e-3):
    t, m = lengths.shape
    speed = np.zeros_like(lengths)
    if t > 1:
        speed[1:-1] = -(lengths[2:] - lengths[:-2]) / (2 * dt)
        speed[0] = -(lengths[1] - lengths[0]) / dt
        speed[-1] = -(lengths[-1] - lengths[-2]) / dt
    normal = ee * (2 * np.sin(guide / 2) + 2 * np.sin(wrap / 2))
    if law == "coulomb":
        state = speed / np.sqrt(speed**2 + smoothing**2)
    else:
        state = np.zeros_like(lengths)
        z = np.zeros(m)
        for k in range(1, t):
            ds = -(lengths[k] - lengths[k - 1])
            d = np.sign(ds)
            z = np.where(ds == 0, z, d + (z - d) * np.exp(-np.abs(ds) / presliding))
            state[k] = z
    friction = mu * normal * state + sv * speed
    return ee + friction, friction, speed
