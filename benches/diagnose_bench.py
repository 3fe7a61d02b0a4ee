"""Diagnosis budget (issue #19 §5): a 20 s, 1 kHz fit run and a 20 s held-out run against the whole
(effect, site) library in <= 30 s on 2 cores for the **slowest** case of both self-tests.

Cases: by default the regression self-test's slowest effects (friction and hysteresis need the
most RK4 substeps), a pair and a control, plus the independent self-test's CI subset and its
slowest cases (pretension loss, LuGre and Tustin friction: kinks and sharp friction), each with the
seed its self-test draws it with (the regression cases at 20 s instead of 8 s), and benchmark A's
slowest cases (friction, and the friction + lag pair) when ``../shared`` is beside the checkout;
``--all`` runs every case of both self-tests and of benchmark A (~20 min). Prints each case and
the distribution (min, median, 90th percentile, max); exit 1 if the slowest is over budget. Each
case is diagnosed with its suite's options: the self-tests' bootstrap seed 0, benchmark A's the
command line's 2026 (``--benchmark-seed``): the seed decides close calls of the selection, and so
which fits run (case 13 takes another path at seed 0, docs/diagnosis.md).

Usage (release build installed): python benches/diagnose_bench.py [--all]
"""

from __future__ import annotations

import argparse
import sys
import time
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from cablekit.diagnose import Options, diagnose  # noqa: E402
from cablekit.diagnose import selftest_independent as si  # noqa: E402
from cablekit.diagnose import selftest_transmission as tx  # noqa: E402
from cablekit.diagnose.selftest import CONTROLS, PAIRS, SINGLE, make_case  # noqa: E402

REGRESSION = [("dahl_hysteresis",), ("coulomb_friction", "sensor_lag"), ("sensor_sampling",), ()]
#: benchmark A's slowest cases (issue #36 §5): sharp Coulomb friction, Stribeck, and the pair
BENCHMARK_A = ["case00", "case01", "case13"]
INDEPENDENT = [
    *si.CI_SUBSET,
    "slack@cable.both/lost_pretension",
    "slack@cable.drive/lost_pretension",
    "coulomb_friction@joint/lugre",
    # among the slowest of the full independent self-test (2026-11-27, beside the CI subset's
    # power-law drag pair and Tustin friction): the LuGre friction + second-order lag pair
    "coulomb_friction@joint/lugre+sensor_lag@sensors.force/butterworth2",
]


#: the bootstrap seed ``cablekit diagnose --benchmark`` uses (its ``--seed`` default); the
#: self-tests diagnose their cases with seed 0
CLI_SEED = 2026


def _time(spec: Any, fit: list[Any], hold: list[Any], seed: int = 0) -> tuple[float, str]:
    """One diagnosis with the options its suite uses (the bootstrap seed decides close calls of
    the selection, and so which fits run)."""
    t0 = time.perf_counter()
    res = diagnose(spec, fit, hold, Options(progress=False, seed=seed))
    return (
        time.perf_counter() - t0,
        f"verdict={res.verdict:<20} selected={','.join(res.selected.effects) or '-'}",
    )


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--all", action="store_true", help="every case of both self-tests")
    ap.add_argument(
        "--benchmark-seed",
        type=int,
        default=CLI_SEED,
        help="bootstrap seed of benchmark A's diagnoses (default: the command line's)",
    )
    args = ap.parse_args()
    budget = tomllib.loads((ROOT / "benches" / "budgets.toml").read_text())["python"]["diagnose_20s_s"]
    times: list[float] = []
    # the cases exactly as the self-tests draw them (same seeds; the regression ones at 20 s)
    regression = [("joint", (e,)) for e in SINGLE] + [("joint", p) for p in PAIRS]
    regression += [("joint", ())] * CONTROLS + [("raven", (e,)) for e in tx.TRANSMISSION_SINGLE]
    regression += [("raven", p) for p in tx.TRANSMISSION_PAIRS]
    regression += [("raven", ())] * tx.TRANSMISSION_CONTROLS
    for i, (plant, effects) in enumerate(regression):
        if not args.all and (plant != "joint" or tuple(effects) not in REGRESSION):
            continue
        if not args.all and effects == () and i != regression.index(("joint", ())):
            continue  # one control
        make = make_case if plant == "joint" else tx.make_transmission_case
        case = make(tuple(effects), 2026 + 97 * i, 20.0)
        dt, what = _time(case.spec, case.fit, case.hold)
        times.append(dt)
        label = f"{plant}:{'+'.join(effects) or 'control'}"
        print(f"regression  {label:<52} {dt:6.1f} s  {what}", flush=True)
    # the cases with the seeds run_independent draws them with (si.case_plan)
    for c in si.case_plan(4242):
        label = c["label"]
        if not args.all and label not in INDEPENDENT:
            continue
        effs = c["effects"]
        if c["kind"] == "pair":
            case = si.make_independent_pair(effs, c["seed"], 20.0)
        else:
            e, s, f = effs[0] if effs else (None, None, None)
            case = si.make_independent_case(e, s, f, c["seed"], 20.0)
        dt, what = _time(case.spec, case.fit, case.hold)
        times.append(dt)
        print(f"independent {label:<52} {dt:6.1f} s  {what}", flush=True)
    bench = ROOT.parent / "shared" / "benchmarks" / "blind_joint_a"
    if bench.is_dir():
        from cablekit.diagnose import load_model_spec, load_run

        for d in sorted(p for p in bench.iterdir() if (p / "truth.json").exists()):
            if not args.all and d.name not in BENCHMARK_A:
                continue
            spec = load_model_spec(d / "model.toml")
            fit, hold = [load_run(d / "fit.csv.gz")], [load_run(d / "holdout.csv.gz")]
            dt, what = _time(spec, fit, hold, args.benchmark_seed)
            times.append(dt)
            print(f"benchmark A {d.name:<52} {dt:6.1f} s  {what}", flush=True)
    t = np.array(times)
    worst = float(t.max())
    ok = worst <= budget
    print(
        f"{len(t)} cases: min {t.min():.1f} s, median {np.median(t):.1f} s, 90th percentile "
        f"{np.quantile(t, 0.9):.1f} s, slowest {worst:.1f} s (budget {budget} s)  "
        + ("ok" if ok else "OVER BUDGET")
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
