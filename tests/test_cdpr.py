"""Cable-driven parallel robots (issue #21): the Rust kinematics and tension distribution against
the NumPy reference (tests/reference/cdpr.py), an exact LP (scipy HiGHS) and a second QP solver
(quadprog), and the robot files' errors."""

from __future__ import annotations

import tomllib
from importlib import resources

import numpy as np
import pytest
import quadprog
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog

import cablekit as ck
from cablekit.cdpr import Robot, shipped
from tests.reference import cdpr as ref

NAMES = ["seed002_mini", "seed003_planar", "ipanema_like"]


def _doc(name: str) -> dict:
    text = (resources.files("cablekit.cdpr") / "robots" / f"{name}.toml").read_text(encoding="utf-8")
    return tomllib.loads(text)


def _reference_robot(name: str) -> dict:
    doc = _doc(name)
    cables = doc["cables"]
    pulleys = {}
    for i, c in enumerate(cables):
        if "pulley" in c:
            axis = np.asarray(c["pulley"]["axis"], float)
            pulleys[i] = (c["pulley"]["radius"], axis / np.linalg.norm(axis))
    return {
        "motion": doc["motion"],
        "anchors": [c["anchor"] for c in cables],
        "attachments": [c["attachment"] for c in cables],
        "pulleys": pulleys,
    }


def _poses(robot: Robot, count: int, rng: np.random.Generator, rotation: float = 0.1) -> np.ndarray:
    """Poses inside the frame: the central 70 % of its span, small rotations."""
    anchors, _ = robot.points()
    lo, hi = anchors.min(axis=0), anchors.max(axis=0)
    mid, half = 0.5 * (lo + hi), 0.35 * (hi - lo)
    if robot.motion == "planar":
        xy = mid[:2] + half[:2] * rng.uniform(-1, 1, (count, 2))
        return np.column_stack([xy, rotation * rng.uniform(-1, 1, count)])
    xyz = mid + half * rng.uniform(-1, 1, (count, 3))
    return np.column_stack([xyz, rotation * rng.uniform(-1, 1, (count, 3))])


