"""Wrist posture as a run attribute (issue #37 §4): read from a bench folder's README or given by
the user, carried by every run, compared with the posture the nominal was calibrated at; a run at
an unknown posture gets a warning in the diagnosis, not a silent offset."""

from __future__ import annotations

import gzip
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import cablekit as ck
from cablekit.diagnose.data import Run
from cablekit.diagnose.davinci import DEFAULT_SPLIT, SPLITS, BenchSplit, prepare_bench, split_for
from cablekit.diagnose.prepare import prepare, unknown_conditions
from cablekit.diagnose.spec import model_spec_from_dict
from cablekit.forceps.posture import Posture, folder_posture, parse_posture, posture_from_text, run_posture
from tests.bench_data import davinci_dir

# the upstream folders' README lines, verbatim in form
PITCH_README = (
    "This is a roll of 0 degrees (i.e. 90 degrees on the outer ring of the protractor)\n"
    "This is a pitch of +60 degrees (i.e. 120 on the top of the shaft)\n"
)
ROLL_README = "This is a roll of -90 degrees (i.e. 0 degrees on the outer ring of the protractor)"


def test_the_upstream_readme_sentences_give_pitch_and_roll_not_the_protractor_readings():
    p = posture_from_text(PITCH_README, "ReadME.txt")
    assert (p.pitch_deg, p.roll_deg) == (60.0, 0.0)
    r = posture_from_text(ROLL_README, "README.txt")
    assert (r.pitch_deg, r.roll_deg) == (None, -90.0)
    # an unstated angle is 0 once the other is stated (the upstream files name the moved one)
    assert r.attributes() == {"pitch_deg": 0.0, "roll_deg": -90.0}
    assert not posture_from_text("Tool 4, Maryland forceps, left spindle", "x").stated
    assert posture_from_text("pitch = -30°, roll: 45 deg", "x").attributes() == {
        "pitch_deg": -30.0,
        "roll_deg": 45.0,
    }
    with pytest.raises(ck.DataError, match="states the pitch twice"):
        posture_from_text("a pitch of 30 degrees ... a pitch of 60 degrees", "x")


def test_a_folder_readme_is_found_compressed_or_not_and_the_jaw_stop_comes_from_the_run_name(tmp_path):
    (tmp_path / "a").mkdir()
    with gzip.open(tmp_path / "a" / "ReadME.txt.gz", "wt") as fh:
        fh.write(PITCH_README)
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "README.txt").write_text(ROLL_README)
    (tmp_path / "c").mkdir()
    (tmp_path / "c" / "notes.txt").write_text("pitch of 30 degrees")  # not a README
    a, b, c = (folder_posture(tmp_path / n) for n in "abc")
    assert (a.pitch_deg, a.roll_deg, a.source) == (60.0, 0.0, "ReadME.txt.gz")
    assert (b.pitch_deg, b.roll_deg) == (None, -90.0)
    assert not c.stated and c.attributes() == {}
    assert run_posture(a, "113").attributes() == {"pitch_deg": 60.0, "roll_deg": 0.0, "yaw_index": 1.0}
    assert run_posture(a, "13").yaw_index is None
    assert run_posture(c, "403").attributes() == {"yaw_index": 4.0}
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "README.txt.gz").write_bytes(b"not gzip")
    with pytest.raises(ck.DataError, match="cannot read the folder's README"):
        folder_posture(tmp_path / "d")


def test_a_posture_given_by_the_user_is_checked():
    assert parse_posture("pitch=30, roll=-45").attributes() == {"pitch_deg": 30.0, "roll_deg": -45.0}
    assert parse_posture("roll=90").pitch_deg == 0.0
    for bad, match in (
        ("", "expected"),
        ("yaw=3", "not pitch=DEG"),
        ("pitch=abc", "not a number"),
        ("pitch=1,pitch=2", "given twice"),
        ("pitch=nan", "not an angle"),
        ("roll=1e300", "not an angle"),
        ("pitch", "not pitch=DEG"),
    ):
        with pytest.raises(ck.DataError, match=match):
            parse_posture(bad)
    with pytest.raises(ck.DataError, match="stopping position"):
        Posture(0.0, 0.0, -1)
    with pytest.raises(ck.DataError, match="number of degrees"):
        Posture("30", 0.0)  # type: ignore[arg-type]


@settings(max_examples=200, deadline=None)
@given(st.one_of(st.text(max_size=80), st.integers(), st.none(), st.floats(), st.binary(max_size=20)))
def test_any_posture_text_is_a_posture_or_a_data_error(text):
    for parse in (parse_posture, lambda x: posture_from_text(x, "README")):
        try:
            p = parse(text)
        except (ck.DataError, ck.DTypeError):  # not a text at all: the argument check's type error
            continue
        assert all(math.isfinite(v) for v in p.attributes().values())


