"""Sim-to-real gap diagnosis: data and model-file handling, the grey-box problem against NumPy
references, recovery of every candidate effect, controls, JSON schema and the CLI."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import cablekit as ck
from cablekit._cablekit import JointProblem, JointRun, effect_catalogue
from cablekit.diagnose import Options, diagnose, load_model_spec, load_run, model_spec_from_dict
from cablekit.diagnose.data import Run, check_units, from_arrays, scored_start
from cablekit.diagnose.report import to_json, validate
from cablekit.diagnose.selftest import make_case
from tests.reference import signal as sig

# ---- a small nominal joint and run used throughout ----------------------------------------------

NOMINAL = {
    "radius": 3e-3,
    "stiffness": 2e4,
    "inertia": 4e-6,
    "damping": 10.0,
    "pretension": 12.0,
    "viscous": 5e-5,
    "smoothing": 0.2,
    "contact_angle": 0.2,
    "contact_stiffness": 800.0,
    "contact_damping": 0.1,
    "contact_lever_arm": 0.01,
}
DT = 1e-3
CHANNELS = [(0, 1.0, True), (1, 1.0, True), (4, 300.0, False)]


def _x_m(seconds: float = 3.0) -> np.ndarray:
    t = np.arange(int(seconds / DT)) * DT
    w = 2 * np.pi * np.array([0.6, 3.1, 17.0])
    return NOMINAL["radius"] * (0.4 * np.sin(w[0] * t) + 0.05 * np.sin(w[1] * t) + 0.01 * np.sin(w[2] * t))


def _run(x_m: np.ndarray, measured: np.ndarray | None = None, coupled: np.ndarray | None = None) -> JointRun:
    measured = measured if measured is not None else np.zeros((len(x_m), 3))
    return JointRun(DT, x_m, measured, coupled=coupled, start=50)


def _problem(
    effects: list[str], measured=None, substeps: int = 4, coupled=None, kink_refine: int = 1
) -> JointProblem:
    """The problem on one run; no kink refinement by default, so that the replay is exactly
    ``ck.simulate`` of the model it describes."""
    model = ck.AntagonisticJoint(**NOMINAL)
    x = _x_m()
    if coupled is None and "coupling" in effects:
        coupled = 0.3 * np.sin(2 * np.pi * 0.2 * np.arange(len(x)) * DT)
    return JointProblem(
        model, CHANNELS, [_run(x, measured, coupled)], effects, substeps, kink_refine=kink_refine
    )


# ---- run files --------------------------------------------------------------------------------


def _csv(tmp_path, header, rows, name="run.csv"):
    p = tmp_path / name
    p.write_text(",".join(header) + "\n" + "\n".join(",".join(str(v) for v in r) for r in rows) + "\n")
    return p


def _rows(n=50, dt=1e-3):
    return [[k * dt, 1e-4 * k, 10.0 + 0.01 * k] for k in range(n)]


def test_csv_round_trip_and_duplicates_are_counted(tmp_path):
    rows = _rows()
    rows.insert(10, list(rows[9]))  # an exactly duplicated row, as loggers write
    run = load_run(_csv(tmp_path, ["t", "x_m", "T"], rows))
    assert len(run) == 50
    assert run.notes == ["removed 1 exactly duplicated rows"]
    np.testing.assert_allclose(run.column("T"), [r[2] for r in _rows()])
    assert run.dt == pytest.approx(1e-3)


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda r: r[5].__setitem__(2, ""), "missing or non-finite value in column 'T' at data row 6"),
        (lambda r: r[7].__setitem__(0, r[6][0] - 1e-4), "time goes backwards at data row 8"),
        (lambda r: r[7].__setitem__(0, r[6][0]), "repeats at data rows 7 and 8 with different values"),
        (lambda r: r[3].__setitem__(1, "abc"), "'abc' is not a number"),
    ],
)
def test_malformed_runs_raise_data_errors(tmp_path, mutate, message):
    rows = _rows()
    mutate(rows)
    with pytest.raises(ck.DataError, match=message):
        load_run(_csv(tmp_path, ["t", "x_m", "T"], rows))


def test_jittered_sample_times_are_resampled_and_short_gaps_filled_with_a_note(tmp_path):
    """A logger without a real-time clock: sample times jittered by up to 30 % of the 1 ms
    interval and 3 samples dropped in a row. The run comes back on a uniform 1 ms grid; a signal
    linear in time is reproduced exactly and a 3 Hz sine within linear interpolation's bound."""
    rng = np.random.default_rng(1)
    t = np.arange(400) * 1e-3 + rng.uniform(-3e-4, 3e-4, 400)
    t[0] = 0.0
    t = np.delete(t, [100, 101, 102])
    rows = [[tk, 2.0 + 5.0 * tk, np.sin(2 * np.pi * 3 * tk)] for tk in t]
    run = load_run(_csv(tmp_path, ["t", "x_m", "T"], rows))
    step = np.diff(run.t)
    assert np.ptp(step) < 1e-12 and abs(step[0] - np.median(np.diff(t))) < 1e-15
    np.testing.assert_allclose(run.column("x_m"), 2.0 + 5.0 * run.t, rtol=0, atol=1e-12)
    # |f''|·h²/8 with h up to 4 ms across the gap
    bound = (2 * np.pi * 3) ** 2 * 4e-3**2 / 8
    assert np.max(np.abs(run.column("T") - np.sin(2 * np.pi * 3 * run.t))) < bound
    assert len(run.notes) == 1 and "resampled onto a uniform" in run.notes[0]
    assert "about 2 dropped samples filled" in run.notes[0] or "about 3 dropped" in run.notes[0]
    assert abs(len(run) - 400) <= 1


def test_rows_on_a_uniform_clock_with_jittered_stamps_keep_their_values(tmp_path):
    """A host stamping a DAQ's 1 kHz rows on arrival: the values are the clock's (smooth row by
    row), the stamps jitter by up to ±0.3 ms and 2 rows are lost. The loader keeps every row's
    values, puts them on the clock's grid (its period fitted to 0.02 %) and fills the 2 lost rows
    by interpolation; resampling at the stamped times instead would move a 50 mm/s ramp by up to
    15 µm."""
    rng = np.random.default_rng(2)
    clock = np.arange(500) * 1e-3
    x = 0.01 + 0.05 * clock + 1e-3 * np.sin(2 * np.pi * 2 * clock)
    v = 0.05 + 2e-3 * np.pi * 2 * np.cos(2 * np.pi * 2 * clock)
    stamps = 3.0 + clock + rng.uniform(-3e-4, 3e-4, 500)
    keep = np.ones(500, bool)
    keep[[200, 201]] = False
    rows = [[s, a, b] for s, a, b in zip(stamps[keep], x[keep], v[keep], strict=True)]
    run = load_run(_csv(tmp_path, ["t", "x_m", "v"], rows))
    assert len(run) == 500 and abs(run.dt - 1e-3) < 2e-7  # 4 standard errors of the fitted period
    np.testing.assert_allclose(run.column("x_m")[keep], x[keep], rtol=0, atol=1e-15)
    np.testing.assert_allclose(run.column("x_m"), x, rtol=0, atol=2e-7)  # lost rows: |f"|·h²/8, h = 3 ms
    assert "time stamps jitter" in run.notes[0] and "about 2 dropped samples filled" in run.notes[0]


@settings(max_examples=200, deadline=None)
@given(
    n=st.integers(10, 300),
    jitter=st.floats(0.0, 0.45),
    stamped=st.booleans(),
    drops=st.lists(st.integers(1, 298), max_size=6),
    seed=st.integers(0, 2**32 - 1),
    scale=st.sampled_from([1e-6, 1e-3, 1.0, 1e3]),
    amplitude=st.sampled_from([1.0, 1e300, 1.7e308]),
)
def test_any_increasing_time_base_becomes_a_uniform_grid_or_a_data_error(
    n, jitter, stamped, drops, seed, scale, amplitude
):
    """Times from either logger with any jitter below half an interval, rows dropped anywhere, at
    any time scale, values up to 1.7e308: a uniform grid whose rows are finite, or a
    ``DataError`` (a long gap, too few samples) — never another exception or a warning."""
    from cablekit.diagnose.data import uniform_time

    rng = np.random.default_rng(seed)
    clock = np.arange(n) * scale
    t = clock + rng.uniform(-jitter, jitter, n) * scale * (0.5 if stamped else 1.0)
    values = amplitude * (np.sin(clock / scale / 17.0) if stamped else np.sin(t / scale / 17.0))
    keep = np.ones(n, bool)
    keep[[d for d in drops if d < n - 1]] = False
    t, values = np.sort(t[keep]), values[keep]
    if not (np.diff(t) > 0).all():
        return
    notes: list[str] = []
    try:
        grid, out = uniform_time("run", np.column_stack([t, values, -values]), 0, notes)
    except ck.DataError:
        return
    assert np.isfinite(out).all() and len(grid) >= 10 and np.all(out[:, 0] == grid)
    # within the 1 % tolerance as given, else exactly uniform (and said so)
    spread = 0.02 if not notes else 1e-9
    assert np.ptp(np.diff(grid)) <= spread * np.median(np.diff(grid)) and len(notes) <= 1