@pytest.mark.parametrize("name", NAMES)
def test_kinematics_match_the_reference(name):
    """Lengths (pulley arcs included) and structure matrices ≤ 1e-12 of the NumPy reference."""
    robot = shipped(name)
    poses = _poses(robot, 200, np.random.default_rng(1))
    kin = robot.inverse_kinematics(poses)
    spec = _reference_robot(name)
    for q, length, at in zip(poses, kin.length, kin.structure, strict=True):
        ref_length, ref_at = ref.inverse_kinematics(spec, q)
        np.testing.assert_allclose(length, ref_length, rtol=0, atol=1e-12)
        np.testing.assert_allclose(at, ref_at, rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", NAMES)
def test_forward_kinematics_inverts_the_inverse(name):
    robot = shipped(name)
    rng = np.random.default_rng(2)
    for q in _poses(robot, 20, rng):
        lengths = robot.inverse_kinematics(q[None]).length[0]
        pose, rms, iterations, converged = robot.forward_kinematics(
            lengths, q + 0.01 * rng.standard_normal(len(q))
        )
        assert converged and rms < 1e-10 and iterations < 20
        np.testing.assert_allclose(pose, q, atol=1e-8)


@pytest.mark.parametrize("method", ["minimum_norm", "closed_form", "improved_closed_form", "qp", "auto"])
@pytest.mark.parametrize("name", NAMES)
def test_every_feasible_answer_holds_the_wrench_within_the_bounds(name, method):
    """Aᵀf + w = 0 to 1e-9 and f_min ≤ f ≤ f_max exactly wherever a method says feasible; the closed
    forms equal the NumPy equations."""
    robot = shipped(name)
    rng = np.random.default_rng(3)
    poses = _poses(robot, 100, rng)
    res = robot.distribute(poses, method=method)
    kin = robot.inverse_kinematics(poses)
    f_min, f_max = robot.bounds
    for i, q in enumerate(poses):
        w = robot.gravity_wrench(q)
        at = kin.structure[i]
        f = res.f[i]
        if res.feasible[i]:
            # one meaning for every method (issue #38): equilibrium and the bounds
            assert np.linalg.norm(at @ f + w) <= 1e-9 * (1 + np.abs(f).max())
            assert np.all(f >= f_min) and np.all(f <= f_max)
        if method == "closed_form":
            np.testing.assert_allclose(f, ref.closed_form(at, w, f_min, f_max), rtol=1e-10, atol=1e-9)
        if method == "minimum_norm":
            np.testing.assert_allclose(f, ref.minimum_norm(at, w), rtol=1e-10, atol=1e-9)
            within = bool(np.all(f >= f_min) and np.all(f <= f_max))
            held = np.linalg.norm(at @ f + w) <= 1e-9 * (1 + np.abs(w).max() + np.abs(f).max())
            assert res.feasible[i] == (within and held)
    if method != "minimum_norm":
        assert res.feasible.mean() > 0.5, "the shipped robots hold their weight over most of the frame"


def _lp_feasible(at, w, f_min, f_max) -> bool:
    lp = linprog(
        np.zeros(at.shape[1]), A_eq=at, b_eq=-w, bounds=list(zip(f_min, f_max, strict=True)), method="highs"
    )
    return lp.status == 0


def test_qp_finds_tensions_wherever_an_exact_lp_does():
    """2,000 random poses and wrenches of the IPAnema-like robot: where HiGHS finds feasible
    tensions the QP must too, and it never calls an infeasible case feasible. The improved
    closed form's coverage of the QP's feasible cases is measured (literature: about 99.8 %)."""
    robot = shipped("ipanema_like")
    rng = np.random.default_rng(4)
    poses = _poses(robot, 2000, rng)
    wrenches = np.column_stack([rng.uniform(-1500, 1500, (2000, 3)), rng.uniform(-150, 150, (2000, 3))])
    qp = robot.distribute(poses, wrenches, method="qp")
    icf = robot.distribute(poses, wrenches, method="improved_closed_form")
    kin = robot.inverse_kinematics(poses)
    f_min, f_max = robot.bounds
    lp = np.array(
        [
            _lp_feasible(kin.structure[i], robot.gravity_wrench(q) + wrenches[i], f_min, f_max)
            for i, q in enumerate(poses)
        ]
    )
    assert 0.3 < lp.mean() < 0.95, "the sample must hold both kinds of case"
    assert np.all(qp.feasible[lp]), f"QP missed {np.sum(~qp.feasible[lp])} LP-feasible cases"
    assert not np.any(qp.feasible[~lp]), "QP called an LP-infeasible case feasible"
    assert set(qp.method) <= {"qp", "least_wrench_error"}
    coverage = icf.feasible[lp].mean()
    print(f"improved closed form covers {100 * coverage:.2f} % of {lp.sum()} LP-feasible cases")
    assert coverage > 0.9


def test_qp_equals_a_second_solver():
    """Clarabel's polished answer equals quadprog's (Goldfarb–Idnani) to 1e-6 N."""
    robot = shipped("seed002_mini")
    rng = np.random.default_rng(5)
    poses = _poses(robot, 200, rng)
    wrenches = np.column_stack([rng.uniform(-8, 8, (200, 3)), rng.uniform(-0.3, 0.3, (200, 3))])
    res = robot.distribute(poses, wrenches, method="qp")
    kin = robot.inverse_kinematics(poses)
    f_min, f_max = robot.bounds
    f_ref = 0.5 * (f_min + f_max)
    m = robot.n_cables
    compared = 0
    for i, q in enumerate(poses):
        if not res.feasible[i]:
            continue
        at = kin.structure[i]
        w = robot.gravity_wrench(q) + wrenches[i]
        # quadprog: min ½xᵀGx − aᵀx s.t. Cᵀx ≥ b, the first meq as equalities
        c = np.hstack([at.T, np.eye(m), -np.eye(m)])
        b = np.concatenate([-w, f_min, -f_max])
        x = quadprog.solve_qp(np.eye(m), f_ref, c, b, meq=at.shape[0])[0]
        np.testing.assert_allclose(res.f[i], x, atol=1e-6)
        compared += 1
    assert compared > 100


def test_an_impossible_wrench_is_reported_not_clamped():
    robot = shipped("seed003_planar")
    pose = np.array([[0.6, 0.5, 0.0]])
    res = robot.distribute(pose, np.array([[0.0, 1e4, 0.0]]))
    assert not res.feasible[0] and res.method == ["least_wrench_error"]
    assert res.residual[0] > 1e3
    f_min, f_max = robot.bounds
    assert np.all(res.f[0] >= f_min) and np.all(res.f[0] <= f_max)
    cf = robot.distribute(pose, np.array([[0.0, 1e4, 0.0]]), method="improved_closed_form")
    assert not cf.feasible[0] and cf.residual[0] < 1e-6, (
        "the closed form keeps the equilibrium, flags the bounds"
    )


def test_bad_input_is_a_typed_error():
    robot = shipped("seed003_planar")
    with pytest.raises(ck.NotFiniteError):
        robot.distribute(np.array([[0.6, 0.5, 0.0]]), np.array([[np.nan, 0.0, 0.0]]))
    with pytest.raises(ck.ShapeError):
        robot.distribute(np.zeros((2, 6)))
    with pytest.raises(ck.ParameterError, match="method"):
        robot.distribute(np.array([[0.6, 0.5, 0.0]]), method="simplex")
    # degenerate geometry: the platform on an anchor
    with pytest.raises(ck.ParameterError, match="poses\\[1\\]"):
        robot.inverse_kinematics(np.array([[0.6, 0.5, 0.0], [0.05, 0.95, 0.0]]))
    doc = _doc("seed003_planar")
    bad = {**doc, "cable": {**doc["cable"], "f_min": 200.0}}
    with pytest.raises(ck.ParameterError, match=r"cables\[0\]\.f_max"):
        Robot.from_dict(bad)
    with pytest.raises(ck.DataError, match="unknown key"):
        Robot.from_dict({**doc, "colour": "red"})
    with pytest.raises(ck.DataError, match=r"cables\[1\]\.anchor"):
        Robot.from_dict(
            {**doc, "cables": [doc["cables"][0], {**doc["cables"][1], "anchor": [0, 1]}, *doc["cables"][2:]]}
        )
    with pytest.raises(ck.DataError, match="not valid TOML"):
        Robot.from_toml("name = ")
    with pytest.raises(ck.DataError, match="elasticity"):
        Robot.from_dict({**doc, "cable": {"f_min": 1.0, "f_max": 10.0}})
    # a structure matrix without full rank: all cables through one point cannot take a moment
    collinear = {**doc, "cables": [{**c, "attachment": [0.0, 0.0, 0.0]} for c in doc["cables"]]}
    with pytest.raises(ck.ParameterError, match="full row rank"):
        Robot.from_dict(collinear).distribute(np.array([[0.6, 0.5, 0.0]]), method="closed_form")


_VALUES = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(10**6), 10**6),
    st.text(max_size=5),
    st.lists(st.floats(-10, 10), max_size=4),
    st.none(),
    st.booleans(),
)


