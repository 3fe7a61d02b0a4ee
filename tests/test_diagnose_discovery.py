"""Issue #36: the blind-benchmark scorer, discrepancy discovery, the schema-3 verdict fields and
the new sensor forms, each against what a wrong implementation would get wrong."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cablekit._cablekit import effect_catalogue
from cablekit.diagnose import Options, diagnose
from cablekit.diagnose.benchmark import _score, _truth, format_benchmark, run_benchmark
from cablekit.diagnose.data import write_csv
from cablekit.diagnose.discover import (
    KINDS,
    MEASUREMENT_SIGNATURES,
    DiscoveredTerm,
    describe_remaining,
    discover,
    revealed,
    signature_missing,
)
from cablekit.diagnose.fit import baseline, fit_many
from cablekit.diagnose.localise import smooth_velocity
from cablekit.diagnose.prepare import prepare
from cablekit.diagnose.report import to_json, validate
from cablekit.diagnose.selftest import make_case
from cablekit.diagnose.spec import write_model_toml
from cablekit.errors import DataError

# ---- the benchmark scorer ------------------------------------------------------------------------


def _doc(top: tuple[str, str], verdict: str, selected: list[tuple[str, str]], closed: float = 0.9) -> dict:
    """A minimal diagnosis document: the first-ranked (name, site) and the selected ones."""
    effects = [{"name": top[0], "site": top[1], "id": f"{top[0]}@{top[1]}", "status": "converged"}]
    for name, site in selected:
        if f"{name}@{site}" != effects[0]["id"]:
            effects.append({"name": name, "site": site, "id": f"{name}@{site}", "status": "converged"})
    return {
        "effects": effects,
        "selected": {"effects": [f"{n}@{s}" for n, s in selected], "held_out": {"closed_fraction": closed}},
        "verdict": verdict,
        "gap": {"held_out": 50.0, "significant": verdict != "no_significant_gap"},
    }


def test_scoring_rules_follow_the_benchmark_readme():
    one = ["time_delay"]
    site = {"time_delay": "sensors.force"}
    ok = _score("c", one, site, True, _doc(("time_delay", "sensors.force"), "explained", []), 1.0)
    assert ok.correct and ok.site_correct and ok.kind == "single"
    # right effect, wrong site: the effect counts, the site does not
    wrong_site = _score("c", one, site, True, _doc(("time_delay", "input"), "explained", []), 1.0)
    assert wrong_site.correct and wrong_site.site_correct is False
    # the right name with no significant gap does not count
    assert not _score(
        "c", one, site, True, _doc(("time_delay", "input"), "no_significant_gap", []), 1
    ).correct
    # a pair: top-1 one of the two; both found only when each is selected
    pair = ["coulomb_friction", "sensor_lag"]
    half = _doc(("sensor_lag", "sensors.force"), "explained", [("sensor_lag", "sensors.force")])
    both = _doc(
        ("sensor_lag", "sensors.force"),
        "explained",
        [("sensor_lag", "sensors.force"), ("coulomb_friction", "joint")],
    )
    assert (
        _score("p", pair, {}, True, half, 1).correct and not _score("p", pair, {}, True, half, 1).both_found
    )
    assert _score("p", pair, {}, True, both, 1).both_found
    # a control is clean only with no gap and nothing selected
    assert _score("k", [], {}, True, _doc(("creep", "cable.both"), "no_significant_gap", []), 1).correct
    assert not _score(
        "k", [], {}, True, _doc(("creep", "cable.both"), "explained", [("creep", "cable.both")]), 1
    ).correct
    # outside the library: honest unless claimed explained
    out = _doc(("creep", "cable.both"), "partially_explained", [("creep", "cable.both")])
    assert _score("o", [], {}, False, out, 1).correct
    out["verdict"] = "explained"
    assert not _score("o", [], {}, False, out, 1).correct


def test_truth_files_are_read_with_their_sites_and_refused_when_broken(tmp_path: Path):
    d = tmp_path / "case01"
    d.mkdir()
    (d / "truth.json").write_text(json.dumps({"effects": {"a": {}, "b": {}}, "site": ["joint", "input"]}))
    names, sites, in_lib = _truth(d)
    assert names == ["a", "b"] and sites == {"a": "joint", "b": "input"} and in_lib
    (d / "truth.json").write_text(json.dumps({"effects": {"none_of_library": {}}, "in_library": False}))
    assert _truth(d) == ([], {}, False)
    for bad in ["{", json.dumps({"effects": [1, 2]}), json.dumps({"nothing": 1})]:
        (d / "truth.json").write_text(bad)
        with pytest.raises(DataError, match="truth"):
            _truth(d)
    with pytest.raises(DataError, match="not a benchmark folder"):
        run_benchmark(tmp_path / "missing")
    with pytest.raises(DataError, match="no case"):
        run_benchmark(tmp_path, ["case99"])


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    st.one_of(
        st.binary(max_size=200),
        st.recursive(
            st.none() | st.booleans() | st.floats() | st.text(max_size=8),
            lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=8), c, max_size=3),
            max_leaves=10,
        ).map(lambda v: json.dumps({"effects": v}).encode()),
    )
)
def test_any_truth_file_is_read_or_refused_with_a_data_error(tmp_path_factory, content: bytes):
    d = tmp_path_factory.mktemp("b") / "case00"
    d.mkdir()
    (d / "truth.json").write_bytes(content)
    try:
        names, sites, in_lib = _truth(d)
    except DataError:
        return
    assert all(isinstance(n, str) for n in names) and isinstance(in_lib, bool) and isinstance(sites, dict)


@pytest.fixture(scope="module")
def tiny_benchmark(tmp_path_factory) -> Path:
    """Two cases in the benchmark layout: a withheld gain error and a control."""
    root = tmp_path_factory.mktemp("bench")
    for name, effects, seed in (("case00", ("sensor_gain_bias",), 3), ("case01", (), 11)):
        case = make_case(effects, seed=seed, duration=4.0)
        d = root / name
        d.mkdir()
        write_csv(case.fit[0], d / "fit.csv")
        write_csv(case.hold[0], d / "holdout.csv")
        write_model_toml(case.spec, d / "model.toml")
        (d / "truth.json").write_text(json.dumps({"effects": {e: {} for e in effects}}))
    return root


def test_a_benchmark_folder_is_diagnosed_and_scored(tiny_benchmark: Path, tmp_path: Path):
    res = run_benchmark(
        tiny_benchmark, out=tmp_path, options=Options(progress=False, bootstrap=300), progress=False
    )
    by = {c.case: c for c in res.cases}
    assert by["case00"].top1_effect == "sensor_gain_bias" and by["case00"].correct
    assert by["case01"].verdict == "no_significant_gap" and by["case01"].correct
    assert res.top1 == (1, 1) and res.controls_clean == (1, 1)
    table = format_benchmark(res)
    assert "top-1 1/1" in table and "controls clean 1/1" in table
    doc = res.to_json()
    assert doc["scores"]["top1"] == [1, 1] and len(doc["cases"]) == 2
    assert (tmp_path / "case00.json").exists()
    validate(json.loads((tmp_path / "case00.json").read_text()))


# ---- discrepancy discovery -------------------------------------------------------------------------


@pytest.fixture(scope="module")
def control_prep():
    case = make_case((), seed=11, duration=5.0)
    prep = prepare(case.spec, case.fit, case.hold)
    return prep, baseline(prep)


def _inject(prep, base, make) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The control's residuals plus ``make(run, start)`` (noise units) on every channel."""

    def add(runs, resid):
        out = []
        for run, r in zip(runs, resid, strict=True):
            start = len(run) - r.shape[0]
            out.append(r + make(run, start)[:, None])
        return out

    return add(prep.fit_runs, base.fit_resid), add(prep.hold_runs, base.hold_resid)


