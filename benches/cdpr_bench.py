"""Tension distribution from Python against peers in the same run (issue #21): cablekit's improved
closed form and QP (batched, GIL released) against a NumPy closed form, scipy's HiGHS LP and
quadprog's QP, per pose on the IPAnema-like robot; ratios printed (the machine is shared, so
only ratios from one run mean anything).

Usage: python benches/cdpr_bench.py [--poses 2000]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from cablekit.cdpr import shipped


def _per_pose(fn, count: int) -> float:
    t0 = time.perf_counter()
    fn()
    return (time.perf_counter() - t0) / count * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--poses", type=int, default=2000)
    args = ap.parse_args()
    import quadprog
    from scipy.optimize import linprog

    robot = shipped("ipanema_like")
    rng = np.random.default_rng(0)
    t = args.poses
    poses = np.column_stack([
        rng.uniform(-1.4, 1.4, t), rng.uniform(-1.05, 1.05, t), rng.uniform(0.45, 2.55, t),
        rng.uniform(-0.1, 0.1, (t, 3)),
    ])  # fmt: skip
    kin = robot.inverse_kinematics(poses)
    w = np.array([robot.gravity_wrench(q) for q in poses])
    f_min, f_max = robot.bounds
    f_ref = 0.5 * (f_min + f_max)
    m = robot.n_cables
    few = min(t, 300)  # the slow peers on a subset

    def numpy_cfm():
        for at, wi in zip(kin.structure, w, strict=True):
            f_ref - np.linalg.pinv(at) @ (wi + at @ f_ref)

    bounds = list(zip(f_min, f_max, strict=True))

    def highs():
        for at, wi in zip(kin.structure[:few], w[:few], strict=True):
            linprog(np.zeros(m), A_eq=at, b_eq=-wi, bounds=bounds, method="highs")

    def qp_peer():
        for at, wi in zip(kin.structure[:few], w[:few], strict=True):
            c = np.hstack([at.T, np.eye(m), -np.eye(m)])
            try:
                quadprog.solve_qp(np.eye(m), f_ref, c, np.concatenate([-wi, f_min, -f_max]), meq=6)
            except ValueError:  # infeasible: quadprog says so by raising
                pass

    def ours(method: str) -> float:
        return _per_pose(lambda: robot.distribute(poses, method=method), t)

    rows = [
        ("cablekit improved closed form", ours("improved_closed_form")),
        ("cablekit QP (clarabel, warm)", ours("qp")),
        ("cablekit auto chain", ours("auto")),
        ("NumPy closed form (pinv)", _per_pose(numpy_cfm, t)),
        ("scipy HiGHS LP (feasibility)", _per_pose(highs, few)),
        ("quadprog QP", _per_pose(qp_peer, few)),
    ]
    base = rows[0][1]
    qp = rows[1][1]
    print(f"tension distribution, IPAnema-like 8 cables x 6 DOF, {t} poses (peers: {few}), per pose")
    for name, us in rows:
        print(f"  {name:32s} {us:10.2f} us   {us / base:8.1f}x improved closed form   {us / qp:6.2f}x QP")
    workspace_peers(robot)


def workspace_peers(robot) -> None:
    """The static workspace of a 50 x 50 x 50 grid (capacity margins, Rust, 2 threads) against
    per-pose membership by an LP (HiGHS) and the NumPy hyperplane-shifting reference (SVD per
    column set), each on a subset; ratios per pose."""
    import sys
    from pathlib import Path

    from scipy.optimize import linprog

    from cablekit.cdpr import Requirement, workspace

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from tests.reference import cdpr as ref

    t0 = time.perf_counter()
    ws = workspace(robot, counts=50)
    ours = (time.perf_counter() - t0) / ws.margin.size * 1e6
    t0 = time.perf_counter()
    inside = workspace(robot, counts=50, requirement=Requirement(margins="inside"))
    ours_inside = (time.perf_counter() - t0) / inside.margin.size * 1e6
    assert np.array_equal(inside.feasible, ws.feasible)
    x, y, z = ws.axes
    rng = np.random.default_rng(1)
    pick = rng.integers(0, 50, (200, 3))
    poses = np.column_stack([x[pick[:, 0]], y[pick[:, 1]], z[pick[:, 2]], np.zeros((200, 3))])
    kin = robot.inverse_kinematics(poses)
    f_min, f_max = robot.bounds
    bounds = list(zip(f_min, f_max, strict=True))
    w = [robot.gravity_wrench(q) for q in poses]

    def lp():
        for at, wi in zip(kin.structure, w, strict=True):
            linprog(np.zeros(robot.n_cables), A_eq=at, b_eq=-wi, bounds=bounds, method="highs")

    def svd():
        for at, wi in zip(kin.structure[:50], w[:50], strict=True):
            ref.capacity_margin(at, wi, f_min, f_max)

    rows = [
        ("cablekit capacity margin (grid)", ours),
        ("cablekit, margins inside only", ours_inside),
        ("scipy HiGHS LP (membership only)", _per_pose(lp, 200)),
        ("NumPy hyperplane shifting (SVD)", _per_pose(svd, 50)),
    ]
    print(
        f"static workspace, 50^3 grid = {ws.margin.size:,} poses in {ws.seconds * 1e3:.1f} ms "
        f"({inside.seconds * 1e3:.1f} ms with margins inside only), per pose"
    )
    for name, us in rows:
        print(f"  {name:34s} {us:10.3f} us   {us / ours:8.0f}x cablekit")


if __name__ == "__main__":
    main()