@settings(max_examples=150, deadline=None)
@given(
    where=st.sampled_from(["top", "platform", "cable", "cables"]),
    key=st.sampled_from(
        [
            "mass",
            "com",
            "inertia",
            "f_min",
            "f_max",
            "ea",
            "anchor",
            "attachment",
            "motion",
            "gravity",
            "pulley",
            "x",
        ]
    ),
    value=_VALUES,
)
def test_any_value_anywhere_in_a_robot_file_loads_or_raises_a_cablekit_error(where, key, value):
    doc = _doc("seed002_mini")
    if where == "top":
        doc[key] = value
    elif where == "cables":
        doc["cables"][3] = {**doc["cables"][3], key: value}
    else:
        doc[where] = {**doc[where], key: value}
    try:
        robot = Robot.from_dict(doc)
    except ck.CablekitError:
        return
    res = robot.distribute(np.array([[0.0, 0.0, 0.475, 0.0, 0.0, 0.0]]))
    assert np.all(np.isfinite(res.f))


@settings(max_examples=100, deadline=None)
@given(
    rows=st.integers(0, 3),
    cols=st.integers(0, 8),
    fill=st.sampled_from([0.0, np.nan, np.inf, 1e308, -1e308, 0.3]),
    dtype=st.sampled_from([np.float64, np.float32, np.int64]),
    method=st.sampled_from(["auto", "qp", "closed_form"]),
)
def test_any_array_to_the_robot_calls_is_a_typed_error_or_finite(rows, cols, fill, dtype, method):
    robot = shipped("seed003_planar")
    with np.errstate(all="ignore"):
        poses = np.full((rows, cols), fill).astype(dtype)
    for call in (lambda: robot.distribute(poses, method=method), lambda: robot.inverse_kinematics(poses)):
        try:
            out = call()
        except ck.CablekitError:
            continue
        values = out.f if hasattr(out, "f") else out.length
        assert np.all(np.isfinite(values))


@pytest.mark.parametrize(
    ("name", "start", "end", "load"),
    [
        ("seed002_mini", [-0.3, -0.2, 0.2, 0, 0, 0], [0.3, 0.2, 0.75, 0.1, -0.1, 0.2], [8, 0, 0, 0, 0, 0]),
        (
            "ipanema_like",
            [-0.8, -0.6, 1.0, 0.05, -0.05, 0],
            [0.8, 0.6, 2.0, 0.05, -0.05, 0.1],
            [1500, 0, 0, 0, 0, 0],
        ),
        ("seed003_planar", [0.3, 0.3, -0.2], [0.9, 0.7, 0.2], [10, 0, 0]),
    ],
)
def test_the_auto_chain_is_as_continuous_as_the_qp_along_a_trajectory(name, start, end, load):
    """2,000 poses on a straight path with a constant side load: between feasible neighbours the
    auto chain's largest tension jump is the QP optimum's own (a method switch adds none); the
    jumps are printed for docs/cdpr.md."""
    robot = shipped(name)
    s = np.linspace(0.0, 1.0, 2000)[:, None]
    poses = np.ascontiguousarray((1 - s) * np.array(start, float) + s * np.array(end, float))
    wrenches = np.tile(np.array(load, float), (2000, 1))
    jumps = {}
    for method in ("auto", "qp"):
        res = robot.distribute(poses, wrenches, method=method)
        both = res.feasible[:-1] & res.feasible[1:]
        jumps[method] = np.abs(np.diff(res.f, axis=0)).max(axis=1)[both].max()
    print(
        f"{name}: largest jump between feasible neighbours auto {jumps['auto']:.3f} N, qp {jumps['qp']:.3f} N"
    )
    assert jumps["auto"] <= jumps["qp"] + 1e-6


