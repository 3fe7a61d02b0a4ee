"""Issue #37 §1: the strict protocols (another session, the other spindle, other wrist
postures) — the calibration load step, bad input, and on the real bench (../shared/data, present
in CI) the spindle protocol from the CLI."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cablekit.errors import DataError, DTypeError
from cablekit.forceps import davinci as dv
from cablekit.forceps import protocols as pr
from tests.bench_data import davinci_dir


def _run(name: str, rows: int = 1200) -> dv.BenchRun:
    return dv.BenchRun(name, Path(name), 1e-3, np.zeros((rows, 5)), np.zeros(rows), None, None)


@settings(max_examples=200, deadline=None)
@given(names=st.lists(st.text(alphabet="0123456789ab", min_size=1, max_size=4), max_size=10, unique=True))
def test_the_calibration_load_step_spans_the_loads_or_is_a_data_error(names):
    runs = [_run(n) for n in names]
    digits = [n for n in names if n.isdigit()]
    for width in sorted({len(n) for n in digits}):
        same = [n for n in digits if len(n) == width]
        head = "0" * (width - 1)
        loads = [n[-1] for n in same if n.startswith(head)]
        if head + "0" not in names or max(loads) == "0":
            continue
        heavy = max(loads)
        got = [r.name for r in pr.calibration_runs(runs)]
        # the lightest and the heaviest load at the slowest motion: nothing heavier at X = 0
        assert got[:2] == [head + "0", head + heavy]
        assert all(n[-1] <= heavy for n in same if n.startswith(head))
        want: list[str] = []
        if width >= 2:
            # the same loads at the fastest motion (the largest X of the names 0…0XY)
            lead = "0" * (width - 2)
            top = max(n[-2] for n in same if n.startswith(lead))
            fast = [lead + top + "0", lead + top + heavy]
            want += fast if top != "0" and all(f in names for f in fast) else []
        if width == 3:
            # and the load step at the last jaw stopping position
            last = max(n[0] for n in same)
            stop = [last + "00", last + "0" + heavy]
            want += stop if last != "0" and all(f in names for f in stop) else []
        assert got[2:] == want
        assert len(set(got)) == len(got)
        return
    with pytest.raises(DataError, match="lightest and the heaviest load"):
        pr.calibration_runs(runs)


@settings(max_examples=30, deadline=None)
@given(
    bad=st.one_of(
        st.integers(), st.floats(allow_nan=True), st.none(), st.lists(st.integers(), max_size=3), st.text()
    )
)
def test_wrong_inputs_are_data_errors(bad, tmp_path_factory):
    with pytest.raises((DataError, DTypeError)):
        pr.calibration_runs(bad if not isinstance(bad, list) else [*bad, "00"])
    if not isinstance(bad, str):
        with pytest.raises((DataError, DTypeError), match="must be a path"):
            pr.protocols_present(bad)
    # a folder without the bench's folders, and unknown or wrongly typed protocol names
    empty = tmp_path_factory.mktemp("bench")
    with pytest.raises(DataError, match="none of the folder pairs"):
        pr.protocols_present(empty)
    with pytest.raises(DataError, match="unknown protocol"):
        pr.protocols_present(empty, ["spindle", "elbow"])
    with pytest.raises((DataError, DTypeError), match=r"list of protocol names|list of string"):
        pr.protocols_present(empty, "spindle")
    # transfer: (label, runs) pairs of bench runs, the scored folder with its load step
    runs = [_run("00"), _run("03"), _run("13")]
    fitters = {dv.Linear.name: dv.Linear.fit}
    cases = [(("a", runs), bad), (("a", bad), ("b", runs))] + (
        [] if isinstance(bad, str) else [((bad, runs), ("b", runs))]
    )
    for train, test in cases:
        with pytest.raises((DataError, DTypeError)):
            pr.transfer("session", train, test, fitters)
    with pytest.raises(DataError, match="warm-up"):
        pr.transfer("session", ("a", [_run("13", rows=500)]), ("b", runs), fitters)
    with pytest.raises(DataError, match="00 and 03"):
        pr.transfer("session", ("a", runs), ("b", runs[2:]), fitters)


def test_the_spindle_protocol_on_the_bench_from_the_cli(tmp_path):
    """Left spindle ↔ right spindle (two cable transmissions of one tool): the documented offset
    calibration does not carry the physics model over (every direction has a run far above
    4.42 mN·m), a refit on the new spindle's load step 00 + 03 does much better; the two
    calibration runs are never scored."""
    from cablekit.cli import main

    out = tmp_path / "p"
    args = ["forceps", "protocols", str(davinci_dir()), "--only", "spindle", "--no-networks", "--quiet"]
    assert main([*args, "--out", str(out)]) == 0
    rows = json.loads((out / "protocols.json").read_text(encoding="utf-8"))["folders"]
    assert {(r["train"], r["test"]) for r in rows} == {
        ("tool4_load_sweep", "tool4_right_spindle"),
        ("tool4_right_spindle", "tool4_load_sweep"),
    }
    # the calibration recording (00 + 03 + 40 + 43) is never scored
    assert all(r["n_scored"] == 16 for r in rows)
    for r in rows:
        s = r["scores"]
        if r["estimator"] != dv.Physics.name:
            assert s["offset + friction"] is None
            continue
        assert s["offset"]["worst_run_mnm"] > 3 * dv.PUBLISHED_RMSE
        # the default (the prior) and a refit on the recording both do far better
        for c in ("refit", "prior"):
            assert s[c]["rmse_mnm"] < 0.5 * s["offset"]["rmse_mnm"]
        for c in pr.CALIBRATIONS:
            assert s[c]["worst_run_mnm"] >= s[c]["rmse_mnm"]
    text = (out / "protocols.md").read_text(encoding="utf-8")
    assert text.count("| spindle |") == 4 and "O'Neill" in text


@settings(max_examples=60, deadline=None)
@given(
    values=st.lists(st.floats(0.5, 50.0), min_size=8, max_size=8),
    nan_at=st.one_of(st.none(), st.integers(0, 7)),
)
def test_the_cross_validation_chooses_by_both_recordings(values, nan_at):
    """The chosen (method, share) has the least geometric mean over the recordings of the
    all-pairs criterion; a recording without pairs (NaN) does not count."""
    keys = [("offset", None), ("prior", 16.0), ("prior", 64.0), ("prior", 256.0)]
    rows, overall = [], {}
    for i, (key, recording) in enumerate((k, r) for r in ("documented", "load step") for k in keys):
        v = math.nan if i == nan_at else values[i]
        group = pr.CvGroup(v, v, 0, 1)
        rows.append(pr.CvRow(key[0], key[1], recording, group, group))
        if math.isfinite(v):
            overall.setdefault(key, []).append(v)
    want = min(keys, key=lambda k: math.exp(np.mean(np.log(overall[k]))))
    assert pr._chosen(rows) == want
    table = pr.cv_markdown(rows)
    marked = [line for line in table.splitlines() if "(chosen)" in line]
    assert marked and all(f"| {want[0]} **(chosen)** |" in line for line in marked)
