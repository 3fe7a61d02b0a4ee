"""Diagnosis budget (issue #3): a 20 s, 1 kHz fit run and a 20 s held-out run against all 16
candidates in <= 30 s on 2 cores (candidate fits in parallel threads, simulation in Rust with the
GIL released). Cases: the slowest effects of the self-test (friction and hysteresis need the most
RK4 substeps), a pair, and a control. Exit 1 if any case is over budget.

Usage (release build installed): python benches/diagnose_bench.py
"""

from __future__ import annotations

import sys
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from cablekit.diagnose import Options, diagnose  # noqa: E402
from cablekit.diagnose.selftest import make_case  # noqa: E402

CASES = [("dahl_hysteresis",), ("coulomb_friction", "sensor_lag"), ("sensor_sampling",), ()]


def main() -> int:
    budget = tomllib.loads((ROOT / "benches" / "budgets.toml").read_text())["python"]["diagnose_20s_s"]
    worst = 0.0
    for i, effects in enumerate(CASES):
        case = make_case(effects, seed=300 + i, duration=20.0)
        t0 = time.perf_counter()
        res = diagnose(case.spec, case.fit, case.hold, Options(progress=False))
        dt = time.perf_counter() - t0
        worst = max(worst, dt)
        label = "+".join(effects) or "control"
        print(
            f"{label:<32} {dt:6.1f} s  verdict={res.verdict:<20} "
            f"selected={','.join(res.selected.effects) or '-'}"
        )
    ok = worst <= budget
    print(f"slowest: {worst:.1f} s (budget {budget} s)  {'ok' if ok else 'OVER BUDGET'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
