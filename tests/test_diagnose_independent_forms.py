"""The independent generator's added cases (new single forms, pairs, out-of-library effects):
each generates finite runs, and its withheld effect measurably changes the recorded tensions
against the same seed without it. Generation only (no diagnosis), short runs."""

from __future__ import annotations

import numpy as np
import pytest

from cablekit.diagnose import selftest_independent as si

pytest.importorskip("scipy")  # the generator's integrator and filters

DURATION = 1.5  # s per run: a few reversals, contacts and dwells of every family
SEED = 4242  # the self-test's default: each case is checked on its own seed from the plan

#: the cases added after the original plan: new single forms, pairs, out-of-library effects
NEW = [
    c
    for c in si.case_plan(SEED)
    if c["kind"] in ("pair", "outside")
    or (c["kind"] == "single" and c["effects"][0] in si.CASES[si.ORIGINAL_CASES :])
]


def _clean(case: dict) -> si._Setup:
    """The case's setup with noise-free load cells (a withheld effect that does nothing then
    leaves the runs bit-identical; quantisation stays)."""
    st = si._setup(case["effects"], case["seed"], DURATION)
    st.sens["tension_noise"] = 0.0
    st.sens["hum"] = 0.0
    return st


def _change(a: tuple[list, list], b: tuple[list, list], column: str) -> float:
    """RMS difference of one column between two generations (fit and held-out runs together)."""
    runs = list(zip(a[0] + a[1], b[0] + b[1], strict=True))
    return float(
        np.sqrt(np.mean([np.mean((ra.columns[column] - rb.columns[column]) ** 2) for ra, rb in runs]))
    )


def _tension_change(a: tuple[list, list], b: tuple[list, list]) -> float:
    """The larger of the two load cells' RMS differences."""
    return max(_change(a, b, "T_drive"), _change(a, b, "T_return"))


def test_new_cases_are_planned_with_their_own_seeds():
    """Every new label is in the plan once; the original singles and the controls keep the
    seeds of their original positions (seed + 131·i, the controls right after the 36 singles)."""
    plan = si.case_plan(SEED)
    labels = [c["label"] for c in plan]
    assert len(set(labels)) == len(labels)
    assert len({c["seed"] for c in plan}) == len(plan)
    seeds = {c["label"]: c["seed"] for c in plan}
    original = [f"{e}@{s}/{f}" for e, s, f in si.CASES[: si.ORIGINAL_CASES]]
    original += [f"control/{i}" for i in range(si.CONTROLS)]
    assert si.ORIGINAL_CASES == 36
    for i, label in enumerate(original):
        assert seeds[label] == SEED + 131 * i
    assert set(si.CI_SUBSET) <= set(labels)
    assert len(NEW) == len(si.CASES) - si.ORIGINAL_CASES + len(si.PAIRS) + len(si.OUTSIDE)


@pytest.mark.parametrize("case", NEW, ids=[c["label"] for c in NEW])
def test_new_case_generates_and_its_effect_shows_in_the_tensions(case):
    """At its drawn size or, as the self-test does for an effect hidden by the short runs'
    trajectories, doubled up to four times: an RMS change of several quantisation steps
    (6·T₀/4096 each) on some load cell. A form that does nothing stays at zero."""
    st = _clean(case)
    t0 = st.nom["pretension"]
    nominal = st.generate({}, np.random.default_rng(st.run_seed))
    truth = st.truth
    for _attempt in range(5):
        with_effect = st.generate(truth, np.random.default_rng(st.run_seed))
        for run in with_effect[0] + with_effect[1]:
            assert len(run.t) == round(DURATION / si.DT)
            for name, col in run.columns.items():
                assert np.all(np.isfinite(col)), (case["label"], run.name, name)
        if _tension_change(with_effect, nominal) > 0.005 * t0 or case["kind"] == "pair":
            break
        truth = si._bigger(truth, t0)
    assert _tension_change(with_effect, nominal) > 0.005 * t0, case["label"]
    if case["kind"] == "pair":
        # both effects act: the pair differs from each of its effects alone, in the tensions or
        # (an encoder delay) in the angle
        counts = 2 * np.pi / st.sens["encoder_counts"]
        for alone in st.truth["effects"]:
            one = st.generate(alone, np.random.default_rng(st.run_seed))
            moved = _tension_change(with_effect, one) > 0.002 * t0
            if st.theta_measured:
                moved = moved or _change(with_effect, one, "theta") > 2 * counts
            assert moved, (case["label"], alone["effect"])


def test_a_single_effect_given_as_a_list_generates_the_same_runs():
    """The plant, input path and sensors take a list of effects; one effect given as a list of
    one is the single-effect case, bit for bit."""
    for effects in (
        [("creep", "cable.both", "whole_tension")],
        [("sensor_gain_bias", "sensors.force", "both_cells")],
    ):
        st = si._setup(effects, 7, 1.0)
        a = st.generate(st.truth, np.random.default_rng(st.run_seed))
        b = st.generate({"effects": [st.truth]}, np.random.default_rng(st.run_seed))
        for ra, rb in zip(a[0] + a[1], b[0] + b[1], strict=True):
            for k in ra.columns:
                np.testing.assert_array_equal(ra.columns[k], rb.columns[k])