def test_discovery_finds_the_kind_it_was_given_and_nothing_in_noise(control_prep):
    prep, base = control_prep
    assert discover(prep, base.fit_resid, base.hold_resid) == []  # a control: noise only
    col = prep.spec.inputs[0]

    def acceleration(run):
        # the acceleration as the library builds it (smoothed velocity, differentiated)
        return np.gradient(smooth_velocity(run.column(col), run.dt), run.dt)

    gain = 20.0 / float(np.std(acceleration(prep.fit_runs[0])))  # one physical coefficient

    def accel(run, start):
        return gain * acceleration(run)[start:]

    def drift(run, start):
        t = run.t - run.t[0]
        return 8.0 * (t / t[-1])[start:]

    for make, kind in ((accel, "acceleration"), (drift, "drift")):
        fit, hold = _inject(prep, base, make)
        terms = discover(prep, fit, hold)
        assert terms, kind
        first = {t.channel: t.kind for t in reversed(terms)}
        assert set(first.values()) == {kind}, terms
        assert all(t.held_out_share > 0.5 for t in terms if t.kind == kind)
    # creep's signature is a memory or a drift; a gap that follows acceleration lacks it
    fit, hold = _inject(prep, base, accel)
    assert signature_missing("creep", discover(prep, fit, hold))
    fit, hold = _inject(prep, base, drift)
    assert not signature_missing("creep", discover(prep, fit, hold))
    assert not signature_missing("coulomb_friction", [])  # only flexible effects need one