def test_a_variable_step_solvers_output_is_resampled_at_its_mean_step(tmp_path):
    """An independent simulator's output straight from SciPy's LSODA (no ``t_eval``): steps from
    0.25 ns in a stiff contact to 34 ms, 40 % of them over 6.5 times the median. No uniform
    clock fits them, so the run is resampled at its stamps onto as many samples at the mean step
    (not refused as a logger that lost samples), and each sample lies on the chord between the
    solver's neighbouring rows."""
    from scipy.integrate import solve_ivp

    def rhs(t, y):
        k = 40.0 + 4e4 * (y[0] > 0.05)  # a stiff contact
        return [y[1], -k * y[0] - 0.5 * y[1] + np.sin(3 * t)]

    sol = solve_ivp(rhs, (0.0, 10.0), [0.1, 0.0], method="LSODA", rtol=1e-6, atol=1e-9)
    steps = np.diff(sol.t)
    assert np.mean(steps > 6.5 * np.median(steps)) > 0.2  # a clocked log would be refused
    rows = [[tk, x, v] for tk, x, v in zip(sol.t, *sol.y, strict=True)]
    run = load_run(_csv(tmp_path, ["t", "x_m", "v"], rows))
    assert len(run) == len(sol.t) and np.ptp(np.diff(run.t)) < 1e-12
    assert "no uniform clock" in run.notes[0] and "variable-step" in run.notes[0]
    np.testing.assert_allclose(run.column("x_m"), np.interp(run.t, sol.t, sol.y[0]), rtol=0, atol=1e-12)


def test_a_long_gap_is_a_data_error_naming_its_rows(tmp_path):
    rows = _rows(100)
    del rows[40:48]  # 8 samples dropped in a row
    with pytest.raises(ck.DataError, match=r"8 samples missing .* rows 40 and 41.* split the run"):
        load_run(_csv(tmp_path, ["t", "x_m", "T"], rows))


@pytest.fixture(scope="module")
def example_diagnosed(tmp_path_factory):
    """The embedded example's runs and model, and its diagnosis as the CLI writes it (computed
    once: three tests compare a transformed copy of the runs against it)."""
    from cablekit.cli import main
    from cablekit.cli.diagnose import _write_example

    root = tmp_path_factory.mktemp("example")
    fit, hold, model = _write_example(root / "example")
    out = root / "out"
    options = ["--model", str(model), "--out", str(out), "--quiet", "--no-html"]
    assert main(["diagnose", str(fit), "--holdout", str(hold), *options]) == 0
    return fit, hold, model, json.loads((out / "diagnosis.json").read_text())


def test_a_jittered_run_gets_the_same_diagnosis_as_the_uniform_one(tmp_path, capsys, example_diagnosed):
    """The embedded example with its time stamps jittered by up to ±20 % of the interval: the
    loader puts both runs back on a uniform grid, the CLI prints the note, and the same effects
    are selected."""
    from cablekit.cli import main

    fit, hold, model, uniform = example_diagnosed
    rng = np.random.default_rng(5)
    jittered = []
    for p in (fit, hold):
        header, *body = p.read_text().splitlines()
        rows = [[float(v) for v in line.split(",")] for line in body]
        for r in rows[1:-1]:
            r[0] += rng.uniform(-2e-4, 2e-4)
        jittered.append(tmp_path / f"jit_{p.name}")
        jittered[-1].write_text(header + "\n" + "\n".join(",".join(repr(v) for v in r) for r in rows) + "\n")
    out = tmp_path / "out"
    options = ["--model", str(model), "--out", str(out), "--quiet", "--no-html"]
    assert main(["diagnose", str(jittered[0]), "--holdout", str(jittered[1]), *options]) == 0
    doc = json.loads((out / "diagnosis.json").read_text())
    assert "note: run jit_fit: time stamps jitter" in capsys.readouterr().out
    assert doc["selected"]["effects"] == uniform["selected"]["effects"] and uniform["selected"]["effects"]


def test_columns_in_other_units_are_declared_and_diagnosed_as_in_si(tmp_path, capsys, example_diagnosed):
    """The embedded example recorded as a bench would log it: the angle in degrees, the motor
    displacement in mm, the tensions in kgf. Without ``[units]`` the unit check refuses the
    millimetres; with it the runs are converted on load (a note says so) and the same effects are
    selected with the same fitted values."""
    from cablekit.cli import main

    fit, hold, model, uniform = example_diagnosed
    scale = {"theta": 180 / math.pi, "x_m": 1e3, "T_drive": 1 / 9.80665, "T_return": 1 / 9.80665}
    for p in (fit, hold):
        header, *body = p.read_text().splitlines()
        names = header.split(",")
        factors = [scale.get(n, 1.0) for n in names]
        rows = [[float(v) * f for v, f in zip(line.split(","), factors, strict=True)] for line in body]
        (tmp_path / f"raw_{p.name}").write_text(
            header + "\n" + "\n".join(",".join(repr(v) for v in r) for r in rows) + "\n"
        )
    units = '\n[units]\ntheta = "deg"\nx_m = "mm"\nT_drive = "kgf"\nT_return = {scale = 9.80665}\n'
    declared = tmp_path / "raw_model.toml"
    declared.write_text(model.read_text() + units)
    raw = [str(tmp_path / ("raw_" + fit.name)), "--holdout", str(tmp_path / ("raw_" + hold.name))]
    assert main(["diagnose", *raw, "--model", str(model), "--out", str(tmp_path / "o"), "--quiet"]) == 4
    assert "looks like millimetres" in capsys.readouterr().err
    out = tmp_path / "out_raw"
    assert main(["diagnose", *raw, "--model", str(declared), "--out", str(out), "--quiet", "--no-html"]) == 0
    docs = [uniform, json.loads((out / "diagnosis.json").read_text())]
    assert docs[1]["selected"]["effects"] == docs[0]["selected"]["effects"]
    for a, b in zip(docs[0]["selected"]["parameters"], docs[1]["selected"]["parameters"], strict=True):
        assert b["value"] == pytest.approx(a["value"], rel=1e-3, abs=1e-9)
    assert "converted to SI units: theta from deg" in str(docs[1]["meta"]["fit_runs"][0]["notes"])
    assert "note: column theta converted to SI from deg (x0.0174533 + 0)" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("units", "match"),
    [
        ({"theta": "furlong"}, "is not a unit"),
        ({"T_drive": "deg"}, "is in rad, but T_drive needs N"),
        ({"x_c": "mm"}, "x_c needs a scale table"),
        ({"nope": "mm"}, "not a column the model reads"),
        ({"theta": "counts/0"}, "counts per turn must be > 0"),
        ({"theta": "counts/x"}, "counts per turn"),
        ({"theta": {"scale": 0.0}}, "scale must not be 0"),
        ({"theta": {"scale": 1.0, "gain": 2.0}}, "unknown keys"),
        ({"theta": {"scale": "1"}}, "scale"),
        ({"theta": 3}, "is not a unit"),
        (3, "units must be a table"),
    ],
)
def test_bad_unit_declarations_are_data_errors_naming_them(units, match):
    doc = {
        "model": "antagonistic_joint",
        "parameters": {"radius": 0.0025, "stiffness": 31800.0, "inertia": 2e-6, "pretension": 10.0},
        "inputs": {"x_m": "x_m", "coupled": "x_c"},
        "outputs": {"tension_motor_drive": "T_drive", "theta": "theta"},
        "units": units,
    }
    with pytest.raises(ck.DataError, match=match):
        model_spec_from_dict(doc)


def test_encoder_counts_and_scale_tables_convert_exactly():
    doc = {
        "model": "antagonistic_joint",
        "parameters": {"radius": 0.0025, "stiffness": 31800.0, "inertia": 2e-6, "pretension": 10.0},
        "inputs": {"x_m": "x_m"},
        "outputs": {"tension_motor_drive": "T", "theta": "enc"},
        "units": {"enc": "counts/4096", "T": {"scale": 0.5, "offset": -1.0}},
    }
    spec = model_spec_from_dict(doc)
    t = np.arange(20) * 1e-3
    run = Run("r", t, {"x_m": np.zeros(20), "T": np.arange(20.0), "enc": np.full(20, 1024.0)})
    si = spec.in_si(run)
    np.testing.assert_allclose(si.column("enc"), np.pi / 2)
    np.testing.assert_allclose(si.column("T"), 0.5 * np.arange(20.0) - 1.0)
    assert si.column("x_m") is run.column("x_m") and "enc from counts/4096" in si.notes[-1]
    assert model_spec_from_dict(spec.to_dict()).column_units == spec.column_units
    huge = model_spec_from_dict({**doc, "units": {"enc": "counts/1e-306"}})
    with pytest.raises(ck.DataError, match="'enc' overflows when converted from counts/1e-306"):
        huge.in_si(run)


