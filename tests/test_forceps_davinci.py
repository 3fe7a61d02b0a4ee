"""Issue #22 §3: the bench loader's errors, the drive model against a NumPy reference and on bad
input, and on the real da Vinci bench (read from ../shared/data, present in CI) the held-out
folds and the new-instrument path against the published 4.42 mN·m."""

from __future__ import annotations

import gzip
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cablekit.errors import DataError, NotFiniteError, ParameterError, ShapeError
from cablekit.forceps import DriveModel, bench
from cablekit.forceps import davinci as dv
from tests.bench_data import davinci_dir
from tests.reference import drive as ref

TRAVELS = [0.002, 0.02, 0.2]
SPINDLE_TRAVELS = [0.01, 0.1]


def _synthetic(seed: int, loads=(0.01, 0.03, 0.05), n: int = 3000, dt: float = 1e-3, spindle=(0.0, 0.0)):
    """Runs of an instrument that follows the drive model plus noise: a sine of the spindle,
    the motor ahead of it, friction by direction and varying with the angle, a load level per
    run; ``spindle``: the friction of elements driven by the spindle (``SPINDLE_TRAVELS``)."""
    rng = np.random.default_rng(seed)
    runs = []
    for i, load in enumerate(loads):
        t = np.arange(n) * dt
        th = 0.5 * (1 - np.cos(2 * np.pi * (0.5 + 0.2 * i) * t))
        motor = th + 0.002 * np.sin(2 * np.pi * (0.5 + 0.2 * i) * t + 0.3)
        s = ref.states(motor, TRAVELS)
        tj = -load - 0.01 * th + 0.0005 * rng.standard_normal(n)
        friction = s @ [-0.02, -0.015, -0.01] + th * (s @ [0.008, -0.004, 0.003])
        friction = friction + ref.states(th, SPINDLE_TRAVELS) @ np.asarray(spindle)
        ts = 0.004 - 0.02 * th + friction + (-1.05 + s @ [0.1, 0.05, 0.02]) * tj
        ts = ts + 0.0005 * rng.standard_normal(n)
        ja = 0.4 + 0.95 * th + 0.3 * ts
        runs.append(np.column_stack([th, ts, motor, tj, ja]))
    return runs


