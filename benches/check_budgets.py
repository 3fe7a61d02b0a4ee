"""Compare criterion's estimates with benches/budgets.toml; exit 1 if a budget is exceeded.

Usage: cargo bench -p cable-bench && python benches/check_budgets.py [--target target]

The verdict is on criterion's mean. The median is printed beside it: on a shared machine a
co-tenant's burst lifts the mean first, and the two apart by more than a few per cent say the
run was disturbed (run it again before reading anything into a verdict).
"""

from __future__ import annotations

import argparse
import json
import sys
import tomllib
from pathlib import Path


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--target", default="target", help="cargo target directory")
    ap.add_argument("--budgets", default=str(Path(__file__).with_name("budgets.toml")))
    args = ap.parse_args()
    budgets = tomllib.loads(Path(args.budgets).read_text())["rust"]
    failed = 0
    print(f"{'benchmark':40s} {'mean':>14s} {'median':>14s} {'budget':>14s}  verdict")
    for name, budget_ns in budgets.items():
        est = Path(args.target) / "criterion" / name / "new" / "estimates.json"
        if not est.exists():
            print(f"{name:40s} {'missing':>14s} {'':>14s} {budget_ns:>12.0f}ns  FAIL (run cargo bench first)")
            failed += 1
            continue
        estimates = json.loads(est.read_text())
        mean = estimates["mean"]["point_estimate"]
        median = estimates["median"]["point_estimate"]
        ok = mean <= budget_ns
        failed += not ok
        verdict = "ok" if ok else "OVER BUDGET"
        print(f"{name:40s} {mean:>12.1f}ns {median:>12.1f}ns {budget_ns:>12.0f}ns  {verdict}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
