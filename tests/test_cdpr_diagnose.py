"""The CDPR diagnosis on run files: a twin run written as a table and read back by the CLI, and
the run loader against any bytes and any cell."""

from __future__ import annotations

import csv
import functools
import json
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

import cablekit as ck
from cablekit.cdpr import shipped
from cablekit.cdpr.diagnose import twin_run
from cablekit.cdpr.formats import load_cdpr_run

POSE = ("x", "y", "z", "roll", "pitch", "yaw")


def _write(path, run, poses=True, rows=None):
    m = run.alpha.shape[1]
    header = ["t", *(f"{k}_{j + 1}" for k in ("alpha", "current", "sensor") for j in range(m))]
    data = [run.t[:, None], run.alpha, run.current, run.sensor]
    if poses:
        header += list(POSE)
        data.append(run.lengths.poses)
    table = np.hstack(data)[: rows or len(run.t)]
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(table.tolist())


def robot_file(path: Path) -> Path:
    """The Mini CDPR's robot file with the twin's platform-side pulley friction as its
    ``[path_friction]`` table (the nominal of its drives' diagnosis)."""
    from importlib import resources

    from cablekit.cdpr.compensate import TWIN_FRICTION

    text = (resources.files("cablekit.cdpr") / "robots" / "seed002_mini.toml").read_text(encoding="utf-8")
    text += "\n[path_friction]\n" + "".join(
        f"{k} = {[float(v) for v in TWIN_FRICTION[k]]}\n" for k in ("coefficient", "viscous", "guide_wrap")
    )
    path.write_text(text + f"presliding = {TWIN_FRICTION['presliding']}\n", encoding="utf-8")
    return path


@pytest.mark.timeout(1200)  # (one whole diagnosis of 8 cables: minutes on 2 shared cores)
def test_a_worn_winch_in_a_run_file_is_found_through_the_engine(tmp_path):
    """A twin run whose winch 3 has 50 % more static friction, written as CSV with its poses
    (12 s), read by ``cablekit cdpr diagnose --run``: its drives go through the one engine (first
    half fitted, second held out, each half's rest lengths calibrated on it) and the first effect
    is the dry friction of drum 3; the robot file's ``[path_friction]`` is the platform side's
    nominal."""
    from cablekit.cli import main

    _write(tmp_path / "run.csv", twin_run("drum_friction", 2, seed=4), rows=12_000)
    robot = robot_file(tmp_path / "mini.toml")
    args = ["cdpr", "diagnose", "--run", str(tmp_path / "run.csv"), "--robot", str(robot)]
    assert main([*args, "--out", str(tmp_path / "out"), "--quiet", "--no-plots"]) == 0
    doc = json.loads((tmp_path / "out" / "diagnosis.json").read_text(encoding="utf-8"))
    assert doc["verdict"] in ("explained", "partially_explained"), doc["verdict"]
    first = doc["effects"][0]
    assert first["site"] == "motor.drum3", [e["id"] for e in doc["effects"][:3]]
    assert first["name"] in ("coulomb_friction", "stribeck_friction"), first["id"]
    runs = doc["meta"]["fit_runs"] + doc["meta"]["held_out_runs"]
    assert all(any("rest lengths calibrated" in n for n in r["notes"]) for r in runs), runs


def test_a_run_file_without_poses_gets_the_drum_side_force_check(tmp_path):
    """Without poses, ``cablekit cdpr diagnose --run`` checks the drums against the load cells
    (the force channel); rows a host stamped on arrival (±0.3 ms at 1 kHz) are put back on the
    clock's grid (resampling them at the stamps would turn the drum accelerations into noise:
    0.14 N → 30 N)."""
    from cablekit.cli import main

    run = twin_run("cable_creep", 2, seed=4)
    _write(tmp_path / "nopose.csv", run, poses=False)
    args = ["cdpr", "diagnose", "--run", str(tmp_path / "nopose.csv"), "--robot", "seed002_mini"]
    args += ["--out", str(tmp_path / "out"), "--quiet"]
    assert main(args) == 0
    text = (tmp_path / "out" / "diagnose.md").read_text(encoding="utf-8")
    assert "## length channel" not in text and "## force channel" in text and "force: nothing found" in text
    rows = (tmp_path / "nopose.csv").read_text(encoding="utf-8").splitlines()
    stamps = np.random.default_rng(3).uniform(-3e-4, 3e-4, len(rows) - 1)
    cells = [r.split(",", 1) for r in rows[1:]]
    body = [f"{float(t) + s:.7f},{rest}" for (t, rest), s in zip(cells, stamps, strict=True)]
    (tmp_path / "stamped.csv").write_text("\n".join([rows[0], *body]) + "\n", encoding="utf-8")
    assert main([*args[:3], str(tmp_path / "stamped.csv"), *args[4:]]) == 0
    stamped = (tmp_path / "out" / "diagnose.md").read_text(encoding="utf-8")
    assert "Note: stamped.csv: time stamps jitter" in stamped
    assert "force: nothing found" in stamped, stamped
    noise = [float(re.search(r"force channel.*?noise \(([0-9.]+) N\)", x, re.S)[1]) for x in (text, stamped)]
    assert noise[1] == pytest.approx(noise[0], rel=0.05), noise