@settings(max_examples=15, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    window=st.integers(1, 40),
    angle=st.sampled_from(["default", "fitted", "off", "span"]),
    spindle=st.booleans(),
)
def test_drive_model_equals_the_numpy_reference(seed, window, angle, spindle):
    # the instrument has spindle-driven friction; fitted with or without those elements
    runs = _synthetic(seed, spindle=(0.04, -0.02))
    kw = {} if angle == "default" else {"angle_friction": (0.2, 0.7) if angle == "span" else angle}
    sp_travels = SPINDLE_TRAVELS if spindle else []
    if spindle:
        kw["spindle_travels"] = sp_travels
    model = DriveModel.fit(runs, TRAVELS, dt=1e-3, window=window, warmup=0.2, **kw)
    assert model.spindle_travels == sp_travels
    span = {"off": None, "span": (0.2, 0.7)}.get(angle, "fitted")
    c, p = ref.fit(runs, TRAVELS, 1e-3, window, 0.2, span=span, spindle_travels=sp_travels)
    span = ref.fitted_span(runs, 1e-3, 0.2) if span == "fitted" else span
    assert model.angle_friction_span == (None if span is None else pytest.approx(span, abs=0))
    np.testing.assert_allclose(model.coefficients, c, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(model.angle_coefficients, p, rtol=1e-6, atol=1e-9)
    est = model.estimate(runs[1][:, :3].copy(), dt=1e-3)
    torque, angle_ref = ref.estimate(c, p, runs[1], TRAVELS, 1e-3, window, span, sp_travels)
    np.testing.assert_allclose(est.torque, torque, rtol=0, atol=1e-8)
    np.testing.assert_allclose(est.angle, angle_ref, rtol=0, atol=1e-8)
    # one sample at a time, as a controller calls it, gives the same numbers
    obs = model.observer(dt=1e-3)
    for k in range(0, 50):
        sample = obs.step(*runs[1][k, :3])
        assert sample.torque == est.torque[k] and sample.angle == est.angle[k]
    # the model recovers the jaw torque it was built on, to the noise's order; without the
    # angle-dependent friction or the spindle's elements the instrument's is left in the estimate
    rmse = np.sqrt(np.mean((est.torque[500:] - runs[1][500:, 3]) ** 2))
    if angle in ("default", "fitted") and spindle:
        assert rmse < 1e-3
    elif angle == "off" or not spindle:
        assert rmse > 1.5e-3


def test_angle_friction_options_are_checked():
    runs = _synthetic(4)
    for bad in [(0.5, 0.5), (0.7, 0.2), (np.nan, 1.0), (0.0, np.inf)]:
        with pytest.raises(ParameterError if np.isfinite(bad).all() else NotFiniteError):
            DriveModel.fit(runs, TRAVELS, warmup=0.2, angle_friction=bad)
    with pytest.raises(ParameterError, match="angle_friction"):
        DriveModel.fit(runs, TRAVELS, warmup=0.2, angle_friction="linear")
    with pytest.raises(ShapeError):
        DriveModel.fit(runs, TRAVELS, warmup=0.2, angle_friction=np.zeros(3))
    # an array span equals the tuple; the estimate counts the samples beyond it as outside
    a = DriveModel.fit(runs, TRAVELS, warmup=0.2, angle_friction=np.array([0.2, 0.7]))
    b = DriveModel.fit(runs, TRAVELS, warmup=0.2, angle_friction=(0.2, 0.7))
    assert a.coefficients == b.coefficients and a.angle_friction_span == (0.2, 0.7)
    th = runs[1][:, 0]
    est = a.estimate(runs[1][:, :3].copy())
    margin = 0.05 * 0.5  # the core's SPAN_MARGIN of the span's width
    beyond = np.mean((th < 0.2 - margin) | (th > 0.7 + margin))
    # (the warm-up's first samples may also leave the training ranges of the velocity)
    assert beyond - 1e-12 <= est.outside_share <= beyond + 200 / len(th) and beyond > 0.3
    assert DriveModel.fit(runs, TRAVELS, warmup=0.2, angle_friction="off").angle_friction_span is None


def test_drive_model_refuses_bad_input_and_recalibrates_an_offset():
    runs = _synthetic(1)
    with pytest.raises(ShapeError):
        DriveModel.fit([runs[0][:, :4].copy()], TRAVELS)
    bad = runs[0].copy()
    bad[7, 1] = np.nan
    with pytest.raises(NotFiniteError):
        DriveModel.fit([bad, runs[1]], TRAVELS)
    with pytest.raises(ParameterError, match="travels"):
        DriveModel.fit(runs, [])
    with pytest.raises(ParameterError, match="travels"):
        DriveModel.fit(runs, [-0.1])
    for bad in ([0.0], [-0.1], [np.nan], [np.inf], [0.1] * 9):
        with pytest.raises(ParameterError, match="spindle_travels"):
            DriveModel.fit(runs, TRAVELS, spindle_travels=bad)
    constant = runs[0].copy()
    constant[:, 3] = -0.02  # a jaw torque that never varies: no transmission ratio to find
    with pytest.raises(ParameterError, match="design"):
        DriveModel.fit([constant], TRAVELS, warmup=0.2)
    model = DriveModel.fit(runs, TRAVELS, warmup=0.2)
    shifted = runs[2].copy()
    shifted[:, 1] += 0.003  # another instrument's torque zero
    re = model.recalibrated(shifted, friction=False)
    assert re.coefficients[0] == pytest.approx(model.coefficients[0] + 0.003, abs=2e-4)
    with pytest.raises(ShapeError):
        model.recalibrated(shifted[:, :3].copy())


def _write(path: Path, text: str) -> Path:
    with gzip.open(path, "wt") as fh:
        fh.write(text)
    return path


GOOD_ROW = "0.001,10,100,0.05,2000,-300,0.1,0.2,-400,5\n"


def test_loader_reports_the_line_and_column_of_bad_rows(tmp_path):
    header = "% Tool 4\n% columns ...\n"
    rows = "".join(GOOD_ROW.replace("0.001", f"{0.001 * (i + 1):.3f}", 1) for i in range(20))
    run = dv.read_bench_file(_write(tmp_path / "31.TXT.gz", header + rows))
    assert run.frequency == 3 and run.load == 1 and run.signals.shape == (20, 5)
    assert run.dt == pytest.approx(1e-3)
    assert run.signals[0, 1] == pytest.approx(100 * bench.FUTEK_NM)
    assert run.signals[0, 0] == pytest.approx(10 * 2 * math.pi / bench.CUI_COUNTS)
    short = header + rows + "0.5,1,2,3\n"
    with pytest.raises(DataError, match=r"31b.TXT.gz:23: 4 columns"):
        dv.read_bench_file(_write(tmp_path / "31b.TXT.gz", short))
    cell = header + rows + "0.5,1,2,x3,4,5,6,7,8,9\n"
    with pytest.raises(DataError, match=r":23: column 4 is not a number: 'x3'"):
        dv.read_bench_file(_write(tmp_path / "c.TXT.gz", cell))
    nan = header + rows + "0.5,1,2,nan,4,5,6,7,8,9\n"
    with pytest.raises(DataError, match=r":23: column 4 is not finite"):
        dv.read_bench_file(_write(tmp_path / "n.TXT.gz", nan))
    with pytest.raises(DataError, match="at least 10"):
        dv.read_bench_file(_write(tmp_path / "few.TXT.gz", header + GOOD_ROW))
    (tmp_path / "junk.TXT.gz").write_bytes(b"\x1f\x8b\x08garbage")
    with pytest.raises(DataError, match="cannot read"):
        dv.read_bench_file(tmp_path / "junk.TXT.gz")
    with pytest.raises(DataError, match="no such"):
        dv.read_bench_file(tmp_path / "absent.TXT.gz")
    back = header + rows + GOOD_ROW  # time jumps back to 0.001
    assert "dropped 1 rows" in dv.read_bench_file(_write(tmp_path / "b.TXT.gz", back)).notes[0]
    with pytest.raises(DataError, match="no run"):
        dv.read_bench_folder(tmp_path, names=["99"])


def test_physics_meets_the_published_figure_on_every_held_out_fold():
    runs = dv.read_bench_folder(davinci_dir())
    fitters = {dv.Physics.name: dv.Physics.fit, dv.Linear.name: dv.Linear.fit}
    for key in ("frequency", "load"):
        res = dv.leave_one_out(runs, key, fitters)
        assert len(res.folds) == (5 if key == "frequency" else 4)
        for fold, scores in res.folds.items():
            assert scores[dv.Physics.name].rmse_mnm <= dv.PUBLISHED_RMSE, (key, fold)
            assert scores[dv.Physics.name].angle_rmse_deg < 1.0
            # and the plain linear map does not: the physics is doing the work
            assert scores[dv.Linear.name].rmse_mnm > 2 * scores[dv.Physics.name].rmse_mnm


def test_the_new_instrument_path_runs_from_the_cli(tmp_path):
    from cablekit.cli import main

    bench = davinci_dir()
    folder = bench / "tool4_load_sweep"
    cal = [str(folder / f"{n}.TXT.gz") for n in ("00", "03", "40", "43")]
    args = ["forceps", "davinci", str(bench), "--calibrate-on", *cal, "--no-networks", "--quiet"]
    assert main([*args, "--out", str(tmp_path)]) == 0
    text = (tmp_path / "davinci.md").read_text(encoding="utf-8")
    assert "calibrated on 00 + 03 + 40 + 43 (prior), scored on 16 runs" in text
    assert "O'Neill" in text and "passes" in text
    # one run at one load level: the calibration is flagged and the command exits 3 (issue #37 §2)
    one = ["forceps", "davinci", str(bench), "--calibrate-on", cal[0], "--no-networks", "--quiet"]
    with pytest.warns(UserWarning, match="FLAGGED"):
        assert main([*one, "--out", str(tmp_path / "one")]) == 3
    flagged = (tmp_path / "one" / "davinci.md").read_text(encoding="utf-8")
    assert "FLAGGED" in flagged and "one load level" in flagged and "record the load step" in flagged
    with pytest.warns(UserWarning, match="FLAGGED"):
        assert main([*one, "--accept-flagged", "--out", str(tmp_path / "one")]) == 0


def test_a_folder_copied_with_its_upstream_readme_and_serial_log_reads_only_the_runs(tmp_path):
    """Upstream bench folders keep ``README.txt`` and ``SerialLog.txt`` beside the runs (issue #37):
    a folder read whole takes the runs named by their condition digits (XY, ZXY) and nothing else;
    a run with another stem is read when it is named."""
    header = "% Tool 4\n% columns ...\n"
    rows = "".join(GOOD_ROW.replace("0.001", f"{0.001 * (i + 1):.3f}", 1) for i in range(20))
    for stem in ("00", "13", "101"):
        _write(tmp_path / f"{stem}.TXT.gz", header + rows)
    (tmp_path / "README.txt").write_text("Tool 4, Maryland bipolar forceps\n")
    _write(tmp_path / "SerialLog.txt.gz", "COM3 opened\n")
    _write(tmp_path / "extra.TXT.gz", header + rows)
    runs = dv.read_bench_folder(tmp_path)
    assert sorted(r.path.name for r in runs) == ["00.TXT.gz", "101.TXT.gz", "13.TXT.gz"]
    named = dv.read_bench_folder(tmp_path, names=["extra", "00"])
    assert [r.path.name for r in named] == ["extra.TXT.gz", "00.TXT.gz"]
    with pytest.raises(DataError, match=r"README\.txt"):
        dv.read_bench_folder(tmp_path, names=["README"])
    (tmp_path / "notes").mkdir()
    only_text = tmp_path / "notes"
    (only_text / "README.txt").write_text("x\n")
    with pytest.raises(DataError, match="no bench runs"):
        dv.read_bench_folder(only_text)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.text(alphabet="0123456789abcXY_-. ", min_size=1, max_size=6),
            st.sampled_from([".TXT", ".TXT.gz", ".txt", ".txt.GZ", ".csv", "", ".TXT.bak"]),
        ),
        max_size=8,
        unique_by=lambda t: t[0] + t[1],
    )
)
def test_a_folder_of_any_file_names_yields_exactly_its_digit_named_runs(tmp_path_factory, names):
    """Whatever a folder holds, the bench runs are its ``.TXT``/``.TXT.gz`` files (any case) whose
    stem is all digits; every text run is found by its stem."""
    from cablekit._files import bench_runs, text_runs

    d = tmp_path_factory.mktemp("bench")
    made = set()
    for stem, suffix in names:
        name = stem + suffix
        if name in (".", "..") or "/" in name:
            continue
        (d / name).write_text("x")
        made.add(name)
    text = text_runs(d)
    for stem, p in text.items():
        assert p.name in made and p.name[len(stem) :].lower() in (".txt", ".txt.gz")
    for name in made:
        low = name.lower()
        for suffix in (".txt.gz", ".txt"):
            if low.endswith(suffix):
                assert name[: -len(suffix)] in text
                break
    assert set(bench_runs(d)) == {k for k in text if k.isascii() and k.isdigit()}


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), data=st.data())
def test_sample_weights_equal_the_weighted_numpy_reference(seed, data):
    """Weighted least squares per sample (issue #37 §2: a calibration's runs weighted against the
    training runs, the paper's sample-wise split as 0/1 weights): the Rust fit equals NumPy's
    lstsq on rows scaled by the weights' square roots."""
    runs = _synthetic(seed)
    n = len(runs[0])
    kinds = data.draw(
        st.lists(st.sampled_from(["ones", "zeros-half", "random", "heavy"]), min_size=3, max_size=3)
    )
    rng = np.random.default_rng(seed)
    weights = []
    for kind in kinds:
        w = {
            "ones": np.ones(n),
            "zeros-half": np.r_[np.ones(n // 2), np.zeros(n - n // 2)],
            "random": rng.uniform(0.0, 3.0, n),
            "heavy": np.full(n, 40.0),
        }[kind]
        weights.append(w)
    model = DriveModel.fit(runs, TRAVELS, dt=1e-3, window=20, warmup=0.2, weights=weights)
    c, p = ref.fit(runs, TRAVELS, 1e-3, 20, 0.2, weights)
    np.testing.assert_allclose(model.coefficients, c, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(model.angle_coefficients, p, rtol=1e-6, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(
    bad=st.one_of(
        st.just("nan"),
        st.just("negative"),
        st.just("inf"),
        st.just("short"),
        st.just("2d"),
        st.just("strings"),
        st.just("count"),
        st.floats(min_value=1e300, max_value=1e308),
    )
)
def test_bad_sample_weights_are_typed_errors(bad):
    from cablekit.errors import CablekitError

    runs = _synthetic(3)
    n = len(runs[0])
    w = [np.ones(n) for _ in runs]
    if bad == "nan":
        w[1][5] = np.nan
    elif bad == "negative":
        w[2][9] = -1e-3
    elif bad == "inf":
        w[0][0] = np.inf
    elif bad == "short":
        w[1] = np.ones(n - 1)
    elif bad == "2d":
        w[1] = np.ones((n, 1))
    elif bad == "strings":
        w[1] = ["a"] * n  # type: ignore[call-overload]
    elif bad == "count":
        w = w[:2]
    else:
        # huge but finite weights: a result or a typed error, never NaN coefficients
        w[0] = np.full(n, float(bad))
        try:
            m = DriveModel.fit(runs, TRAVELS, warmup=0.2, weights=w)
        except CablekitError:
            return
        assert np.isfinite(m.coefficients).all()
        return
    with pytest.raises((CablekitError, TypeError)):
        DriveModel.fit(runs, TRAVELS, warmup=0.2, weights=w)


def test_recalibration_on_several_runs_pools_them():
    runs = _synthetic(2)
    model = DriveModel.fit(runs, TRAVELS, warmup=0.2)
    a, b = runs[0].copy(), runs[2].copy()
    a[:, 1] += 0.002
    b[:, 1] += 0.004
    both = model.recalibrated([a, b], friction=False)
    one_a, one_b = model.recalibrated(a), model.recalibrated(b)
    # the pooled offset lies between the two runs' own (the runs have equal length)
    lo, hi = sorted([one_a.coefficients[0], one_b.coefficients[0]])
    assert lo < both.coefficients[0] < hi
    assert both.coefficients[0] == pytest.approx(0.5 * (lo + hi), abs=1e-9)
    with pytest.raises(ShapeError):
        model.recalibrated([])


@settings(max_examples=60, deadline=None)
@given(
    span=st.one_of(
        st.tuples(st.floats(), st.floats()),
        st.none(),
        st.text(max_size=6),
        st.lists(st.floats(-2.0, 2.0), max_size=4),
        st.integers(),
    )
)
def test_the_physics_estimators_span_is_a_model_or_a_typed_error(span):
    """``Physics.fit(span=...)``: a finite ``lo < hi`` gives a model holding the friction's angle
    dependence there (a finite estimate); anything else is a typed error, never NaN."""
    from cablekit.errors import CablekitError

    runs = [
        dv.BenchRun(f"0{i}", Path(f"0{i}"), 1e-3, r, np.zeros(len(r)), 0, i)
        for i, r in enumerate(_synthetic(5))
    ]
    good = (
        isinstance(span, tuple)
        and all(math.isfinite(v) for v in span)
        and span[0] < span[1]
        and max(abs(v) for v in span) < 1e150
    )
    try:
        est = dv.Physics.fit(runs, span=span)  # type: ignore[arg-type]
    except (CablekitError, TypeError) as exc:
        assert not good or isinstance(exc, CablekitError), exc
        return
    if span is not None:
        assert est.model.angle_friction_span == pytest.approx(tuple(span))  # type: ignore[arg-type]
    torque, _, _ = est.predict(runs[1])
    assert np.isfinite(torque).all()


@settings(max_examples=20, deadline=None)
@given(spindle=st.one_of(st.booleans(), st.integers(), st.text(max_size=4), st.none(), st.floats()))
def test_the_physics_estimators_spindle_elements_are_a_switch(spindle):
    """``Physics.fit(spindle=...)``: ``True`` fits the spindle-driven friction elements with the
    motor's travels, ``False`` leaves them out (five coefficients fewer); any other value is a
    typed error."""
    from cablekit.errors import CablekitError

    runs = [
        dv.BenchRun(f"0{i}", Path(f"0{i}"), 1e-3, r, np.zeros(len(r)), 0, i)
        for i, r in enumerate(_synthetic(5, spindle=(0.04, -0.02)))
    ]
    if not isinstance(spindle, bool):
        with pytest.raises(CablekitError):
            dv.Physics.fit(runs, spindle=spindle)  # type: ignore[arg-type]
        return
    est = dv.Physics.fit(runs, spindle=spindle)
    without = dv.Physics.fit(runs, spindle=False)
    expect = [math.radians(d) for d in dv.SPINDLE_TRAVELS_DEG] if spindle else []
    assert est.model.spindle_travels == pytest.approx(expect)
    assert len(est.model.coefficients) == len(without.model.coefficients) + len(expect)
    assert np.isfinite(est.predict(runs[1])[0]).all()