def test_a_lag_behind_dry_friction_shows_on_the_friction_models_predictions():
    """A force-sensor lag behind a dominant Coulomb friction: the gap the friction fit leaves
    follows the rate of change of the *friction model's* tension (the lag of its reversal
    steps), which the nominal model's tension does not have. Discovery on the fitted model's
    predictions reveals the lag (and forward selection offers it again); on the nominal
    predictions it does not; and behind friction alone nothing is revealed."""
    from cablekit.diagnose.selftest import PAIRS, SINGLE

    pair = make_case(PAIRS[0], seed=2026 + 97 * len(SINGLE), duration=4.0)
    assert set(PAIRS[0]) == {"coulomb_friction", "sensor_lag"}
    alone = make_case(("coulomb_friction",), seed=2026 + 97 * len(SINGLE), duration=4.0)
    opts = Options(progress=False)
    shown = {}
    for name, case in (("pair", pair), ("alone", alone)):
        prep = prepare(case.spec, case.fit, case.hold)
        (friction,) = fit_many(prep, [(["coulomb_friction@joint"], None)], opts, "test")
        assert friction.error is None
        shown[name] = (
            revealed(discover(prep, friction.fit_resid, friction.hold_resid, model=friction)),
            revealed(discover(prep, friction.fit_resid, friction.hold_resid)),
        )
    assert "sensor_lag" in shown["pair"][0], shown
    assert "sensor_lag" not in shown["pair"][1], shown  # the nominal predictions hide it
    assert not shown["alone"][0], shown


@given(st.lists(st.tuples(st.sampled_from(sorted(KINDS)), st.floats(allow_nan=True)), max_size=6))
def test_revealed_names_only_measurement_effects_whose_signature_is_found(items):
    terms = [DiscoveredTerm("ch", k, v, KINDS[k]) for k, v in items]
    kinds = {k for k, v in items if v >= 0.2}
    assert revealed(terms) == {e for e, sig in MEASUREMENT_SIGNATURES.items() if sig & kinds}


@given(st.lists(st.tuples(st.sampled_from(sorted(KINDS)), st.floats(allow_nan=True)), max_size=6))
def test_remaining_structure_is_described_only_above_its_share(items):
    terms = [DiscoveredTerm("ch", k, v, KINDS[k]) for k, v in items]
    out = describe_remaining(terms)
    assert len(out) == sum(1 for _, v in items if v >= 0.2)
    assert all(s.startswith("the remaining gap on ch follows ") for s in out)


# ---- schema 3 and the new forms ----------------------------------------------------------------------


def test_new_forms_are_offered_with_their_parameters():
    case = make_case(("sensor_lag",), seed=5, duration=4.0)
    prep = prepare(case.spec, case.fit, case.hold)
    ids = set(prep.candidates)
    assert "sensor_lag@sensors.force/resonant" in ids
    assert "sensor_sampling@sensors.force/averaging" in ids
    specs = prep.fit0.with_effects(["sensor_lag@sensors.force/resonant"], 1).param_specs()
    assert [s.name for s in specs] == ["tau_s", "zeta"]
    assert {e["name"] for e in effect_catalogue()} >= {"sensor_lag", "sensor_sampling"}


def test_schema_three_fields_round_trip_and_verdicts_are_documented():
    case = make_case(("sensor_gain_bias",), seed=3, duration=4.0)
    res = diagnose(case.spec, case.fit, case.hold, Options(progress=False, bootstrap=300))
    doc = json.loads(json.dumps(to_json(res)))
    validate(doc)
    assert doc["schema"] == "cablekit.diagnosis/3"
    for key in ("discovery", "unexplained", "ambiguity", "vetoed"):
        assert key in doc
    assert {"nominal", "remaining"} <= set(doc["discovery"])
    # the nominal gap of a gain error follows the channels' own level or an offset
    kinds = {t["kind"] for t in doc["discovery"]["nominal"]}
    assert kinds & {"level", "offset"}, kinds
    assert type(res).from_json(doc).to_json() == doc
    bad = dict(doc, verdict="confident")
    with pytest.raises(ValueError, match="verdict"):
        validate(bad)
    assert not math.isnan(res.selected.held_out.closed_fraction)