@settings(max_examples=100, deadline=None)
@given(
    st.one_of(
        st.none(),
        st.floats(allow_nan=True, allow_infinity=True),
        st.integers(-(10**9), 10**9),
        st.text(max_size=3),
    ),
    st.one_of(st.none(), st.floats(allow_nan=True, allow_infinity=True), st.integers(-(10**9), 10**9)),
    st.one_of(st.none(), st.integers(-5, 10**6), st.booleans(), st.floats()),
)
def test_a_posture_is_finite_and_bounded_or_a_data_error(pitch, roll, yaw):
    try:
        p = Posture(pitch, roll, yaw)
    except ck.DataError:
        return
    attrs = p.attributes()
    assert all(math.isfinite(v) for v in attrs.values())
    assert abs(attrs.get("pitch_deg", 0.0)) <= 180.0 and abs(attrs.get("roll_deg", 0.0)) <= 360.0


def _grid(z: str, xs: range, ys: range) -> set[str]:
    return {f"{z}{x}{y}" for x in xs for y in ys}


def test_the_default_split_keeps_its_design_on_a_wrist_folders_conditions():
    full = _grid("", range(5), range(4))
    assert split_for(DEFAULT_SPLIT, full) == DEFAULT_SPLIT
    assert split_for(
        SPLITS["frequency"], _grid("0", range(5), range(4)) | _grid("1", range(5), range(4))
    ) == (BenchSplit(("000",), ("011", "022"), ("041", "042")))
    pitch = _grid("0", range(2), range(4)) | _grid("1", range(2), range(4))  # Z 0-1, 0.1-0.2 Hz
    roll = set().union(*(_grid(str(z), range(1), range(4)) for z in range(5)))  # Z 0-4, 0.1 Hz
    for stems in (pitch, roll):
        sp = split_for(DEFAULT_SPLIT, stems)
        every = sp.calibration + sp.fit + sp.held_out
        assert set(every) <= stems and len(set(every)) == len(every)
        assert {s[0] for s in every} == {"0"}  # one jaw stopping position: the nominal knows it
        assert sp.calibration == ("000",)  # slowest, lightest
        heaviest = max(int(s[2]) for s in stems)
        fastest = max(int(s[1]) for s in stems)
        assert f"0{fastest}{heaviest}" in sp.held_out  # new load at the fastest motion
        assert 1 <= len(sp.fit) <= 2
    assert split_for(DEFAULT_SPLIT, roll) == BenchSplit(("000",), ("001", "002"), ("003",))
    with pytest.raises(ck.DataError, match="too few conditions"):
        split_for(DEFAULT_SPLIT, {"000", "001"})
    # a split the user names is not rewritten
    named = BenchSplit(("000",), ("001",), ("403",))
    assert split_for(named, roll) == named


PARAMS = {"radius": 4.5e-3, "stiffness": 5e4, "inertia": 1e-5, "pretension": 20.0, "viscous": 0.03}


def _run(name: str, attributes: dict[str, float]) -> Run:
    t = np.arange(200) * 1e-3
    return Run(name, t, {"x": np.sin(t)}, [], attributes)


def test_a_run_at_a_posture_the_nominal_does_not_know_gets_a_warning():
    spec = model_spec_from_dict(
        {
            "model": "antagonistic_joint",
            "parameters": PARAMS,
            "inputs": {"x_m": "x"},
            "outputs": {"theta": "x"},
            "conditions": {"pitch_deg": 0, "yaw_index": [0, 1]},
        }
    )
    assert spec.conditions == {"pitch_deg": (0.0,), "yaw_index": (0.0, 1.0)}
    assert spec.to_dict()["conditions"] == {"pitch_deg": [0.0], "yaw_index": [0.0, 1.0]}
    known = _run("a", {"pitch_deg": 0.0, "yaw_index": 1.0})
    assert unknown_conditions(spec, [known], [known]) == []
    w = unknown_conditions(
        spec, [known], [_run("b", {"pitch_deg": 60.0, "yaw_index": 1.0}), _run("c", {"yaw_index": 4.0})]
    )
    assert any("run(s) b at pitch_deg = 60" in x for x in w)
    assert any("run(s) c state no pitch_deg" in x for x in w)
    assert any("run(s) c at yaw_index = 4" in x for x in w)
    assert len(w) == 3
    # without conditions on the nominal: a held-out posture that no fit run has
    spec.conditions = {}
    w = unknown_conditions(spec, [known], [_run("d", {"pitch_deg": 30.0, "yaw_index": 1.0})])
    assert w == [
        "held-out run(s) d at pitch_deg = 30, which no fit run has (0): the fitted effects never saw it, "
        "and the model has no input for it"
    ]
    for bad in ({"pitch_deg": "x"}, {"pitch_deg": []}, {"pitch_deg": float("nan")}, [1]):
        with pytest.raises(ck.DataError, match="conditions"):
            model_spec_from_dict(
                {
                    "model": "antagonistic_joint",
                    "parameters": PARAMS,
                    "inputs": {"x_m": "x"},
                    "outputs": {"theta": "x"},
                    "conditions": bad,
                }
            )


