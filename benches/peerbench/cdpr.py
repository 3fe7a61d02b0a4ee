"""Cable-driven parallel robots (the IPAnema-like 8-cable, 6-DOF robot; the Mini CDPR with
swivelling pulleys for MuJoCo): tension distribution, the wrench-feasible workspace and the
cable kinematics against what a user would otherwise pick, answers checked first.

* Tension distribution, random poses in the frame holding the platform's weight (seed 002
  eq. 5, ``Aᵀf + w = 0``, 10–3000 N): the closed form ``f = f_ref − A⁺ᵀ(w + Aᵀf_ref)`` against
  NumPy's ``pinv`` per pose (to 1e-6 N); the QP ``min ½‖f − f_ref‖²`` within the bounds against
  quadprog (Goldfarb–Idnani), qpsolvers on quadprog and on HiGHS's QP solver, every pose's
  feasibility the same and the tensions to 1e-6 of ``f_max`` (3 mN: HiGHS's interior tolerance;
  quadprog agrees to 1e-9 N); quadprog also against ``method="auto"``, the default (the improved
  closed form, the QP only where it fails), whose answers are the QP's optimum on these poses;
  and feasibility alone against scipy's HiGHS LP (an easier question than the QP's: the same
  verdict on every pose, no tensions compared).
* Wrench-feasible workspace: a 30³ grid at the home orientation that must hold the weight plus
  a 300 N side force and a 50 N·m moment about z (``Requirement(wrench=...)``, the capacity margin
  of every grid pose) against one HiGHS LP per pose on grid poses drawn at random: the same
  verdict on every drawn pose whose margin is not within 1e-6 N of zero.
* Kinematics: cable lengths and the structure matrix ``Aᵀ`` (``Robot.inverse_kinematics``,
  batched) against MuJoCo reading the exported MJCF (``mj_kinematics``, ``mj_comPos``,
  ``mj_tendon``: the least MuJoCo computes for tendon lengths and moment arms) pose by pose, as
  ``tests/test_mjcf.py`` compares them, to 1e-9 relative.
"""

from __future__ import annotations

import contextlib
import functools
import os
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from .core import Config, Kernel, Pair, Peer, Side, Verdict, both, close, same_flags

#: the workspace's required external wrench besides the weight: N and N·m
SIDE_WRENCH = np.array([300.0, 0.0, 0.0, 0.0, 0.0, 50.0])


@functools.cache
def _tension(quick: bool) -> dict[str, Any]:
    from cablekit.cdpr import shipped

    robot = shipped("ipanema_like")
    n = 300 if quick else 2000
    rng = np.random.default_rng(0)
    poses = np.column_stack([
        rng.uniform(-1.4, 1.4, n), rng.uniform(-1.05, 1.05, n), rng.uniform(0.45, 2.55, n),
        rng.uniform(-0.1, 0.1, (n, 3)),
    ])  # fmt: skip
    kin = robot.inverse_kinematics(poses)
    w = np.array([robot.gravity_wrench(q) for q in poses])
    f_min, f_max = robot.bounds
    return {"robot": robot, "poses": poses, "A": kin.structure, "w": w, "f_min": f_min, "f_max": f_max}


@contextlib.contextmanager
def _quiet_stdout():
    """Silence a C library's banner on file descriptor 1 (HiGHS prints one on first use)."""
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
            yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def _solver(name: str, d: dict[str, Any]) -> Any:
    """``(Aᵀ, w) ↦ f`` or ``None`` (infeasible), as a user of ``name`` writes it."""
    f_min, f_max = d["f_min"], d["f_max"]
    m = len(f_min)
    f_ref = 0.5 * (f_min + f_max)
    if name == "numpy":
        return lambda at, w: f_ref - np.linalg.pinv(at) @ (w + at @ f_ref)
    if name == "quadprog":
        import quadprog

        def solve(at: np.ndarray, w: np.ndarray) -> np.ndarray | None:
            c = np.hstack([at.T, np.eye(m), -np.eye(m)])
            try:
                return quadprog.solve_qp(np.eye(m), f_ref, c, np.concatenate([-w, f_min, -f_max]), meq=6)[0]
            except ValueError:  # quadprog's way of saying infeasible
                return None

        return solve
    if name.startswith("qpsolvers"):
        import qpsolvers
        import scipy.sparse as sp

        backend = name.split(":")[1]
        sparse = backend == "highs"  # HiGHS takes CSC matrices (qpsolvers warns otherwise)
        p = sp.identity(m, format="csc") if sparse else np.eye(m)

        def solve(at: np.ndarray, w: np.ndarray) -> np.ndarray | None:
            a = sp.csc_matrix(at) if sparse else at
            return qpsolvers.solve_qp(p, -f_ref, A=a, b=-w, lb=f_min, ub=f_max, solver=backend)

        if sparse:
            with _quiet_stdout():
                solve(d["A"][0], d["w"][0])
        return solve
    if name == "linprog":
        from scipy.optimize import linprog

        bounds = list(zip(f_min, f_max, strict=True))

        def solve(at: np.ndarray, w: np.ndarray) -> np.ndarray | None:
            res = linprog(np.zeros(m), A_eq=at, b_eq=-w, bounds=bounds, method="highs")
            return res.x if res.status == 0 else None

        return solve
    raise KeyError(name)