# ---- screening on the head of the runs, the provisional first pick --------------------------------


@pytest.fixture(scope="module")
def viscous_prep():
    case = make_case(("viscous_friction",), seed=5, duration=6.0)
    return prepare(case.spec, case.fit, case.hold)


def test_a_screen_on_the_head_is_scored_on_the_whole_runs(viscous_prep):
    """A screening fit searches the first seconds only, but its cost and residuals are the whole
    fit runs' (what the shortlist ranks), its held-out residuals are the held-out runs', and it
    claims no standard errors; a wrong implementation would rank screens by the head's cost."""
    from cablekit.diagnose.fit import fit_candidate

    prep = viscous_prep
    full = fit_candidate(prep, ["viscous_friction@joint"], max_iter=20)
    head = fit_candidate(prep, ["viscous_friction@joint"], max_iter=20, head_s=2.0)
    n_fit = [r.shape for r in full.fit_resid]
    assert [r.shape for r in head.fit_resid] == n_fit
    assert [r.shape for r in head.hold_resid] == [r.shape for r in full.hold_resid]
    r = np.concatenate([x.ravel() for x in head.fit_resid])
    assert head.cost == pytest.approx(0.5 * float(r @ r), rel=1e-12)
    assert np.all(np.isnan(head.param_sd)) and np.all(np.isfinite(full.param_sd))
    # one viscous coefficient is well determined by 2 s of a 6 s run: the same answer
    assert head.params[0] == pytest.approx(full.params[0], rel=0.05)
    # the core's head: fewer residuals, or None when a run is too short to cut
    problem = prep.fit0.with_effects(["viscous_friction@joint"], prep.substeps)
    cut = problem.head(2.0)
    assert cut is not None and cut.n_residuals < problem.n_residuals
    assert problem.head(1e4) is None
    with pytest.raises(ValueError):
        problem.head(float("nan"))
    with pytest.raises(ValueError):
        problem.fit(None, max_iter=2, atol=-1.0)


def _fake_fit(effects: list[str], hold: list[np.ndarray]):
    from cablekit.diagnose.fit import CandidateFit

    return CandidateFit(effects, np.zeros(1), [], 1, True, [], hold, 0.0, np.zeros(1), 1)


def test_the_first_pick_is_provisional_only_among_equivalents():
    """Equivalent first picks (another effect, held-out closure within 5 points, neither
    significantly better) are carried into round 2; a clearly worse one, one of the same effect,
    or one that is not significant is not."""
    from types import SimpleNamespace

    from cablekit.diagnose.select import _equivalents, compare

    rng = np.random.default_rng(3)
    n = 20000
    noise = [rng.normal(size=(n, 2))]
    base = [noise[0] * 3.0]  # gap 9
    a = [noise[0] * 1.30 + 0.05 * rng.normal(size=(n, 2))]
    twin = [noise[0] * 1.30 + 0.05 * rng.normal(size=(n, 2))]
    worse = [noise[0] * 2.0]
    ids = {"a": "lag", "twin": "inertia", "same": "lag", "worse": "damping"}
    info = {k: {"effect": v} for k, v in ids.items()}
    fits = {
        "a": _fake_fit(["a"], a),
        "twin": _fake_fit(["twin"], twin),
        "same": _fake_fit(["same"], twin),
        "worse": _fake_fit(["worse"], worse),
    }
    from cablekit.diagnose.prepare import Options

    opts = Options(progress=False)
    scores = {k: compare(base, f.hold_resid, 1e-3, opts, rng) for k, f in fits.items()}
    prep = SimpleNamespace(info=info)
    got = _equivalents(prep, fits["a"], list(fits.values()), scores, 1e-3, opts, rng, most=3)
    assert got == ["twin"]
    scores["twin"]["significant"] = False
    assert _equivalents(prep, fits["a"], list(fits.values()), scores, 1e-3, opts, rng, most=3) == []