@pytest.mark.parametrize(
    ("name", "sep", "decimal"),
    [
        ("semicolon.csv", ";", ","),
        ("tabs.tsv", "\t", "."),
        ("matlab.txt", "   ", "."),
        ("tabs_comma.txt", "\t", ","),
    ],
)
def test_other_separators_and_decimal_commas_read_as_the_comma_file(tmp_path, name, sep, decimal):
    """A spreadsheet's export (``;`` between columns, ``,`` as the decimal mark), a tab-separated
    file and MATLAB's ``save -ascii`` (spaces) read as the comma-separated run."""
    rows = _rows()
    text = sep.join(["t", "x_m", "T"]) + "\n"
    text += "".join(sep.join(repr(v).replace(".", decimal) for v in r) + "\n" for r in rows)
    (tmp_path / name).write_text(text)
    run, ref = load_run(tmp_path / name), load_run(_csv(tmp_path, ["t", "x_m", "T"], rows))
    assert sorted(run.columns) == sorted(ref.columns) and run.dt == ref.dt
    for c in ref.columns:
        np.testing.assert_array_equal(run.column(c), ref.column(c))


def test_runs_at_different_rates_are_diagnosed_at_the_coarsest(tmp_path, example_diagnosed):
    """The example's held-out run logged at 500 Hz, its fit run at 1 kHz: the fit run is
    resampled onto 2 ms (noted), never the held-out run onto 1 ms, and the same effects are
    selected with the same backlash (to 0.1 %)."""
    from cablekit.cli import main

    fit, hold, model, uniform = example_diagnosed
    rows = hold.read_text().splitlines()
    slow = tmp_path / "hold_500hz.csv"
    slow.write_text("\n".join([rows[0], *rows[1::2]]) + "\n")
    out = tmp_path / slow.stem
    options = ["--model", str(model), "--out", str(out), "--quiet", "--no-html"]
    assert main(["diagnose", str(fit), "--holdout", str(slow), *options]) == 0
    docs = [uniform, json.loads((out / "diagnosis.json").read_text())]
    assert docs[1]["selected"]["effects"] == docs[0]["selected"]["effects"]
    backlash = [d["selected"]["parameters"][0]["value"] for d in docs]
    assert backlash[1] == pytest.approx(backlash[0], rel=1e-3)
    meta = docs[1]["meta"]
    assert meta["fit_runs"][0]["dt"] == pytest.approx(2e-3) and meta["held_out_runs"][0]["notes"] == []
    assert "resampled from 0.001 s to 0.002 s" in meta["fit_runs"][0]["notes"][0]


def test_missing_time_column_and_milliseconds(tmp_path):
    with pytest.raises(ck.DataError, match="no time column 't'"):
        load_run(_csv(tmp_path, ["time", "x_m"], [[k, 0.0] for k in range(20)]))
    with pytest.raises(ck.DataError, match="milliseconds"):
        load_run(_csv(tmp_path, ["t", "x_m"], [[k, 0.0] for k in range(20)]))
    with pytest.raises(ck.DataError, match="no such file"):
        load_run(tmp_path / "nope.csv")


def test_unit_checks_catch_degrees_and_millimetres():
    t = np.arange(100) * 1e-3
    run = from_arrays("r", ["t", "theta", "x_m"], np.column_stack([t, 30 * np.sin(50 * t), 2.0 + 0 * t]))
    with pytest.raises(ck.DataError, match="looks like degrees"):
        check_units(run, {"theta": "rad"})
    with pytest.raises(ck.DataError, match="looks like millimetres"):
        check_units(run, {"x_m": "m"})
    with pytest.raises(ck.DataError, match="has no column 'T'"):
        run.column("T")


def test_parquet_runs_load_like_csv(tmp_path):
    import pyarrow as pa  # a test dependency (the `test` extra), so this always runs
    import pyarrow.parquet as pq

    rows = np.array(_rows())
    pq.write_table(pa.table({"t": rows[:, 0], "x_m": rows[:, 1], "T": rows[:, 2]}), tmp_path / "r.parquet")
    run = load_run(tmp_path / "r.parquet")
    np.testing.assert_array_equal(run.column("T"), rows[:, 2])


# ---- model files ------------------------------------------------------------------------------

GOOD = {
    "model": "antagonistic_joint",
    "parameters": {"radius": 3e-3, "stiffness": 2e4, "inertia": 4e-6, "pretension": 12.0},
    "inputs": {"x_m": "x_m"},
    "outputs": {"tension_motor_drive": "T1", "tension_motor_return": "T2"},
}


def test_model_file_parses(tmp_path):
    p = tmp_path / "m.toml"
    p.write_text(
        'model = "antagonistic_joint"\n[parameters]\nradius = 0.003\nstiffness = 2e4\ninertia = 4e-6\n'
        '[inputs]\nx_m = "x"\n[outputs]\ntension_motor_drive = "T1"\ntheta = "th"\n'
        "[diagnosis]\nwarmup = 0.1\n"
    )
    spec = load_model_spec(p)
    assert spec.x_m == "x" and spec.outputs == [("tension_motor_drive", "T1"), ("theta", "th")]
    assert spec.channels() == [(0, True), (4, False)]
    assert spec.warmup == 0.1


@pytest.mark.parametrize(
    ("change", "error", "message"),
    [
        ({"model": "robot"}, ck.DataError, "'model' must be one of"),
        ({"inputs": {}}, ck.DataError, "needs x_m"),
        ({"inputs": {"x_m": "x", "speed": "v"}}, ck.DataError, "unknown keys"),
        ({"outputs": {"force": "F"}}, ck.DataError, "is not an output"),
        ({"outputs": {}}, ck.DataError, "maps no measured column"),
        ({"diagnosis": {"effects": ["friction"]}}, ck.DataError, "unknown"),
        (
            {"parameters": {"radius": 3e-3, "stiffness": -2e4, "inertia": 4e-6}},
            ck.ParameterError,
            "stiffness",
        ),
    ],
)
def test_bad_model_files_raise_specific_errors(change, error, message):
    with pytest.raises(error, match=message):
        model_spec_from_dict(GOOD | change)


def test_bad_toml_is_a_data_error(tmp_path):
    p = tmp_path / "m.toml"
    p.write_text("model = \n")
    with pytest.raises(ck.DataError, match="not valid TOML"):
        load_model_spec(p)


# ---- the grey-box problem against NumPy references ---------------------------------------------


def test_effect_catalogue_has_the_canonical_names():
    names = [e["name"] for e in effect_catalogue()]
    assert names == [
        "coulomb_friction", "viscous_friction", "stribeck_friction", "dahl_hysteresis", "capstan_friction",
        "nonlinear_stiffness", "cable_damping", "creep", "backlash", "slack", "coupling", "sensor_lag",
        "sensor_sampling", "time_delay", "sensor_gain_bias", "inertia_error",
    ]  # fmt: skip
    stages = {e["name"]: e["stage"] for e in effect_catalogue()}
    assert stages["sensor_lag"] == "sensor" and stages["backlash"] == "input" and stages["creep"] == "plant"


def test_nominal_prediction_equals_simulate_with_central_difference_velocity():
    """The replay is ``ck.simulate`` on the central-difference velocity (first-order hold, from
    rest at ``x_m(0)/r``), except that sample intervals with a kink (here the joint's reversals
    against its dry friction) are integrated with 8x the substeps: it lies closer to a 64-substep
    reference than the plain 4-substep simulation does, and agrees with it to 1e-4 relative."""
    p = _problem([], kink_refine=8)
    x = _x_m()
    model = ck.AntagonisticJoint(**NOMINAL)
    u = np.ascontiguousarray(np.column_stack([x, sig.velocity(x, DT)]))
    x0 = np.array([x[0] / NOMINAL["radius"], 0.0])

    def sim(substeps: int) -> np.ndarray:
        res = ck.simulate(model, u, DT, x0, substeps=substeps, hold="foh")
        return np.column_stack([res["tension_motor_drive"], res["tension_motor_return"], res["theta"]])

    got, plain, fine = p.predict(p.reference(), 0), sim(4), sim(64)
    np.testing.assert_allclose(got, plain, rtol=1e-4, atol=1e-7)
    err = np.abs(got - fine).max(axis=0)
    assert np.all(err <= np.abs(plain - fine).max(axis=0)), err


@settings(max_examples=25, deadline=None)
@given(tau=st.floats(1e-4, 0.05), gain=st.floats(-0.3, 0.3), bias=st.floats(-2.0, 2.0))
def test_sensor_stage_matches_numpy(tau, gain, bias):
    """Lag then gain/bias on force channels only; encoder untouched (1e-12 relative)."""
    p = _problem(["sensor_lag", "sensor_gain_bias"])
    base = _problem([]).predict(np.zeros(0), 0)
    got = p.predict(np.array([tau, gain, bias, -gain, -bias]), 0)
    for c, (g, b) in enumerate(((gain, bias), (-gain, -bias))):
        want = (1 + g) * sig.lag(base[:, c], tau, DT) + b
        np.testing.assert_allclose(got[:, c], want, rtol=1e-12, atol=1e-10)
    np.testing.assert_array_equal(got[:, 2], base[:, 2])


@settings(max_examples=20, deadline=None)
@given(period=st.floats(0.013, 0.4), frac=st.floats(0.0, 0.99))
def test_sample_hold_matches_numpy(period, frac):
    p = _problem(["sensor_sampling"])
    base = _problem([]).predict(np.zeros(0), 0)
    phase = frac * period
    # at every force sensor each channel has its own converter: the return cell's clock runs
    # 3 % slower and a quarter period later
    clocks = [(period, phase), (1.03 * period, (phase + 0.25 * period) % (1.03 * period))]
    got = p.predict(np.array([v for pair in clocks for v in pair]), 0)
    for c in (0, 1):
        want = sig.sample_hold(base[:, c], *clocks[c], DT)
        mismatch = np.flatnonzero(got[:, c] != want)
        # an instant within 1e-9 dt of a sample boundary may round either way; nothing else differs
        assert mismatch.size <= 2, mismatch[:5]


