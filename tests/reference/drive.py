"""NumPy reference of the drive model (``cablekit.DriveModel``, issue #22 §3), written from its
equations: the Maxwell-slip direction states as relaxations toward ``sgn Δφ``, the causal
velocity by array indexing, the forward model fitted by ``numpy.linalg.lstsq`` on the full
design (not streamed normal equations), the estimate by inverting it."""

from __future__ import annotations

import numpy as np


def states(motor, travels):
    """``(T, m)`` direction states along the motor angle."""
    out = np.zeros((len(motor), len(travels)))
    s = np.zeros(len(travels))
    for k in range(1, len(motor)):
        d = motor[k] - motor[k - 1]
        if d != 0.0:
            s = s + (np.sign(d) - s) * -np.expm1(-abs(d) / np.asarray(travels))
        out[k] = s
    return out


def velocity(angle, dt, window):
    k = np.arange(len(angle))
    span = np.minimum(k, window)
    w = np.zeros(len(angle))
    w[1:] = (angle[1:] - angle[k[1:] - span[1:]]) / (span[1:] * dt)
    return w


def fit(runs, travels, dt, window, warmup, weights=None):
    """``(coefficients, angle coefficients)`` from ``(T, 5)`` runs; ``weights``: per run an array
    of sample weights (weighted least squares: each row scaled by the weight's square root)."""
    rows, ys, arows, ays = [], [], [], []
    for i, r in enumerate(runs):
        sw = np.ones(len(r)) if weights is None else np.sqrt(np.asarray(weights[i], dtype=float))
        th, ts, motor, tj, ja = r.T
        s = states(motor, travels)
        w = velocity(th, dt, window)
        k = int(np.ceil(warmup / dt))
        a = np.column_stack([np.ones_like(th), th, w, s, tj, s * tj[:, None]])
        rows.append((a * sw[:, None])[k:])
        ys.append((ts * sw)[k:])
        arows.append((np.column_stack([np.ones_like(th), th, ts]) * sw[:, None])[k:])
        ays.append((ja * sw)[k:])
    c = np.linalg.lstsq(np.vstack(rows), np.concatenate(ys), rcond=None)[0]
    p = np.linalg.lstsq(np.vstack(arows), np.concatenate(ays), rcond=None)[0]
    return c, p


def estimate(c, p, run, travels, dt, window):
    th, ts, motor = run[:, 0], run[:, 1], run[:, 2]
    m = len(travels)
    s = states(motor, travels)
    w = velocity(th, dt, window)
    rest = c[0] + c[1] * th + c[2] * w + s @ c[3 : 3 + m]
    gain = c[3 + m] + s @ c[4 + m :]
    return (ts - rest) / gain, p[0] + p[1] * th + p[2] * ts