def test_stick_phase_forms_share_the_bristle_and_a_dahl_at_its_floor_is_named_sticking():
    """The sticking Coulomb and LuGre Stribeck forms are offered with their break-away fixed
    (lower = upper: not a fitted parameter), never fitted together with a joint Dahl element
    (one bristle state), and a Dahl fit whose break-away ended at that floor loses the name to
    the sticking law it became even when it is significantly better; above the floor it keeps it."""
    from cablekit.diagnose.fit import CandidateFit, combinable, n_free
    from cablekit.diagnose.select import parsimony, reduces_to

    case = make_case(("sensor_lag",), seed=5, duration=4.0)
    prep = prepare(case.spec, case.fit, case.hold)
    dahl, stick, lugre = (
        "dahl_hysteresis@joint",
        "coulomb_friction@joint/sticking",
        "stribeck_friction@joint/lugre",
    )
    assert {dahl, stick, lugre} <= set(prep.candidates)
    specs = {k: prep.fit0.with_effects([k], 1).param_specs() for k in (dahl, stick, lugre)}
    assert [s.name for s in specs[stick]] == ["F_c", "theta_d"]
    assert [s.name for s in specs[lugre]] == ["F_c", "F_s_minus_F_c", "v_s", "theta_d"]
    floor = specs[stick][1].lower
    assert specs[stick][1].upper == floor == specs[lugre][3].lower == specs[dahl][1].lower > 0
    assert not combinable(prep, [dahl, stick]) and not combinable(prep, [lugre, stick])
    assert combinable(prep, [stick, "viscous_friction@joint"])

    def fake(k: str, params: list[float], hold_gap: float) -> CandidateFit:
        hold = [np.full((100, 1), math.sqrt(hold_gap))]
        return CandidateFit([k], np.array(params), specs[k], 1, True, [], hold, 0.0, np.zeros(len(params)), 1)

    assert (
        n_free(fake(stick, [0.1, floor], 2.0)) == 1 and n_free(fake(lugre, [0.1, 0.1, 0.1, floor], 2.0)) == 3
    )
    for theta_d, named in ((floor, stick), (30 * floor, dahl)):
        fits = {dahl: fake(dahl, [0.1, theta_d], 2.0), stick: fake(stick, [0.1, floor], 2.2)}
        assert reduces_to(fits[dahl]) == ("coulomb_friction" if theta_d == floor else None)
        scores = {k: {"gap_after": f.hold_resid[0][0, 0] ** 2} for k, f in fits.items()}
        # the Dahl fit is "significantly better" here: only its degeneracy takes the name away
        assert parsimony([dahl, stick], fits, scores, lambda a, b: a == dahl)[0] == named


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    st.lists(
        st.one_of(
            st.text(max_size=40),
            st.sampled_from(
                [
                    "dahl_hysteresis@joint",
                    "dahl_hysteresis@joint/generalised",
                    "coulomb_friction@joint/sticking",
                    "stribeck_friction@joint/lugre",
                    "viscous_friction@joint/power_law",
                    "backlash@joint",
                    "no_such_effect@joint",
                    "coulomb_friction@joint/no_such_form",
                ]
            ),
        ),
        max_size=4,
    )
)
def test_any_combination_of_ids_is_combinable_or_not_without_raising(control_prep, ids):
    """``combinable`` answers for any list of ids (unknown ids, forms and sites included) and
    refuses exactly the pairs that share the joint's bristle state among valid ids."""
    from cablekit.diagnose.fit import combinable

    prep, _ = control_prep
    got = combinable(prep, ids)
    assert isinstance(got, bool)
    bristle = {"dahl_hysteresis@joint", "dahl_hysteresis@joint/generalised"}
    bristle |= {"coulomb_friction@joint/sticking", "stribeck_friction@joint/lugre"}
    if len(set(ids) & bristle) >= 2:
        assert not got


