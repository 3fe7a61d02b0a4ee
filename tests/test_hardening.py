"""Regression tests of issue #20's fuzz findings: calls that hung holding the GIL, a panic that
reached Python, unbounded substeps, non-finite results from finite input, and unchecked NaN.

Calls that once hung run in a subprocess with a timeout, so a regression fails the test instead
of freezing the suite; the rest run in process.
"""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import cablekit as ck
from cablekit.nn import MapMinMax
from cablekit.nn.export import write_weights

# ---- calls that hung (or looped for ever) -------------------------------------------------------

_RAVEN = "import numpy as np, cablekit as ck\nR3 = ck.CableTransmission.raven2(3)\n"


def _raven_with(**change) -> ck.CableTransmission:
    p = ck.CableTransmission.raven2(1).params()
    p.update(change)
    return ck.CableTransmission(**{k: v for k, v in p.items() if k != "n_links"})


HANGS = {
    # a NaN Jacobian sent the eigenvalue iteration into an endless loop holding the GIL
    "huge_state": ("ck.propose_step(R3, 1e-3, np.full(12, 1e154))", "NonFiniteResultError"),
    # a parameter that makes the Jacobian overflow at rest
    "tiny_gear_ratio": (
        "p = ck.CableTransmission.raven2(1).params(); p['gear_ratio'] = [1e-300]; "
        "ck.propose_step(ck.CableTransmission(**{k: v for k, v in p.items() if k != 'n_links'}), 1e-3)",
        "NonFiniteResultError",
    ),
    # advice of 2**64 - 1 substeps, then loops that never end
    "advice_for_huge_dt": ("ck.propose_step(R3, 1e300)", "ParameterError"),
    "rk4_substeps": ("R3.rk4_step(np.zeros(12), np.zeros(6), 1e-3, substeps=10**10)", "ParameterError"),
    "simulate_substeps": ("ck.simulate(R3, np.zeros((10, 6)), 1e-3, substeps=10**10)", "ParameterError"),
    "estimate_huge_dt": (
        "ck.estimate_joint_states(R3, np.zeros((10, 3)), np.zeros((10, 3)), 1e300)",
        "ParameterError",
    ),
}


