"""Python-side budget: 10 s at 10 kHz (100k steps) of the Raven 3-link model from Python,
compared with the NumPy reference in the same run (ratio printed). Exit 1 if over budget.

Usage (with a release build installed): python benches/python_bench.py
"""

from __future__ import annotations

import sys
import time
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import cablekit as ck  # noqa: E402
from tests.reference import rk4  # noqa: E402
from tests.reference.transmission import TransmissionRef  # noqa: E402


def main() -> int:
    budgets = tomllib.loads((ROOT / "benches" / "budgets.toml").read_text())["python"]
    model = ck.CableTransmission.raven2(3)
    steps, dt = 100_000, 1e-4
    t = np.arange(steps) * dt
    u = np.zeros((steps, 6))
    u[:, :3] = np.array([0.1, 0.05, 0.2]) * np.sin(6.0 * t)[:, None]
    x0 = np.zeros(12)
    ck.simulate(model, u[:1000], dt, x0)  # warm-up
    runs = []
    for _ in range(15):  # median of 15: robust to the bursts of a shared 2-core machine
        t0 = time.perf_counter()
        ck.simulate(model, u, dt, x0)
        runs.append(time.perf_counter() - t0)
    rust_ms = 1e3 * float(np.median(runs))
    ref = TransmissionRef(model.params())
    n_ref = 2000  # the reference is timed on a slice and scaled per step
    t0 = time.perf_counter()
    rk4.simulate(ref.derivative, ref.output, u[:n_ref], x0, dt, 1, "zoh")
    numpy_ms = 1e3 * (time.perf_counter() - t0) * steps / n_ref
    speedup = numpy_ms / rust_ms
    ok_time = rust_ms <= budgets["simulate_100k_ms"]
    ok_ratio = speedup >= budgets["min_speedup_vs_numpy"]
    budget_ms, min_ratio = budgets["simulate_100k_ms"], budgets["min_speedup_vs_numpy"]
    print(
        f"python simulate, Raven 3-link, 100k steps: median {rust_ms:.2f} ms, "
        f"min {1e3 * min(runs):.2f} ms (budget {budget_ms} ms)"
    )
    print(f"  -> {10.0 / (rust_ms / 1e3):.0f}x real time  {'ok' if ok_time else 'OVER BUDGET'}")
    print(f"numpy reference, same run (scaled from {n_ref} steps): {numpy_ms:.0f} ms")
    print(f"  -> speed-up {speedup:.0f}x (budget >= {min_ratio:.0f}x)  {'ok' if ok_ratio else 'BELOW'}")
    return 0 if ok_time and ok_ratio else 1


if __name__ == "__main__":
    sys.exit(main())
