"""Issue #38 §1: the Python layers check their arguments as the bindings do — every wrong type,
NaN/inf, huge or out-of-range value given to a public function of ``cablekit.cdpr``,
``cablekit.forceps`` and the estimators is a cablekit error (never a builtin ``ValueError``,
``IndexError``, ``ZeroDivisionError``, ``AttributeError`` or ``MemoryError``), and unbounded
work is refused with the bound."""

from __future__ import annotations

import importlib
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import cablekit as ck
from cablekit._args import choice, count, real
from cablekit.cdpr import Robot, sensors, shipped
from cablekit.cdpr.formats import read_trajectory
from cablekit.cdpr.planar import PlanarRobot, circle
from cablekit.estimate.joint_states import estimate_joint_states
from cablekit.forceps.twin import twin_from_toml

workspace_module = importlib.import_module("cablekit.cdpr.workspace")

#: anything a user might pass where a number belongs
WILD = st.one_of(
    st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308, 1e-300, 0.0, -1.0, 2**63, -(2**63)]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(2**70), 2**70),
    st.text(max_size=4),
    st.none(),
    st.booleans(),
    st.lists(st.floats(-2, 2), max_size=3),
    st.just(object()),
)


def _finite(value) -> bool:
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, np.ndarray) and value.dtype.kind == "f":
        return bool(np.isfinite(value).all())
    if isinstance(value, list | tuple):
        return all(_finite(v) for v in value)
    return True


def typed_or_finite(f, *args, **kwargs):
    """``f(*args, **kwargs)`` either raises a cablekit error or returns something whose floats
    are finite (the properties of a result object checked one level deep)."""
    try:
        out = f(*args, **kwargs)
    except ck.CablekitError:
        return None
    values = [out] if not hasattr(out, "__dict__") else list(vars(out).values())
    for v in values:
        assert _finite(v), (f, args, kwargs, v)
    return out


@pytest.fixture(scope="module")
def planar():
    return PlanarRobot()


def test_the_checks_refuse_what_the_issue_listed(planar, tmp_path):
    """The reproducers of issue #38 §1, each a typed error now."""
    with pytest.raises(ck.ParameterError, match="period"):
        planar.circle(0.05, 0.0)
    with pytest.raises(ck.ParameterError, match="dt"):
        planar.step(dt=0.0)
    with pytest.raises(ck.DTypeError, match="poses"):
        planar.follow("abc")
    robot = shipped("seed003_planar")
    with pytest.raises(ck.DTypeError, match="lower"):
        workspace_module.workspace(robot, lower="abc")
    with pytest.raises(ck.DTypeError, match="requirement"):
        workspace_module.workspace(robot, requirement=5)
    with pytest.raises(ck.ParameterError, match="at most 1,000,000"):
        workspace_module.workspace(robot, counts=1000 * 1000)
    with pytest.raises(ck.ParameterError, match="readings_per_mass"):
        sensors.calibrate("a", 1.0, 0.0, readings_per_mass=2**31)
    with pytest.raises(ck.DTypeError, match="masses"):
        sensors.calibrate("a", 1.0, 0.0, masses=None)
    with pytest.raises(ck.ParameterError, match="position"):
        sensors.current_sweep(0.0)
    path = tmp_path / "traj.csv"
    path.write_text("t,x,y,theta\n0,0.6,0.5,0\n0.001,0.6,0.5,0\n")
    with pytest.raises(ck.ParameterError, match="motion"):
        read_trajectory(path, "x")
    assert read_trajectory(path, "planar").poses.shape == (2, 3)
    for load in (Robot.from_toml, twin_from_toml):
        with pytest.raises(ck.DTypeError, match="must be a string"):
            load(5)
    with pytest.raises(ck.DTypeError, match="ea"):
        Robot.from_caspr("a_bodies.xml", "a_cables.xml", ea="a")
    with pytest.raises(ck.DTypeError, match="CableTransmission"):
        estimate_joint_states(
            ck.AntagonisticJoint.forceps_example(), np.zeros((10, 2)), np.zeros((10, 2)), 1e-3
        )