@pytest.mark.parametrize("name", sorted(HANGS))
def test_calls_that_hung_now_end_with_a_typed_error(name):
    call, error = HANGS[name]
    prog = _RAVEN + textwrap.dedent(f"""
        try:
            {call}
        except ck.errors.{error} as e:
            print("typed:", type(e).__name__, e)
        else:
            print("no error")
    """)
    done = subprocess.run([sys.executable, "-c", prog], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith(f"typed: {error}"), done.stdout + done.stderr[-2000:]


def test_step_advice_is_capped_and_names_dt():
    r3 = ck.CableTransmission.raven2(3)
    with pytest.raises(ck.ParameterError, match="MAX_SUBSTEPS") as e:
        ck.propose_step(r3, 1e300)
    assert e.value.parameter == "dt"
    # the cap is the same number the integrator accepts
    adv = ck.propose_step(r3, 1e-3)
    assert 1 <= adv.substeps <= 100_000
    ck.simulate(r3, np.zeros((3, 6)), 1e-3, substeps=100_000)
    with pytest.raises(ck.ParameterError):
        ck.simulate(r3, np.zeros((3, 6)), 1e-3, substeps=100_001)


# ---- a panic that reached Python ---------------------------------------------------------------


def test_degenerate_run_time_base_is_not_a_panic():
    from cablekit._cablekit import JointProblem, JointRun

    aj = ck.AntagonisticJoint.forceps_example()
    runs = [JointRun(1e300, np.zeros(200), np.zeros((200, 1)))]
    try:
        JointProblem(aj, [(0, 1.0, True)], runs, ["coulomb_friction"])
    except ck.InternalError as e:  # pragma: no cover - the regression
        pytest.fail(f"panic reached Python: {e}")
    except ck.CablekitError:
        pass
    # a time base that overflows is refused, naming the run
    runs = [JointRun(1e307, np.zeros(200), np.zeros((200, 1)))]
    with pytest.raises(ck.ParameterError, match="dt"):
        JointProblem(aj, [(0, 1.0, True)], runs, ["coulomb_friction"])


# ---- non-finite results from finite input ------------------------------------------------------


def test_model_evaluations_refuse_to_return_overflow():
    r3 = ck.CableTransmission.raven2(3)
    x = np.zeros(12)
    x[10] = 50.0  # the exponential cable law overflows
    with pytest.raises(ck.NonFiniteResultError) as e:
        r3.derivative(x, np.zeros(6))
    assert e.value.argument == "derivative"
    with pytest.raises(ck.CablekitError):
        r3.output(x, np.zeros(6))
    with pytest.raises(ck.CablekitError):
        r3.jacobian(x, np.zeros(6))
    with pytest.raises(ck.SimulationDivergedError):
        r3.rk4_step(x, np.zeros(6), 1e-3)


def test_capstan_overflow_and_huge_dt_are_errors():
    with pytest.raises(ck.NonFiniteResultError):
        ck.capstan_ratio(np.array([-1.0]), mu=10.0, wrap=100.0, smoothing=0.1)
    # moving forwards the same wrap attenuates to zero: finite, no error
    assert ck.capstan_ratio(np.array([1.0]), mu=10.0, wrap=100.0, smoothing=0.1)[0] == 0.0
    r1 = ck.CableTransmission.raven2(1)
    with pytest.raises(ck.ParameterError, match="dt"):
        ck.simulate(r1, np.zeros((3, 2)), 1e308)


def _net(tmp_path, w_scale=1.0, in_range=(-1.0, 1.0), name="n.safetensors"):
    rng = np.random.default_rng(0)
    return write_weights(
        tmp_path / name,
        [w_scale * rng.normal(size=(5, 2)), rng.normal(size=(1, 5))],
        [np.zeros(5), np.zeros(1)],
        ["tansig", "purelin"],
        MapMinMax(np.full(2, in_range[0]), np.full(2, in_range[1])),
        MapMinMax(np.zeros(1), np.ones(1)),
    )


def test_network_overflow_is_an_error_at_load_or_predict(tmp_path):
    net = ck.Mlp.load(_net(tmp_path))
    far = np.array([1e308, -1e308])  # the first layer's net input is inf − inf
    with pytest.raises(ck.NonFiniteResultError):
        net.predict(far)
    with pytest.raises(ck.NonFiniteResultError, match=r"flat index 2"):
        net.predict(np.vstack([np.zeros((2, 2)), far]))
    out = np.zeros(1)
    with pytest.raises(ck.NonFiniteResultError):
        net.predict_into(far, out)
    # saturated, not overflowed: a far input on one side is a finite answer
    assert np.isfinite(net.predict(np.full(2, 1e308))).all()
    # finite weights that overflow once folded, or on the training range itself, never load
    with pytest.raises(ck.errors.WeightsValueError):
        ck.Mlp.load(_net(tmp_path, w_scale=1e308, name="big.safetensors"))
    with pytest.raises(ck.errors.WeightsValueError):
        ck.Mlp.load(_net(tmp_path, in_range=(0.0, 1e-308), name="narrow.safetensors"))


# ---- NaN input and parameters ------------------------------------------------------------------

NAN_CALLS = {
    "coulomb_friction": lambda v: ck.coulomb_friction(v, coulomb=1.0, smoothing=0.1),
    "stribeck_friction": lambda v: ck.stribeck_friction(
        v, coulomb=1.0, static_level=1.5, stribeck_velocity=0.1, smoothing=0.01
    ),
    "capstan_ratio": lambda v: ck.capstan_ratio(v, mu=0.1, wrap=1.0, smoothing=0.1),
    "dahl_rate(force)": lambda v: ck.dahl_rate(v, np.ones_like(v), sigma0=1.0, coulomb=1.0),
    "dahl_rate(v)": lambda v: ck.dahl_rate(np.ones_like(v), v, sigma0=1.0, coulomb=1.0),
    "cable_tension(stretch)": lambda v: ck.cable_tension(v, np.zeros_like(v), stiffness=1e3, pretension=10.0),
    "cable_tension(rate)": lambda v: ck.cable_tension(np.zeros_like(v), v, stiffness=1e3, pretension=10.0),
}


@settings(max_examples=40, deadline=None)
@given(
    name=st.sampled_from(sorted(NAN_CALLS)),
    n=st.integers(1, 20),
    at=st.integers(0, 19),
    bad=st.sampled_from([np.nan, np.inf, -np.inf]),
)
def test_curves_refuse_non_finite_input_and_name_the_element(name, n, at, bad):
    v = np.linspace(-1.0, 1.0, n)
    v[at % n] = bad
    with pytest.raises(ck.NotFiniteError) as e:
        NAN_CALLS[name](v)
    assert e.value.index == at % n


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_transmission_maps_refuse_non_finite_input(bad):
    r2 = ck.CableTransmission.raven2(2)
    for call in (
        lambda: r2.energy(np.full(8, bad)),
        lambda: r2.motor_to_joint(np.array([0.0, bad])),
        lambda: r2.joint_to_motor(np.array([bad, 0.0])),
    ):
        with pytest.raises(ck.NotFiniteError):
            call()
    q = np.zeros((40, 2))
    q[37, 1] = bad
    with pytest.raises(ck.NotFiniteError, match="row 37, column 1"):
        ck.kinematic_joint_angles(r2, q)


def test_kinematic_joint_angles_is_the_core_map_row_by_row():
    r3 = ck.CableTransmission.raven2(3)
    q_m = np.random.default_rng(1).normal(size=(25, 3))
    rows = np.array([r3.motor_to_joint(np.ascontiguousarray(r)) for r in q_m])
    np.testing.assert_array_equal(ck.kinematic_joint_angles(r3, q_m), rows)
    # and it inverts T (reference: NumPy's solve), 1e-12 of the angles
    np.testing.assert_allclose(rows, np.linalg.solve(r3.transmission_matrix, q_m.T).T, atol=1e-12)


# ---- filters: NaN parameters, error locations, divergence, gating, threads ---------------------


def _param_filter(bounds):
    r1 = ck.CableTransmission.raven2(1)
    return ck.SrUkf.with_parameters(
        r1, ["cable_stiffness[0]"], np.zeros(5), np.eye(5), 1e-6 * np.eye(5), np.eye(1),
        dt=1e-3, states=[0], bounds=bounds,
    )  # fmt: skip


def _dual(bounds=None):
    r1 = ck.CableTransmission.raven2(1)
    k = r1.params()["cable_stiffness"][0]
    return ck.DualSrUkf(
        r1, ["cable_stiffness[0]"], r1.rest_state() if hasattr(r1, "rest_state") else np.zeros(4),
        1e-6 * np.eye(4), 1e-9 * np.eye(4), np.array([[(0.1 * k) ** 2]]), np.array([[1.0]]),
        1e-8 * np.eye(2), dt=1e-3, states=[0, 2], bounds=bounds,
    )  # fmt: skip


@pytest.mark.parametrize("bounds", [[(np.nan, 1.0)], [(0.0, np.nan)], [(np.nan, np.nan)]])
def test_nan_parameter_bounds_are_refused(bounds):
    with pytest.raises(ck.ParameterError, match=r"bounds\[0\]"):
        _param_filter(bounds)
    with pytest.raises(ck.ParameterError, match=r"bounds\[0\]"):
        _dual(bounds)
    _param_filter([(-np.inf, np.inf)])  # infinite ends mean "no bound"


def test_fit_tolerances_are_checked():
    from cablekit._cablekit import JointProblem, JointRun

    aj = ck.AntagonisticJoint.forceps_example()
    t = np.arange(400) * 1e-3
    runs = [JointRun(1e-3, 1e-3 * np.sin(6 * t), np.zeros((400, 1)))]
    prob = JointProblem(aj, [(0, 1.0, True)], runs, ["coulomb_friction"])
    for kw in (dict(ftol=np.nan), dict(xtol=-1.0), dict(max_iter=10**9), dict(threads=0)):
        with pytest.raises(ck.ParameterError):
            prob.fit(None, **kw)


def test_dual_run_names_the_row_of_a_nan_measurement():
    dual = _dual()
    u = np.zeros((60, 2))
    y = np.zeros((60, 2))
    y[37, 1] = np.nan
    with pytest.raises(ck.NotFiniteError, match=r"row 37, column 1") as e:
        dual.run(u, y)
    assert e.value.index == 37 * 2 + 1
    u[12, 0] = np.inf
    with pytest.raises(ck.NotFiniteError, match=r"row 12, column 0"):
        dual.run(u, np.zeros((60, 2)))


def _unstable(gain=1e120):
    """A scalar random walk whose transition overflows within a few steps."""
    return ck.SrUkf.linear(np.array([[gain]]), np.eye(1), np.ones(1), np.eye(1), np.eye(1), np.eye(1))


def test_a_diverged_step_is_typed_and_leaves_the_filter_where_it_was():
    f = _unstable()
    with pytest.raises(ck.FilterDivergedError) as e:
        for _ in range(10):
            before = (f.x.copy(), f.S.copy())
            f.step(np.zeros(0), np.zeros(1))
    step = e.value.step
    assert 1 <= step < 10 and f.health.steps == step
    np.testing.assert_array_equal(f.x, before[0])
    np.testing.assert_array_equal(f.S, before[1])
    # a run reports the row, and the filter is not stuck: a reset makes it usable again
    g = _unstable()
    with pytest.raises(ck.FilterDivergedError, match=f"step {step}"):
        g.run(np.zeros((10, 0)), np.zeros((10, 1)))
    assert np.isfinite(g.x).all()
    g.reset(np.zeros(1), np.eye(1))
    assert g.health.steps == 0


def _walk():
    """A 2-state constant-velocity filter measuring position (consistent on a slow sine: NIS
    below 0.2 after the start)."""
    dt = 0.01
    return ck.SrUkf.linear(
        np.array([[1.0, dt], [0.0, 1.0]]), np.array([[1.0, 0.0]]), np.zeros(2), np.eye(2),
        np.diag([1e-8, 1e-3]), 1e-4 * np.eye(1),
    )  # fmt: skip


def test_innovation_gate_rejects_a_spike_and_counts_it():
    ys = np.sin(np.linspace(0, 3, 300))[:, None]
    spiked = ys.copy()
    spiked[150] = 1e100
    clean, gated, open_ = _walk(), _walk(), _walk()
    gated.nis_gate = 30.0
    assert gated.nis_gate == 30.0 and open_.nis_gate is None
    r_clean = clean.run(np.zeros((300, 0)), ys)
    r_gated = gated.run(np.zeros((300, 0)), spiked)
    r_open = open_.run(np.zeros((300, 0)), spiked)
    assert r_gated.gated.sum() == 1 and r_gated.gated[150]
    assert gated.health.rejected_total == r_gated.gated.sum()
    # the gated filter tracks as if the spike were missing; the open one is thrown far off
    assert np.max(np.abs(r_gated.x[-50:, 0] - r_clean.x[-50:, 0])) < 0.05
    assert np.max(np.abs(r_open.x[151:, 0])) > 1e10
    with pytest.raises(ck.ParameterError):
        gated.nis_gate = -1.0
    gated.nis_gate = None
    assert gated.nis_gate is None


def test_filters_are_refused_concurrently_and_networks_shared(tmp_path):
    import threading

    f = _walk()
    u, y = np.zeros((20_000, 0)), np.sin(np.linspace(0, 30, 20_000))[:, None]
    outcomes: list[str] = []

    def use():
        for _ in range(5):
            try:
                f.run(u, y)
                outcomes.append("ok")
            except ck.ConcurrentUseError:
                outcomes.append("busy")
            except Exception as e:  # pragma: no cover - the regression
                outcomes.append(f"{type(e).__name__}: {e}")

    threads = [threading.Thread(target=use) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=120)
    assert not any(t.is_alive() for t in threads)
    assert set(outcomes) <= {"ok", "busy"} and "ok" in outcomes, outcomes

    net = ck.Mlp.load(_net(tmp_path))
    xs = np.random.default_rng(2).normal(size=(64, 2))
    want = np.array([net.predict(np.ascontiguousarray(x)) for x in xs])
    got: list[object] = []

    def predict():
        out = np.zeros(1)
        for _ in range(200):
            for k, x in enumerate(xs):
                try:
                    net.predict_into(np.ascontiguousarray(x), out)
                    if out[0] != want[k, 0]:
                        got.append(("mismatch", k))
                except Exception as e:  # pragma: no cover - the regression
                    got.append(e)

    threads = [threading.Thread(target=predict) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=120)
    assert got == []


# ---- loaders: every defect of a file is a DataError --------------------------------------------


def _csv_rows(n=30, dt=1e-3):
    t = np.arange(n) * dt
    return "t,a\n" + "".join(f"{ti:.6f},{np.sin(ti):.6f}\n" for ti in t)


def test_run_files_with_encoding_container_and_size_defects_are_data_errors(tmp_path):
    import gzip

    from cablekit.diagnose.data import load_run

    cases = {
        "latin1.csv": b"t,a\n0,\xe9\n",
        "huge_field.csv": ("t,a\n" + "0," + "9" * 140_000 + "\n").encode(),
        "corrupt.csv.gz": gzip.compress(_csv_rows().encode())[:40],
        "identical.csv": ("t,a\n" + "0.0,1.0\n" * 20).encode(),
        "ten_dupes_plus_one.csv": ("t,a\n" + "0.0,1.0\n" * 10 + "0.001,1.0\n").encode(),
        "unterminated_quote.csv": b't,a\n0,"1\n',
    }
    for name, blob in cases.items():
        (tmp_path / name).write_bytes(blob)
        with pytest.raises(ck.DataError):
            load_run(tmp_path / name)
    with pytest.raises(ck.DataError, match="folder"):
        load_run(tmp_path)
    # a byte-order mark is not part of the first column's name
    (tmp_path / "bom.csv").write_bytes(b"\xef\xbb\xbf" + _csv_rows().encode())
    run = load_run(tmp_path / "bom.csv")
    assert len(run) == 30 and "a" in run.columns


@settings(max_examples=150, deadline=None)
@given(
    blob=st.binary(max_size=400) | st.text(alphabet='t,a0123456789.e-+\n #"nan', max_size=300).map(str.encode)
)
def test_any_bytes_as_a_run_file_load_or_raise_data_error(tmp_path_factory, blob):
    from cablekit.diagnose.data import load_run

    p = tmp_path_factory.mktemp("fuzz") / "run.csv"
    p.write_bytes(blob)
    try:
        run = load_run(p)
    except ck.DataError:
        return
    assert len(run) >= 10 and np.isfinite(run.t).all()
    assert all(np.isfinite(v).all() for v in run.columns.values())


_JOINT = {
    "model": "antagonistic_joint",
    "parameters": {"radius": 0.0025, "stiffness": 31800.0, "inertia": 2e-6, "pretension": 10.0},
    "inputs": {"x_m": "x_m"},
    "outputs": {"tension_motor_drive": "T1"},
}


@pytest.mark.parametrize(
    ("change", "where"),
    [
        ({"colour": "red"}, "unknown keys"),
        ({"extra_table": {"a": 1}}, "unknown keys"),
        ({"diagnosis": {"warmpu": 0.1}}, "unknown keys"),
        ({"diagnosis": {"warmup": float("nan")}}, "warmup"),
        ({"diagnosis": {"warmup": "0.2"}}, "warmup"),
        ({"diagnosis": {"substeps": 1.5}}, "substeps"),
        ({"diagnosis": {"substeps": True}}, "substeps"),
        ({"diagnosis": {"substeps": 10**12}}, "substeps"),
        ({"diagnosis": {"effects": "coulomb_friction"}}, "effects"),
        ({"diagnosis": "fast"}, "diagnosis"),
        ({"inputs": {"x_m": "x_m", "external": ["f", "1"]}}, "external"),
        ({"inputs": {"x_m": 3}}, "x_m"),
        ({"parameters": {**_JOINT["parameters"], "radius": [[[1.0]]]}}, "radius"),
        ({"parameters": {**_JOINT["parameters"], "radius": {"a": 1}}}, "radius"),
        ({"parameters": {**_JOINT["parameters"], "radius": True}}, "radius"),
    ],
)
def test_model_file_defects_are_data_errors_naming_the_key(change, where):
    from cablekit.diagnose.spec import model_spec_from_dict

    with pytest.raises(ck.DataError, match=where):
        model_spec_from_dict({**_JOINT, **change})


def test_servo_gains_must_be_finite():
    from cablekit.diagnose.spec import model_spec_from_dict

    doc = {
        "model": "cable_transmission",
        "parameters": {"preset": "raven2"},
        "inputs": {"q_m_ref": ["r1"]},
        "outputs": {"q_m1": "q1"},
        "servo": {"kp": [float("nan")], "kd": [1.0], "torque_limit": [0.5]},
    }
    with pytest.raises(ck.DataError, match=r"kp\[0\]"):
        model_spec_from_dict(doc)
    with pytest.raises(ck.DataError, match="unknown keys"):
        model_spec_from_dict({**doc, "servo": {"preset": "raven2", "ki": [1.0]}})


_toml_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**70), 2**70)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
    max_leaves=12,
)


