"""Particle swarm optimisation of all weights and biases (seed 000, eq. 18 and Table 1).

``v ← w·v + c₁u₁(p − x) + c₂u₂(g − x)``, ``x ← x + v``, per coordinate, with ``v`` clamped to
``±v_max`` and ``x`` to ``±x_max`` (the PSO-BP literature's clamping, which the seed omits).
Fitness is the training MSE (normalised units), minimised; the seed's "Fit > pbest" is written
for a fitness to maximise. All particles are scored in one batched torch pass.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch

from cablekit.nn import flat
from cablekit.nn.spec import PsoConfig


def pso(
    fitness: Callable[[torch.Tensor], torch.Tensor],
    dim: int,
    cfg: PsoConfig,
    gen: torch.Generator,
    on_iteration: Callable[[int, float], None] | None = None,
) -> tuple[torch.Tensor, list[float]]:
    """Minimise ``fitness`` (``(S, dim)`` → ``(S,)``) over the box ``±x_max``.

    Returns the global best position and the global best fitness after the initial swarm and
    after each iteration (non-increasing by construction).
    """
    s, dt = cfg.swarm, torch.float64

    def uniform(*shape: int) -> torch.Tensor:
        return torch.rand(*shape, generator=gen, dtype=dt)

    x = (uniform(s, dim) * 2 - 1) * cfg.x_max
    v = (uniform(s, dim) * 2 - 1) * cfg.v_max
    fit = fitness(x)
    pbest, pfit = x.clone(), fit.clone()
    i = int(torch.argmin(pfit))
    gbest, gfit = pbest[i].clone(), float(pfit[i])
    history = [gfit]
    for it in range(cfg.iterations):
        u1, u2 = uniform(s, dim), uniform(s, dim)
        if cfg.u_range == "symmetric":
            u1, u2 = u1 * 2 - 1, u2 * 2 - 1
        v = cfg.w * v + cfg.c1 * u1 * (pbest - x) + cfg.c2 * u2 * (gbest - x)
        v = v.clamp(-cfg.v_max, cfg.v_max)
        x = (x + v).clamp(-cfg.x_max, cfg.x_max)
        fit = fitness(x)
        better = fit < pfit
        pbest[better], pfit[better] = x[better], fit[better]
        i = int(torch.argmin(pfit))
        if float(pfit[i]) < gfit:
            gbest, gfit = pbest[i].clone(), float(pfit[i])
        history.append(gfit)
        if on_iteration is not None:
            on_iteration(it, gfit)
    return gbest, history


def network_fitness(
    x: torch.Tensor, t: torch.Tensor, sizes: Sequence[int], acts: Sequence[str]
) -> Callable[[torch.Tensor], torch.Tensor]:
    """Training MSE of each particle's network on normalised data ``x`` → ``t``."""

    def fitness(theta: torch.Tensor) -> torch.Tensor:
        y = flat.forward(theta, x, sizes, acts)
        return ((y - t.unsqueeze(0)) ** 2).mean(dim=(1, 2))

    return fitness
