"""Speed on a shared machine (issue #20 §3): PSO-BPNN training (seed 000 Table 1, 5,436
samples, ``method="pso-lm"``) quiet and with one core taken by a competing busy process, with
torch's default thread count and with cablekit's choice (``threads=None``: from the problem's
size and the free cores). Both figures of each setting come from the same run.

Usage (release build, ``train`` extra): python benches/threads_bench.py [--reps 2]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import torch  # noqa: E402

from cablekit.nn import train_mlp  # noqa: E402
from cablekit.nn.datasets import forceps_free_motion  # noqa: E402


def _spin(stop: float) -> None:  # pragma: no cover - a child process
    while time.time() < stop:
        pass


def _train(data, threads: int | None) -> tuple[float, int]:
    t0 = time.perf_counter()
    res = train_mlp(data.x, data.y, method="pso-lm", seed=0, progress=False, threads=threads)
    return time.perf_counter() - t0, res.threads


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--reps", type=int, default=2, help="best of this many trainings per setting")
    args = ap.parse_args()
    data = forceps_free_motion()
    cores = len(os.sched_getaffinity(0))
    default = torch.get_num_threads()
    rows = []
    for label, busy in (("quiet", False), ("one core busy", True)):
        hog = None
        if busy:
            hog = mp.get_context("spawn").Process(target=_spin, args=(time.time() + 3600,), daemon=True)
            hog.start()
            time.sleep(2.0)
        try:
            t_default = min(_train(data, default)[0] for _ in range(args.reps))
            t_auto, auto = min(_train(data, None) for _ in range(args.reps))
        finally:
            if hog is not None:
                hog.terminate()
                hog.join()
        rows.append((label, default, t_default, auto, t_auto))
    print(f"PSO-BPNN Table 1 on {cores} cores (best of {args.reps}):")
    print(f"{'machine':<16}{'torch default':>22}{'cablekit choice':>22}{'ratio':>8}")
    for label, d, td, a, ta in rows:
        default_s, auto_s = f"{td:.2f} s ({d} threads)", f"{ta:.2f} s ({a} thread(s))"
        print(f"{label:<16}{default_s:>22}{auto_s:>22}{td / ta:>7.1f}x")


if __name__ == "__main__":
    main()
