"""Train a multilayer perceptron (torch, float64): PSO-BPNN, LM, Bayesian regularisation,
Adam, L-BFGS — with MATLAB's conventions (``mapminmax`` to [−1, 1], a seeded random split,
validation early stopping after ``max_fail`` failures).

Everything runs in normalised units; the reported MSEs are in physical units (N² for tensions).
Deterministic for a given seed (one ``torch.Generator``, one NumPy ``Generator``).
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
import torch

from cablekit._threads import choose_threads, torch_threads
from cablekit.diagnose.progress import Progress
from cablekit.errors import NotFiniteError, ParameterError, ShapeError
from cablekit.nn import flat
from cablekit.nn.export import data_sha256
from cablekit.nn.lm import levenberg_marquardt
from cablekit.nn.mapminmax import F64, MapMinMax
from cablekit.nn.pso import network_fitness, pso
from cablekit.nn.spec import ACTIVATIONS, TrainConfig, TrainResult


def _checked(x: F64, y: F64) -> tuple[F64, F64]:
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if y.ndim == 1:
        y = y[:, None]
    if x.ndim != 2 or y.ndim != 2 or x.shape[0] != y.shape[0]:
        raise ShapeError(f"x must be (N, n_in) and y (N, n_out) with the same N; got {x.shape}, {y.shape}")
    if x.shape[0] < 10:
        raise ShapeError(f"need at least 10 samples, got {x.shape[0]}")
    for name, a in (("x", x), ("y", y)):
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise NotFiniteError(f"{name} holds a non-finite value at flat index {bad[0]}")
    return x, y


def split_indices(n: int, cfg: TrainConfig) -> dict[str, np.ndarray]:
    """Seeded random test / validation / training indices (MATLAB ``dividerand``)."""
    perm = np.random.default_rng(cfg.seed).permutation(n)
    n_test = round(cfg.test_fraction * n)
    rest = perm[n_test:]
    n_val = 0 if cfg.method == "br" else round(cfg.val_fraction * rest.size)
    return {"test": np.sort(perm[:n_test]), "val": np.sort(rest[:n_val]), "train": np.sort(rest[n_val:])}


def _adam(theta, tr, val, sizes, acts, cfg: TrainConfig, gen, bar):  # type: ignore[no-untyped-def]
    x, t = tr
    p = torch.nn.Parameter(theta.clone())
    opt = torch.optim.Adam([p], lr=cfg.lr)
    history: list[dict[str, float]] = []
    best, best_theta, fails, reason = np.inf, p.detach().clone(), 0, "epochs"
    for _ in range(cfg.epochs):
        order = torch.randperm(x.shape[0], generator=gen)
        for k in range(0, x.shape[0], cfg.batch_size):
            idx = order[k : k + cfg.batch_size]
            opt.zero_grad()
            loss = ((flat.forward_one(p, x[idx], sizes, acts) - t[idx]) ** 2).mean()
            loss.backward()
            opt.step()
        reason, stop, best, best_theta, fails = _epoch_end(
            p.detach(), tr, val, sizes, acts, cfg, history, best, best_theta, fails, bar
        )
        if stop:
            break
    return (best_theta if val is not None else p.detach()), history, reason


def _lbfgs(theta, tr, val, sizes, acts, cfg: TrainConfig, bar):  # type: ignore[no-untyped-def]
    x, t = tr
    p = torch.nn.Parameter(theta.clone())
    opt = torch.optim.LBFGS([p], lr=1.0, max_iter=10, history_size=20, line_search_fn="strong_wolfe")

    def closure() -> torch.Tensor:
        opt.zero_grad()
        loss = ((flat.forward_one(p, x, sizes, acts) - t) ** 2).mean()
        loss.backward()
        return loss

    history: list[dict[str, float]] = []
    best, best_theta, fails, reason = np.inf, p.detach().clone(), 0, "epochs"
    for _ in range(cfg.epochs):
        opt.step(closure)
        reason, stop, best, best_theta, fails = _epoch_end(
            p.detach(), tr, val, sizes, acts, cfg, history, best, best_theta, fails, bar
        )
        if stop:
            break
    return (best_theta if val is not None else p.detach()), history, reason


def _epoch_end(theta, tr, val, sizes, acts, cfg, history, best, best_theta, fails, bar):  # type: ignore[no-untyped-def]
    with torch.no_grad():
        mse = float(((flat.forward_one(theta, tr[0], sizes, acts) - tr[1]) ** 2).mean())
        v = (
            float(((flat.forward_one(theta, val[0], sizes, acts) - val[1]) ** 2).mean())
            if val
            else float("nan")
        )
    history.append({"mse": mse, "val": v})
    bar.advance(f"mse {mse:.3g}")
    if not np.isfinite(mse):
        return "diverged", True, best, best_theta, fails
    if val is None:
        return "epochs", False, best, best_theta, fails
    if v < best:
        return "epochs", False, v, theta.clone(), 0
    fails += 1
    return (
        ("validation", True, best, best_theta, fails)
        if fails >= cfg.max_fail
        else ("epochs", False, best, best_theta, fails)
    )


def train_mlp(x: F64, y: F64, config: TrainConfig | None = None, **overrides: object) -> TrainResult:
    """Train on ``x`` ``(N, n_in)`` → ``y`` ``(N, n_out)`` (physical units).

    ``config`` (or keyword overrides of :class:`TrainConfig`, e.g. ``method="br"``,
    ``hidden=(20,)``, ``seed=3``) says what to train. The test part (``test_fraction``) is never
    seen by training or early stopping; its MSE is the figure to compare.
    """
    cfg = replace(config or TrainConfig(), **overrides)  # type: ignore[arg-type]
    cfg.check()
    x, y = _checked(x, y)
    split = split_indices(x.shape[0], cfg)
    if split["train"].size < 2:
        raise ParameterError("the split leaves fewer than 2 training samples")
    fit_rows = np.concatenate([split["train"], split["val"]])
    imap, omap = MapMinMax.fit(x[fit_rows], "x"), MapMinMax.fit(y[fit_rows], "y")
    act = ACTIVATIONS[cfg.activation]
    sizes = [x.shape[1], *cfg.hidden, y.shape[1]]
    acts = [act] * len(cfg.hidden) + ["purelin"]

    def part(name: str) -> tuple[torch.Tensor, torch.Tensor] | None:
        idx = split[name]
        if idx.size == 0:
            return None
        return torch.from_numpy(imap.apply(x[idx])), torch.from_numpy(omap.apply(y[idx]))

    tr, val = part("train"), part("val")
    assert tr is not None
    # LM's J^T J dominates a step: N * P^2 multiply-adds (PSO's swarm x N x P is smaller)
    n_params = flat.n_params(sizes)
    threads = choose_threads(2.0 * tr[0].shape[0] * n_params**2, cfg.threads)
    with torch_threads(threads):
        result = _train(x, y, cfg, split, imap, omap, sizes, acts, tr, val)
    result.threads = threads
    return result


def _train(x, y, cfg, split, imap, omap, sizes, acts, tr, val):  # type: ignore[no-untyped-def]
    """The training of :func:`train_mlp` once the data are split and normalised."""
    gen = torch.Generator().manual_seed(cfg.seed)
    t0 = time.perf_counter()
    pso_history: list[float] = []
    with torch.no_grad():
        if cfg.method.startswith("pso"):
            with Progress(cfg.pso.iterations, "PSO", enabled=cfg.progress) as bar:
                theta, pso_history = pso(
                    network_fitness(tr[0], tr[1], sizes, acts),
                    flat.n_params(sizes),
                    cfg.pso,
                    gen,
                    on_iteration=lambda _i, f: bar.advance(f"best mse {f:.3g}"),
                )
        else:
            theta = flat.nguyen_widrow(sizes, gen)
    label = {"pso-lm": "LM", "lm": "LM", "br": "LM+BR", "adam": "Adam", "pso-adam": "Adam", "lbfgs": "L-BFGS"}
    with Progress(max(cfg.epochs, 1), label[cfg.method], enabled=cfg.progress) as bar:
        if cfg.method in ("pso-lm", "lm", "br"):
            with torch.no_grad():
                out = levenberg_marquardt(
                    theta,
                    tr,
                    val,
                    sizes,
                    acts,
                    epochs=cfg.epochs,
                    mu=5e-3 if cfg.method == "br" else cfg.mu,
                    mu_dec=cfg.mu_dec,
                    mu_inc=cfg.mu_inc,
                    mu_max=cfg.mu_max,
                    min_grad=cfg.min_grad,
                    max_fail=cfg.max_fail,
                    bayesian=cfg.method == "br",
                    on_epoch=lambda r: bar.advance(f"mse {r['mse']:.3g}"),
                )
            theta, history, reason = out.theta, out.history, out.stop_reason
        elif cfg.method in ("adam", "pso-adam"):
            theta, history, reason = _adam(theta, tr, val, sizes, acts, cfg, gen, bar)
        else:
            theta, history, reason = _lbfgs(theta, tr, val, sizes, acts, cfg, bar)
    elapsed = time.perf_counter() - t0
    layers = flat.unflatten(theta.detach().unsqueeze(0), sizes)
    result = TrainResult(
        weights=[w[0].numpy().copy() for w, _ in layers],
        biases=[b[0].numpy().copy() for _, b in layers],
        activations=acts,
        input_map=imap,
        output_map=omap,
        config=cfg,
        train_mse=float("nan"),
        test_mse=float("nan"),
        test_mse_per_output=np.full(y.shape[1], np.nan),
        train_time_s=elapsed,
        split=split,
        history=history,
        pso_history=pso_history,
        stop_reason=reason,
        data_sha256=data_sha256(x, y),
    )
    result.train_mse = float(np.mean((result.predict(x[split["train"]]) - y[split["train"]]) ** 2))
    if split["test"].size:
        err = result.predict(x[split["test"]]) - y[split["test"]]
        result.test_mse_per_output = np.mean(err**2, axis=0)
        result.test_mse = float(np.mean(err**2))
    return result
