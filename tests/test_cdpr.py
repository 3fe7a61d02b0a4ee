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
            assert np.linalg.norm(at @ f + w) <= 1e-9 * (1 + np.abs(f).max())
            if method != "minimum_norm":
                assert np.all(f >= f_min) and np.all(f <= f_max)
        if method == "closed_form":
            np.testing.assert_allclose(f, ref.closed_form(at, w, f_min, f_max), rtol=1e-10, atol=1e-9)
        if method == "minimum_norm":
            np.testing.assert_allclose(f, ref.minimum_norm(at, w), rtol=1e-10, atol=1e-9)
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