def test_run_file_defects_are_data_errors_naming_them(tmp_path):
    run = twin_run(None, 0, seed=1)
    robot = shipped("seed002_mini")
    path = tmp_path / "run.csv"
    _write(path, run, rows=500)
    ok = load_cdpr_run(path, robot)
    assert ok.alpha.shape == (500, 8) and ok.poses is not None and ok.poses.shape == (500, 6)
    text = path.read_text(encoding="utf-8").splitlines()
    cases = {
        "missing": [text[0].replace("sensor_8", "sensor_9"), *text[1:]],
        "unknown": [text[0] + ",colour", *(r + ",1" for r in text[1:])],
        "pose": [text[0].replace(",yaw", ",yew"), *text[1:]],
        "finite": [text[0], text[1], text[2].replace(text[2].split(",")[3], "nan"), *text[3:]],
        "increase": [text[0], text[2], text[1], *text[3:]],
        "rows": text[:50],
    }
    for name, lines in cases.items():
        bad = tmp_path / f"{name}.csv"
        bad.write_text("\n".join(lines) + "\n", encoding="utf-8")
        with pytest.raises(ck.DataError):
            load_cdpr_run(bad, robot)
    with pytest.raises(ck.DataError):  # a planar robot's run has 4 cables
        load_cdpr_run(path, shipped("seed003_planar"))


@settings(max_examples=120, deadline=None)
@given(
    blob=st.binary(max_size=400)
    | st.text(alphabet="t,alph_curensox1234567890.e-+\n nai", max_size=400).map(str.encode)
)
def test_any_bytes_as_a_cdpr_run_load_or_raise_data_error(tmp_path_factory, blob):
    robot = shipped("seed003_planar")
    p = tmp_path_factory.mktemp("fuzz") / "run.csv"
    p.write_bytes(blob)
    try:
        run = load_cdpr_run(p, robot)
    except ck.DataError:
        return
    assert run.alpha.shape[1] == 4 and np.isfinite(run.alpha).all()


@settings(max_examples=60, deadline=None)
@given(
    row=st.integers(0, 149),
    col=st.integers(0, 15),
    value=st.sampled_from(["nan", "inf", "-inf", "1e308", "-1e308", "", "x", "1e-320", "0"]),
)
def test_any_cell_of_a_cdpr_run_loads_or_raises_data_error(tmp_path_factory, row, col, value):
    """Rows of a planar robot's run with one cell replaced: a DataError naming the defect, or a
    run whose diagnosis is finite or a CablekitError."""
    from cablekit.cdpr.diagnose import diagnose_file

    robot = shipped("seed003_planar")
    rng = np.random.default_rng(row)
    t = np.arange(150) * 1e-3
    cells = np.column_stack([t, rng.normal(0, 0.01, (150, 4)), rng.normal(0.5, 0.1, (150, 4))])
    cells = np.column_stack([cells, rng.normal(20, 1, (150, 4)), np.tile([0.6, 0.5, 0.0], (150, 1))])
    header = ["t", *(f"{k}_{j + 1}" for k in ("alpha", "current", "sensor") for j in range(4)), "x", "y"]
    header.append("theta")
    lines = [",".join(header)] + [",".join(repr(float(v)) for v in r) for r in cells]
    parts = lines[row + 1].split(",")
    parts[col] = value
    lines[row + 1] = ",".join(parts)
    p = tmp_path_factory.mktemp("cell") / "run.csv"
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    try:
        d = diagnose_file(p, robot)
    except ck.CablekitError:
        return
    for ch in d.channels:
        assert np.isfinite(ch.residual_rms).all() and np.isfinite(ch.noise)


