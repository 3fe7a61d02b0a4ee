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
    """y(t) = x(t − d): the Catmull–Rom cubic through the four samples around t − d (the
    spline with tangents (x[j+1] − x[j−1])/2), indices clamped to the record."""
    n = len(x)
    s = np.arange(n) - d / dt  # fractional sample index of t − d
    j = np.floor(s).astype(int)
    u = s - j

    def at(i):
        return x[np.clip(i, 0, n - 1)]

    p0, p1, p2, p3 = at(j - 1), at(j), at(j + 1), at(j + 2)
    # Hermite basis with the Catmull–Rom tangents
    m1, m2 = (p2 - p0) / 2, (p3 - p1) / 2
    h00, h10 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u
    h01, h11 = -2 * u**3 + 3 * u**2, u**3 - u**2
    return h00 * p1 + h10 * m1 + h01 * p2 + h11 * m2


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