# --- capacity margin and workspace ---------------------------------------------------------


@pytest.mark.parametrize("name", NAMES)
def test_capacity_margin_matches_the_reference_with_and_without_a_wrench_box(name):
    """The core's margins (elimination + generalised cross products) equal the SVD reference
    over every (n − 1)-column set to 1e-9 N relative, for the weight, a wrench box and a
    moment length."""
    robot = shipped(name)
    rng = np.random.default_rng(11)
    poses = _poses(robot, 60, rng, rotation=0.2)
    kin = robot.inverse_kinematics(poses)
    f_min, f_max = robot.bounds
    n = robot.dof
    scale = f_max.max()
    center = rng.uniform(-0.05, 0.05, n) * scale
    half = rng.uniform(0.0, 0.05, n) * scale
    for kwargs, args in [({}, {}), ({"moment_length": 0.2}, {"moment_length": 0.2})]:
        plain = robot.capacity(poses, **kwargs)
        boxed = robot.capacity(poses, center, half, **kwargs)
        for i, q in enumerate(poses):
            w = robot.gravity_wrench(q)
            want = ref.capacity_margin(kin.structure[i], w, f_min, f_max, **args)
            np.testing.assert_allclose(plain.margin[i], want, rtol=1e-9, atol=1e-9 * scale)
            want_box = ref.capacity_margin(kin.structure[i], w, f_min, f_max, center, half, **args)
            np.testing.assert_allclose(boxed.margin[i], want_box, rtol=1e-9, atol=1e-9 * scale)
        assert np.array_equal(plain.feasible, plain.margin >= 0)
        assert not plain.degenerate.any()
        # margins="inside": the same membership and inside margins; outside, a crossed facet's
        # distance, between the exact margin and zero
        for full, args in [(plain, ()), (boxed, (center, half))]:
            fast = robot.capacity(poses, *args, margins="inside", **kwargs)
            assert np.array_equal(fast.feasible, full.feasible)
            inside = full.feasible
            assert np.array_equal(fast.margin[inside], full.margin[inside])
            out = fast.margin[~inside]
            assert np.all(out < 0) and np.all(out >= full.margin[~inside] - 1e-9 * scale)
    assert (~plain.feasible).sum() >= 5  # the outside branch above is exercised


def test_capacity_sign_is_lp_feasibility_and_the_weakest_direction_is_tight():
    """1,000 random poses and wrenches of the IPAnema-like robot: margin > 0 exactly where
    HiGHS finds tensions; inside, the wrench moved by 0.99 × margin along the weakest
    direction is still held and by 1.01 × margin is not."""
    robot = shipped("ipanema_like")
    rng = np.random.default_rng(12)
    poses = _poses(robot, 1000, rng)
    kin = robot.inverse_kinematics(poses)
    f_min, f_max = robot.bounds
    inside = outside = 0
    for i, q in enumerate(poses):
        wc = np.concatenate([rng.uniform(-1500, 1500, 3), rng.uniform(-150, 150, 3)])
        cap = robot.capacity(q[None, :], wc)
        s, weak = cap.margin[0], cap.weakest[0]
        w = robot.gravity_wrench(q) + wc
        at = kin.structure[i]
        if abs(s) < 1e-6:
            continue
        assert _lp_feasible(at, w, f_min, f_max) == (s > 0), (i, s)
        if s > 1.0 and inside < 150:
            inside += 1
            assert _lp_feasible(at, w + 0.99 * s * weak, f_min, f_max)
            assert not _lp_feasible(at, w + 1.01 * s * weak, f_min, f_max)
        outside += s < 0
    assert inside >= 100 and outside >= 100, (inside, outside)