def test_backward_elimination_drops_an_effect_the_others_made_superfluous(viscous_prep):
    """A selection that carries a superfluous effect next to the one in the data (creep fitted
    beside the viscous friction that made the runs) loses it, with a ``removed`` step; the true
    effect stays (dropping it costs a significant, practical share of the held-out gap), and a
    selection of the true effect alone is left as it is. A pass that never removes anything, or
    removes the wrong one, fails."""
    from cablekit.diagnose.fit import fit_candidate
    from cablekit.diagnose.select import Forward, backward_eliminate

    prep = viscous_prep
    base = baseline(prep)
    true, spurious = "viscous_friction@joint", "creep@cable.both"
    both = fit_candidate(prep, [spurious, true], max_iter=20)
    assert not both.error
    sel = Forward([spurious, true], [{"added": [spurious]}, {"added": [true]}], both)
    out = backward_eliminate(prep, sel, base, Options(progress=False), np.random.default_rng(1))
    assert out.chosen == [true]
    assert out.steps[-1]["removed"] == spurious and out.steps[-1]["added"] == []
    assert out.current.effects == [true] and not out.current.error
    alone = fit_candidate(prep, [true], max_iter=20)
    kept = backward_eliminate(
        prep, Forward([true], [], alone), base, Options(progress=False), np.random.default_rng(1)
    )
    assert kept.chosen == [true] and kept.current is alone and kept.steps == []


def test_a_revisited_law_starts_from_the_parameters_it_shares_with_the_one_it_replaces(control_prep):
    """Swapping a selected Stribeck law for the Coulomb law nested in it starts the Coulomb
    level where the Stribeck fit left ``F_c`` (clipped to the bounds), not where Coulomb's own
    single fit did; parameters of the other selected effects and unshared ones are untouched."""
    from cablekit.diagnose.fit import CandidateFit
    from cablekit.diagnose.select import _carry_over

    prep, _ = control_prep
    strib, coul, lag = "stribeck_friction@joint", "coulomb_friction@joint", "sensor_lag@sensors.force"
    specs = prep.fit0.with_effects([lag, strib], prep.substeps).param_specs()
    params = np.array([0.5 * (s.lower + s.upper) if s.effect == lag else 0.0 for s in specs])
    fc = next(i for i, s in enumerate(specs) if s.effect == strib and s.name == "F_c")
    params[fc] = 0.0123
    cur = CandidateFit([lag, strib], params, specs, 1, True, [], [], 0.0, np.zeros(len(specs)), 1)
    new_specs = prep.fit0.with_effects([lag, coul], prep.substeps).param_specs()
    start = np.array([-7.0] * len(new_specs))
    out = _carry_over(prep, cur, strib, coul, [lag, coul], start)
    for i, s in enumerate(new_specs):
        want = 0.0123 if (s.effect, s.name) == (coul, "F_c") else -7.0
        assert out[i] == pytest.approx(want)
    params[fc] = 1e9  # beyond the Coulomb bound: clipped
    cur.params = params
    out = _carry_over(prep, cur, strib, coul, [lag, coul], start)
    i = next(i for i, s in enumerate(new_specs) if (s.effect, s.name) == (coul, "F_c"))
    assert out[i] == new_specs[i].upper
    assert _carry_over(prep, cur, strib, coul, [lag, coul], None) is None


def test_a_revisited_law_is_refined_from_its_global_stage_too(control_prep, monkeypatch):
    """The alternative a selected law is swapped for is refined twice — from the start carried
    over from the law it replaces and from the core's global stage (no start) — and the fit of
    lower fit cost is the one judged on the held-out runs: a carried start stuck in the replaced
    law's basin no longer hides a better alternative (the da Vinci bench's smooth Stribeck law),
    and a global stage that ends worse on the fit runs is not taken for its held-out luck."""
    import cablekit.diagnose.select as sel_mod
    from cablekit.diagnose.fit import CandidateFit
    from cablekit.diagnose.select import Forward, refine_forms

    prep, _ = control_prep
    lag, lugre, strib = "sensor_lag@sensors.force", "stribeck_friction@joint/lugre", "stribeck_friction@joint"
    rng = np.random.default_rng(4)
    q = len(prep.channel_names)
    hold = [rng.normal(0.0, 3.0, (4000, q))]

    def fake(effects, cost, scale, start=None):
        specs = prep.fit0.with_effects(effects, 1).param_specs()
        params = np.zeros(len(specs)) if start is None else np.asarray(start, dtype=float)
        resid = [h * scale for h in hold]
        return CandidateFit(effects, params, specs, 1, True, [], resid, cost, np.zeros(len(specs)), 1)

    current = fake([lag, lugre], 100.0, 1.0)
    fits = {k: fake([k], 200.0, 1.0) for k in (lag, lugre, strib)}
    scores = {k: {"closed_fraction": 0.5} for k in fits}

    def fitter(carried_cost: float, global_cost: float, refined: list):
        def fit_many(prep_, jobs, opts, label, *a, **k):
            if label.strip() == "forms":
                return [fake(e, 150.0, 1.0, th) for e, th in jobs]
            refined.extend(jobs)
            # the carried start ends where it began (held out unchanged); the global stage finds
            # the basin that closes most of the held-out gap
            return [
                fake(e, carried_cost, 1.0, th) if th is not None else fake(e, global_cost, 0.4)
                for e, th in jobs
            ]

        return fit_many

    for carried_cost, global_cost, swapped in ((90.0, 80.0, True), (80.0, 90.0, False)):
        refined: list = []
        monkeypatch.setattr(sel_mod, "fit_many", fitter(carried_cost, global_cost, refined))
        sel = Forward([lag, lugre], [], current)
        out = refine_forms(prep, sel, fits, scores, Options(progress=False), np.random.default_rng(1))
        assert [e for e, _ in refined] == [[lag, strib], [lag, strib]]
        assert refined[0][1] is not None and refined[1][1] is None
        assert out.chosen == ([lag, strib] if swapped else [lag, lugre])
        assert (out.current.cost == global_cost) if swapped else (out.current is current)


