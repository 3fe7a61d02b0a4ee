"""The da Vinci Maryland bench loader and calibration on the real files (read from
``../shared/data/davinci-maryland-bench`` or ``$CABLEKIT_DAVINCI_DATA``; never copied here)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import cablekit as ck
from cablekit.diagnose.davinci import SPINDLE_RADIUS, calibrate, load_bench_run, prepare_bench
from tests.bench_data import davinci_dir


def _data_dir() -> Path:
    return davinci_dir()


def test_bench_file_converts_to_si_units():
    run = load_bench_run(_data_dir() / "tool4_load_sweep" / "00.TXT.gz")
    assert run.dt == pytest.approx(1e-3, rel=1e-6)
    assert 19.0 < run.duration < 20.5
    # a ±30° spindle sine: 60° peak to peak (8192 counts/rev)
    assert np.ptp(run.column("spindle_angle")) == pytest.approx(np.deg2rad(60.0), rel=0.05)
    np.testing.assert_allclose(
        run.column("x_m"), SPINDLE_RADIUS * (run.column("spindle_angle") - run.column("spindle_angle")[0])
    )
    # jaw torque at 10 % load: a few hundredths of a N·m (3.9811e-5 N·m/count)
    assert 0.005 < np.mean(np.abs(run.column("jaw_torque"))) < 0.05
    assert run.notes[-1] == "0.1 Hz, 10 % resistive torque"


def test_calibrated_nominal_has_the_instrument_ratio():
    run = load_bench_run(_data_dir() / "tool4_load_sweep" / "00.TXT.gz")
    p = calibrate([run])
    ratio = SPINDLE_RADIUS / p["radius"]  # jaw rad per spindle rad
    assert 0.85 < ratio < 0.93
    assert p["stiffness"] > 1e3 and p["viscous"] >= 0.0
    ck.AntagonisticJoint(**p)  # a valid model


def test_split_holds_out_new_frequencies_and_loads():
    spec, fit, hold = prepare_bench(_data_dir(), decimate=10)
    assert [r.name for r in fit] == ["11", "22"] and [r.name for r in hold] == ["43", "40"]
    assert spec.external == ["tau_load"]
    fit_conditions = {r.notes[-1] for r in fit}
    assert not fit_conditions & {r.notes[-1] for r in hold}


def test_missing_bench_file_is_a_data_error(tmp_path):
    with pytest.raises(ck.DataError, match="no such bench file"):
        load_bench_run(tmp_path / "99.TXT.gz")


def test_jaw_torque_network_from_drive_side_signals_beats_the_linear_map_on_unseen_frequencies(tmp_path):
    from cablekit.nn import Mlp, export, train_mlp
    from cablekit.nn.datasets import davinci_jaw_torque

    data = davinci_jaw_torque(_data_dir())
    # 12 training runs (0.1/0.3/0.5 Hz x 4 loads) and 8 held-out runs, 19 s at 25 Hz each
    assert data.x.shape == (12 * 475, 4) and data.x_test is not None and data.x_test.shape == (8 * 475, 4)
    assert data.y_test is not None and data.baseline_test is not None
    # jaw torque: tens of mN·m; the spindle velocity peaks near 2π·0.5 Hz·30° ≈ 1.6 rad/s
    assert 5 < np.abs(data.y).mean() < 60 and 1.2 < np.abs(data.x[:, 1]).max() < 2.2
    base = float(np.mean((data.baseline_test - data.y_test) ** 2))
    res = train_mlp(data.x, data.y, method="br", seed=0, progress=False)
    mse = float(np.mean((res.predict(data.x_test) - data.y_test) ** 2))
    assert mse < base / 10, (mse, base)
    # the exported file gives the same held-out predictions from Rust
    mlp = Mlp.load(export(res, tmp_path / "jaw.safetensors", output_units=data.output_units))
    np.testing.assert_allclose(mlp.predict(data.x_test), res.predict(data.x_test), rtol=0, atol=1e-10)
    assert mlp.output_units == ["mN·m"]


def test_named_splits_hold_out_a_new_frequency_or_a_new_load():
    from cablekit.diagnose.davinci import FREQS, LOADS, SPLITS

    def conditions(names: tuple[str, ...]) -> tuple[set[float], set[int]]:
        return {FREQS[int(n[0])] for n in names}, {LOADS[int(n[1])] for n in names}

    for split, new in (("frequency", 0), ("load", 1)):
        sp = SPLITS[split]
        fit, hold = conditions(sp.fit + sp.calibration), conditions(sp.held_out)
        assert not hold[new] & fit[new]  # the held-out frequency (load) was never fitted
        assert hold[1 - new] <= conditions(sp.fit)[1 - new]  # the other condition was
        _, _, runs = prepare_bench(_data_dir(), sp, decimate=20)
        assert [r.name for r in runs] == list(sp.held_out)


def test_bench_folder_errors_name_the_expected_files(tmp_path):
    from cablekit.diagnose.davinci import BenchSplit, bench_directory

    with pytest.raises(ck.DataError, match=r"no bench files found; expected files named FL\.TXT"):
        bench_directory(tmp_path)
    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(ck.DataError, match="no bench files found"):
        bench_directory(tmp_path)
    (tmp_path / "00.TXT").write_text("% header\n1,2,3\n")
    with pytest.raises(ck.DataError, match=r"00\.TXT:2: 3 columns, need at least 6 .*expected files named"):
        prepare_bench(tmp_path, BenchSplit(("00",), ("01",), ("02",)))
    (tmp_path / "00.TXT").write_text("a,b,c,d,e,f\n" * 20)
    with pytest.raises(ck.DataError, match="not a bench file"):
        load_bench_run(tmp_path / "00.TXT")
    rows = "\n".join(f"{i * 1e-3},{i},{i},0.1,{i},nan" for i in range(20))
    (tmp_path / "00.TXT").write_text(rows)
    with pytest.raises(ck.DataError, match=r"00\.TXT:1: column 6 is not finite"):
        load_bench_run(tmp_path / "00.TXT")
    rows = "\n".join(f"{i * 1e-3},{i},{i},0.1,{i},{i}" for i in range(20))
    (tmp_path / "00.TXT").write_text(rows)
    with pytest.raises(ck.DataError, match=r"no bench run '42' \(have 00, notes\)"):
        prepare_bench(tmp_path, BenchSplit(("00",), ("42",), ("01",)))
    with pytest.raises(ck.DataError, match="both held out and fitted"):
        BenchSplit(("00",), ("11",), ("11",))
    with pytest.raises(ck.DataError, match="no fit runs"):
        BenchSplit(("00",), (), ("11",))
    for stem in ("01", "02"):
        (tmp_path / f"{stem}.TXT").write_text(rows)
    with pytest.raises(ck.DataError, match="0 samples after the 1 s warm-up"):
        prepare_bench(tmp_path, BenchSplit(("00",), ("01",), ("02",)))


@settings(max_examples=60, deadline=None)
@given(
    rows=st.integers(0, 40),
    cols=st.integers(1, 8),
    bad=st.sampled_from(["", "nan", "inf", "-inf", "1e400", "abc", "1,2", "0x10", "\x00"]),
    where=st.integers(0, 10_000),
    gz=st.booleans(),
)
def test_any_malformed_bench_file_is_a_data_error_or_a_finite_run(
    tmp_path_factory, rows, cols, bad, where, gz
):
    """Bench files with too few rows or columns, non-numbers, NaN/inf, huge values or NUL bytes in
    any cell: a DataError naming the file, or a run whose every column is finite."""
    import gzip

    cells = [[f"{(i * 1e-3 if j == 0 else i * (j + 1)):g}" for j in range(cols)] for i in range(rows)]
    if rows:
        cells[where % rows][where % cols] = bad
    text = "% header\n" + "\n".join(",".join(r) for r in cells) + "\n"
    d = tmp_path_factory.mktemp("bench")
    path = d / ("00.TXT.gz" if gz else "00.TXT")
    if gz:
        path.write_bytes(gzip.compress(text.encode()))
    else:
        path.write_text(text)
    try:
        run = load_bench_run(path)
    except ck.DataError as exc:
        assert str(path) in str(exc)
        return
    assert all(np.isfinite(v).all() for v in run.columns.values())


def test_a_split_named_by_any_stems_finds_its_folder(tmp_path):
    """Issue #37: a folder whose runs all have three-digit names (a wrist posture's ZXY), or other
    stems, is found when the split names them; the upstream README.txt alone is no bench folder."""
    from cablekit.diagnose.davinci import BenchSplit, bench_directory

    rows = "\n".join(f"{i * 1e-3},{i},{i},0.1,{i},{i}" for i in range(20))
    (tmp_path / "README.txt").write_text("Tool 4 at pitch +60\n")
    with pytest.raises(ck.DataError, match="no bench files found"):
        bench_directory(tmp_path)
    for stem in ("100", "111", "122", "143"):
        (tmp_path / f"{stem}.TXT").write_text(rows)
    assert bench_directory(tmp_path) == tmp_path
    split = BenchSplit(("100",), ("111", "122"), ("143",))
    assert bench_directory(tmp_path, split.calibration + split.fit + split.held_out) == tmp_path
    other = tmp_path / "other"
    other.mkdir()
    for stem in ("cal", "a", "b"):
        (other / f"{stem}.txt").write_text(rows)
    with pytest.raises(ck.DataError, match="no bench files found"):
        bench_directory(other)
    assert bench_directory(other, ("cal", "a", "b")) == other
    with pytest.raises(ck.DataError, match=r"no bench run 'z' \(have a, b, cal\)"):
        prepare_bench(other, BenchSplit(("cal",), ("a",), ("z",)))
