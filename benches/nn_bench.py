"""Python-side network budgets (issue #5), with torch and NumPy measured in the same run:

* ``Mlp.predict_into`` of the 4-10-4 forceps network, one sample (controller path);
* ``Mlp.predict`` of 1e6 rows (GIL released, parallel);
* torch eager single-sample forward (float64 ``nn.Sequential``) and a NumPy forward, as ratios;
* PSO-BPNN with the Table 1 settings on the 5,436-sample forceps twin (training time).

Usage (with a release build and the ``train`` extra installed): python benches/nn_bench.py
"""

from __future__ import annotations

import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from cablekit.nn import Mlp, export, train_mlp  # noqa: E402
from cablekit.nn.datasets import forceps_free_motion  # noqa: E402
from tests.reference import mlp as ref  # noqa: E402


def best_of(fn, reps: int, inner: int) -> float:
    """Best mean time per call over ``reps`` batches of ``inner`` calls, s."""
    best = np.inf
    for _ in range(reps):
        t0 = time.perf_counter()
        for _ in range(inner):
            fn()
        best = min(best, (time.perf_counter() - t0) / inner)
    return best


def main() -> int:
    budgets = tomllib.loads((ROOT / "benches" / "budgets.toml").read_text())["python"]
    data = forceps_free_motion()
    t0 = time.perf_counter()
    res = train_mlp(data.x, data.y, method="pso-lm", seed=0, progress=False)
    pso_s = time.perf_counter() - t0
    path = export(res, ROOT / "target" / "bench_forceps.safetensors")
    mlp = Mlp.load(path)
    x1 = np.ascontiguousarray(data.x[0])
    out = np.empty(4)
    into_us = best_of(lambda: mlp.predict_into(x1, out), 7, 20_000) * 1e6

    torch.set_num_threads(1)
    net = torch.nn.Sequential(torch.nn.Linear(4, 10), torch.nn.Tanh(), torch.nn.Linear(10, 4)).double()
    with torch.no_grad():
        net[0].weight.copy_(torch.from_numpy(res.weights[0]))
        net[0].bias.copy_(torch.from_numpy(res.biases[0]))
        net[2].weight.copy_(torch.from_numpy(res.weights[1]))
        net[2].bias.copy_(torch.from_numpy(res.biases[1]))
    a1 = torch.from_numpy(res.input_map.apply(x1)).unsqueeze(0)

    def torch_one() -> None:
        with torch.no_grad():
            net(a1)

    torch_us = best_of(torch_one, 5, 5_000) * 1e6
    lo, hi = res.input_map.min, res.input_map.max
    olo, ohi = res.output_map.min, res.output_map.max
    numpy_us = (
        best_of(lambda: ref.forward(x1, res.weights, res.biases, res.activations, lo, hi, olo, ohi), 5, 5_000)
        * 1e6
    )

    big = np.ascontiguousarray(np.tile(data.x, (1_000_000 // data.x.shape[0] + 1, 1))[:1_000_000])
    batch_ms = best_of(lambda: mlp.predict(big), 5, 1) * 1e3
    torch.set_num_threads(2)
    tb = torch.from_numpy(res.input_map.apply(big))

    def torch_batch() -> None:
        with torch.no_grad():
            net(tb)

    torch_batch_ms = best_of(torch_batch, 3, 1) * 1e3

    checks = [
        ("Mlp.predict_into, 1 sample", into_us, "us", budgets["mlp_predict_into_us"]),
        ("Mlp.predict, 1e6 rows", batch_ms, "ms", budgets["mlp_batch_1e6_ms"]),
        ("PSO-BPNN Table 1, 5,436 samples", pso_s, "s", budgets["pso_bpnn_table1_s"]),
    ]
    failed = 0
    for name, value, unit, budget in checks:
        ok = value <= budget
        failed += not ok
        print(
            f"  {name:34s} {value:9.3f} {unit:2s}  budget {budget:g} {unit}  {'ok' if ok else 'OVER BUDGET'}"
        )
    print(
        f"  torch eager, 1 sample (normalised in, no denormalisation) {torch_us:8.2f} us  "
        f"-> predict_into is {torch_us / into_us:5.1f}x faster"
    )
    print(
        f"  NumPy forward, 1 sample                                 {numpy_us:8.2f} us  "
        f"-> predict_into is {numpy_us / into_us:5.1f}x faster"
    )
    print(
        f"  torch eager, 1e6 rows, 2 threads (layers only)          {torch_batch_ms:8.2f} ms  "
        f"-> Mlp.predict is {torch_batch_ms / batch_ms:5.2f}x faster"
    )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
