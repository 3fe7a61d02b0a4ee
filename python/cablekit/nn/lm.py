"""Levenberg–Marquardt (MATLAB ``trainlm``) and Bayesian regularisation (MacKay; MATLAB
``trainbr``) on a flat parameter vector.

LM step: ``Δθ = −(JᵀJ + μI)⁻¹ Jᵀe``; accepted when the sum of squares falls (``μ ← μ·μ_dec``),
else ``μ ← μ·μ_inc`` and retried up to ``μ_max``.

BR minimises ``F = β·E_D + α·E_W`` (``E_D`` = Σe², ``E_W`` = Σθ², MATLAB's scaling) with the
step ``Δθ = −(βJᵀJ + (μ+α)I)⁻¹(βJᵀe + αθ)``, then re-estimates, each epoch,
``γ = P − α·tr((βJᵀJ + αI)⁻¹) = Σλᵢ/(λᵢ + α)`` (the effective number of parameters; λ the
eigenvalues of ``βJᵀJ``), ``α = γ/(2E_W)`` and
``β = (N − γ)/(2E_D)`` (MacKay 1992; Foresee & Hagan 1997).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import torch

from cablekit.nn import flat


@dataclass
class LmOutcome:
    theta: torch.Tensor
    history: list[dict[str, float]]
    stop_reason: str


def levenberg_marquardt(
    theta: torch.Tensor,
    data: tuple[torch.Tensor, torch.Tensor],
    val: tuple[torch.Tensor, torch.Tensor] | None,
    sizes: Sequence[int],
    acts: Sequence[str],
    *,
    epochs: int,
    mu: float,
    mu_dec: float,
    mu_inc: float,
    mu_max: float,
    min_grad: float,
    max_fail: int,
    bayesian: bool = False,
    on_epoch: Callable[[dict[str, float]], None] | None = None,
) -> LmOutcome:
    x, t = data
    p = theta.numel()
    n_err = t.numel()
    eye = torch.eye(p, dtype=theta.dtype)

    def sse(th: torch.Tensor) -> float:
        return float(((flat.forward_one(th, x, sizes, acts) - t) ** 2).sum())

    def val_mse(th: torch.Tensor) -> float:
        if val is None:
            return float("nan")
        return float(((flat.forward_one(th, val[0], sizes, acts) - val[1]) ** 2).mean())

    ss_e, ss_x = sse(theta), float((theta**2).sum())
    if bayesian:
        gamma = float(p)
        alpha = 1.0 if ss_x == 0 else gamma / (2 * ss_x)
        beta = (n_err - gamma) / (2 * ss_e) if ss_e > 0 else 1.0
        if beta <= 0:  # more parameters than errors: start unregularised in β, as trainbr does
            beta = 1.0
    else:
        alpha, beta, gamma = 0.0, 1.0, float(p)
    perf = beta * ss_e + alpha * ss_x
    best_val, best_theta, fails = val_mse(theta), theta.clone(), 0
    history: list[dict[str, float]] = []
    reason = "epochs"
    for _ in range(epochs):
        j = flat.jacobian(theta, x, sizes, acts)
        e = (flat.forward_one(theta, x, sizes, acts) - t).reshape(-1)
        jj, je = j.T @ j, j.T @ e
        grad = float(torch.linalg.vector_norm(2 * (beta * je + alpha * theta)))
        if grad < min_grad:
            reason = "min_grad"
            break
        accepted = False
        while mu <= mu_max:
            step = torch.linalg.solve(beta * jj + (mu + alpha) * eye, -(beta * je + alpha * theta))
            cand = theta + step
            ss_e2, ss_x2 = sse(cand), float((cand**2).sum())
            perf2 = beta * ss_e2 + alpha * ss_x2
            if perf2 < perf:
                theta, ss_e, ss_x, perf = cand, ss_e2, ss_x2, perf2
                mu = max(mu * mu_dec, 1e-20)
                accepted = True
                break
            mu *= mu_inc
        if not accepted:
            reason = "mu_max"
            break
        if bayesian:
            # γ = P − α·tr((βJᵀJ + αI)⁻¹) = Σ λᵢ/(λᵢ + α) over the eigenvalues of βJᵀJ: the
            # same number, and well defined when βJᵀJ + αI is numerically singular.
            lam = torch.linalg.eigvalsh(beta * jj).clamp(min=0.0)
            gamma = float((lam / (lam + alpha)).sum()) if alpha > 0 else float((lam > 0).sum())
            alpha = gamma / (2 * ss_x) if ss_x > 0 else 1.0
            beta_new = (n_err - gamma) / (2 * ss_e) if ss_e > 0 else beta
            beta = beta_new if beta_new > 0 else beta
            perf = beta * ss_e + alpha * ss_x
        v = val_mse(theta)
        row = {"mse": ss_e / n_err, "val": v, "mu": mu, "grad": grad}
        if bayesian:
            row.update(alpha=alpha, beta=beta, gamma=gamma)
        history.append(row)
        if on_epoch is not None:
            on_epoch(row)
        if val is not None:
            if v < best_val:
                best_val, best_theta, fails = v, theta.clone(), 0
            else:
                fails += 1
                if fails >= max_fail:
                    reason = "validation"
                    break
    if val is not None and best_val <= val_mse(theta):
        theta = best_theta
    return LmOutcome(theta, history, reason)