@pytest.mark.timeout(1200)  # (one whole diagnosis of 8 cables: minutes on 2 shared cores)
def test_cablekit_diagnose_takes_a_robot_file_as_the_model(tmp_path):
    """``cablekit diagnose FIT --holdout HOLD --model robot.toml``: the engine's command takes a
    cable robot's file, its runs with poses (4 s each, both with a Dahl pulley before cable 6's
    load cell) going through the same engine as a network's: the first effect is that pulley's
    friction at cable 6's routing, and the report is the engine's."""
    from cablekit.cli import main

    for name, seed in (("fit", 3), ("hold", 4)):
        _write(tmp_path / f"{name}.csv", twin_run("pulley_friction", 5, seed=seed), rows=4_000)
    robot = robot_file(tmp_path / "mini.toml")
    out = tmp_path / "out"
    args = [str(tmp_path / "fit.csv"), "--holdout", str(tmp_path / "hold.csv"), "--model", str(robot)]
    # (linearised intervals: the refits' bootstrap is the joint engine's, tested there)
    assert main(["diagnose", *args, "--intervals", "0", "--out", str(out), "--quiet"]) == 0
    doc = json.loads((out / "diagnosis.json").read_text(encoding="utf-8"))
    first = doc["effects"][0]
    assert first["site"] == "routing.c6", first["id"]
    assert first["name"] in ("dahl_hysteresis", "capstan_friction"), first["id"]
    assert doc["verdict"] == "explained"
    assert (out / "diagnosis.html").stat().st_size > 10_000


def test_a_creeping_cable_is_found_across_runs_with_estimated_rest_lengths(tmp_path):
    """Fitted on one run and scored on another, each run's rest lengths estimated from its first
    sample: every run's offsets are its own (a held-out run's from its first 2 s, not scored), so
    the creep is found at its cable and nothing is found with nothing withheld."""
    from cablekit.cdpr.compensate import TWIN_FRICTION
    from cablekit.cdpr.diagnose import diagnose_runs

    robot = shipped("seed002_mini")
    for effect, cable in (("cable_creep", 2), (None, 0)):
        for name, seed in (("fit", 3), ("hold", 4)):
            _write(tmp_path / f"{name}.csv", twin_run(effect, cable, seed=seed))
        d = diagnose_runs([tmp_path / "fit.csv"], [tmp_path / "hold.csv"], robot, platform_side=TWIN_FRICTION)
        assert d.length is not None
        got = d.length.found
        if effect is None:
            assert got is None and d.length.status == "no gap", d.summary()
        else:
            assert got is not None and (got.effect, got.cable) == (effect, cable), d.summary()


@settings(max_examples=40, deadline=None)
@given(
    blob=st.one_of(
        st.binary(max_size=200),
        st.sampled_from(
            [b'motion = "planar"\ncables = []\n', b'model = "antagonistic_joint"\n', b"\xff\xfe", b""]
        ),
    )
)
def test_is_robot_file_answers_for_any_bytes(tmp_path_factory, blob):
    """Any file: a bool, never an exception; the shipped robot file is one, a joint model is not."""
    from importlib import resources

    from cablekit.cdpr.diagnose import is_robot_file

    p = tmp_path_factory.mktemp("any") / "model.toml"
    p.write_bytes(blob)
    assert is_robot_file(p) is (blob.startswith(b'motion = "planar"'))
    mini = resources.files("cablekit.cdpr") / "robots" / "seed002_mini.toml"
    assert is_robot_file(Path(str(mini))) is True


@functools.cache
def _short_run():
    """4 s of a twin run without poses (the force channel only), read as a run file would be."""
    from cablekit.cdpr.formats import RunFile

    twin = twin_run(None, 0, seed=1)
    k = 4000
    return RunFile(twin.t[:k], twin.alpha[:k], twin.current[:k], twin.sensor[:k], None)


@settings(max_examples=40, deadline=None)
@given(
    n_fit=st.one_of(st.integers(-(2**65), 2**65), st.floats(), st.text(max_size=3), st.none(), st.booleans()),
    runs=st.sampled_from(["ok", "empty", "not pairs", "names"]),
)
@example(n_fit=1, runs="ok")
def test_diagnose_loaded_refuses_bad_splits_and_runs(n_fit, runs):
    """``diagnose_loaded``: a split without a fit or a held-out run, a wrong-typed count or run
    list is a typed error before any work; a valid split of two runs gives a diagnosis."""
    from cablekit.cdpr.diagnose import diagnose_loaded

    run = _short_run()
    given_runs = {
        "ok": [("a", run), ("b", run)],
        "empty": [],
        "not pairs": [run, run],
        "names": [(1, run), (2, run)],
    }[runs]
    robot = shipped("seed002_mini")
    valid = runs == "ok" and type(n_fit) is int and n_fit == 1
    if not valid:
        with pytest.raises(ck.CablekitError):
            diagnose_loaded(given_runs, n_fit, robot)  # type: ignore[arg-type]
        return
    d = diagnose_loaded(given_runs, n_fit, robot)
    assert d.length is None and np.isfinite(d.force.noise) and d.status in ("found", "unexplained", "no gap")