def test_workspace_grid_summary_and_files(tmp_path):
    """The grid covers the anchors' box; the planar map is the capacity of its poses; the
    wrench-feasible workspace lies inside the static one; the saved map reads back."""
    from cablekit.cdpr import Requirement, workspace

    robot = shipped("seed003_planar")
    ws = workspace(robot, counts=(30, 20))
    assert ws.margin.shape == (30, 20) and ws.requirement.kind == "static"
    anchors, _ = robot.points()
    assert ws.axes[0][0] == anchors[:, 0].min() and ws.axes[1][-1] == anchors[:, 1].max()
    i, j = 17, 9
    cap = robot.capacity(np.array([[ws.axes[0][i], ws.axes[1][j], 0.0]]))
    assert cap.margin[0] == ws.margin[i, j]
    assert 0.2 < ws.fraction < 1.0
    assert ws.size == pytest.approx(ws.feasible.sum() * np.diff(ws.axes[0])[0] * np.diff(ws.axes[1])[0])
    box = workspace(robot, counts=(30, 20), requirement=Requirement(half_width=np.array([5.0, 5.0, 0.2])))
    assert box.requirement.kind == "wrench-feasible"
    assert not np.any(box.feasible & ~ws.feasible) and box.feasible.sum() < ws.feasible.sum()
    assert np.all(box.margin <= ws.margin + 1e-9)
    d = ws.save(tmp_path / "ws")
    with np.load(d / "workspace.npz") as back:
        assert np.array_equal(back["margin"], ws.margin) and np.array_equal(back["x"], ws.axes[0])
    assert "static" in (d / "workspace.md").read_text()
    with pytest.raises(ck.ShapeError):
        workspace(robot, lower=[0.0, 0.0, 0.0])
    with pytest.raises(ck.ParameterError):
        workspace(robot, counts=0)
    with pytest.raises(ck.ParameterError):
        workspace(robot, lower=[1.0, 1.0], upper=[0.0, 0.0])


def test_capacity_bad_input_is_a_typed_error():
    robot = shipped("seed002_mini")
    q = np.zeros((1, 6))
    q[0, 2] = 0.4
    with pytest.raises(ck.ShapeError):
        robot.capacity(q, np.zeros(5))
    with pytest.raises(ck.NotFiniteError):
        robot.capacity(q, np.full(6, np.nan))
    with pytest.raises(ck.ParameterError):
        robot.capacity(q, None, -np.ones(6))
    with pytest.raises(ck.ParameterError):
        robot.capacity(q, moment_length=0.0)
    with pytest.raises(ck.DTypeError):
        robot.capacity(q.astype(np.float32))
    with pytest.raises(ck.ParameterError, match="everywhere, inside"):
        robot.capacity(q, margins="outside")


# --- the controller API --------------------------------------------------------------------


def test_the_controller_steps_equal_the_batch_and_write_in_place():
    robot = shipped("seed002_mini")
    s = np.linspace(0, 1, 60)[:, None]
    poses = np.column_stack([0.3 * s, -0.2 * s, 0.3 + 0.2 * s, 0 * s, 0.1 * s, 0.05 * s])
    wrenches = np.column_stack([2.0 * s, 0 * s, 0 * s, 0 * s, 0 * s, 0.1 * s])
    batch = robot.distribute(poses, wrenches)
    ctl = robot.controller("auto")
    out = np.zeros(robot.n_cables)
    prev = None
    for k, (q, w) in enumerate(zip(poses, wrenches, strict=True)):
        st_ = ctl.step(q, w, out)
        assert st_.f is out
        np.testing.assert_allclose(out, batch.f[k], rtol=0, atol=1e-9)
        assert st_.method == batch.method[k] and st_.feasible == batch.feasible[k]
        want = 0.0 if prev is None else float(np.abs(out - prev).max())
        assert st_.jump == pytest.approx(want, abs=1e-12)
        prev = out.copy()
    fresh = ctl.step(poses[0])
    np.testing.assert_allclose(fresh.f, robot.distribute(poses[:1]).f[0], atol=1e-9)
    for bad, err in [
        (lambda: ctl.step(np.zeros(5)), ck.ShapeError),
        (lambda: ctl.step(poses[0], np.full(6, np.inf)), ck.NotFiniteError),
        (lambda: ctl.step(poses[0], None, np.zeros(8, np.float32)), ck.DTypeError),
        (lambda: ctl.step(poses[0], None, np.zeros(7)), ck.ShapeError),
        (lambda: robot.controller("simplex"), ck.ParameterError),
    ]:
        with pytest.raises(err):
            bad()
    ro = np.zeros(8)
    ro.flags.writeable = False
    with pytest.raises(ck.CablekitError):
        ctl.step(poses[0], None, ro)


