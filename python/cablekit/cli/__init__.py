"""The ``cablekit`` command line: the root parser, the exit codes and ``simulate`` here; one
module per command family beside it (``diagnose``, ``cdpr``, ``forceps``, ``nn``), each adding
its sub-parser. The run-file formats the commands read live with the library
(:mod:`cablekit.diagnose.data`, :mod:`cablekit.cdpr.formats`, :mod:`cablekit.forceps.bench`), not
here, so nothing in the library imports the command line."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from cablekit import __version__
from cablekit.errors import CablekitError, InternalError
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


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """``--help`` with every option's default, ``(default: …)``, unless it has none (``None``, an
    off switch) or its text already says it."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if "%(default)" in text or action.default in (None, False, argparse.SUPPRESS) or action.default == []:
            return text
        return f"{text} (default: %(default)s)" if text else "default: %(default)s"


class Parser(argparse.ArgumentParser):
    """The parser of every ``cablekit`` command and sub-command (sub-parsers are made of the
    parent's class, so all of them show their defaults)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)


def build_parser() -> argparse.ArgumentParser:
    p = Parser(
        prog="cablekit",
        description="Cable-driven robot toolkit: simulate, estimate, distribute tensions and diagnose "
        "why a model disagrees with the robot",
        epilog="exit codes: 0 done; 1 a goal or check the run states failed; 2 usage; 3 a result "
        "flagged unreliable by its own check; 4 bad input (data, array or parameter); 5 the "
        "computation failed (diverged, not converged, overflow); 70 a bug in cablekit",
    )
    p.add_argument("--version", action="version", version=f"cablekit {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("simulate", help="simulate an embedded example, write CSV + PNG")
    s.add_argument(
        "--example",
        choices=sorted(EXAMPLES),
        default="raven-link",
        help="raven-link: a Raven-II link under its servo; forceps: an antagonistic forceps joint",
    )
    s.add_argument("--out", default="out", help="output directory (created)")
    s.add_argument("--duration", type=float, default=4.0, help="seconds")
    s.add_argument("--dt", type=float, default=1e-3, help="sample interval, s")
    s.add_argument("--no-plot", action="store_true", help="skip the PNG (no matplotlib needed)")
    s.set_defaults(func=_simulate)
    from cablekit.cli.diagnose import add_parser as add_diagnose

    add_diagnose(sub)
    from cablekit.cli.cdpr import add_parser as add_cdpr
    from cablekit.cli.forceps import add_parser as add_forceps
    from cablekit.cli.network import add_parser as add_network
    from cablekit.cli.nn import add_parser as add_nn

    add_nn(sub)
    add_network(sub)
    add_cdpr(sub)
    add_forceps(sub)
    return p


#: exit codes of every ``cablekit`` command (README, "Exit codes")
EXIT_OK = 0
#: the run finished and a goal or check it states failed (a self-test or benchmark miss)
EXIT_GOAL = 1
#: usage: an unknown option or a value argparse refuses
EXIT_USAGE = 2
#: a result flagged as unreliable by its own check (a calibration that does not fit)
EXIT_FLAGGED = 3
#: bad input: a data file, an array or a parameter the command cannot use
EXIT_INPUT = 4
#: the computation failed: a simulation diverged, a fit did not converge, a result overflowed
EXIT_FAILED = 5
#: a bug inside cablekit (a Rust panic caught at the boundary)
EXIT_INTERNAL = 70


def exit_code(exc: CablekitError) -> int:
    """The exit code a cablekit error ends a command with."""
    if isinstance(exc, InternalError):
        return EXIT_INTERNAL
    if isinstance(exc, ArithmeticError | RuntimeError):
        return EXIT_FAILED
    return EXIT_INPUT


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except CablekitError as exc:
        print(f"cablekit: error: {type(exc).__name__}: {exc}", file=sys.stderr)
        return exit_code(exc)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