@settings(max_examples=15, deadline=None)
@given(delta=st.floats(0.0, 3e-4), d=st.floats(0.0, 0.02), kappa=st.floats(-3e-3, 3e-3))
def test_input_stage_matches_numpy(delta, d, kappa):
    """coupling → play → delay on x_m, velocity by central differences, then the plant."""
    x = _x_m()
    xc = 0.3 * np.sin(2 * np.pi * 0.2 * np.arange(len(x)) * DT)
    p = _problem(["backlash", "coupling", "time_delay"], coupled=xc)
    got = p.predict(np.array([delta, kappa, d]), 0)
    xe = sig.delay(sig.play(x + kappa * xc, delta), d, DT)
    u = np.ascontiguousarray(np.column_stack([xe, sig.velocity(xe, DT)]))
    res = ck.simulate(
        ck.AntagonisticJoint(**NOMINAL),
        u,
        DT,
        np.array([xe[0] / NOMINAL["radius"], 0.0]),
        substeps=4,
        hold="foh",
    )
    np.testing.assert_allclose(got[:, 0], res["tension_motor_drive"], rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(got[:, 2], res["theta"], rtol=1e-10, atol=1e-12)


def _joint_reference(m: dict, substeps: int) -> dict:
    model = ck.AntagonisticJoint(**m)
    x = _x_m()
    u = np.ascontiguousarray(np.column_stack([x, sig.velocity(x, DT)]))
    x0 = np.zeros(model.n_states)
    x0[0] = x[0] / m["radius"]
    return ck.simulate(model, u, DT, x0, substeps=substeps, hold="foh")


def test_plant_effects_match_the_model_they_describe():
    """Creep, capstan, slack, inertia as parameters of AntagonisticJoint (same RK4, same bits up
    to the summation order)."""
    p = _problem(["creep", "capstan_friction", "slack", "inertia_error"])
    # canonical order: capstan (μφ), creep (κ, τ), slack (ΔT0), inertia (ε)
    theta = np.array([0.15, 0.2, 0.3, 3.0, 0.5])
    got = p.predict(theta, 0)
    m = dict(NOMINAL)
    m.update(
        creep_fraction=0.2, creep_time_constant=0.3, capstan_mu=0.15, capstan_wrap=1.0,
        pretension=NOMINAL["pretension"] - 3.0, inertia=NOMINAL["inertia"] * 1.5,
    )  # fmt: skip
    res = _joint_reference(m, 4)
    np.testing.assert_allclose(got[:, 1], res["tension_motor_return"], rtol=1e-12, atol=1e-10)


def test_joint_dahl_in_closed_form_converges_to_the_dahl_ode():
    """The joint's Dahl torque is advanced in closed form between substeps (no stiff mode): at 4
    substeps it agrees with a 64-substep RK4 of AntagonisticJoint's Dahl ODE to 1e-3 of the
    tension swing, and the error shrinks with the substeps."""
    m = dict(NOMINAL)
    m.update(dahl_coulomb=2e-3, dahl_sigma0=2e-3 / 0.02)
    fine = _joint_reference(m, 64)["tension_motor_drive"]
    swing = np.ptp(fine)
    theta = np.array([2e-3, 0.02])
    errs = []
    for sub in (2, 4, 16):
        got = _problem(["dahl_hysteresis"], substeps=sub).predict(theta, 0)[:, 0]
        errs.append(np.abs(got - fine).max() / swing)
    assert errs[1] < 1e-3, errs
    assert errs[2] < errs[0], errs


def test_problem_rejects_bad_input_with_typed_errors():
    model = ck.AntagonisticJoint(**NOMINAL)
    x = _x_m()
    with pytest.raises(ck.ShapeError):
        JointProblem(model, CHANNELS, [_run(x, np.zeros((len(x), 2)))], [])
    with pytest.raises(ck.ParameterError, match="output"):
        JointProblem(model, [(9, 1.0, True)], [_run(x, np.zeros((len(x), 1)))], [])
    with pytest.raises(ck.ParameterError, match="weight"):
        JointProblem(model, [(0, -1.0, True)], [_run(x, np.zeros((len(x), 1)))], [])
    bad = x.copy()
    bad[7] = np.nan
    with pytest.raises(ck.NotFiniteError):
        JointProblem(model, CHANNELS, [_run(bad)], [])
    with pytest.raises(ck.ParameterError, match="coupled"):
        JointProblem(model, CHANNELS, [_run(x)], ["coupling"])
    with pytest.raises(ck.ParameterError, match="effect"):
        JointProblem(model, CHANNELS, [_run(x)], ["friction"])
    with pytest.raises(TypeError):  # a run is a JointRun, not a dict
        JointProblem(model, CHANNELS, [{"dt": DT, "measured": np.zeros((3, 3))}], [])
    with pytest.raises(ck.DTypeError):
        JointRun(DT, x.astype(np.float32), np.zeros((len(x), 3)))
    p = _problem(["sensor_lag"])
    with pytest.raises(ck.ShapeError):
        p.predict(np.zeros(3), 0)
    with pytest.raises(ck.ParameterError, match="run index"):
        p.predict(np.zeros(1), 4)


# ---- every candidate effect, injected alone, is recovered ---------------------------------------

#: true parameters per effect (noise-free data from the augmented model itself) and the
#: relative tolerance of the recovery
RECOVERY = {
    "coulomb_friction": ([3e-3, 0.1], 1e-3),
    "viscous_friction": ([2e-4], 1e-3),
    "stribeck_friction": ([1e-3, 2e-3, 0.3, 2.0], 2e-2),
    "dahl_hysteresis": ([2e-3, 0.02], 1e-2),
    "capstan_friction": ([0.2], 1e-4),
    "nonlinear_stiffness": ([600.0], 1e-3),
    "cable_damping": ([40.0], 1e-3),
    "creep": ([0.2, 0.3], 1e-3),
    "backlash": ([1e-4], 1e-3),
    "slack": ([4.0], 1e-4),
    "coupling": ([1e-3], 1e-4),
    "sensor_lag": ([0.01], 1e-4),
    "sensor_sampling": ([0.1, 0.04, 0.083, 0.011], 2e-2),
    "time_delay": ([0.004], 1e-3),
    "sensor_gain_bias": ([0.05, 0.3, -0.04, -0.2], 1e-4),
    "inertia_error": ([2.0], 1e-2),
}


@pytest.mark.parametrize("effect", list(RECOVERY))
def test_each_effect_is_recovered(effect):
    truth, rtol = RECOVERY[effect]
    gen = _problem([effect], substeps=8)
    measured = gen.predict(np.array(truth), 0)
    p = _problem([effect], measured=np.ascontiguousarray(measured), substeps=8)
    res = p.fit()
    got = res.params
    if effect == "sensor_sampling":  # grid search, each channel's clock: within a sample
        for m in (0, 1):
            period, phase = truth[2 * m], truth[2 * m + 1]
            assert abs(got[2 * m] - period) < 0.02 * period
            d = (got[2 * m + 1] - phase) % got[2 * m]
            assert min(d, got[2 * m] - d) <= DT + 1e-9
        return
    np.testing.assert_allclose(got, truth, rtol=rtol, atol=1e-12)
    assert res.cost <= 1e-6 * res.initial_cost


# ---- diagnoses ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def control_result():
    case = make_case((), seed=11, duration=5.0)
    return diagnose(case.spec, case.fit, case.hold, Options(progress=False, bootstrap=400))


def test_contact_is_a_localisation_condition(control_result):
    """The self-test jaw closes on an object: in-contact and free samples split the record."""
    rows = {c.condition: c for c in control_result.where.conditions_held_out if c.family == "contact"}
    assert set(rows) == {"in contact", "free"}
    assert rows["in contact"].time_share + rows["free"].time_share == pytest.approx(1.0)
    assert 0.05 < rows["in contact"].time_share < 0.95


def test_a_gap_in_the_fit_runs_alone_is_flagged_not_named():
    """A sensor lag in the fit run and none in the held-out one (the same nominal; seed 5 draws the
    same model for both): the held-out runs decide the verdict (``no_significant_gap``), and a flag
    says that the fit runs have a significant gap the held-out runs do not, with the candidate that
    closes most of it there (the lag). A control gets no such flag."""
    lag, control = make_case(("sensor_lag",), seed=5, duration=5.0), make_case((), seed=5, duration=5.0)
    res = diagnose(lag.spec, lag.fit, control.hold, Options(progress=False, bootstrap=400))
    assert res.verdict == "no_significant_gap" and res.selected.effects == []
    (flag,) = [f for f in res.flags if "fit runs show a significant gap" in f]
    assert "sensor_lag@" in flag, flag
    both = diagnose(control.spec, control.fit, control.hold, Options(progress=False, bootstrap=400))
    assert both.verdict == "no_significant_gap"
    assert not any("fit runs show" in f for f in both.flags), both.flags


def test_control_run_has_no_significant_gap(control_result):
    assert control_result.verdict == "no_significant_gap"
    assert control_result.selected.effects == []
    assert control_result.gap.held_out < 1.15


@pytest.fixture(scope="module")
def lag_result():
    case = make_case(("sensor_lag",), seed=5, duration=5.0)
    return case, diagnose(case.spec, case.fit, case.hold, Options(progress=False, bootstrap=400))


def test_withheld_effect_is_named_and_closes_the_held_out_gap(lag_result):
    case, res = lag_result
    top = res.effects[0]
    assert top.name == "sensor_lag"
    assert top.site == "sensors.force"  # both tension channels share the lag
    assert res.verdict == "explained"
    assert res.selected.held_out.closed_fraction > 0.8
    lo, hi = res.selected.held_out.interval
    assert lo <= res.selected.held_out.closed_fraction <= hi
    # a two-pole sensor (τ, τ/3) has a low-frequency delay of 4τ/3: the one-pole fit's τ_s, or
    # twice the two-equal-pole fit's, lands between τ and 1.4τ
    tau = case.truth["effects"]["sensor_lag"]["tau_s"]
    fitted = next(p for p in top.parameters if p.name == "tau_s").value
    assert fitted is not None
    if top.form == "resonant":  # a second order of 1/ω_n and ζ lags by 2ζ/ω_n at low frequency
        zeta = next(p for p in top.parameters if p.name == "zeta").value
        equivalent = 2 * zeta * fitted
    else:
        equivalent = 2 * fitted if top.form == "second_order" else fitted
    assert tau < equivalent < 1.4 * tau


def test_json_schema(lag_result, control_result, tmp_path):
    for res in (lag_result[1], control_result):
        doc = json.loads(json.dumps(to_json(res)))
        validate(doc)
        assert {e["name"] for e in doc["effects"]} <= {e["name"] for e in effect_catalogue()}
        for e in doc["effects"]:
            assert e["held_out"]["closed_fraction"] is None or e["held_out"]["closed_fraction"] <= 1.0
    broken = to_json(control_result)
    broken["verdict"] = "maybe"
    with pytest.raises(ValueError, match="verdict"):
        validate(broken)
    broken = to_json(control_result)
    del broken["effects"][0]["held_out"]
    with pytest.raises(ValueError, match="held_out"):
        validate(broken)


def test_result_is_typed_and_round_trips_through_its_json(lag_result):
    """The result is a typed Diagnosis; its JSON reads back into an equal object, holds no
    internal objects, and a document with an unknown key is refused (nothing silently lost)."""
    from cablekit.diagnose import Diagnosis
    from cablekit.diagnose.result import ChannelChange, EffectResult

    res = lag_result[1]
    assert isinstance(res, Diagnosis) and all(isinstance(e, EffectResult) for e in res.effects)
    assert all(isinstance(c, ChannelChange) for c in res.selected.channels_held_out)
    doc = json.loads(json.dumps(res.to_json()))
    assert "internal" not in doc and not any(k.startswith("_") for k in doc)
    back = Diagnosis.from_json(doc)
    assert back == res and back.internal is None and res.internal is not None
    assert back.effect(res.effects[0].id) == res.effects[0]
    doc["selected"]["surprise"] = 1
    with pytest.raises(ValueError, match=r"Selection has unknown keys \['surprise'\]"):
        Diagnosis.from_json(doc)


def test_diagnose_needs_held_out_runs():
    case = make_case((), seed=3, duration=3.0)
    with pytest.raises(ck.DataError, match="held-out"):
        diagnose(case.spec, case.fit, [], Options(progress=False))


def test_residual_tests_separate_a_wrong_model_from_noise(control_result):
    """Backlash: tension residuals depend on the input and loop against velocity; the control's
    are white noise with ~no loop."""
    case = make_case(("backlash",), seed=21, duration=5.0)
    res = diagnose(case.spec, case.fit, case.hold, Options(progress=False, bootstrap=200, max_effects=1))
    assert res.effects[0].name == "backlash"
    ctrl = control_result.where.residual_tests
    for ch in ("tension_motor_drive", "tension_motor_return"):
        t = res.where.residual_tests[ch]
        assert t.reading == "depends on the input: the model is wrong"
        assert ctrl[ch].reading == "consistent with white measurement noise"
        assert t.loop_area_velocity > 5 * ctrl[ch].loop_area_velocity


@settings(max_examples=30, deadline=None)
@given(
    n=st.integers(10, 60),
    bad_row=st.integers(0, 59),
    bad_col=st.sampled_from(["x_m", "T"]),
    bad=st.sampled_from([math.nan, math.inf, -math.inf]),
)
def test_any_non_finite_cell_is_named(n, bad_row, bad_col, bad):
    """Property: whichever cell holds NaN/inf, the loader names its column and row."""
    bad_row = bad_row % n
    data = np.column_stack([np.arange(n) * 1e-3, np.linspace(0, 1e-3, n), np.full(n, 5.0)])
    data[bad_row, ["t", "x_m", "T"].index(bad_col)] = bad
    with pytest.raises(ck.DataError, match=f"column '{bad_col}' at data row {bad_row + 1}"):
        from_arrays("r", ["t", "x_m", "T"], data)


@settings(max_examples=25, deadline=None)
@given(t_len=st.integers(4, 200), q=st.integers(1, 3), extra=st.integers(-2, 2).filter(lambda v: v != 0))
def test_problem_shapes_are_checked(t_len, q, extra):
    """Property: measured arrays whose size is not (T, q) are ShapeErrors, never a panic."""
    model = ck.AntagonisticJoint(**NOMINAL)
    x = np.zeros(t_len)
    measured = np.zeros(t_len * q + extra) if t_len * q + extra > 0 else np.zeros(1)
    chans = CHANNELS[:q]
    with pytest.raises(ck.ShapeError):
        JointProblem(model, chans, [JointRun(DT, x, measured)], [])


# ---- the cable transmission as a diagnosis model ------------------------------------------------

TX_DOC = {
    "model": "cable_transmission",
    "parameters": {"preset": "raven2", "links": 2},
    "inputs": {"tau_m": ["tau1", "tau2"]},
    "outputs": {"q_m1": "qm1", "q_l1": "ql1", "q_m2": "qm2", "q_l2": "ql2"},
    "diagnosis": {"warmup": 0.05},
}


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"inputs": {"tau": ["a"]}}, "needs tau_m"),
        ({"inputs": {"tau_m": ["a", "b"], "external": ["e"]}}, "one column per link"),
        ({"outputs": {"q_m3": "x"}}, "is not an output"),
        ({"parameters": {"preset": "davinci", "links": 2}}, "preset"),
    ],
)
def test_bad_transmission_model_files(change, message):
    with pytest.raises(ck.DataError, match=message):
        model_spec_from_dict(TX_DOC | change)


