"""``cablekit diagnose``: the sim-to-real gap diagnosis on run files, the embedded example, the
self-tests, blind benchmarks, campaigns and the da Vinci bench."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cablekit.errors import DataError

if TYPE_CHECKING:
    from cablekit.diagnose import ModelSpec, Run


EXAMPLE_EFFECTS = ("backlash", "sensor_gain_bias")


def _write_example(directory: Path) -> tuple[Path, Path, Path]:
    """Write the embedded diagnosis example: a forceps-like joint whose drive has play and whose
    tension sensors are miscalibrated (withheld from the model file)."""
    from cablekit.diagnose.data import write_csv
    from cablekit.diagnose.selftest import make_case
    from cablekit.diagnose.spec import write_model_toml

    case = make_case(EXAMPLE_EFFECTS, seed=7, duration=8.0)
    directory.mkdir(parents=True, exist_ok=True)
    paths = [
        write_csv(run, directory / name)
        for run, name in ((case.fit[0], "fit.csv"), (case.hold[0], "holdout.csv"))
    ]
    model = write_model_toml(
        case.spec,
        directory / "model.toml",
        "cablekit diagnosis example: nominal model of a forceps-like antagonistic joint",
    )
    (directory / "TRUTH.json").write_text(
        json.dumps({"withheld_effects": case.truth["effects"]}, indent=2, default=float)
    )
    return paths[0], paths[1], model


def _write_self_test(out: Path, stem: str, table: str, res: dict[str, Any]) -> int:
    """Print a self-test's table, write it and its JSON to OUT; exit code 0 when goals are met."""
    print(table)
    (out / f"{stem}.txt").write_text(table + "\n")
    (out / f"{stem}.json").write_text(json.dumps(res, indent=2, default=float))
    print(f"  wrote {out / (stem + '.txt')} and {out / (stem + '.json')}")
    return 0 if res["passed"] else 1