@settings(max_examples=100, deadline=None)
@given(
    rows=st.integers(0, 3),
    cols=st.integers(0, 7),
    fill=st.sampled_from([0.0, np.nan, np.inf, 1e308, -1e308, 0.3]),
    dtype=st.sampled_from([np.float64, np.float32, np.int64]),
    length=st.sampled_from([1.0, 0.0, -1.0, np.nan, 1e308]),
)
def test_any_array_to_capacity_and_the_controller_is_a_typed_error_or_finite(rows, cols, fill, dtype, length):
    robot = shipped("seed002_mini")
    with np.errstate(all="ignore"):
        poses = np.full((rows, cols), fill).astype(dtype)
        vec = np.full(cols, fill).astype(dtype)
    try:
        cap = robot.capacity(poses, vec if cols == 6 else None, moment_length=length)
        assert np.all(np.isfinite(cap.margin)) and np.all(np.isfinite(cap.weakest))
    except ck.CablekitError:
        pass
    ctl = robot.controller()
    try:
        s = ctl.step(vec, vec)
        assert np.all(np.isfinite(s.f)) and np.isfinite(s.residual)
    except ck.CablekitError:
        pass


# --- the CLI ------------------------------------------------------------------------------


def test_cli_distribute_writes_the_batch_answer_and_rejects_bad_columns(tmp_path, capsys):
    from cablekit.cli import main

    robot = shipped("seed003_planar")
    t = np.linspace(0, 1, 25)
    poses = np.column_stack([0.2 + 0.6 * t, 0.3 + 0.2 * t, 0.1 * np.sin(6 * t)])
    path = tmp_path / "traj.csv"
    lines = ["t,x,y,theta,fx,fy,mz"] + [
        f"{a},{float(q[0])!r},{float(q[1])!r},{float(q[2])!r},1.0,0.0,0.01"
        for a, q in zip(t, poses, strict=True)
    ]
    path.write_text("\n".join(lines) + "\n")
    assert (
        main(
            [
                "cdpr",
                "distribute",
                "seed003_planar",
                "--trajectory",
                str(path),
                "--out",
                str(tmp_path / "o"),
                "--no-plots",
            ]
        )
        == 0
    )
    rows = (tmp_path / "o" / "tensions.csv").read_text().splitlines()
    header = rows[0].split(",")
    assert header[:5] == ["t", "f1", "f2", "f3", "f4"] and header[-4:] == [
        "method",
        "feasible",
        "residual",
        "jump",
    ]
    got = np.array([[float(v) for v in r.split(",")[1:5]] for r in rows[1:]])
    want = robot.distribute(poses, np.tile([1.0, 0.0, 0.01], (25, 1))).f
    np.testing.assert_allclose(got, want, rtol=1e-8)
    jumps = np.array([float(r.split(",")[-1]) for r in rows[1:]])
    np.testing.assert_allclose(jumps[1:], np.abs(np.diff(want, axis=0)).max(axis=1), rtol=1e-5)
    for text, needle in [
        ("t,x,y\n0,0.5,0.4\n", "missing column"),
        ("x,y,theta,speed\n0.5,0.4,0,1\n", "unknown column"),
        ("x,y,theta,fx\n0.5,0.4,0,1\n", "all wrench columns"),
        ("x,y,theta\n0.5,nan,0\n", "not finite"),
        ("x,y,theta\n0.5,,0\n", "missing"),
        ("x,y,theta\n0.5,abc,0\n", "not a number"),
        ("x,y,x\n0.5,0.1,0\n", "duplicated"),
        ("x,y,theta\n", "no rows"),
    ]:
        path.write_text(text)
        code = main(
            ["cdpr", "distribute", "seed003_planar", "--trajectory", str(path), "--out", str(tmp_path / "x")]
        )
        assert code == 4 and needle in capsys.readouterr().err


def test_cli_workspace_writes_the_map_table_and_plots(tmp_path):
    from cablekit.cli import main

    out = tmp_path / "w"
    assert main(["cdpr", "workspace", "seed002_mini", "--out", str(out), "--counts", "12"]) == 0
    back = np.load(out / "workspace.npz")
    assert back["margin"].shape == (12, 12, 12)
    assert {"workspace_slices.png", "workspace_3d.png", "workspace.md"} <= {p.name for p in out.iterdir()}
    assert main(["cdpr", "workspace", "no_such_robot", "--out", str(out)]) == 4


# --- CASPR import ---------------------------------------------------------------------------

_BODIES = """<?xml version="1.0" encoding="utf-8"?>
<links display_range="-3 3 -3 3 0 3">
  <link_rigid num="1" name="test platform">
    <joint type="{joint}" />
    <physical>
      <mass>{mass}</mass>
      <com_location>0.0 0.0 0.05</com_location>
      <end_location>0.0 0.0 0.0</end_location>
      <inertia ref="com">
        <Ixx>0.2</Ixx><Iyy>0.3</Iyy><Izz>0.4</Izz><Ixy>0.01</Ixy><Ixz>0.0</Ixz><Iyz>0.0</Iyz>
      </inertia>
    </physical>
    <parent><num>0</num><location>0.0 0.0 0.0</location></parent>
  </link_rigid>
</links>
"""