def _tx_run(name: str, problem: JointProblem, theta: np.ndarray, tau: np.ndarray) -> Run:
    y = problem.predict(theta, 0)
    t = np.arange(len(tau)) * DT
    cols = {
        "tau1": tau[:, 0],
        "tau2": tau[:, 1],
        "qm1": y[:, 0],
        "ql1": y[:, 1],
        "qm2": y[:, 2],
        "ql2": y[:, 3],
    }
    return Run(name, t, {k: np.ascontiguousarray(v) for k, v in cols.items()})


def test_transmission_diagnosis_names_a_coupling_error():
    """Plumbing end to end (model file, torque inputs, initial state from the first angles, per
    link outputs): noise-free runs from the same simulator with the elbow cable's coupling
    coefficient off by 0.2. Open-loop torque replay of frictional links is ill-conditioned on
    noisy data (docs/diagnosis.md), so this checks the mechanics, not robustness."""
    spec = model_spec_from_dict(TX_DOC)
    model = spec.model()
    runs = []
    for name, f in (("fit", (0.5, 2.0)), ("held_out", (0.8, 3.3))):
        t = np.arange(3000) * DT
        tau = np.column_stack([0.06 * np.sin(2 * np.pi * f[0] * t), 0.04 * np.sin(2 * np.pi * f[1] * t)])
        gen = JointProblem(
            model,
            [(0, 1.0, False), (1, 1.0, False), (5, 1.0, False), (6, 1.0, False)],
            [JointRun(DT, np.ascontiguousarray(tau), np.zeros((3000, 4)))],
            ["coupling"],
            2,
        )
        runs.append(_tx_run(name, gen, np.array([0.2]), tau))
    res = diagnose(spec, [runs[0]], [runs[1]], Options(progress=False, bootstrap=200, max_effects=1))
    assert res.effects[0].name == "coupling"
    assert res.selected.held_out.closed_fraction > 0.9
    c = next(p for p in res.selected.parameters if p.name == "C[1][0]").value
    assert c == pytest.approx(0.2, rel=0.05)
    assert "dahl_hysteresis" in res.skipped and "backlash" in res.skipped