def test_two_forms_of_one_law_at_one_site_are_never_fitted_together(control_prep):
    """Coulomb beside Stribeck friction at the joint, or two forms of one effect at one site, are
    alternatives of one law (their sum is that law with other parameters): not combinable. The
    same effect at two sites and unrelated effects at one site are."""
    from cablekit.diagnose.fit import combinable

    prep, _ = control_prep
    assert not combinable(prep, ["coulomb_friction@joint", "stribeck_friction@joint"])
    assert not combinable(prep, ["stribeck_friction@joint/lugre", "stribeck_friction@joint"])
    assert not combinable(prep, ["sensor_lag@sensors.force", "sensor_lag@sensors.force/second_order"])
    assert combinable(prep, ["coulomb_friction@joint", "viscous_friction@joint"])
    assert combinable(
        prep, ["sensor_lag@sensor.tension_motor_drive", "sensor_lag@sensor.tension_motor_return"]
    )


def test_a_richer_law_worse_than_the_law_it_contains_is_refitted_from_it(control_prep, monkeypatch):
    """LuGre-Stribeck contains the sticking Coulomb law (F_s = F_c): when its fit ended with a
    higher cost than the sticking law's full fit, it is fitted again from the sticking law's F_c
    and its own other parameters, and the better of its fits is kept (and counts as a full fit);
    when its cost is already lower, nothing is refitted."""
    import cablekit.diagnose.screen as screen_mod
    from cablekit.diagnose.fit import CandidateFit

    prep, _ = control_prep
    stick, lugre = "coulomb_friction@joint/sticking", "stribeck_friction@joint/lugre"

    def fake(k: str, params: list[float], cost: float) -> CandidateFit:
        specs = prep.fit0.with_effects([k], 1).param_specs()
        return CandidateFit([k], np.array(params), specs, 1, True, [], [], cost, np.zeros(len(specs)), 1)

    floor = prep.fit0.with_effects([stick], 1).param_specs()[1].lower
    jobs_seen: list = []

    def fit_many(prep_, jobs, opts, label, *a, **k):
        jobs_seen.extend(jobs)
        return [fake(e[0], list(theta), refit_cost) for e, theta in jobs]

    monkeypatch.setattr(screen_mod, "fit_many", fit_many)
    opts = Options(progress=False)
    singles = [fake(stick, [0.05, floor], 10.0), fake(lugre, [0.2, 0.03, 0.4, floor], 50.0)]
    for refit_cost, kept_cost in ((20.0, 20.0), (80.0, 50.0)):
        for was_full in (False, True):
            jobs_seen.clear()
            out, full = screen_mod._nest(prep, singles, {stick, lugre} if was_full else {stick}, opts)
            assert len(jobs_seen) == 1 and jobs_seen[0][0] == [lugre]
            assert list(jobs_seen[0][1]) == pytest.approx([0.05, 0.03, 0.4, floor])
            assert next(c for c in out if c.effects == [lugre]).cost == kept_cost
            # a screen fit that the refit did not beat stays a screen fit
            assert (lugre in full) == (was_full or refit_cost < 50.0)
    jobs_seen.clear()
    better = [singles[0], fake(lugre, [0.05, 0.01, 0.4, floor], 9.0)]
    out, full = screen_mod._nest(prep, better, {stick, lugre}, opts)
    assert jobs_seen == [] and out is better