@settings(max_examples=300, deadline=None)
@given(
    table=st.sampled_from(["parameters", "inputs", "outputs", "diagnosis", "servo", "model", "new"]),
    key=st.sampled_from(["radius", "x_m", "external", "warmup", "substeps", "effects", "kp", "preset", "zz"]),
    value=_toml_values,
)
def test_any_value_anywhere_in_a_model_file_loads_or_raises_a_cablekit_error(table, key, value):
    from cablekit.diagnose.spec import model_spec_from_dict

    doc = {k: (dict(v) if isinstance(v, dict) else v) for k, v in _JOINT.items()}
    if table == "model":
        doc["model"] = value
    else:
        doc.setdefault(table, {})
        if isinstance(doc[table], dict):
            doc[table][key] = value
    try:
        spec = model_spec_from_dict(doc)
    except ck.CablekitError:
        return
    assert math.isfinite(spec.warmup) and 0 <= spec.substeps <= 100_000
    assert all(isinstance(c, str) for c in [*spec.inputs, *spec.external, *(c for _, c in spec.outputs)])


# ---- thread counts on a shared machine ----------------------------------------------------------


def test_thread_counts_follow_the_problem_the_option_and_the_environment(monkeypatch):
    import os

    from cablekit import _threads
    from cablekit._threads import PARALLEL_WORK, available_cores, choose_threads

    monkeypatch.delenv("CABLEKIT_THREADS", raising=False)
    assert choose_threads(PARALLEL_WORK / 10) == 1  # small problems: one thread
    assert 1 <= choose_threads(PARALLEL_WORK * 10) <= len(os.sched_getaffinity(0))
    # the free cores are the idle share of the CPUs over the window, within the affinity mask
    cpus = os.cpu_count()
    for idle_share, want in ((1.0, cpus), (0.5, cpus / 2), (0.0, 1)):
        samples = iter([(0.0, 0.0), (idle_share * 100.0, 100.0)])
        monkeypatch.setattr(_threads, "_cpu_times", lambda s=samples: next(s))
        got = available_cores(window_s=0.0)
        assert got == max(1, min(len(os.sched_getaffinity(0)), int(want + 0.5))), (idle_share, got)
    assert choose_threads(1e3, threads=3) == 3  # the option wins
    monkeypatch.setenv("CABLEKIT_THREADS", "2")
    assert choose_threads(1e3) == 2  # then the environment
    assert choose_threads(1e3, threads=1) == 1
    for bad in ("0", "two", "-1"):
        monkeypatch.setenv("CABLEKIT_THREADS", bad)
        with pytest.raises(ck.ParameterError, match="CABLEKIT_THREADS"):
            choose_threads(1e3)
    for bad in (0, -2, 1.5, True):
        with pytest.raises(ck.ParameterError):
            choose_threads(1e3, threads=bad)