def _caspr_cables(robot: Robot, reference: str, model: str = "cable_ideal") -> str:
    anchors, attachments = robot.points()
    anchors, attachments = anchors.tolist(), attachments.tolist()
    f_min, f_max = robot.bounds
    shift = np.array([0.0, 0.0, 0.05]) if reference == "com" else np.zeros(3)
    body = []
    for i, (a, b) in enumerate(zip(anchors, attachments, strict=True)):
        b = (np.asarray(b) - shift).tolist()
        body.append(
            f'<{model} name="cable {i + 1}" attachment_reference="{reference}">'
            f"<properties><force_min>{float(f_min[i])!r}</force_min><force_max>{float(f_max[i])!r}</force_max></properties>"
            "<attachments>"
            f"<attachment><link>0</link><location>{a[0]!r} {a[1]!r} {a[2]!r}</location></attachment>"
            f"<attachment><link>1</link><location>{b[0]!r} {b[1]!r} {b[2]!r}</location></attachment>"
            f"</attachments></{model}>"
        )
    return (
        '<?xml version="1.0" encoding="utf-8"?>\n<cables default_cable_set="main">'
        f'<cable_set id="other"></cable_set><cable_set id="main">{"".join(body)}</cable_set></cables>\n'
    )


@pytest.mark.parametrize("reference", ["joint", "com"])
@pytest.mark.parametrize("name", ["ipanema_like", "seed003_planar"])
def test_a_caspr_robot_imports_with_its_geometry_bounds_and_platform(tmp_path, name, reference):
    """A robot written in CASPR's format (bodies + cables files, either attachment reference)
    imports to the same kinematics, bounds and weight as the cablekit file it was written from."""
    robot = shipped(name)
    joint = "PLANAR_XY" if robot.motion == "planar" else "SPATIAL_EULER_XYZ"
    mass = 2.5
    (tmp_path / "b.xml").write_text(_BODIES.format(joint=joint, mass=mass))
    (tmp_path / "c.xml").write_text(_caspr_cables(robot, reference))
    got = Robot.from_caspr(tmp_path / "b.xml", tmp_path / "c.xml", ea=2e6)
    assert got.motion == robot.motion and got.n_cables == robot.n_cables and got.name == "test platform"
    poses = _poses(robot, 50, np.random.default_rng(5))
    np.testing.assert_allclose(
        got.inverse_kinematics(poses).structure, robot.inverse_kinematics(poses).structure, atol=1e-12
    )
    for a, b in zip(got.bounds, robot.bounds, strict=True):
        np.testing.assert_array_equal(a, b)
    # CASPR's gravity: 9.81 m/s² along the base's -z for every model, so a planar CASPR robot
    # moves in a horizontal plane with no weight in it
    g = got.gravity_wrench(poses[0])
    if robot.motion == "planar":
        assert np.all(g == 0.0)
    else:
        np.testing.assert_allclose(g[:3], [0.0, 0.0, -9.81 * mass], rtol=1e-12)
    with pytest.raises(ck.DataError, match="no cable set"):
        Robot.from_caspr(tmp_path / "b.xml", tmp_path / "c.xml", "missing")
    with pytest.raises(ck.DataError, match="no cables"):
        Robot.from_caspr(tmp_path / "b.xml", tmp_path / "c.xml", "other")


def test_the_layouts_of_caspr_s_own_example_files_import(tmp_path):
    """Issue #38: CASPR's shipped files wrap <links> in <bodies_system>, give the joint type as an
    element and keep <display_range> beside the link (CoGiRo's, KNTU_planar's layout): they
    import to the same robot as the plain layout."""
    robot = shipped("ipanema_like")
    (tmp_path / "c.xml").write_text(_caspr_cables(robot, "joint"))
    plain = _BODIES.format(joint="SPATIAL_EULER_XYZ", mass=91.058)
    newer = (
        plain.replace('<joint type="SPATIAL_EULER_XYZ" />', "<joint_type>SPATIAL_EULER_XYZ</joint_type>")
        .replace("</links>", "<display_range>-8 8 -6 6 0 6</display_range></links>")
        .replace('<links display_range="-3 3 -3 3 0 3">', "<bodies_system><links>")
        .replace("</links>", "</links><operational_spaces/></bodies_system>")
    )
    assert "<bodies_system>" in newer and "<joint_type>" in newer
    (tmp_path / "plain.xml").write_text(plain)
    (tmp_path / "newer.xml").write_text(newer)
    a = Robot.from_caspr(tmp_path / "plain.xml", tmp_path / "c.xml")
    b = Robot.from_caspr(tmp_path / "newer.xml", tmp_path / "c.xml")
    poses = _poses(robot, 20, np.random.default_rng(1))
    np.testing.assert_array_equal(
        a.inverse_kinematics(poses).structure, b.inverse_kinematics(poses).structure
    )
    np.testing.assert_array_equal(a.gravity_wrench(poses[0]), b.gravity_wrench(poses[0]))
    assert b.gravity_wrench(poses[0])[2] == pytest.approx(-9.81 * 91.058)  # CASPR's gravity
    (tmp_path / "empty.xml").write_text("<bodies_system><operational_spaces/></bodies_system>")
    with pytest.raises(ck.DataError, match="holds no <links>"):
        Robot.from_caspr(tmp_path / "empty.xml", tmp_path / "c.xml")