@settings(max_examples=80, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.sampled_from(["a", "b"]),
            st.sampled_from(["F_c", "v_s", "tau", "eps"]),
            st.floats(-1e6, 1e6),
            st.floats(0.0, 1e3),
        ),
        max_size=6,
    ),
    st.lists(st.tuples(st.sampled_from(["F_c", "v_s", "x"]), st.floats(allow_nan=False)), max_size=4),
)
def test_carried_sets_exactly_the_shared_names_within_their_bounds(target, source):
    """``carried`` changes only ``effect``'s parameters whose name the source effect has, to that
    value clipped to the bounds; every other entry of the start stays as it was."""
    from types import SimpleNamespace

    from cablekit.diagnose.fit import carried

    specs = [SimpleNamespace(effect=e, name=n, lower=lo, upper=lo + w) for e, n, lo, w in target]
    start = np.arange(len(specs), dtype=float) * 0.5
    src_specs = [SimpleNamespace(effect="s", name=n) for n, _ in source]
    src = SimpleNamespace(specs=src_specs, params=np.array([v for _, v in source], dtype=float))
    out = carried(specs, start, src, "s", "a")  # type: ignore[arg-type]
    have = {n: v for n, v in source}
    assert out.shape == start.shape and np.all(np.isfinite(out))
    for i, s in enumerate(specs):
        if s.effect == "a" and s.name in have:
            assert s.lower <= out[i] <= s.upper
            assert out[i] == min(max(have[s.name], s.lower), s.upper)
        else:
            assert out[i] == start[i]


def test_a_failed_reveal_leaves_the_selection_as_before(monkeypatch):
    """The discovery on the first pick's predictions replays that model; if the replay fails
    (a divergence at the pick's substeps), nothing is revealed and the diagnosis goes on."""
    import cablekit.diagnose.select as select
    from cablekit.diagnose.selftest import PAIRS, SINGLE
    from cablekit.errors import SimulationDivergedError

    case = make_case(PAIRS[0], seed=2026 + 97 * len(SINGLE), duration=4.0)
    real = select.discover
    calls = []

    def failing(prep, fit, hold, **kw):
        if kw.get("model") is not None:
            calls.append(kw["model"].effects)
            raise SimulationDivergedError("replay diverged")
        return real(prep, fit, hold, **kw)

    monkeypatch.setattr(select, "discover", failing)
    res = diagnose(case.spec, case.fit, case.hold, Options(progress=False, bootstrap=300))
    assert calls, "the reveal was not attempted"
    assert res.selected.effects and res.selected.effects[0].startswith("coulomb_friction")


def test_a_creep_faster_than_ten_samples_is_vetoed_as_a_stiffness():
    """A significant creep whose τ is within 10 samples is vetoed (a softer cable about its
    reference), a slower one or one that is not significant is left, and other effects are never
    touched."""
    from types import SimpleNamespace as NS

    from cablekit.diagnose.engine import FAST_CREEP_SAMPLES, fast_creep_vetoes

    dt = 0.004

    def fit(k, tau):
        return NS(specs=[NS(effect=k, name="kappa"), NS(effect=k, name="tau")], params=np.array([0.3, tau]))

    cases = {
        "creep@cable.c1": (FAST_CREEP_SAMPLES * dt, True, True),  # on the edge: vetoed
        "creep@cable.c2": (5 * dt, True, True),
        "creep@cable.c3": (2.0, True, False),  # a real creep
        "creep@cable.c4/whole": (5 * dt, False, False),  # not significant: nothing to veto
        "nonlinear_stiffness@cable.c5": (5 * dt, True, False),  # not a creep (its "tau" is ignored)
    }
    info = {k: {"effect": k.split("@")[0]} for k in cases}
    fits = {k: fit(k, tau) for k, (tau, _, _) in cases.items()}
    scores = {k: {"significant": sig, "closed_fraction": 0.9} for k, (_, sig, _) in cases.items()}
    out = fast_creep_vetoes(list(cases), info, fits, scores, dt)
    assert [v["id"] for v in out] == [k for k, (_, _, veto) in cases.items() if veto]
    assert all("stiffness" in v["reason"] for v in out)
    for k, (_, sig, veto) in cases.items():
        assert scores[k]["significant"] == (sig and not veto)