def test_servo_replay_diagnosis_names_link_friction():
    """Closed-loop replay under Raven-II's servo: references in, encoders and applied torques
    out; noise-free runs with extra link Coulomb friction are attributed to it."""
    doc = {
        "model": "cable_transmission",
        "parameters": {"preset": "raven2", "links": 2},
        "inputs": {"q_m_ref": ["r1", "r2"]},
        "servo": {"preset": "raven2"},
        "outputs": {
            "q_m1": "qm1",
            "q_l1": "ql1",
            "q_m2": "qm2",
            "q_l2": "ql2",
            "tau_m1": "u1",
            "tau_m2": "u2",
        },
        "diagnosis": {"warmup": 0.05},
    }
    spec = model_spec_from_dict(doc)
    assert spec.servo() == ([0.3, 0.3], [0.008, 0.008], [0.68, 0.68])
    model = spec.model()
    tmat = model.transmission_matrix
    runs = []
    for name, f in (("fit", (0.4, 0.7)), ("held_out", (0.9, 1.3))):
        t = np.arange(3000) * DT
        ql = np.column_stack([0.4 * np.sin(2 * np.pi * f[0] * t), 0.3 * np.sin(2 * np.pi * f[1] * t)])
        qm = ql @ tmat.T
        refs = np.ascontiguousarray(np.column_stack([qm, np.gradient(qm, DT, axis=0)]))
        gen = JointProblem(
            model,
            [
                (0, 1.0, False),
                (1, 1.0, False),
                (5, 1.0, False),
                (6, 1.0, False),
                (10, 1.0, False),
                (11, 1.0, False),
            ],
            [JointRun(DT, refs, np.zeros((3000, 6)))],
            ["coulomb_friction"],
            2,
            spec.servo(),
        )
        y = gen.predict(np.array([0.3, 0.2]), 0)
        cols = dict(zip(["qm1", "ql1", "qm2", "ql2", "u1", "u2"], y.T, strict=True))
        cols |= {"r1": qm[:, 0], "r2": qm[:, 1]}
        runs.append(Run(name, t, {k: np.ascontiguousarray(v) for k, v in cols.items()}))
    res = diagnose(spec, [runs[0]], [runs[1]], Options(progress=False, bootstrap=200, max_effects=1))
    assert res.effects[0].name == "coulomb_friction"
    assert res.selected.held_out.closed_fraction > 0.9
    with pytest.raises(ck.DataError, match=r"\[servo\]"):
        model_spec_from_dict({k: v for k, v in doc.items() if k != "servo"})


# ---- noise level of geared encoders and the servo-replay self-test cases ------------------------


@settings(max_examples=20, deadline=None)
@given(
    turns=st.floats(1.0, 200.0),
    f=st.floats(0.1, 2.0),
    sigma=st.floats(1e-5, 1e-3),
    seed=st.integers(0, 2**16),
)
def test_noise_level_of_a_geared_encoder(turns, f, sigma, seed):
    """A motor angle sweeping up to 200 rad at 1 kHz with white noise: the noise estimate is
    within 15 % of the truth (a smooth signal must not leak in, a wide range must not floor it)."""
    from cablekit.diagnose.localise import noise_sigma

    rng = np.random.default_rng(seed)
    t = np.arange(8000) * DT
    y = turns * np.sin(2 * np.pi * f * t) + rng.normal(0.0, sigma, t.size)
    assert noise_sigma(y) == pytest.approx(sigma, rel=0.15)


def test_noise_level_of_held_and_noise_free_signals_is_finite_and_small():
    from cablekit.diagnose.localise import noise_sigma

    t = np.arange(4000) * DT
    held = np.repeat(np.sin(2 * np.pi * 0.5 * t[::100]), 100)  # a 10 Hz sample-and-hold
    s = noise_sigma(held)
    assert 0 < s < 0.05 * np.std(held)
    assert 0 < noise_sigma(np.zeros(100)) <= 1e-12


@settings(max_examples=15, deadline=None)
@given(
    mains=st.sampled_from([50.0, 60.0]),
    ratio=st.floats(0.2, 1.0),
    f=st.floats(0.1, 2.0),
    seed=st.integers(0, 2**16),
)
def test_mains_hum_is_measurement_error(mains, ratio, f, seed):
    """A supply tone added to a moving load cell is found at its frequency with its rms within
    20 %, and counted with the white noise in the measurement error (a hum 0.3 of the noise must
    not read as a model gap on a control run)."""
    from cablekit.diagnose.localise import mains_interference, measurement_sigma

    rng = np.random.default_rng(seed)
    t = np.arange(20000) * DT
    sigma = 0.05
    y = 10 * np.sin(2 * np.pi * f * t) + rng.normal(0.0, sigma, t.size)
    hum = ratio * sigma * math.sqrt(2) * np.sin(2 * np.pi * mains * t + rng.uniform(0, 6.3))
    lines = mains_interference(y + hum, DT)
    assert [fr for fr, _ in lines] == [mains]
    assert lines[0][1] == pytest.approx(ratio * sigma, rel=0.2)
    s, _ = measurement_sigma(y + hum, DT)
    assert s == pytest.approx(sigma * math.sqrt(1 + ratio**2), rel=0.1)
    assert mains_interference(y, DT) == []


def test_motion_modulated_lines_are_not_mains_hum():
    """A 10 Hz sample-and-hold has harmonics at 50 and 60 Hz: on a sine they are modulated by
    the motion (no constant phasor), on a steady ramp they are constant but come with their own
    10 Hz fundamental. Neither is counted as interference (it is an effect to diagnose)."""
    from cablekit.diagnose.localise import mains_interference

    rng = np.random.default_rng(1)
    t = np.arange(20000) * DT
    held_t = np.floor(t / 0.1) * 0.1
    for y in (50 * np.sin(2 * np.pi * 0.5 * held_t), 5 * held_t):
        assert mains_interference(y + rng.normal(0.0, 0.05, t.size), DT) == []


@pytest.fixture(scope="module")
def raven_cases():
    from cablekit.diagnose.selftest_transmission import make_transmission_case

    which = (("control", (), 11), ("slack", ("slack",), 12), ("delay", ("time_delay",), 13))
    return {name: make_transmission_case(effects, seed, duration=6.0) for name, effects, seed in which}


def test_servo_replay_control_with_encoder_noise_has_no_gap(raven_cases):
    """A varied Raven-II 2-link under its servo, 0.1 mrad encoder noise, nothing withheld: the
    replay from the first noisy motor angles stays at the noise level on the held-out run."""
    case = raven_cases["control"]
    res = diagnose(case.spec, case.fit, case.hold, Options(progress=False, bootstrap=200))
    assert res.verdict == "no_significant_gap"
    assert res.gap.held_out < 1.15


def test_servo_replay_finds_a_pretension_loss_from_a_flat_start(raven_cases):
    """Slack is invisible at the default start (no cable slackens at a 5 % loss): the fit
    falls back to the start grid and recovers the lost share of the pretension."""
    case = raven_cases["slack"]
    res = diagnose(case.spec, case.fit, case.hold, Options(progress=False, bootstrap=200, max_effects=1))
    assert res.effects[0].name == "slack"
    frac = next(p for p in res.selected.parameters if p.name == "delta_T0_frac").value
    assert frac == pytest.approx(case.truth["effects"]["slack"]["fraction"], abs=0.03)
    assert res.selected.held_out.closed_fraction > 0.9


def test_servo_replay_measures_a_reference_delay(raven_cases):
    case = raven_cases["delay"]
    res = diagnose(case.spec, case.fit, case.hold, Options(progress=False, bootstrap=200, max_effects=1))
    assert res.effects[0].name == "time_delay"
    d = next(p for p in res.selected.parameters if p.name == "d").value
    assert d == pytest.approx(case.truth["effects"]["time_delay"]["d"], rel=0.02)


def test_a_saturating_servo_replay_is_flagged():
    """References whose accelerations need more than the current limit: the nominal replay sits
    at the limit, and the diagnosis says so (no warning for the feasible control)."""
    from cablekit.diagnose.prepare import prepare
    from cablekit.diagnose.selftest_transmission import make_transmission_case

    case = make_transmission_case((), 21, duration=3.0)
    assert prepare(case.spec, case.fit, case.hold).warnings == []
    fast = []
    for run in case.fit:
        cols = dict(run.columns)
        t = run.t
        for i in (1, 2):  # 40 rad of motor travel at 3 Hz: ~14000 rad/s² against ~0.68 N·m
            cols[f"ref{i}"] = 40.0 * np.sin(2 * np.pi * 3.0 * t)
            cols[f"dref{i}"] = 40.0 * 2 * np.pi * 3.0 * np.cos(2 * np.pi * 3.0 * t)
        fast.append(Run("fast", t, cols))
    warnings = prepare(case.spec, fast, case.hold).warnings
    assert len(warnings) == 2 and all("torque limit" in w and "'fast'" in w for w in warnings)


# ---- noise-robust sample-and-hold detection, quantised sensors, the independent generator ------


