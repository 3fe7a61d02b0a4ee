"""Networks: the forward pass of a trained MLP (the forceps' 4-10-4, tansig, MATLAB
``mapminmax`` on both sides) against torch eager and onnxruntime, and PSO-BPNN training against
pyswarms + torch.

* Forward: cablekit's ``Mlp`` (Rust) against a torch ``nn.Module`` holding the same weights and
  normalisation in float64, and onnxruntime on ``cablekit.nn.onnx_model`` of the same network —
  one sample per call (a controller's path: ``predict_into``) and a batch of rows (``predict``,
  parallel, GIL released; torch with its default threads and with one, since its default pool
  spins against other load on a shared machine). Every side converts from and to NumPy, as a
  user's call does. The outputs agree to 1e-12 of the output range (the same float64 operations
  in another order).
* Training: seed 000's Table 1 (10 particles, 30 iterations, c₁ = c₂ = 1.49445, w = 1, the
  position and velocity clamps; 4-10-4; 100 epochs, validation stop after 6 failures) on the
  forceps free-motion twin with cablekit's split and normalisation, against pyswarms'
  ``GlobalBestPSO`` with the same swarm settings (a torch fitness) followed by torch's Adam
  (torch has no Levenberg–Marquardt), both on one torch thread. Training is stochastic and the
  optimisers differ, so the
  check is on the outcome: both test MSEs (physical units, the held-out 10 %) within a factor
  of :data:`LOSS_FACTOR` of each other and below a tenth of the targets' variance.
"""

from __future__ import annotations

import contextlib
import functools
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from .core import Config, Kernel, Pair, Peer, Side, Verdict, both, close

FORWARD_TOL = 1e-12
#: the largest ratio of the two training outcomes' test MSEs that counts as the same result
LOSS_FACTOR = 3.0
#: torch threads of both trainings: torch's default of one per core spins against any other
#: load on a shared machine (docs/benchmarks.md, "A shared machine": 2.5× to 100× slower)
THREADS = 1


@functools.cache
def _network() -> dict[str, Any]:
    """A 4-10-4 tansig network on the forceps inputs' range, weights drawn once (seeded)."""
    from cablekit.nn import MapMinMax, Mlp
    from cablekit.nn.datasets import forceps_free_motion
    from cablekit.nn.export import write_weights

    data = forceps_free_motion()
    rng = np.random.default_rng(7)
    weights = [rng.normal(0, 0.5, (10, 4)), rng.normal(0, 0.3, (4, 10))]
    biases = [rng.normal(0, 0.2, 10), rng.normal(0, 0.1, 4)]
    imap, omap = MapMinMax.fit(data.x), MapMinMax.fit(data.y)
    with tempfile.TemporaryDirectory() as tmp:
        path = write_weights(
            Path(tmp) / "net.safetensors", weights, biases, ["tansig", "purelin"], imap, omap
        )
        mlp = Mlp.load(path)
    span = float(np.max(omap.max - omap.min))
    return {"mlp": mlp, "x": np.ascontiguousarray(data.x), "w": weights, "b": biases, "imap": imap,
            "omap": omap, "span": span}  # fmt: skip


def _rows(cfg: Config, batch: bool) -> np.ndarray:
    x = _network()["x"]
    n = (10_000 if cfg.quick else 100_000) if batch else (50 if cfg.quick else 200)
    return np.ascontiguousarray(np.resize(x, (n, x.shape[1])))


