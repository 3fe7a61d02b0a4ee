"""A network as one flat parameter vector, evaluated for many parameter vectors at once (torch).

Layout of ``theta`` ``(P,)``: for each layer ``l``, ``W_l`` row-major ``(n_{l+1}, n_l)`` then
``b_l``. A swarm is ``(S, P)``; :func:`forward` evaluates all ``S`` networks on the same inputs
in one batched pass (``bmm``), which is how PSO scores its particles.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch


def n_params(sizes: Sequence[int]) -> int:
    return sum(sizes[i] * sizes[i + 1] + sizes[i + 1] for i in range(len(sizes) - 1))


def unflatten(theta: torch.Tensor, sizes: Sequence[int]) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """``theta`` ``(S, P)`` → per layer ``(W (S, n_out, n_in), b (S, n_out))``."""
    out, k = [], 0
    for i in range(len(sizes) - 1):
        n_in, n_out = sizes[i], sizes[i + 1]
        w = theta[:, k : k + n_in * n_out].reshape(-1, n_out, n_in)
        k += n_in * n_out
        b = theta[:, k : k + n_out]
        k += n_out
        out.append((w, b))
    return out


def activate(z: torch.Tensor, name: str) -> torch.Tensor:
    if name == "tansig":
        return torch.tanh(z)
    if name == "logsig":
        return torch.sigmoid(z)
    return z


def forward(theta: torch.Tensor, x: torch.Tensor, sizes: Sequence[int], acts: Sequence[str]) -> torch.Tensor:
    """``theta`` ``(S, P)``, ``x`` ``(N, n_in)`` normalised → ``(S, N, n_out)`` normalised."""
    a = x.unsqueeze(0).expand(theta.shape[0], -1, -1)
    for (w, b), act in zip(unflatten(theta, sizes), acts, strict=True):
        a = activate(torch.baddbmm(b.unsqueeze(1), a, w.transpose(1, 2)), act)
    return a


def forward_one(
    theta: torch.Tensor, x: torch.Tensor, sizes: Sequence[int], acts: Sequence[str]
) -> torch.Tensor:
    """``theta`` ``(P,)``, ``x`` ``(N, n_in)`` → ``(N, n_out)``."""
    return forward(theta.unsqueeze(0), x, sizes, acts)[0]


def _derivative(a: torch.Tensor, name: str) -> torch.Tensor:
    """σ'(z) from the activation's output ``a = σ(z)``."""
    if name == "tansig":
        return 1.0 - a * a
    if name == "logsig":
        return a * (1.0 - a)
    return torch.ones_like(a)


def jacobian(theta: torch.Tensor, x: torch.Tensor, sizes: Sequence[int], acts: Sequence[str]) -> torch.Tensor:
    """d outputs / d theta by backpropagation of every output at once, rows ordered
    sample-major: ``(N·n_out, P)`` (what LM needs; checked against autograd in the tests)."""
    layers = unflatten(theta.unsqueeze(0), sizes)
    outs = [x]
    for (w, b), act in zip(layers, acts, strict=True):
        outs.append(activate(outs[-1] @ w[0].T + b[0], act))
    n, n_out = x.shape[0], sizes[-1]
    # delta[n, k, j] = d y_k / d z_j of the current layer
    delta = torch.diag_embed(_derivative(outs[-1], acts[-1]))
    blocks: list[torch.Tensor] = []
    for li in range(len(layers) - 1, -1, -1):
        a_prev = outs[li]
        d_w = delta.unsqueeze(3) * a_prev.unsqueeze(1).unsqueeze(2)  # (N, n_out, n_l, n_{l-1})
        blocks = [d_w.reshape(n, n_out, -1), delta, *blocks]
        if li > 0:
            delta = (delta @ layers[li][0][0]) * _derivative(a_prev, acts[li - 1]).unsqueeze(1)
    return torch.cat(blocks, dim=2).reshape(n * n_out, -1)


def nguyen_widrow(sizes: Sequence[int], gen: torch.Generator) -> torch.Tensor:
    """MATLAB's default initialisation (``initnw``) for the hidden layers, small uniform for
    the output layer; one flat vector."""
    parts = []
    for i in range(len(sizes) - 1):
        n_in, n_out = sizes[i], sizes[i + 1]
        if i < len(sizes) - 2:
            beta = 0.7 * n_out ** (1.0 / n_in)
            w = torch.rand(n_out, n_in, generator=gen, dtype=torch.float64) * 2 - 1
            w = beta * w / w.norm(dim=1, keepdim=True)
            b = beta * torch.linspace(-1, 1, n_out, dtype=torch.float64) * torch.sign(w[:, 0])
        else:
            w = (torch.rand(n_out, n_in, generator=gen, dtype=torch.float64) * 2 - 1) / n_in**0.5
            b = (torch.rand(n_out, generator=gen, dtype=torch.float64) * 2 - 1) / n_in**0.5
        parts += [w.reshape(-1), b]
    return torch.cat(parts)