@settings(max_examples=12, deadline=None)
@given(
    # known gap (issue #19): ~100-sample holds are sometimes read at half the period
    period_samples=st.floats(10.0, 60.0),
    frac=st.floats(0.0, 0.99),
    noise=st.floats(0.01, 0.05),
    seed=st.integers(0, 2**16),
)
def test_hold_is_found_to_a_fraction_of_a_sample_with_noise_after_the_hold(period_samples, frac, noise, seed):
    """An HX711-like hold whose output is noisy (noise added after the hold, so no value repeats
    exactly): the detector finds the period to a tenth of a sample and the update instants to
    within a sample."""
    model = ck.AntagonisticJoint(**NOMINAL)
    x = _x_m(10.0)
    period, phase = period_samples * DT, frac * period_samples * DT
    gen = JointProblem(model, CHANNELS, [_run(x)], ["sensor_sampling"], 4)
    y = np.array(gen.predict(np.array([period, phase, period, phase]), 0))
    rng = np.random.default_rng(seed)
    y[:, :2] += rng.normal(0.0, noise, (len(x), 2))
    p = JointProblem(model, CHANNELS, [_run(x, np.ascontiguousarray(y))], ["sensor_sampling"], 4)
    got = p.hold_from_updates()
    assert got is not None
    assert abs(got[0] - period) < 0.1 * DT, (got, period)
    d = (got[1] - phase) % period
    assert min(d, period - d) <= 1.0 * DT, (got, phase)
    # the same noise on the continuous signal: no hold
    z = np.array(JointProblem(model, CHANNELS, [_run(x)], [], 4).predict(np.zeros(0), 0))
    z[:, :2] += rng.normal(0.0, noise, (len(x), 2))
    smooth = JointProblem(model, CHANNELS, [_run(x, np.ascontiguousarray(z))], [], 4)
    assert smooth.hold_from_updates() is None


@settings(max_examples=20, deadline=None)
@given(counts=st.sampled_from([1024, 4096, 8000, 2**14]), f=st.floats(0.05, 2.0), amp=st.floats(0.2, 1.5))
def test_noise_level_of_a_quantised_encoder_is_its_rounding_error(counts, f, amp):
    """A noise-free encoder is off by up to half a count however slowly it moves: its noise is
    the rounding error q/√12, which the differences of a slow signal (mostly zero) miss."""
    from cablekit.diagnose.localise import noise_sigma, quantum

    q = 2 * np.pi / counts
    t = np.arange(8000) * DT
    y = np.round(amp * np.sin(2 * np.pi * f * t) / q) * q
    assert quantum(y) == pytest.approx(q, rel=1e-6)
    # never below the rounding error (a coarse, fast encoder's differences over-read it: up to
    # 1.8x at 1024 counts, the differences estimator's own bias on non-Gaussian noise)
    assert q / math.sqrt(12) * (1 - 1e-9) <= noise_sigma(y) <= 2.0 * q / math.sqrt(12)
    slow = np.round(0.3 * np.sin(2 * np.pi * 0.05 * t) / q) * q
    assert noise_sigma(slow) == pytest.approx(q / math.sqrt(12), rel=0.05)
    assert quantum(amp * np.sin(2 * np.pi * f * t)) == 0.0


def test_independent_generator_agrees_with_cablekit_on_the_nominal_plant():
    """The independent generator (LSODA, its own equations) and cablekit's RK4 simulator agree
    on the nominal plant with no effect (a wrong sign, stretch or contact law in either breaks
    this): tensions within 1 % of the pretension, angle within 1 mrad."""
    from cablekit.diagnose import selftest_independent as si

    rng = np.random.default_rng(3)
    for scale in ("forceps", "pulley_board"):
        nom = si._nominal(rng, scale)
        tf = np.arange(3000 * si.FINE) * (si.DT / si.FINE)
        xm = nom["radius"] * si._trajectory("multisine", rng, tf)
        plant = si._Plant(nom, None, None, None, {})
        got = si._simulate(plant, tf, xm, np.zeros_like(tf))
        model = ck.AntagonisticJoint(**nom)
        u = np.column_stack([xm, np.gradient(xm, tf[1])])
        x0 = np.array([xm[0] / nom["radius"], 0.0])
        ref = ck.simulate(model, np.ascontiguousarray(u), tf[1], x0, substeps=4, hold="foh")
        keep = slice(0, None, si.FINE)
        tens = np.column_stack([ref["tension_motor_drive"][keep], ref["tension_motor_return"][keep]])
        np.testing.assert_allclose(got[:, :2], tens, atol=0.01 * nom["pretension"])
        np.testing.assert_allclose(got[:, 2], ref["theta"][keep], atol=1e-3)


# ---- localisation on quantised encoders, per-channel verdicts ----------------------------------


@settings(max_examples=25, deadline=None)
@given(
    counts=st.sampled_from([1024, 4000, 8192]),
    f=st.floats(0.1, 1.0),
    amp=st.floats(0.1, 0.6),
    phase=st.floats(0.0, 2 * np.pi),
    noise=st.sampled_from([0.0, 0.2]),
    seed=st.integers(0, 2**16),
)
def test_reversals_of_a_quantised_encoder_are_found(counts, f, amp, phase, noise, seed):
    """A slow sine read by an encoder (velocity passes through exact zero between counts; with
    noise of 0.2 counts before the rounding, counts flicker at the turning points): every turning
    point is found once, within 2 % of the period of the true one, and the speed terciles follow
    the true speed."""
    from cablekit.diagnose.localise import condition_masks, reversal_band, smooth_velocity, turning_points

    q = 2 * np.pi / counts
    t = np.arange(round(6.0 / f / DT)) * DT  # six periods
    rng = np.random.default_rng(seed)
    clean = amp * np.sin(2 * np.pi * f * t + phase)
    y = np.round((clean + noise * q * rng.normal(size=t.size)) / q) * q
    got = turning_points(y, reversal_band(y)) * DT
    k = np.arange(-2, 20)
    true = ((k + 0.5) * np.pi - phase) / (2 * np.pi * f)
    # every true turning point at least a tenth of a period from the record's ends is found ...
    inner = true[(true > 0.1 / f) & (true < t[-1] - 0.1 / f)]
    assert all(np.min(np.abs(got - tp)) < 0.02 / f for tp in inner), (got, inner)
    # ... every one found is a true one, and each is found once
    assert all(np.min(np.abs(true - g)) < 0.02 / f for g in got), (got, true)
    assert np.all(np.diff(got) > 0.25 / f), got
    v = smooth_velocity(y, DT)
    speed = np.abs(2 * np.pi * f * amp * np.cos(2 * np.pi * f * t + phase))
    assert np.corrcoef(np.abs(v), speed)[0, 1] > 0.95
    masks = {n: m for _, n, m in condition_masks(t, y, DT, np.abs(y))}
    assert 0.05 < masks["near reversal"].mean() < 0.4
    assert speed[masks["low speed"]].mean() < 0.5 * speed[masks["high speed"]].mean()


def test_a_channel_made_worse_is_flagged_even_when_the_pooled_gap_improves():
    """Force channel: gap 100 → 4; angle channel: 3 → 6. Pooled, the gap improves by 90 %; the
    angle channel is flagged as worse, the force channel is not."""
    from types import SimpleNamespace

    from cablekit.diagnose.select import channel_changes, compare

    rng = np.random.default_rng(0)
    n = 20_000
    before = [np.column_stack([10.0 * rng.normal(size=n), math.sqrt(3.0) * rng.normal(size=n)])]
    after = [np.column_stack([2.0 * rng.normal(size=n), math.sqrt(6.0) * rng.normal(size=n)])]
    opts = Options(bootstrap=300)
    prep = SimpleNamespace(channel_names=["net_motor_force", "theta"])
    ch = channel_changes(prep, before, after, DT, opts, rng)  # type: ignore[arg-type]
    assert [c["worsened"] for c in ch] == [False, True]
    assert ch[1]["change"] == pytest.approx(1.0, abs=0.1)
    assert compare(before, after, DT, opts, rng)["closed_fraction"] > 0.85
    # a channel that stays at the noise level is not flagged, however noisy its ratio
    after[0][:, 1] = rng.normal(size=n) * 1.02
    before[0][:, 1] = rng.normal(size=n)
    assert not any(c["worsened"] for c in channel_changes(prep, before, after, DT, opts, rng))  # type: ignore[arg-type]


def test_parsimony_prefers_the_simpler_unless_the_richer_is_better_on_held_out_data():
    """Coulomb (2 parameters) and Stribeck (4) leave equivalent held-out gaps: Coulomb is ranked
    first, unless the held-out test says Stribeck is significantly better, then Stribeck."""
    from types import SimpleNamespace

    from cablekit.diagnose.select import parsimony

    def fake(effect: str, n: int) -> SimpleNamespace:
        specs = [SimpleNamespace(effect=effect, name=f"p{i}", lower=0.0, upper=1.0) for i in range(n)]
        return SimpleNamespace(params=[0.5] * n, specs=specs)

    fits = {"stribeck": fake("stribeck_friction@joint", 4), "coulomb": fake("coulomb_friction@joint", 2)}
    scores = {"stribeck": {"gap_after": 1.9}, "coulomb": {"gap_after": 2.0}}
    ranked = ["stribeck", "coulomb"]
    assert parsimony(ranked, fits, scores) == ["coulomb", "stribeck"]  # type: ignore[arg-type]
    assert parsimony(ranked, fits, scores, lambda a, b: False) == ["coulomb", "stribeck"]  # type: ignore[arg-type]
    richer_wins = parsimony(ranked, fits, scores, lambda a, b: (a, b) == ("stribeck", "coulomb"))  # type: ignore[arg-type]
    assert richer_wins == ["stribeck", "coulomb"]
    # not equivalent at all (Coulomb's gap 3x): the ranking stands whatever the test says
    scores["coulomb"]["gap_after"] = 3.7
    assert parsimony(ranked, fits, scores, lambda a, b: False) == ["stribeck", "coulomb"]  # type: ignore[arg-type]


