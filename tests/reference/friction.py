"""Friction and cable laws, written from the equations in docs/models.md (pure NumPy)."""

from __future__ import annotations

import numpy as np


def smooth_sign(v, eps):
    """σ_ε(v) = v / sqrt(v² + ε²)."""
    v = np.asarray(v, dtype=float)
    return v / np.sqrt(v * v + eps * eps)


def coulomb_viscous(v, coulomb, viscous, eps):
    """F_c σ_ε(v) + b v."""
    return coulomb * smooth_sign(v, eps) + viscous * np.asarray(v, dtype=float)


def stribeck(v, coulomb, static, vs, delta, viscous, eps):
    """(F_c + (F_s − F_c) exp(−|v/v_s|^δ)) σ_ε(v) + b v."""
    v = np.asarray(v, dtype=float)
    level = coulomb + (static - coulomb) * np.exp(-(np.abs(v / vs) ** delta))
    return level * smooth_sign(v, eps) + viscous * v


def capstan_ratio(v, mu, wrap, eps):
    """T_out / T_in = exp(−μ φ σ_ε(v))."""
    return np.exp(-mu * wrap * smooth_sign(v, eps))


def dahl_rate(force, v, sigma0, coulomb, n):
    """dF/dt = σ₀ |1 − F/F_c sgn v|^n sgn(1 − F/F_c sgn v) v (seed 002 eq. 8)."""
    s = 1.0 - np.asarray(force, dtype=float) / coulomb * np.sign(v)
    return sigma0 * np.abs(s) ** n * np.sign(s) * np.asarray(v, dtype=float)


def elastic(s, law, k, ell):
    """F(s): k s (linear) or k ℓ (exp(s/ℓ) − 1) (exponential)."""
    s = np.asarray(s, dtype=float)
    if law == "linear":
        return k * s
    return k * ell * np.expm1(s / ell)


def run_tension(s, sd, law, k, ell, c, t0):
    """T = max(0, T₀ + F(s) + c ṡ)."""
    return np.maximum(0.0, t0 + elastic(s, law, k, ell) + c * np.asarray(sd, dtype=float))