def _diagnose(args: argparse.Namespace) -> int:
    from cablekit.diagnose import load_model_spec, load_run

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.self_test:
        from cablekit.diagnose.selftest import format_confusion, run_self_test

        print("cablekit: diagnosis self-test (effects withheld from the diagnoser) ...", flush=True)
        res = run_self_test(seed=args.seed, duration=args.duration, progress=not args.quiet)
        return _write_self_test(out, "self_test", format_confusion(res), res)
    if args.independent:
        from cablekit.diagnose.selftest_independent import CI_SUBSET, format_independent, run_independent

        print(
            "cablekit: independent self-test (runs from a separate LSODA simulator with its own effect "
            f"forms; {'CI subset' if args.independent == 'ci' else 'every case'}) ...",
            flush=True,
        )
        res = run_independent(
            seed=args.seed + 2216,
            duration=args.duration if args.duration != 8.0 else 20.0,
            progress=not args.quiet,
            only=CI_SUBSET if args.independent == "ci" else None,
        )
        return _write_self_test(out, "independent", format_independent(res), res)
    if args.networks:
        from cablekit.diagnose.selftest_independent import format_independent
        from cablekit.diagnose.selftest_network import CI_CASES as NETWORK_CI
        from cablekit.diagnose.selftest_network import run_network_self_test

        print(
            "cablekit: network self-test (two-stage instrument, tendon finger, two-link transmission; runs "
            "from an independent simulator written from the literature; "
            f"{ {'quick': 'quick subset', 'ci': 'CI subset'}.get(args.networks, 'every case') }) ...",
            flush=True,
        )
        res = run_network_self_test(
            seed=args.seed,
            quick=args.networks == "quick",
            progress=not args.quiet,
            only=list(NETWORK_CI) if args.networks == "ci" else None,
        )
        by_plant = ", ".join(
            f"{p}: effect {v['effect']:.0%}, site {v['site']:.0%} of {v['cases']}"
            for p, v in res["scores"]["by_plant"].items()
        )
        return _write_self_test(out, "networks", format_independent(res) + f"\nby plant: {by_plant}", res)
    if args.benchmark:
        from cablekit.diagnose import Options
        from cablekit.diagnose.benchmark import format_benchmark, run_benchmark

        print(f"cablekit: scoring the diagnosis on the blind cases in {args.benchmark} ...", flush=True)
        bench = run_benchmark(
            args.benchmark,
            args.cases,
            out=out / "cases",
            options=Options(progress=False, seed=args.seed, workers=args.workers),
            progress=not args.quiet,
        )
        table = format_benchmark(bench)
        print(table)
        (out / "benchmark.txt").write_text(table + "\n")
        (out / "benchmark.json").write_text(json.dumps(bench.to_json(), indent=2, default=float))
        print(f"  wrote {out / 'benchmark.txt'} and {out / 'benchmark.json'}")
        # a case whose diagnosis errs is a failure (failed candidate fits are listed, not silent);
        # --strict: so is any miss
        missed = [c.case for c in bench.cases if not c.correct or c.both_found is False]
        if args.strict and missed:
            print(f"  --strict: missed {', '.join(missed)}")
        return 1 if any(c.error for c in bench.cases) or (args.strict and missed) else 0
    if args.many:
        from cablekit.diagnose.many import run_many, summary_table

        print(f"cablekit: diagnosing the campaign in {args.many} ...", flush=True)
        t0 = time.perf_counter()
        results = run_many(
            args.many,
            out,
            engine=args.engine,
            address=args.address,
            workers=args.workers,
            seed=args.seed,
            progress=not args.quiet,
            html=not args.no_html,
            interval_refits=args.intervals,
        )
        print(summary_table(results))
        print(f"  wrote {out / 'summary.json'}, {out / 'summary.txt'} and one folder per group")
        print(f"  done in {time.perf_counter() - t0:.1f} s")
        return 0 if all(r.error is None for r in results) else 1
    if args.davinci:
        from cablekit._files import text_runs
        from cablekit.diagnose.davinci import (
            CITATION,
            SPLITS,
            BenchSplit,
            bench_directory,
            describe,
            prepare_bench,
            split_for,
        )
        from cablekit.forceps.posture import parse_posture

        preset = SPLITS[args.bench_split]
        sp = BenchSplit(
            calibration=tuple(args.bench_calibration or preset.calibration),
            fit=tuple(args.bench_fit or preset.fit),
            held_out=tuple(args.bench_holdout or preset.held_out),
        )
        posture = parse_posture(args.posture) if args.posture is not None else None
        sp = split_for(sp, text_runs(bench_directory(args.davinci, sp.calibration + sp.fit + sp.held_out)))
        spec, fit, hold = prepare_bench(args.davinci, sp, posture=posture)
        print(f"cablekit: da Vinci Maryland bench ({CITATION})")
        print(f"  calibration runs {sp.calibration}, fit runs {sp.fit}, held out {sp.held_out}")
        print(f"  {describe(spec)}")
        if spec.conditions:
            built = ", ".join(f"{k} {'/'.join(f'{v:g}' for v in vs)}" for k, vs in spec.conditions.items())
            print(f"  nominal calibrated at {built}")
        return _run_diagnosis(spec, fit, hold, out, args, "da Vinci bench")
    if args.example:
        fit_paths, hold_paths, model_path = _write_example(out / "example")
        fit_paths, hold_paths = [fit_paths], [hold_paths]
        print(
            f"cablekit: example written to {out / 'example'} (fit.csv, holdout.csv, model.toml; "
            f"TRUTH.json holds the withheld effects)"
        )
    else:
        if not args.fit or not args.holdout or not args.model:
            raise DataError(
                "give FIT.csv ..., --holdout HOLD.csv ... and --model MODEL.toml (or --example / --self-test)"
            )
        fit_paths, hold_paths, model_path = (
            [Path(p) for p in args.fit],
            [Path(p) for p in args.holdout],
            Path(args.model),
        )
    from cablekit.cdpr.diagnose import is_robot_file

    if is_robot_file(model_path):
        from cablekit._files import parse_toml, read_text
        from cablekit.cdpr import Robot, Winch, path_friction_of, topics_of
        from cablekit.cdpr.diagnose import diagnose_runs
        from cablekit.cdpr.formats import load_cdpr_run
        from cablekit.cli.cdpr import write_run_diagnosis

        robot = Robot.load(model_path)
        doc = parse_toml(read_text(model_path, "robot file"), str(model_path))
        topics = topics_of(doc, str(model_path))
        runs = [(p.name, load_cdpr_run(p, robot, topics=topics)) for p in [*fit_paths, *hold_paths]]
        if all(r.poses is not None for _, r in runs):
            from cablekit.cdpr.drives import drive_runs

            print(
                f"cablekit: {robot.name} is a cable robot: its drives at the measured poses as a cable "
                "network (seed 003's winch; see docs/cdpr.md)"
            )
            friction = path_friction_of(doc, str(model_path))
            spec, loaded = drive_runs(robot, Winch.seed003(), runs, friction)
            return _run_diagnosis(
                spec, loaded[: len(fit_paths)], loaded[len(fit_paths) :], out, args, str(model_path)
            )
        print(
            f"cablekit: {robot.name} is a cable robot without measured poses: the drum-side force check "
            "(seed 003's winch; see docs/cdpr.md)"
        )
        d = diagnose_runs(fit_paths, hold_paths, robot, topics=topics)
        fit_names, hold_names = [str(p) for p in fit_paths], [str(p) for p in hold_paths]
        write_run_diagnosis(robot, d, fit_names, hold_names, out, args.quiet, plots=not args.no_html)
        return 0
    spec = load_model_spec(model_path)
    fit = [load_run(p, columns=list(spec.columns())) for p in fit_paths]
    hold = [load_run(p, columns=list(spec.columns())) for p in hold_paths]
    return _run_diagnosis(spec, fit, hold, out, args, str(model_path))


