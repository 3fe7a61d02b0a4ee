"""Classical RK4 with sub-steps and zero/first-order input hold, from the textbook formulas."""

from __future__ import annotations

import numpy as np


def rk4_step(f, x, u0, um, u1, h):
    k1 = f(x, u0)
    k2 = f(x + h / 2 * k1, um)
    k3 = f(x + h / 2 * k2, um)
    k4 = f(x + h * k3, u1)
    return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def advance(f, x, ua, ub, dt, substeps):
    """One sample interval: inputs linear from ua to ub (ub = ua for zero-order hold)."""
    h = dt / substeps
    x = np.array(x, dtype=float)
    ua, ub = np.asarray(ua, dtype=float), np.asarray(ub, dtype=float)
    for j in range(substeps):
        a, b = j / substeps, (j + 1) / substeps
        x = rk4_step(f, x, ua + a * (ub - ua), ua + 0.5 * (a + b) * (ub - ua), ua + b * (ub - ua), h)
    return x


def simulate(f, h_out, inputs, x0, dt, substeps=1, hold="zoh"):
    """states[0] = x0, states[k+1] = advance(states[k]); outputs[k] = h(states[k], u[k])."""
    inputs = np.asarray(inputs, dtype=float)
    xs, ys = [np.array(x0, dtype=float)], []
    for k in range(1, len(inputs)):
        ub = inputs[k] if hold == "foh" else inputs[k - 1]
        xs.append(advance(f, xs[-1], inputs[k - 1], ub, dt, substeps))
    for k in range(len(inputs)):
        ys.append(h_out(xs[k], inputs[k]))
    return np.array(xs), np.array(ys)
