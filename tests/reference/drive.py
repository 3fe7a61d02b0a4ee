"""NumPy reference of the drive model (``cablekit.DriveModel``, issue #22 §3), written from its
equations: the Maxwell-slip direction states as relaxations toward ``sgn Δφ``, the causal
velocity by array indexing, the angle-dependent friction ``eᵢ·clip(θ, span)·σᵢ`` and the
elements driven by the spindle angle ``hₖ·ρₖ`` (issue #37),
the forward model fitted by ``numpy.linalg.lstsq`` on the full design (not streamed normal
equations), the estimate by inverting it."""

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


def fitted_span(runs, dt, warmup, weights=None):
    """The range of the spindle angle over the fitted samples (after the warm-up, weight > 0)."""
    k = int(np.ceil(warmup / dt))
    kept = [
        r[k:, 0] if weights is None else r[k:, 0][np.asarray(weights[i])[k:] > 0] for i, r in enumerate(runs)
    ]
    th = np.concatenate(kept)
    return float(th.min()), float(th.max())


def fit(runs, travels, dt, window, warmup, weights=None, span="fitted", spindle_travels=()):
    """``(coefficients, angle coefficients)`` from ``(T, 5)`` runs; ``weights``: per run an array
    of sample weights (weighted least squares: each row scaled by the weight's square root);
    ``span``: ``"fitted"`` (the fitted samples' angle range), ``None`` (no angle-dependent
    friction) or ``(lo, hi)``; ``spindle_travels``: elements driven by the spindle angle."""
    if span == "fitted":
        span = fitted_span(runs, dt, warmup, weights)
    rows, ys, arows, ays = [], [], [], []
    for i, r in enumerate(runs):
        sw = np.ones(len(r)) if weights is None else np.sqrt(np.asarray(weights[i], dtype=float))
        th, ts, motor, tj, ja = r.T
        s = states(motor, travels)
        w = velocity(th, dt, window)
        k = int(np.ceil(warmup / dt))
        angle = [] if span is None else [np.clip(th, *span)[:, None] * s]
        rho = [states(th, spindle_travels)] if len(spindle_travels) else []
        a = np.column_stack([np.ones_like(th), th, w, s, *angle, *rho, tj, s * tj[:, None]])
        rows.append((a * sw[:, None])[k:])
        ys.append((ts * sw)[k:])
        arows.append((np.column_stack([np.ones_like(th), th, ts]) * sw[:, None])[k:])
        ays.append((ja * sw)[k:])
    c = np.linalg.lstsq(np.vstack(rows), np.concatenate(ys), rcond=None)[0]
    p = np.linalg.lstsq(np.vstack(arows), np.concatenate(ays), rcond=None)[0]
    return c, p


def estimate(c, p, run, travels, dt, window, span=None, spindle_travels=()):
    """Jaw torque and angle; ``span`` and ``spindle_travels`` as the fit's (``None``, ``()``:
    without them)."""
    th, ts, motor = run[:, 0], run[:, 1], run[:, 2]
    m = len(travels)
    s = states(motor, travels)
    w = velocity(th, dt, window)
    rest = c[0] + c[1] * th + c[2] * w + s @ c[3 : 3 + m]
    r = 3 + m
    if span is not None:
        rest = rest + np.clip(th, *span) * (s @ c[r : r + m])
        r += m
    q = len(spindle_travels)
    if q:
        rest = rest + states(th, spindle_travels) @ c[r : r + q]
        r += q
    gain = c[r] + s @ c[r + 1 :]
    return (ts - rest) / gain, p[0] + p[1] * th + p[2] * ts