def test_a_fit_left_on_a_bound_away_from_off_is_named():
    """The bound check: a parameter on a bound other than its "off" value is named; one at its
    "off" bound (the nested model without the effect) is not; grid parameters never are."""
    from cablekit._cablekit import ParamSpec
    from cablekit.diagnose.fit import CandidateFit, _bound_away

    def spec(effect, name, grid):
        return ParamSpec(effect, name, "1", 0.0, 0.0, 0.0, 1.0, 1.0, grid, [])

    specs = [
        spec("creep@cable.both", "kappa", False),
        spec("creep@cable.both", "tau", False),
        spec("sensor_sampling@sensors.force", "period", True),
    ]
    import pickle

    back = pickle.loads(pickle.dumps(specs[2]))  # crosses to Ray workers and back
    assert (back.effect, back.name, back.grid, back.upper) == (specs[2].effect, "period", True, 1.0)
    params = np.array([0.0, 0.005, 0.1])
    assert _bound_away(params, np.array([True, True, True]), specs) == ["creep@cable.both:tau"]
    assert _bound_away(params, np.array([True, False, True]), specs) == []
    c = CandidateFit(["creep@cable.both"], params, specs, 1, True, [], [], 0.0, params, 3)
    assert c.bound == []


def test_bootstrap_refit_intervals_bracket_the_estimate():
    """Refits on block-bootstrap resamples of the fit run: the blocks tile the run, and the
    refit interval of the lag's time constant contains the fitted value, has a real width and
    stays inside the parameter's range; without refits there is no such interval."""
    from cablekit.diagnose.intervals import blocks

    case = make_case(("sensor_lag",), seed=5, duration=5.0)
    pieces = blocks(case.fit, warmup=0.3)
    assert len(pieces) == 4 and sum(len(p) for p in pieces) == len(case.fit[0])
    res = diagnose(case.spec, case.fit, case.hold, Options(progress=False, bootstrap=200, interval_refits=6))
    p = next(p for p in res.selected.parameters if p.name == "tau_s")
    assert p.ci95_refit is not None and p.value is not None
    lo, hi = p.ci95_refit
    assert lo is not None and hi is not None
    assert lo <= p.value <= hi and hi - lo > 1e-4 * p.value and lo >= 0.0
    plain = diagnose(case.spec, case.fit, case.hold, Options(progress=False, bootstrap=200, max_effects=1))
    assert all(q.ci95_refit is None for q in plain.selected.parameters)


def test_refit_interval_of_a_parameter_no_refit_moves_is_none(monkeypatch):
    """A parameter the replicates never move (a flat direction of the cost) gets no refit
    interval rather than a zero-width one that would read as certainty."""
    from cablekit.diagnose import intervals
    from cablekit.diagnose.fit import fit_candidate
    from cablekit.diagnose.prepare import prepare

    case = make_case(("sensor_lag",), seed=5, duration=5.0)
    prep = prepare(case.spec, case.fit, case.hold)
    cur = fit_candidate(prep, ["sensor_lag"], None, 10)
    monkeypatch.setattr(intervals, "fit_candidate", lambda *a, **k: cur)
    out = intervals.refit_intervals(
        prep, cur, Options(progress=False, interval_refits=4), np.random.default_rng(0)
    )
    assert out == [None] * len(cur.params)


def test_refit_intervals_are_the_same_on_one_thread_or_several():
    """The replicates are refitted in parallel threads; the resamples are drawn before, in order,
    so the intervals do not depend on the number of threads or the order the refits finish in."""
    from cablekit.diagnose import intervals
    from cablekit.diagnose.fit import fit_candidate
    from cablekit.diagnose.prepare import prepare

    case = make_case(("sensor_lag",), seed=5, duration=5.0)
    prep = prepare(case.spec, case.fit, case.hold)
    cur = fit_candidate(prep, ["sensor_lag"], None, 10)
    got = [
        intervals.refit_intervals(
            prep, cur, Options(progress=False, interval_refits=5, workers=w), np.random.default_rng(3)
        )
        for w in (1, 3)
    ]
    assert got[0] == got[1] and got[0][0] is not None


def test_an_unchanged_channel_is_not_significantly_worse():
    """Issue #37: a channel whose held-out gap is exactly unchanged was marked
    ``significantly_worse`` (a tie counted as "not better"); a channel that grew in every
    resample still is."""
    from types import SimpleNamespace

    from cablekit.diagnose.prepare import Options
    from cablekit.diagnose.select import channel_changes

    rng = np.random.default_rng(4)
    before = [rng.normal(size=(20000, 2)) * [3.0, 1.0]]
    after = [before[0] * [1.0, 1.0]]
    after[0][:, 0] *= 0.5  # channel a improved; channel b exactly unchanged
    prep = SimpleNamespace(channel_names=["a", "b"])
    opts = Options(progress=False)
    ch = {c["channel"]: c for c in channel_changes(prep, before, after, 1e-3, opts, rng)}  # type: ignore[arg-type]
    assert not ch["b"]["significantly_worse"] and not ch["b"]["worsened"] and ch["b"]["change"] == 0.0
    assert not ch["a"]["significantly_worse"] and ch["a"]["better"]
    grown = [before[0] * [1.0, 1.5]]
    ch = {c["channel"]: c for c in channel_changes(prep, before, grown, 1e-3, opts, rng)}  # type: ignore[arg-type]
    assert ch["b"]["significantly_worse"] and ch["b"]["worsened"]


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(12, 400),
    cut=st.floats(0.0, 1.0),
    context=st.one_of(
        st.floats(0.0, 1e3),
        st.sampled_from([math.nan, math.inf, -math.inf, -1e-3, 1e300]),
        st.text(max_size=3),
        st.none(),
    ),
)
def test_a_segment_carries_its_history_and_scores_after_it(n, cut, context):
    """``Run.segment(..., context=c)`` starts ``c`` s earlier (as much as the run has), says so
    in ``context``, and its scored part (:func:`scored_start`) is the plain segment's samples."""
    dt = 0.01
    t = dt * np.arange(n)
    run = Run("r", t, {"x": np.sin(t), "y": t**2})
    start = round(cut * (n - 10)) * dt
    plain = run.segment(start - 0.5 * dt, n * dt)
    ok = isinstance(context, float) and math.isfinite(context) and context >= 0.0
    if not ok:
        with pytest.raises((ck.DataError, TypeError)):
            run.segment(start - 0.5 * dt, n * dt, context=context)
        return
    seg = run.segment(start - 0.5 * dt, n * dt, context=context)
    k = scored_start(0.0, seg)
    assert seg.t[0] == 0.0 and len(seg) - k == len(plain)
    assert seg.context == pytest.approx(min(start, dt * math.floor(context / dt + 1e-9)), abs=1e-9)
    for c in ("x", "y"):
        assert np.array_equal(seg.columns[c][k:], plain.columns[c])
    # the warm-up counts after the history
    assert scored_start(0.05, seg) == k + 5


def test_a_held_out_continuation_is_replayed_from_its_history():
    """A held-out run that continues the fit run (``context``) is predicted as the whole run's
    tail (the same simulation from the same start), and scored only after its history."""
    from cablekit.diagnose.prepare import prepare

    case = make_case(("viscous_friction",), seed=3)
    whole = case.fit[0]
    mid = 0.5 * whole.duration
    tail = whole.segment(mid, whole.duration + 1.0, context=mid + 1.0)
    restart = whole.segment(mid, whole.duration + 1.0)
    assert tail.context == pytest.approx(whole.t[whole.t >= mid][0], abs=1e-12)
    full = prepare(case.spec, case.fit, [whole])
    cont = prepare(case.spec, case.fit, [tail])
    fresh = prepare(case.spec, case.fit, [restart])
    k = scored_start(case.spec.warmup, tail)
    assert k == len(whole) - len(restart) + round(case.spec.warmup / whole.dt)
    q = len(cont.channel_names)
    assert cont.hold0.residuals(np.zeros(0)).size == (len(tail) - k) * q
    # with a second held-out run the residuals split per run after each one's history
    from cablekit.diagnose.fit import _split

    both = prepare(case.spec, case.fit, [tail, restart])
    r = np.asarray(both.hold0.residuals(np.zeros(0)))
    w = round(case.spec.warmup / whole.dt)
    assert [x.shape for x in _split(both, both.hold_runs, r)] == [(len(tail) - k, q), (len(restart) - w, q)]
    assert r.size == (len(tail) - k + len(restart) - w) * q
    p_full = np.asarray(full.hold0.predict(np.zeros(0), 0))
    p_cont = np.asarray(cont.hold0.predict(np.zeros(0), 0))
    np.testing.assert_allclose(p_cont, p_full, rtol=0, atol=1e-9 * np.abs(p_full).max())
    # a restart from rest differs from the continuation where the state has memory
    p_fresh = np.asarray(fresh.hold0.predict(np.zeros(0), 0))
    assert not np.allclose(p_fresh, p_cont[-len(restart) :])
    bad = whole.segment(mid, whole.duration + 1.0, context=1.0)
    bad.context = whole.duration + 1.0
    with pytest.raises(ck.DataError, match="history"):
        prepare(case.spec, case.fit, [bad])