def _run_diagnosis(
    spec: ModelSpec, fit: list[Run], hold: list[Run], out: Path, args: argparse.Namespace, what: str
) -> int:
    from cablekit.diagnose import Options, diagnose
    from cablekit.diagnose.report import write_html, write_json

    print(
        f"cablekit: diagnosing {len(fit)} fit run(s) against {len(hold)} held-out run(s), model {what} ...",
        flush=True,
    )
    for r in (*fit, *hold):
        for n in r.notes:
            print(f"  note: run {r.name}: {n}")
    for col, (scale, offset, declared) in spec.column_units.items():
        print(f"  note: column {col} converted to SI from {declared} (x{scale:g} + {offset:g})")
    t0 = time.perf_counter()
    res = diagnose(
        spec,
        fit,
        hold,
        Options(
            progress=not args.quiet, workers=args.workers, seed=args.seed, interval_refits=args.intervals
        ),
    )
    elapsed = time.perf_counter() - t0
    j = write_json(res, out / "diagnosis.json")
    for w in res.meta.warnings:
        print(f"  warning: {w}")
    print(f"  verdict: {res.verdict}")
    for f in res.flags:
        print(f"  FLAG: {f}")
    for e in res.effects[:5]:
        cf = e.held_out.closed_fraction
        print(
            f"  {'*' if e.selected else ' '} {e.id:<40} "
            f"held-out closed {cf if cf is None else f'{cf:6.1%}'}"
            f"  significant={e.held_out.significant}"
            + (f"  (collinear with {e.identifiability[0].with_})" if e.identifiability else "")
        )
    sel = res.selected
    if sel.effects:
        print(
            f"  selected {' + '.join(sel.effects)}: held-out gap "
            f"{sel.held_out.gap_before:.3g} -> {sel.held_out.gap_after:.3g} (noise = 1)"
        )
        for p in sel.parameters:
            ci = p.ci95_refit
            print(
                f"    {p.effect}: {p.name} = {p.value:.4g} {p.unit}"
                + (f"  [{ci[0]:.4g}, {ci[1]:.4g}] (bootstrap refits)" if ci and None not in ci else "")
            )
        for c in sel.channels_held_out:
            print(
                f"    {c.channel:<24} held-out gap {c.gap_before:10.4g} -> {c.gap_after:10.4g} "
                f"({c.change:+.0%}){'  WORSE' if c.worsened else ''}"
            )
    print(f"  wrote {j}")
    if not args.no_html:
        h = write_html(res, out / "diagnosis.html")
        print(f"  wrote {h}")
    print(f"  done in {elapsed:.1f} s")
    return 0


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """``cablekit diagnose``."""
    d = sub.add_parser(
        "diagnose",
        help="sim-to-real gap diagnosis: where, which effect, how far it closes on held-out runs",
        description="Fit candidate effects on FIT runs, score them on --holdout runs, write "
        "diagnosis.json and .html",
    )
    d.add_argument("fit", nargs="*", help="fit run(s): CSV or Parquet with a t column")
    d.add_argument("--holdout", nargs="+", help="held-out run(s), never fitted")
    d.add_argument("--model", help="nominal model file (TOML, see docs/diagnosis.md)")
    d.add_argument("--out", default="out", help="output directory (created)")
    d.add_argument("--example", action="store_true", help="run on the embedded example")
    d.add_argument(
        "--self-test", action="store_true", help="score the diagnoser on generated runs with withheld effects"
    )
    d.add_argument(
        "--independent",
        choices=["all", "ci"],
        help="score the diagnoser on runs from the independent simulator (every case, or the CI subset)",
    )
    d.add_argument(
        "--networks",
        choices=["all", "quick", "ci"],
        help="score the diagnoser on cable-network plants (a two-stage instrument, a tendon finger, a "
        "two-link transmission) from an independent simulator: every case, a quick subset of 8, or "
        "the CI subset of 3",
    )
    d.add_argument(
        "--benchmark",
        metavar="DIR",
        help="score the diagnoser on a folder of blind cases (caseNN/ with fit, holdout, model.toml and "
        "truth.json, e.g. ../shared/benchmarks/blind_joint_a) and print the table",
    )
    d.add_argument(
        "--cases", nargs="+", metavar="CASE", help="with --benchmark: only these cases (folder names)"
    )
    d.add_argument(
        "--strict",
        action="store_true",
        help="with --benchmark: exit 1 unless every case counts (each top-1 right, both effects of every "
        "pair found, every control clean, nothing outside the library claimed explained)",
    )
    m = d.add_argument_group(
        "campaigns (--many)",
        "DIR/manifest.toml groups the runs of DIR: per [[group]] a name, a model file, fit and held_out "
        "run lists (docs/diagnosis.md). Candidate fits fan out on Ray when it is installed "
        "(pip install 'cablekit[scale]'), locally or on a cluster; without Ray the groups run serially. "
        "Writes OUT/<group>/diagnosis.json, OUT/summary.json and OUT/summary.txt.",
    )
    m.add_argument(
        "--many",
        metavar="DIR",
        help="diagnose every group of DIR/manifest.toml (each with its model file: a joint, a "
        "transmission, a cable network or a cable robot's file)",
    )
    m.add_argument(
        "--address", help="Ray cluster address (e.g. ray://head:10001 or auto); default: local Ray"
    )
    m.add_argument(
        "--engine",
        choices=["auto", "ray", "serial"],
        default="auto",
        help="where candidate fits run: Ray if installed (auto), Ray (ray), or this machine (serial)",
    )
    b = d.add_argument_group(
        "bench data (--davinci)",
        "A folder in the da Vinci Maryland bench's format (any instrument): files FL.TXT[.gz], F = "
        "frequency index 0-4 (0.1-0.5 Hz), L = load index (10-40 % resistive torque), or ZFL.TXT[.gz] in "
        "a wrist-posture folder (Z = jaw stopping position); run names are the file stems. The nominal "
        "model is calibrated on the calibration runs, fitted on the fit runs and scored on the held-out "
        "runs. The wrist posture (pitch, roll) is read from the folder's README or given by --posture; "
        "runs at a posture or stopping position the nominal was not calibrated at get a warning.",
    )
    b.add_argument(
        "--davinci", metavar="DIR", help="diagnose the da Vinci Maryland bench data in DIR (real data)"
    )
    b.add_argument(
        "--bench-split",
        choices=["default", "frequency", "load"],
        default="default",
        help="preset split: default (calibrate 00; fit 11 22; hold out 43 40: new frequency at new loads; "
        "in a folder without these runs the same design on the conditions it has), "
        "frequency (hold out 41 42: 0.5 Hz at the fit loads), load (hold out 13 23: 40 %% at the fit "
        "frequencies)",
    )
    b.add_argument(
        "--bench-calibration", nargs="+", metavar="RUN", help="calibration runs (override the split)"
    )
    b.add_argument("--bench-fit", nargs="+", metavar="RUN", help="fit runs (override the split)")
    b.add_argument("--bench-holdout", nargs="+", metavar="RUN", help="held-out runs (override the split)")
    b.add_argument(
        "--posture",
        metavar="pitch=DEG,roll=DEG",
        help="the wrist posture of the folder's runs, if its README does not state it (overrides the README)",
    )
    d.add_argument(
        "--duration", type=float, default=8.0, help="self-test run length, s (independent: 20 s unless given)"
    )
    d.add_argument(
        "--intervals",
        type=int,
        default=20,
        metavar="N",
        help="refit the selected effects on N bootstrap resamples of fit-run segments for the parameters' "
        "ci95_refit (0: linearised intervals only; self-tests use 0)",
    )
    d.add_argument(
        "--seed", type=int, default=2026, help="seed of the self-tests' runs and of the bootstrap resamples"
    )
    d.add_argument("--workers", type=int, default=0, help="parallel candidate fits (0 = all cores)")
    d.add_argument("--no-html", action="store_true", help="skip the HTML report (no matplotlib needed)")
    d.add_argument("--quiet", action="store_true", help="no progress bars")
    d.set_defaults(func=_diagnose)