def test_the_bench_diagnosis_carries_the_folders_posture_and_warns_at_another_stop():
    root = davinci_dir()
    spec, fit, hold = prepare_bench(root / "tool4_wrist" / "roll_1", decimate=10)
    assert [r.name for r in fit] == ["001", "002"] and [r.name for r in hold] == ["003"]
    assert spec.conditions == {"pitch_deg": (0.0,), "roll_deg": (-90.0,), "yaw_index": (0.0,)}
    assert all(r.attributes == {"pitch_deg": 0.0, "roll_deg": -90.0, "yaw_index": 0.0} for r in fit + hold)
    assert prepare(spec, fit, hold).warnings == []
    # held out at the other jaw stopping positions: warned, by value
    spec, fit, hold = prepare_bench(
        root / "tool4_wrist" / "roll_1", BenchSplit(("000",), ("001", "002"), ("103", "403")), decimate=10
    )
    w = prepare(spec, fit, hold).warnings
    assert any("103 at yaw_index = 1" in x for x in w) and any("403 at yaw_index = 4" in x for x in w)
    # a posture the user gives overrides the README (and is then what the nominal knows)
    spec, fit, hold = prepare_bench(root / "tool4_load_sweep", decimate=10, posture=parse_posture("pitch=30"))
    assert spec.conditions == {"pitch_deg": (30.0,), "roll_deg": (0.0,)}
    # the straight wrist's folder states nothing: no attribute, no warning
    spec, fit, hold = prepare_bench(root / "tool4_load_sweep", decimate=10)
    assert spec.conditions == {} and all(r.attributes == {} for r in fit + hold)


def test_the_cli_refuses_a_malformed_posture_before_it_reads_anything(tmp_path, capsys):
    from cablekit.cli import main

    code = main(["diagnose", "--davinci", str(tmp_path), "--posture", "yaw=3", "--out", str(tmp_path / "o")])
    assert code == 4
    assert "posture: 'yaw=3' is not pitch=DEG or roll=DEG" in capsys.readouterr().err


@settings(max_examples=200, deadline=None)
@given(
    st.sets(
        st.one_of(st.from_regex(r"[0-9]{2,3}", fullmatch=True), st.text(max_size=4)),
        max_size=30,
    ),
    st.sampled_from(sorted(SPLITS)),
)
def test_any_folder_gets_a_valid_split_or_a_data_error(stems, preset):
    try:
        sp = split_for(SPLITS[preset], stems)
    except ck.DataError:
        return
    every = sp.calibration + sp.fit + sp.held_out
    if sp is SPLITS[preset]:
        return  # as named: bench_file then names what is missing
    assert set(every) <= stems and len(set(every)) == len(every)
    assert not set(sp.held_out) & (set(sp.fit) | set(sp.calibration))


_value = st.one_of(st.floats(allow_nan=False, allow_infinity=False, width=64), st.integers(-3, 3).map(float))


@settings(max_examples=150, deadline=None)
@given(
    st.dictionaries(
        st.sampled_from(["pitch_deg", "roll_deg", "yaw_index"]), st.lists(_value, min_size=1, max_size=3)
    ),
    st.lists(
        st.dictionaries(st.sampled_from(["pitch_deg", "roll_deg", "yaw_index", "x"]), _value), min_size=2
    ),
)
def test_condition_warnings_are_one_per_attribute_and_value(conditions, attributes):
    spec = model_spec_from_dict(
        {
            "model": "antagonistic_joint",
            "parameters": PARAMS,
            "inputs": {"x_m": "x"},
            "outputs": {"theta": "x"},
        }
    )
    spec.conditions = {k: tuple(v) for k, v in conditions.items()}
    runs = [_run(f"r{i}", a) for i, a in enumerate(attributes)]
    fit, hold = runs[:1], runs[1:]
    w = unknown_conditions(spec, fit, hold)
    assert len(w) == len(set(w))
    # a run at a value outside the conditions is always named
    for r in runs:
        for k, v in r.attributes.items():
            built = spec.conditions.get(k)
            if built and not any(math.isclose(v, c, rel_tol=1e-9, abs_tol=1e-9) for c in built):
                assert any(f"{r.name}" in x and f"{k} = {v + 0.0:g}" in x for x in w)  # -0 reads 0