def test_caspr_files_outside_what_is_imported_are_data_errors(tmp_path):
    robot = shipped("ipanema_like")
    b, c = tmp_path / "b.xml", tmp_path / "c.xml"
    c.write_text(_caspr_cables(robot, "joint"))
    cases = [
        (_BODIES.format(joint="R_X", mass=1.0), "joint type"),
        (_BODIES.format(joint="SPATIAL", mass="heavy"), "must be a number"),
        (
            _BODIES.format(joint="SPATIAL", mass=1.0).replace("</links>", "<link_rigid num='2'/></links>"),
            "single-platform",
        ),
        ("<links><link_rigid", "cannot read"),
        ("<bodies/>", "<links> root"),
        (
            _BODIES.format(joint="SPATIAL", mass=1.0).replace("</links>", "<spring/></links>"),
            "single-platform",
        ),
    ]
    for text, needle in cases:
        b.write_text(text)
        with pytest.raises(ck.DataError, match=needle):
            Robot.from_caspr(b, c)
    b.write_text(_BODIES.format(joint="SPATIAL", mass=1.0))
    c.write_text(_caspr_cables(robot, "joint", model="cable_vsd"))
    with pytest.raises(ck.DataError, match="cable model"):
        Robot.from_caspr(b, c)
    c.write_text(_caspr_cables(robot, "joint").replace("<link>1</link>", "<link>0</link>", 1))
    with pytest.raises(ck.DataError, match="link 0 and one on link 1"):
        Robot.from_caspr(b, c)
    c.write_text(_caspr_cables(robot, "joint").replace("<force_max>", "<force_max>-", 1))
    with pytest.raises(ck.ParameterError):
        Robot.from_caspr(b, c)


def test_the_least_wrench_error_is_the_optimum_an_independent_bounded_least_squares_finds():
    """Issue #38: with no feasible tensions the QP's fallback answer is the optimum of
    ½‖Aᵀf + w‖² + ½ε‖f − f_mid‖² within the bounds — checked against SciPy's BVLS on the
    issue's reproducer and on random impossible wrenches."""
    from scipy.optimize import lsq_linear

    robot = shipped("seed003_planar")
    f_min, f_max = robot.bounds
    eps = 1e-6
    rng = np.random.default_rng(7)
    cases = [([0.451, 0.294, 0.234], [56.2024, -72.7657, 4.0646])]
    cases += [
        ([rng.uniform(0.3, 0.9), rng.uniform(0.3, 0.7), rng.uniform(-0.3, 0.3)], rng.normal(0, 150, 3))
        for _ in range(20)
    ]
    for q, wrench in cases:
        q, wrench = np.asarray(q), np.asarray(wrench)
        res = robot.distribute(q[None, :], wrench[None, :], method="qp")
        if res.feasible[0]:
            continue
        at = robot.inverse_kinematics(q[None, :]).structure[0]
        w = robot.gravity_wrench(q) + wrench
        mid = 0.5 * (f_min + f_max)
        a = np.vstack([at, np.sqrt(eps) * np.eye(len(mid))])
        b = np.concatenate([-w, np.sqrt(eps) * mid])
        ref = lsq_linear(a, b, bounds=(f_min, f_max), method="bvls", tol=1e-14).x

        def objective(f, at=at, w=w, mid=mid):
            return 0.5 * np.sum((at @ f + w) ** 2) + 0.5 * eps * np.sum((f - mid) ** 2)

        f = res.f[0]
        assert np.all(f >= f_min) and np.all(f <= f_max)
        assert objective(f) <= objective(ref) * (1 + 1e-9) + 1e-12, (q, wrench)
        assert res.residual[0] <= np.linalg.norm(at @ ref + w) + 1e-6