def test_a_step_that_does_not_settle_says_so_instead_of_nan(planar):
    # the θ step of the default robot does not reach 90 % within 0.3 s: explicit None, not NaN
    s = planar.step(2, 0.02, t_end=0.3)
    assert s.rise_time is None or 0.0 < s.rise_time < 0.3
    assert s.settling_time is None or 0.0 <= s.settling_time < 0.3
    assert all(math.isfinite(v) for v in (s.overshoot, s.final_error))
    late = planar.step(0, 0.02, t_end=3.0)
    assert late.rise_time is not None and 0.0 < late.rise_time < 1.0


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.sampled_from(["axis", "size", "t_end", "dt"]), WILD)
def test_any_step_argument_is_a_step_or_a_typed_error(planar, which, value):
    kw = {"axis": 0, "size": 0.01, "t_end": 0.25, "dt": 1e-3} | {which: value}
    if which in ("t_end", "dt") and isinstance(value, int | float) and not isinstance(value, bool):
        # only cheap runs: a valid but long run is not what this test is about
        t_end, dt = kw["t_end"], kw["dt"]
        if math.isfinite(t_end) and math.isfinite(dt) and dt > 0 and 0 < t_end / dt > 5000:
            return
    typed_or_finite(planar.step, kw.pop("axis"), kw.pop("size"), **kw)


@settings(max_examples=120, deadline=None)
@given(st.sampled_from(["radius", "period", "turns", "dt", "home"]), WILD)
def test_any_circle_argument_is_a_circle_or_a_typed_error(which, value):
    kw = {"home": [0.6, 0.5, 0.0], "radius": 0.1, "period": 0.05, "turns": 1.0, "dt": 1e-3} | {which: value}
    try:
        poses = circle(**kw)
    except ck.CablekitError:
        return
    except MemoryError:  # pragma: no cover - the bound must prevent this
        pytest.fail(f"unbounded circle for {which}={value!r}")
    assert poses.ndim == 2 and poses.shape[1] == 3 and np.isfinite(poses).all()


@settings(max_examples=120, deadline=None)
@given(st.sampled_from(["counts", "lower", "upper", "orientation", "requirement"]), WILD)
def test_any_workspace_argument_is_a_workspace_or_a_typed_error(which, value):
    robot = shipped("seed003_planar")
    kw = {"counts": 3} | {which: value}
    ws = typed_or_finite(workspace_module.workspace, robot, **kw)
    if ws is not None:
        assert ws.margin.size <= workspace_module.MAX_POSES


@settings(max_examples=120, deadline=None)
@given(
    st.sampled_from(["name", "gain", "offset", "capstan", "noise", "readings_per_mass", "masses", "seed"]),
    WILD,
)
def test_any_calibration_argument_is_a_calibration_or_a_typed_error(which, value):
    kw = {"name": "cell", "gain": 2.0, "offset": 0.1} | {which: value}
    run = typed_or_finite(
        lambda **k: sensors.calibrate(k.pop("name"), k.pop("gain"), k.pop("offset"), **k), **kw
    )
    if run is not None:
        assert np.isfinite(run.readings).all()


@settings(max_examples=60, deadline=None)
@given(st.sampled_from(["position", "total_length", "levels", "hold", "ramp"]), WILD)
def test_any_current_sweep_argument_is_a_sweep_or_a_typed_error(which, value):
    kw = {"position": 0.5, "levels": [0.0, 0.5], "hold": 0.02, "ramp": 0.005} | {which: value}
    if which == "hold" and isinstance(value, int | float) and not isinstance(value, bool) and value > 0.5:
        return  # valid and slow
    typed_or_finite(lambda **k: sensors.current_sweep(k.pop("position"), **k), **kw)


@settings(max_examples=80, deadline=None)
@given(WILD)
def test_any_toml_text_argument_is_a_robot_or_a_typed_error(value):
    for load in (Robot.from_toml, twin_from_toml):
        try:
            load(value)
        except ck.CablekitError:
            pass