def agree_tensions(atol: float, flags_only: bool = False):
    """The same feasibility per pose and, unless ``flags_only``, the same tensions where
    feasible. cablekit's answer: its ``Tensions``; the peer's: one array or ``None`` per pose."""

    def agree(ours: Any, theirs: list[np.ndarray | None]) -> Verdict:
        held = np.array([t is not None for t in theirs])
        flags = same_flags(ours.feasible, held, "feasible poses")
        if flags_only or not flags.ok:
            return flags
        f = np.array([t for t in theirs if t is not None])
        return both(flags, close(ours.f[held], f, atol, "tensions", "N"))

    return agree


def _tension_pair(cfg: Config, peer: str, method: str = "qp") -> Pair:
    """cablekit's ``method`` (the closed form for the NumPy peer) against ``peer``."""
    d = _tension(cfg.quick)
    robot, poses = d["robot"], d["poses"]
    closed = peer == "numpy"
    few = len(poses) if closed else (100 if cfg.quick else 300)  # the slow peers on the first poses
    sub = np.ascontiguousarray(poses[:few])
    method = "closed_form" if closed else method
    solve = _solver(peer, d)
    a_t, w = d["A"][:few], d["w"][:few]

    def theirs() -> list[np.ndarray | None]:
        return [solve(at, wi) for at, wi in zip(a_t, w, strict=True)]

    if closed:
        agree = lambda ours, th: close(ours.f, np.array(th), 1e-6, "tensions", "N")  # noqa: E731
    else:
        agree = agree_tensions(1e-6 * float(d["f_max"].max()), flags_only=peer == "linprog")
    labels = {
        "numpy": "NumPy closed form (pinv per pose)",
        "quadprog": "quadprog.solve_qp per pose",
        "qpsolvers:quadprog": "qpsolvers.solve_qp(solver='quadprog') per pose",
        "qpsolvers:highs": "qpsolvers.solve_qp(solver='highs') per pose (HiGHS QP)",
        "linprog": "scipy linprog(method='highs') per pose (feasibility LP)",
    }
    return Pair(
        Side(f"Robot.distribute(method={method!r}), {few:,} poses in one call",
             lambda: robot.distribute(sub, method=method), few),
        Side(labels[peer], theirs, few),
        agree,
        "pose",
        note="the LP finds some feasible tensions, not the QP's optimum" if peer == "linprog" else "",
    )  # fmt: skip


# ---- workspace -----------------------------------------------------------------------------------


def _workspace_pair(cfg: Config) -> Pair:
    from scipy.optimize import linprog

    from cablekit.cdpr import Requirement, shipped, workspace

    robot = shipped("ipanema_like")
    counts, draws = (12, 40) if cfg.quick else (30, 200)
    req = Requirement(wrench=SIDE_WRENCH)
    grid = workspace(robot, counts=counts, requirement=req)
    rng = np.random.default_rng(1)
    pick = rng.integers(0, counts, (draws, 3))
    poses = np.column_stack([grid.axes[i][pick[:, i]] for i in range(3)] + [np.zeros((draws, 3))])
    kin = robot.inverse_kinematics(poses)
    wrench = [robot.gravity_wrench(q) + SIDE_WRENCH for q in poses]
    f_min, f_max = robot.bounds
    bounds = list(zip(f_min, f_max, strict=True))

    def ours() -> tuple[np.ndarray, np.ndarray]:
        ws = workspace(robot, counts=counts, requirement=req)
        at = tuple(pick.T)
        return ws.feasible[at], ws.margin[at]

    def theirs() -> np.ndarray:
        return np.array([
            linprog(np.zeros(robot.n_cables), A_eq=at, b_eq=-wi, bounds=bounds, method="highs").status == 0
            for at, wi in zip(kin.structure, wrench, strict=True)
        ])  # fmt: skip

    def agree(mine: tuple[np.ndarray, np.ndarray], lp: np.ndarray) -> Verdict:
        feasible, margin = mine
        clear = np.abs(margin) > 1e-6
        v = same_flags(feasible[clear], lp[clear], "verdicts")
        return Verdict(v.ok, f"{v.detail}, {int((~clear).sum())} poses on the edge left out")

    return Pair(
        Side(f"workspace(), {counts}³ grid, capacity margins", lambda: ours(), counts**3, ours),
        Side(f"scipy linprog(method='highs') per pose, {draws} grid poses", theirs, draws),
        agree,
        "pose",
        max_reps=5,
        note="cablekit also returns each pose's margin and weakest direction",
    )


# ---- MuJoCo --------------------------------------------------------------------------------------


def _robot_file(name: str) -> Path:
    return Path(str(resources.files("cablekit.cdpr") / "robots" / f"{name}.toml"))