def test_state_indices_come_from_the_core_layout():
    from cablekit.simulation import state_indices

    for links in (1, 2, 3):
        r = ck.CableTransmission.raven2(links)
        names = r.state_names
        for q in ("q_m", "dq_m", "q_l", "dq_l"):
            idx = state_indices(r, q)
            assert [names[i] for i in idx] == [f"{q}{j}" for j in range(1, links + 1)]
    with pytest.raises(ck.ParameterError, match="no state"):
        state_indices(ck.CableTransmission.raven2(1), "tension")


def test_an_innovation_whose_nis_overflows_is_rejected_not_reported_as_inf():
    """Found by the property suite (issue #20 follow-up): a 1e154 encoder spike made the NIS
    overflow to inf. It is now an outlier by any gate: rejected, counted, NIS at the float max."""
    r1 = ck.CableTransmission.raven2(1)
    q_m = np.full((30, 1), 0.1)
    q_m[5, 0] = 1e154
    est = ck.estimate_joint_states(r1, q_m, np.full((30, 1), 0.1), 1e-3)
    assert np.all(np.isfinite(est.nis)) and est.nis[5] == np.finfo(float).max
    assert np.all(np.isfinite(est.q_l)) and abs(est.q_l[-1, 0]) < 1.0, "the spike left the estimate alone"
