"""Seed 003's sensor signal chain in NumPy, from the module docs of
``cable_core::cdpr::sensors``: window means over (t0 + k·t_c, t0 + (k+1)·t_c], each seen from
its window's end plus the latency, ``signal[0]`` before the first."""

from __future__ import annotations

import numpy as np


def signal_chain(t, signal, conversion_time, latency):
    t, signal = np.asarray(t, float), np.asarray(signal, float)
    tol = 1e-9 * conversion_time
    t0 = t[0]
    # window index of each sample after the first: the k with end_(k-1) + tol < t <= end_k + tol
    k = np.ceil((t[1:] - t0 - tol) / conversion_time).astype(int) - 1
    k = np.maximum(k, 0)
    n_win = int(k.max()) + 1 if k.size else 0
    means = np.empty(n_win)
    last = signal[0]
    for w in range(n_win):
        inside = signal[1:][k == w]
        if inside.size:
            means[w] = inside.mean()
            last = inside[-1]
        else:
            means[w] = last
    out = np.full(t.size, signal[0])
    for w in range(n_win):
        ready = t0 + (w + 1) * conversion_time + latency
        out[t + tol >= ready] = means[w]
    return out
