"""NumPy reference of the network forward pass, written from the equations (MATLAB's
``mapminmax``, ``tansig``, ``logsig``, ``purelin``), not from the Rust.

``weights[l]`` is ``(n_out, n_in)``; ``x`` is ``(N, n_in)`` in physical units.
"""

from __future__ import annotations

import numpy as np


def mapminmax_apply(x, lo, hi):
    rng = hi - lo
    gain = np.where(rng > 0, 2.0 / np.where(rng > 0, rng, 1.0), 1.0)
    return (x - lo) * gain - 1.0


def mapminmax_reverse(a, lo, hi):
    rng = hi - lo
    gain = np.where(rng > 0, 2.0 / np.where(rng > 0, rng, 1.0), 1.0)
    return (a + 1.0) / gain + lo


def transfer(z, name):
    if name == "tansig":
        with np.errstate(over="ignore"):
            return 2.0 / (1.0 + np.exp(-2.0 * z)) - 1.0
    if name == "logsig":
        with np.errstate(over="ignore"):
            return 1.0 / (1.0 + np.exp(-z))
    assert name == "purelin"
    return z


def forward(x, weights, biases, activations, in_lo, in_hi, out_lo, out_hi):
    a = mapminmax_apply(np.atleast_2d(x), in_lo, in_hi)
    for w, b, act in zip(weights, biases, activations, strict=True):
        a = transfer(a @ w.T + b, act)
    return mapminmax_reverse(a, out_lo, out_hi)
