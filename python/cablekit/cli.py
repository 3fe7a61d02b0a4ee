"""The ``cablekit`` command line."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from cablekit.errors import CablekitError
from cablekit.examples import EXAMPLES, run_example


def _simulate(args: argparse.Namespace) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"cablekit: simulating {args.example!r} ({args.duration} s, dt={args.dt} s) ...", flush=True)
    t0 = time.perf_counter()
    result = run_example(args.example, duration=args.duration, dt=args.dt)
    elapsed = time.perf_counter() - t0
    stem = args.example.replace("-", "_")
    csv_path = result.to_csv(out / f"{stem}.csv")
    summary = {
        "example": args.example,
        "samples": len(result.t),
        "dt": args.dt,
        "substeps": result.meta.get("substeps"),
        "wall_time_s": elapsed,
        "outputs": {
            name: {"min": float(np.min(result[name])), "max": float(np.max(result[name]))}
            for name in result.output_names
        },
    }
    (out / f"{stem}.json").write_text(json.dumps(summary, indent=2))
    print(f"  wrote {csv_path} ({len(result.t)} rows, {len(result.columns)} columns)")
    if not args.no_plot:
        from cablekit.plotting import plot_run

        png = plot_run(result, out / f"{stem}.png")
        print(f"  wrote {png}")
    print(f"  done in {elapsed:.3f} s (substeps per sample: {result.meta.get('substeps')})")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="cablekit", description="Cable-driven robot toolkit")
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("simulate", help="simulate an embedded example, write CSV + PNG")
    s.add_argument("--example", choices=sorted(EXAMPLES), default="raven-link")
    s.add_argument("--out", default="out", help="output directory (created)")
    s.add_argument("--duration", type=float, default=4.0, help="seconds")
    s.add_argument("--dt", type=float, default=1e-3, help="sample interval, s")
    s.add_argument("--no-plot", action="store_true", help="skip the PNG (no matplotlib needed)")
    s.set_defaults(func=_simulate)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except CablekitError as exc:
        print(f"cablekit: error: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