def _torch_net() -> Any:
    import torch

    d = _network()

    class Net(torch.nn.Module):
        """The network as a torch user writes it: normalise, Linear–Tanh–Linear, denormalise."""

        def __init__(self) -> None:
            super().__init__()
            self.hidden = torch.nn.Linear(4, 10).double()
            self.out = torch.nn.Linear(10, 4).double()
            with torch.no_grad():
                for layer, w, b in zip((self.hidden, self.out), d["w"], d["b"], strict=True):
                    layer.weight.copy_(torch.from_numpy(w))
                    layer.bias.copy_(torch.from_numpy(b))
            for name, value in (("imin", d["imap"].min), ("igain", d["imap"].gain),
                                ("omin", d["omap"].min), ("ogain", d["omap"].gain)):  # fmt: skip
                self.register_buffer(name, torch.from_numpy(np.asarray(value, dtype=np.float64)))

        def forward(self, x: Any) -> Any:
            a = (x - self.imin) * self.igain - 1.0
            a = self.out(torch.tanh(self.hidden(a)))
            return (a + 1.0) / self.ogain + self.omin

    net = Net().eval()

    def call(x: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return net(torch.from_numpy(x)).numpy()

    return call


def torch_threads(n: int | None, fn: Any) -> Any:
    """``fn`` run with ``n`` torch threads (``None``: torch's default, as it stands)."""
    if n is None:
        return fn
    import torch

    def call(*args: Any) -> Any:
        before = torch.get_num_threads()
        torch.set_num_threads(n)
        try:
            return fn(*args)
        finally:
            torch.set_num_threads(before)

    return call


def _onnx_call() -> Any:
    import onnxruntime as ort

    from cablekit.nn import onnx_model

    model = onnx_model(_network()["mlp"])
    session = ort.InferenceSession(model.SerializeToString(), providers=["CPUExecutionProvider"])
    name = session.get_inputs()[0].name

    def call(x: np.ndarray) -> np.ndarray:
        return session.run(None, {name: x})[0]

    return call


def agree_outputs(what: str):
    """Outputs relative to the network's output range, to :data:`FORWARD_TOL`."""
    span = _network()["span"]
    return lambda a, b: close(np.asarray(a) / span, np.asarray(b) / span, FORWARD_TOL, f"{what}, relative")


def _forward_pair(cfg: Config, peer: str, batch: bool, threads: int | None = None) -> Pair:
    """``threads``: torch's thread count for the peer (``None``: its default)."""
    d = _network()
    mlp, rows = d["mlp"], _rows(cfg, batch)
    call = torch_threads(threads, _torch_net()) if peer == "torch" else _onnx_call()
    label = "torch eager (float64 nn.Module)" if peer == "torch" else "onnxruntime (CPU, float64 ONNX)"
    if batch:
        pool = "its default threads" if threads is None else f"{threads} thread"
        return Pair(
            Side(f"Mlp.predict, {len(rows):,} rows", lambda: mlp.predict(rows), len(rows)),
            Side(f"{label}, {len(rows):,} rows, {pool}", lambda: call(rows), len(rows)),
            agree_outputs(f"{len(rows):,} rows"),
            "row",
        )
    out = np.empty(mlp.n_outputs)
    x1 = np.ascontiguousarray(rows[:1])

    def ours_one() -> None:
        mlp.predict_into(rows[0], out)

    def ours_all() -> np.ndarray:
        res = np.empty((len(rows), mlp.n_outputs))
        for k in range(len(rows)):
            mlp.predict_into(rows[k], out)
            res[k] = out
        return res

    def theirs_all() -> np.ndarray:
        return np.vstack([call(np.ascontiguousarray(rows[k : k + 1])) for k in range(len(rows))])

    return Pair(
        Side("Mlp.predict_into, one sample", ours_one, 1, ours_all),
        Side(f"{label}, one sample", lambda: call(x1), 1, theirs_all),
        agree_outputs(f"{len(rows)} samples one by one"),
        "sample",
    )


# ---- training ------------------------------------------------------------------------------------


@functools.cache
def _training() -> dict[str, Any]:
    from cablekit.nn import MapMinMax
    from cablekit.nn.datasets import forceps_free_motion
    from cablekit.nn.spec import TrainConfig
    from cablekit.nn.train import split_indices

    data = forceps_free_motion()
    # the split of every method but "br"; one torch thread, as the peer gets
    cfg = TrainConfig(method="pso-adam", seed=0, threads=THREADS)
    split = split_indices(len(data.x), cfg)
    fit_rows = np.concatenate([split["train"], split["val"]])
    imap, omap = MapMinMax.fit(data.x[fit_rows]), MapMinMax.fit(data.y[fit_rows])
    test_y = data.y[split["test"]]
    return {"x": data.x, "y": data.y, "split": split, "imap": imap, "omap": omap, "cfg": cfg,
            "var": float(np.mean(np.var(test_y, axis=0)))}  # fmt: skip


def pyswarms_torch(d: dict[str, Any]) -> float:
    """PSO-BPNN as a pyswarms + torch user writes it: ``GlobalBestPSO`` over the flat weights
    (torch fitness), then Adam from the best particle with validation early stopping. Returns the
    test MSE in physical units."""
    import torch

    cfg, pso = d["cfg"], d["cfg"].pso
    imap, omap, split = d["imap"], d["omap"], d["split"]

    def part(name: str) -> tuple[Any, Any]:
        idx = split[name]
        return torch.from_numpy(imap.apply(d["x"][idx])), torch.from_numpy(omap.apply(d["y"][idx]))

    (xt, yt), (xv, yv) = part("train"), part("val")
    n_in, n_h, n_out = xt.shape[1], cfg.hidden[0], yt.shape[1]
    cuts = np.cumsum([n_h * n_in, n_h, n_out * n_h, n_out])

    def layers(theta: Any) -> list[Any]:
        w1, b1, w2, b2 = torch.tensor_split(theta, cuts[:-1].tolist(), dim=1)
        return [w1.reshape(-1, n_h, n_in), b1, w2.reshape(-1, n_out, n_h), b2]

    def cost(particles: np.ndarray) -> np.ndarray:
        w1, b1, w2, b2 = layers(torch.from_numpy(particles))
        with torch.no_grad():
            h = torch.tanh(torch.baddbmm(b1[:, None], xt.expand(len(particles), -1, -1), w1.transpose(1, 2)))
            out = torch.baddbmm(b2[:, None], h, w2.transpose(1, 2))
            return ((out - yt) ** 2).mean(dim=(1, 2)).numpy()

    dim = int(cuts[-1])
    np.random.seed(cfg.seed)  # noqa: NPY002 (pyswarms draws from NumPy's global generator)
    # pyswarms' reporter writes `report.log` into the working directory (on import and for each
    # optimizer): keep it out of the tree
    with tempfile.TemporaryDirectory() as tmp, contextlib.chdir(tmp):
        import pyswarms as ps

        swarm = ps.single.GlobalBestPSO(
            n_particles=pso.swarm,
            dimensions=dim,
            options={"c1": pso.c1, "c2": pso.c2, "w": pso.w},
            bounds=(-pso.x_max * np.ones(dim), pso.x_max * np.ones(dim)),
            velocity_clamp=(-pso.v_max, pso.v_max),
            bh_strategy="nearest",
        )
        _, best = swarm.optimize(cost, iters=pso.iterations, verbose=False)
    net = torch.nn.Sequential(
        torch.nn.Linear(n_in, n_h), torch.nn.Tanh(), torch.nn.Linear(n_h, n_out)
    ).double()
    w1, b1, w2, b2 = layers(torch.from_numpy(best[None]))
    with torch.no_grad():
        for layer, w, b in ((net[0], w1, b1), (net[2], w2, b2)):
            layer.weight.copy_(w[0])
            layer.bias.copy_(b[0])
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    gen = torch.Generator().manual_seed(cfg.seed)
    best_val, fails, state = np.inf, 0, None
    for _ in range(cfg.epochs):
        order = torch.randperm(len(xt), generator=gen)
        for k in range(0, len(xt), cfg.batch_size):
            idx = order[k : k + cfg.batch_size]
            opt.zero_grad()
            loss = ((net(xt[idx]) - yt[idx]) ** 2).mean()
            loss.backward()
            opt.step()
        with torch.no_grad():
            val = float(((net(xv) - yv) ** 2).mean())
        if val < best_val:
            best_val, fails, state = val, 0, {k: v.clone() for k, v in net.state_dict().items()}
        else:
            fails += 1
            if fails >= cfg.max_fail:
                break
    if state is not None:
        net.load_state_dict(state)
    test = split["test"]
    with torch.no_grad():
        pred = omap.reverse(net(torch.from_numpy(imap.apply(d["x"][test]))).numpy())
    return float(np.mean((pred - d["y"][test]) ** 2))


def agree_training(var: float):
    def agree(ours: float, theirs: float) -> Verdict:
        ratio = max(ours, theirs) / max(min(ours, theirs), 1e-300)
        same = Verdict(
            bool(np.isfinite(ratio) and ratio <= LOSS_FACTOR),
            f"test MSE {ours:.3g} (cablekit) and {theirs:.3g} (peer): {ratio:.2f}× apart "
            f"(at most {LOSS_FACTOR:g}×)",
        )
        learned = Verdict(
            bool(max(ours, theirs) < 0.1 * var), f"both below 0.1 × the targets' variance {var:.3g}"
        )
        return both(same, learned)

    return agree


def _training_pair(cfg: Config, method: str) -> Pair:
    from cablekit.nn import train_mlp

    d = _training()

    def ours() -> float:
        return train_mlp(d["x"], d["y"], d["cfg"], method=method, progress=False).test_mse

    n = len(d["x"])
    then = "Levenberg–Marquardt" if method == "pso-lm" else "Adam"
    return Pair(
        Side(f"train_mlp(method={method!r}): PSO, then {then} (torch)", ours),
        Side("pyswarms GlobalBestPSO, then torch Adam", lambda: torch_threads(THREADS, pyswarms_torch)(d)),
        agree_training(d["var"]),
        f"training ({n:,} samples)",
        max_reps=3,
        note=f"{THREADS} torch thread on both sides",
    )


FORWARD = Kernel(
    "nn",
    "network forward (MLP 4-10-4)",
    "the forceps' 4-10-4 network with its input and output normalisation, NumPy in and out, one "
    "sample per call and a batch; the outputs agree to 1e-12 of their range",
    (
        Peer("torch eager, one sample", ("torch",), lambda cfg: _forward_pair(cfg, "torch", False)),
        Peer(
            "onnxruntime, one sample", ("onnx", "onnxruntime"), lambda cfg: _forward_pair(cfg, "onnx", False)
        ),
        Peer("torch eager, batch", ("torch",), lambda cfg: _forward_pair(cfg, "torch", True)),
        Peer("torch eager, batch, 1 thread", ("torch",), lambda cfg: _forward_pair(cfg, "torch", True, 1)),
        Peer("onnxruntime, batch", ("onnx", "onnxruntime"), lambda cfg: _forward_pair(cfg, "onnx", True)),
    ),
)

TRAINING = Kernel(
    "pso",
    "PSO-BPNN training",
    "seed 000's Table 1 swarm and network on the forceps twin, the same split; stochastic, so the "
    f"outcomes must agree: test MSEs within {LOSS_FACTOR:g}× and both well below the variance",
    (
        Peer(
            "pyswarms + torch (vs PSO + LM)", ("torch", "pyswarms"), lambda cfg: _training_pair(cfg, "pso-lm")
        ),
        Peer(
            "pyswarms + torch (vs PSO + Adam)",
            ("torch", "pyswarms"),
            lambda cfg: _training_pair(cfg, "pso-adam"),
        ),
    ),
)
