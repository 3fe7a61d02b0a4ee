"""Signal operators of the diagnosis (input and sensor stages), written from their definitions
in docs/diagnosis.md (pure NumPy, loops kept literal)."""

from __future__ import annotations

import math

import numpy as np


def play(x, d):
    """Backlash play operator of half-width d, starting centred."""
    y = np.empty_like(x)
    prev = x[0]
    for k, xv in enumerate(x):
        prev = min(max(prev, xv - d), xv + d)
        y[k] = prev
    return y


def delay(x, d, dt):
    """y(t) = x(t − d), linear interpolation, first sample held before the start."""
    t = np.arange(len(x)) * dt
    return np.interp(t - d, t, x, left=x[0])


def lag(x, tau, dt):
    """τẏ + y = x, exact for an input linear between samples, y0 = x0."""
    if tau <= 0:
        return x.copy()
    a = math.exp(-dt / tau)
    y = np.empty_like(x)
    y[0] = x[0]
    for k in range(1, len(x)):
        # y_k = a y_{k-1} + ∫ response to the ramp from x_{k-1} to x_k
        slope = (x[k] - x[k - 1]) / dt
        y[k] = a * y[k - 1] + (1 - a) * x[k - 1] + slope * (dt - tau * (1 - a))
    return y


def sample_hold(x, period, phase, dt):
    """Value at the last sampling instant phase + j·period <= t, taken at the nearest sample."""
    y = np.empty_like(x)
    for k in range(len(x)):
        t = k * dt
        if t + 1e-9 * dt < phase:
            y[k] = x[0]
            continue
        j = math.floor((t - phase) / period + 1e-9 * dt / period)
        # nearest sample, halves away from zero (Python's round() would go to even)
        y[k] = x[min(math.floor((phase + j * period) / dt + 0.5), len(x) - 1)]
    return y


def velocity(x, dt):
    return np.gradient(x, dt)
