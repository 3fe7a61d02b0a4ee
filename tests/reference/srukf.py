"""Square-root UKF in NumPy, written from seed 001 eqs 3.9–3.25 (van der Merwe & Wan 2001), as
the reference the Rust filter is compared with. Plain and slow on purpose: numpy's QR, a
textbook rank-one Cholesky update, and `np.linalg.solve` for the triangular systems.

Conventions: S is lower triangular with a positive diagonal (P = S Sᵀ); `fx(x, u)` propagates
one period, `hx(x, u)` measures.
"""

from __future__ import annotations

import math

import numpy as np


def weights(n: int, alpha: float = 1e-3, beta: float = 2.0, kappa: float = 0.0):
    lam = alpha**2 * (n + kappa) - n
    wm = np.full(2 * n + 1, 1.0 / (2 * (n + lam)))
    wc = wm.copy()
    wm[0] = lam / (n + lam)
    wc[0] = wm[0] + 1 - alpha**2 + beta
    return math.sqrt(n + lam), wm, wc


def cholupdate(s: np.ndarray, v: np.ndarray, sign: float) -> np.ndarray:
    """chol(S Sᵀ + sign·v vᵀ), lower; raises np.linalg.LinAlgError when not positive definite."""
    s = s.copy()
    v = v.astype(np.float64).copy()
    n = len(v)
    for k in range(n):
        r2 = s[k, k] ** 2 + sign * v[k] ** 2
        if r2 <= 0:
            raise np.linalg.LinAlgError("downdate lost positive definiteness")
        r = math.sqrt(r2)
        c, sn = r / s[k, k], v[k] / s[k, k]
        s[k, k] = r
        s[k + 1 :, k] = (s[k + 1 :, k] + sign * sn * v[k + 1 :]) / c
        v[k + 1 :] = c * v[k + 1 :] - sn * s[k + 1 :, k]
    return s


def qr_lower(compound: np.ndarray) -> np.ndarray:
    """Sᵀ = R of qr(compoundᵀ), sign-normalised: the lower Cholesky factor of compound·compoundᵀ."""
    r = np.linalg.qr(compound.T, mode="r")
    r = r * np.where(np.diag(r) < 0, -1.0, 1.0)[:, None]
    return r.T


def sigma_points(x: np.ndarray, s: np.ndarray, gamma: float) -> np.ndarray:
    """(2n+1, n): x, x + γ S[:, i], x − γ S[:, i]   (eqs 3.11, 3.16)."""
    return np.vstack([x, x + gamma * s.T, x - gamma * s.T])


class SrUkfRef:
    def __init__(self, fx, hx, x0, p0, q, r, alpha=1e-3, beta=2.0, kappa=0.0):
        self.fx, self.hx = fx, hx
        self.x = np.asarray(x0, dtype=np.float64).copy()
        self.n = len(self.x)
        self.s = np.linalg.cholesky(p0)  # eq 3.9
        self.sq = _psd_sqrt(q)
        self.sr = np.linalg.cholesky(r)
        self.gamma, self.wm, self.wc = weights(self.n, alpha, beta, kappa)

    def _rank_one(self, s, v, w0):
        return cholupdate(s, math.sqrt(abs(w0)) * v, math.copysign(1.0, w0))

    def predict(self, u):
        chi = sigma_points(self.x, self.s, self.gamma)
        chi = np.array([self.fx(c, u) for c in chi])  # eq 3.12
        x = _mean(chi, self.wm)  # eq 3.13
        comp = np.hstack([math.sqrt(self.wc[1]) * (chi[1:] - x).T, self.sq])  # eq 3.14
        s = qr_lower(comp)
        self.s = self._rank_one(s, chi[0] - x, self.wc[0])  # eq 3.15
        self.x = x

    def update(self, u, y, mask=None):
        obs = np.ones(len(y), bool) if mask is None else np.asarray(mask, bool)
        if not obs.any():
            return
        chi = sigma_points(self.x, self.s, self.gamma)  # eq 3.16
        ys = np.array([self.hx(c, u) for c in chi])[:, obs]  # eq 3.17
        yhat = _mean(ys, self.wm)  # eq 3.18
        r_obs = (self.sr @ self.sr.T)[np.ix_(obs, obs)]
        comp = np.hstack([math.sqrt(self.wc[1]) * (ys[1:] - yhat).T, np.linalg.cholesky(r_obs)])  # eq 3.19
        sy = self._rank_one(qr_lower(comp), ys[0] - yhat, self.wc[0])  # eq 3.20
        pxy = ((chi - self.x).T * self.wc) @ (ys - yhat)  # eq 3.21
        k = np.linalg.solve(sy.T, np.linalg.solve(sy, pxy.T)).T  # eq 3.22: (P_xy / S_yᵀ) / S_y
        self.x = self.x + k @ (np.asarray(y)[obs] - yhat)  # eq 3.23
        u_mat = k @ sy  # eq 3.24
        s = self.s
        for j in range(u_mat.shape[1]):  # eq 3.25
            s = cholupdate(s, u_mat[:, j], -1.0)
        self.s = s

    def step(self, u, y, mask=None):
        self.predict(u)
        self.update(u, y, mask)

    @property
    def p(self) -> np.ndarray:
        return self.s @ self.s.T


def _mean(points: np.ndarray, wm: np.ndarray) -> np.ndarray:
    """Σ Wᵢ·χᵢ summed as χ₀ + Σᵢ₌₁ Wᵢ·(χᵢ − χ₀) (the weights sum to one): at α = 1e-3 the
    literal sum cancels terms weighted ±1e6 and loses six digits."""
    return points[0] + wm[1:] @ (points[1:] - points[0])


def _psd_sqrt(q: np.ndarray) -> np.ndarray:
    """A square root of a positive semi-definite matrix (Cholesky when definite)."""
    try:
        return np.linalg.cholesky(q)
    except np.linalg.LinAlgError:
        w, v = np.linalg.eigh(q)
        return v * np.sqrt(np.clip(w, 0.0, None))