def test_the_argument_helpers_name_the_argument_and_the_range():
    assert real(3, "x", lo=0.0) == 3.0
    for bad, err in (
        (True, ck.DTypeError),
        ("1", ck.DTypeError),
        (math.nan, ck.ParameterError),
        (10**400, ck.ParameterError),
    ):
        with pytest.raises(err, match="x"):
            real(bad, "x")
    with pytest.raises(ck.ParameterError, match=r"x must lie in \(0, 1\], got 0"):
        real(0.0, "x", lo=0.0, hi=1.0, lo_open=True)
    assert count(np.int64(4), "n", lo=1) == 4
    with pytest.raises(ck.DTypeError):
        count(4.0, "n")
    with pytest.raises(ck.ParameterError, match=r"n must lie in \[1, 10\]"):
        count(11, "n", lo=1, hi=10)
    assert choice("planar", "m", ["planar", "spatial"]) == "planar"
    with pytest.raises(ck.ParameterError, match="one of"):
        choice(1, "m", [True])


@pytest.mark.parametrize("count_", [1e308, -1e308, 9e307])
def test_a_bench_count_out_of_range_is_a_data_error_in_both_readers(tmp_path, count_):
    from cablekit.diagnose.davinci import load_bench_run
    from cablekit.forceps.davinci import read_bench_file

    rows = [f"{i * 1e-3},{i},{i},0.1,{i},{i},0,0,{i},0" for i in range(30)]
    rows[12] = f"0.012,{count_},12,0.1,{count_},12,0,0,12,0"
    path = tmp_path / "00.TXT"
    path.write_text("\n".join(rows))
    for read in (load_bench_run, read_bench_file):
        with pytest.raises(ck.DataError, match=r"00\.TXT"):
            read(path)


def test_drawing_a_report_leaves_the_users_matplotlib_backend_and_figures_alone(tmp_path):
    import matplotlib

    matplotlib.use("svg")  # the user's choice (a notebook would have its inline backend)
    import matplotlib.pyplot as plt

    from cablekit.examples import run_example
    from cablekit.plotting import plot_run

    before = matplotlib.get_backend()
    path = plot_run(run_example("forceps", duration=0.2), tmp_path / "run.png")
    assert path.stat().st_size > 1000
    assert matplotlib.get_backend() == before
    assert plt.get_fignums() == []


def test_progress_lines_go_through_logging_and_can_be_silenced(caplog, capsys):
    import logging

    from cablekit import _log

    with caplog.at_level(logging.INFO, logger="cablekit"):
        _log.info("a progress line")
    assert [r.getMessage() for r in caplog.records] == ["a progress line"]
    caplog.clear()
    logging.getLogger("cablekit").setLevel(logging.WARNING)
    try:
        _log.info("silenced")
        assert "silenced" not in capsys.readouterr().out
        assert not caplog.records
    finally:
        logging.getLogger("cablekit").setLevel(logging.NOTSET)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.lists(st.floats(allow_nan=False, allow_infinity=False, width=64), min_size=3, max_size=3),
        min_size=1,
        max_size=30,
    ),
    st.sampled_from([",", "\t", ";", " "]),
    st.sampled_from(["{!r}", "{:.3e}", " {!r} "]),
)
def test_the_compiled_csv_parsers_read_what_the_careful_reader_reads(tmp_path_factory, rows, sep, fmt):
    """The fast paths (pyarrow, NumPy) give exactly the numbers the cell-by-cell reader gives."""
    from cablekit.diagnose import data as data_module

    path = tmp_path_factory.mktemp("csv") / "run.csv"
    lines = [sep.join(["t", "a", "b"])] + [sep.join(fmt.format(v) for v in r) for r in rows]
    path.write_text("\n".join(lines) + "\n")
    header, got = data_module.read_table(path)
    assert header == ["t", "a", "b"]
    want = np.array([[float(fmt.format(v)) for v in r] for r in rows])
    np.testing.assert_array_equal(got, want)


def test_the_html_report_escapes_what_the_user_named(tmp_path):
    # run names, notes and file paths come from the user: the report shows them as text
    import dataclasses

    from cablekit.diagnose import Options, diagnose
    from cablekit.diagnose.report import write_html
    from cablekit.diagnose.selftest import make_case

    case = make_case(("sensor_gain_bias",), 3, 2.0)
    hostile = "<script>alert('x')</script>"
    fit = [dataclasses.replace(case.fit[0], name=hostile, notes=[f"note {hostile}"])]
    res = diagnose(case.spec, fit, case.hold, Options(progress=False, interval_refits=0))
    text = write_html(res, tmp_path / "report.html").read_text(encoding="utf-8")
    assert "<script>" not in text
    assert "&lt;script&gt;" in text  # it is there, as text
