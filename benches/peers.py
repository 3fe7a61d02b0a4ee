"""Every peer in one command (issue #40 §4): each cablekit kernel against what a user would
otherwise pick, in one process on this machine, with the same inputs.

For every (kernel, peer) row the answers are compared first; a row whose answers disagree is
void (no times, no ratio), a peer that does not import is reported as not installed. Then both
sides are timed, repeats interleaved, and the medians and the ratio peer / cablekit printed.

Kernels (``--only`` takes these names; details in the docstrings of ``benches/peerbench/``):
``srukf`` sr-UKF step vs filterpy; ``nn`` MLP forward vs torch and onnxruntime; ``tension``
tension distribution vs NumPy, quadprog, qpsolvers and scipy's HiGHS; ``simulate`` RK4 vs
``solve_ivp``; ``pso`` PSO-BPNN training vs pyswarms + torch; ``diagnose`` the diagnosis vs
``least_squares``; ``workspace`` the wrench-feasible workspace vs one LP per pose; ``mujoco``
cable kinematics vs MuJoCo's tendons.

A full run writes the table to ``docs/benchmarks.md`` (between ``<!-- peers:start -->`` and
``<!-- peers:end -->``) and ``docs/benchmarks.json``; ``--quick`` (smaller problems, fewer
repeats) and ``--only`` print it only, unless ``--write``.

Usage (release build installed; the peers from ``pip install 'cablekit[bench]'``):
    python benches/peers.py [--quick] [--only NAME[,NAME]] [--write | --no-write]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))  # tests.reference (the NumPy models) and benches.peerbench

from benches.peerbench import KERNELS, Config, Kernel, Peer, Row, Side, check, measure  # noqa: E402
from benches.peerbench.report import document, ratio, seconds, table, write  # noqa: E402

#: what ``tests/test_peers.py`` uses: the kernels, and the check without the timing
__all__ = ["KERNELS", "Config", "Kernel", "Peer", "Row", "Side", "check", "main", "measure"]


def select(only: str | None) -> tuple[Kernel, ...]:
    if not only:
        return KERNELS
    names = [n.strip() for n in only.split(",") if n.strip()]
    known = {k.name for k in KERNELS}
    unknown = [n for n in names if n not in known]
    if unknown:
        raise SystemExit(f"unknown kernel {', '.join(unknown)}; choose from {', '.join(sorted(known))}")
    return tuple(k for k in KERNELS if k.name in names)


def run(kernels: tuple[Kernel, ...], cfg: Config) -> list[Row]:
    """Every peer of every kernel, with one progress line per kernel and per row."""
    rows = []
    for i, kernel in enumerate(kernels, 1):
        print(f"[{i}/{len(kernels)}] {kernel.title} ({kernel.name})", flush=True)
        for peer in kernel.peers:
            t0 = time.perf_counter()
            row = measure(kernel, peer, cfg)
            rows.append(row)
            times = f"{seconds(row.ours_s)} vs {seconds(row.peer_s)} per {row.unit}, " if row.ours_s else ""
            said = ratio(row) if row.status == "ok" else row.status
            print(f"    {peer.name}: {times}{said}  ({time.perf_counter() - t0:.1f} s)", flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="smaller problems and 3 repeats (a smoke run)")
    ap.add_argument("--only", metavar="NAME", help="only these kernels (comma-separated)")
    ap.add_argument(
        "--write",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="write docs/benchmarks.md and .json (default: only for a full run)",
    )
    args = ap.parse_args(argv)
    kernels, cfg = select(args.only), Config.make(args.quick)
    t0 = time.perf_counter()
    rows = run(kernels, cfg)
    doc = document(rows, cfg, time.perf_counter() - t0)
    print()
    print(table(rows, kernels))
    if args.write if args.write is not None else not (args.quick or args.only):
        write(ROOT / "docs" / "benchmarks.md", ROOT / "docs" / "benchmarks.json", doc, rows, kernels)
        print("\nwrote docs/benchmarks.md (section between the peers markers) and docs/benchmarks.json")
    void = [r for r in rows if r.status.startswith("void")]
    return 1 if void else 0


if __name__ == "__main__":
    sys.exit(main())