def _mujoco_pair(cfg: Config, name: str) -> Pair:
    import mujoco

    from cablekit.cdpr import shipped
    from cablekit.cdpr.mjcf import INLET, mujoco_state, to_mjcf

    robot, path = shipped(name), _robot_file(name)
    m = mujoco.MjModel.from_xml_string(to_mjcf(path))
    d = mujoco.MjData(m)
    n = 100 if cfg.quick else 500
    rng = np.random.default_rng(0)
    anchors, _ = robot.points()
    lo, hi = anchors.min(axis=0), anchors.max(axis=0)
    mid, half = (lo + hi) / 2, (hi - lo) / 4
    poses = np.hstack([mid + half * rng.uniform(-1, 1, (n, 3)), rng.uniform(-0.25, 0.25, (n, 3))])
    qpos = np.array([mujoco_state(path, p) for p in poses])  # MuJoCo's state, not timed
    swivels = [int(m.joint(j).name[6:]) - 1 for j in range(m.njnt) if m.joint(j).name.startswith("swivel")]
    inlet = np.zeros(robot.n_cables)
    inlet[swivels] = INLET
    n_sw, platform = len(swivels), m.body("platform").id
    jac = np.zeros((m.ntendon, m.nv))
    sparse = m if hasattr(m, "ten_J_rownnz") else d

    def one(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_tendon(m, d)
        mujoco.mju_sparse2dense(jac, d.ten_J, sparse.ten_J_rownnz, sparse.ten_J_rowadr, sparse.ten_J_colind)
        rot = d.xmat[platform].reshape(3, 3)  # the free joint's angular part: body to world frame
        p = jac[:, n_sw:]
        return d.ten_length - inlet, -np.hstack([p[:, :3], p[:, 3:] @ rot.T]).T

    def theirs() -> tuple[np.ndarray, np.ndarray]:
        out = [one(q) for q in qpos]
        return np.array([o[0] for o in out]), np.array([o[1] for o in out])

    def ours() -> tuple[np.ndarray, np.ndarray]:
        kin = robot.inverse_kinematics(poses)
        return kin.length, kin.structure

    def agree(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> Verdict:
        scale_l, scale_a = float(np.abs(a[0]).max()), float(np.abs(a[1]).max())
        return both(
            close(a[0] / scale_l, b[0] / scale_l, 1e-9, "lengths (relative)"),
            close(a[1] / scale_a, b[1] / scale_a, 1e-9, "Aᵀ (relative)"),
        )

    return Pair(
        Side(f"Robot.inverse_kinematics, {n} poses in one call", ours, n),
        Side("MuJoCo mj_kinematics + mj_comPos + mj_tendon per pose", theirs, n),
        agree,
        "pose",
        note="MuJoCo's qpos (pose, swivel angles) prepared outside the timing" if n_sw else "",
    )


TENSION = Kernel(
    "tension",
    "tension distribution (8 cables × 6 DOF)",
    "the platform's weight held by 8 cables within 10–3000 N at random poses; the closed form "
    "and the QP per pose, checked against each peer's tensions (or feasibility, for the LP)",
    (
        Peer("NumPy closed form", (), lambda cfg: _tension_pair(cfg, "numpy")),
        Peer("quadprog", ("quadprog",), lambda cfg: _tension_pair(cfg, "quadprog")),
        Peer("quadprog (vs auto)", ("quadprog",), lambda cfg: _tension_pair(cfg, "quadprog", "auto")),
        Peer(
            "qpsolvers (quadprog)",
            ("qpsolvers", "quadprog"),
            lambda cfg: _tension_pair(cfg, "qpsolvers:quadprog"),
        ),
        Peer(
            "qpsolvers (HiGHS QP)",
            ("qpsolvers", "highspy", "scipy"),
            lambda cfg: _tension_pair(cfg, "qpsolvers:highs"),
        ),
        Peer("scipy HiGHS LP", ("scipy",), lambda cfg: _tension_pair(cfg, "linprog")),
    ),
)

WORKSPACE = Kernel(
    "workspace",
    "wrench-feasible workspace",
    "every grid pose that holds the weight plus a 300 N side force and 50 N·m about z: cablekit's "
    "capacity margins on the grid against one LP per pose; the same verdict on every drawn pose",
    (Peer("scipy HiGHS LP per pose", ("scipy",), _workspace_pair),),
)

KINEMATICS = Kernel(
    "mujoco",
    "cable kinematics (lengths, Aᵀ)",
    "cable lengths and moment arms of the exported MJCF in MuJoCo against cablekit's inverse "
    "kinematics and structure matrix, to 1e-9 relative (tests/test_mjcf.py)",
    (
        Peer("MuJoCo, IPAnema-like", ("mujoco",), lambda cfg: _mujoco_pair(cfg, "ipanema_like")),
        Peer(
            "MuJoCo, Mini CDPR (4 swivelling pulleys)",
            ("mujoco",),
            lambda cfg: _mujoco_pair(cfg, "seed002_mini"),
        ),
    ),
)
