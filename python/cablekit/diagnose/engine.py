"""The diagnosis: localise the gap, attribute it to named effects, quantify how far it closes.

Pipeline (:func:`diagnose`):

1. **Prepare.** Per measured channel, the measurement-noise standard deviation ``σ_c`` from the
   fit runs' second differences; residuals are weighted by ``1/σ_c`` (noise units), so a model
   that is right leaves a mean squared residual ``G ≈ 1`` and the **gap** is the excess
   ``E = G − 1``. The first ``warmup`` seconds of every run absorb the unknown initial state.
2. **Where.** Open-loop replay of the nominal model on the recorded inputs; residual energy by
   operating condition, whiteness and residual–input cross-correlation, hysteresis loops.
3. **Which.** Every applicable candidate effect is fitted alone on the fit runs (grey-box least
   squares through the Rust simulator, candidates in parallel threads, GIL released) and scored
   on the held-out runs, which no fit sees: ``closed = (E_before − E_after)/E_before``, with a
   bootstrap over ~1 s segments of the held-out runs for the interval and the significance of the
   improvement. Forward selection then adds effects while each adds a significant held-out
   improvement. Candidates whose residual signatures are collinear get identifiability notes
   with the experiment that would separate them.
4. **How far.** Before/after per channel and per condition, fit and held-out, fitted parameters
   with confidence intervals, and what is left unexplained.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cablekit.diagnose import localise
from cablekit.diagnose.data import Run, common_interval
from cablekit.diagnose.discover import DOMINANT, SIGNATURES, describe_remaining, discover, signature_missing
from cablekit.diagnose.fit import CandidateFit, baseline, parameters_out
from cablekit.diagnose.identifiability import identifiability, separating_experiment
from cablekit.diagnose.intervals import refit_intervals
from cablekit.diagnose.prepare import NOISE_LEVEL, Options, Prepared, prepare
from cablekit.diagnose.result import SCHEMA, Diagnosis, jsonable
from cablekit.diagnose.screen import screen
from cablekit.diagnose.select import (
    Forward,
    backward_eliminate,
    bic,
    channel_changes,
    closed_fraction,
    compare,
    forward_select,
    gap,
    integrated_time,
    parsimony,
    refine_forms,
    segments,
)
from cablekit.diagnose.spec import ModelSpec
from cablekit.diagnose.where import localise_all

__all__ = ["Diagnosis", "Options", "diagnose"]

_F = NDArray[np.float64]


def _run_info(r: Run) -> dict[str, Any]:
    info: dict[str, Any] = {"name": r.name, "samples": len(r), "dt": r.dt, "notes": r.notes}
    return info | ({"attributes": dict(r.attributes)} if r.attributes else {})


def _per_channel(prep: Prepared, resid: list[_F]) -> dict[str, Any]:
    out = {}
    for c, name in enumerate(prep.channel_names):
        w = np.concatenate([r[:, c] for r in resid])
        out[name] = {
            "rmse": float(np.sqrt(np.mean((w * prep.sigma[c]) ** 2))),
            "gap": float(np.mean(w * w)),
            "unit": prep.spec.output(name)[1],
        }
    return out


def diagnose(
    spec: ModelSpec, fit_runs: list[Run], hold_runs: list[Run], opts: Options | None = None
) -> Diagnosis:
    """Run the whole diagnosis (docs/diagnosis.md); :meth:`Diagnosis.to_json` is the document."""
    opts = opts or Options()
    rng = np.random.default_rng(opts.seed)
    runs = common_interval([spec.in_si(r) for r in [*fit_runs, *hold_runs]])
    fit_runs, hold_runs = runs[: len(fit_runs)], runs[len(fit_runs) :]
    prep = prepare(spec, fit_runs, hold_runs)
    base = baseline(prep)
    dt = prep.fit_runs[0].dt
    where = localise_all(prep, base)
    g_hold = gap(base.hold_resid)
    g_fit = gap(base.fit_resid)
    g_lo = _gap_lower(base.hold_resid, dt, opts, rng)
    gap_significant = g_hold > NOISE_LEVEL and g_lo > 1.0
    # which kinds of term the gap follows, before any candidate is named
    nominal_terms = discover(prep, base.fit_resid, base.hold_resid) if gap_significant else []
    # every applicable candidate alone: a short fit of each screens, the shortlist is fitted in
    # full from where its screen ended
    screening = screen(prep, opts)
    screened_out = screening.screened_out
    fits = {c.effects[0]: c for c in screening.singles}
    scores = {}
    for name, c in fits.items():
        if c.error:
            scores[name] = {
                "gap_before": g_hold,
                "gap_after": math.nan,
                "closed_fraction": -math.inf,
                "interval": [math.nan, math.nan],
                "p_no_improvement": 1.0,
                "significant": False,
                "worsened_channels": [],
            }
        else:
            scores[name] = compare(base.hold_resid, c.hold_resid, dt, opts, rng)
            scores[name]["worsened_channels"] = [
                ch["channel"]
                for ch in channel_changes(prep, base.hold_resid, c.hold_resid, dt, opts, rng)
                if ch["worsened"]
            ]
            if name in screened_out:  # never ranked as if it were a full fit
                scores[name]["significant"] = False
    n_eff = sum(r.shape[0] for r in base.fit_resid) / integrated_time(
        np.concatenate([r[:, 0] for r in base.fit_resid])
    )
    notes = identifiability(prep, base, fits, scores)
    ranked = sorted(
        fits,
        key=lambda k: (
            k in screened_out,
            -scores[k]["closed_fraction"],
            bic(fits[k], n_eff) if not fits[k].error else math.inf,
        ),
    )
    good = [k for k in ranked if k not in screened_out]

    def better(a: str, b: str) -> bool:
        """``a`` significantly better than ``b`` on the held-out runs, where ``b`` leaves more
        than noise: once the simpler one is at the noise level there is nothing left to earn."""
        g_b = scores[b]["gap_after"]
        if not (g_b is not None and math.isfinite(g_b) and g_b > NOISE_LEVEL):
            return False
        return bool(compare(fits[b].hold_resid, fits[a].hold_resid, dt, opts, rng)["significant"])

    ranked = parsimony(good, fits, scores, better) + [k for k in ranked if k not in good]
    # a flexible candidate (creep imitates anything slow) is not selected when the gap follows a
    # kind of term it cannot produce and none it can, while another effect explains the gap
    # comparably (at least half as well)
    vetoed = []
    for k in ranked:
        name = prep.info[k]["effect"]
        if not (scores[k]["significant"] and signature_missing(name, nominal_terms)):
            continue
        rivals = [
            j
            for j in ranked
            if prep.info[j]["effect"] != name
            and scores[j]["significant"]
            and scores[j]["closed_fraction"] >= 0.5 * scores[k]["closed_fraction"]
        ]
        if rivals:
            scores[k]["significant"] = False
            vetoed.append(
                {
                    "id": k,
                    "reason": f"closes {scores[k]['closed_fraction']:.0%} of the held-out gap, but the gap "
                    "follows "
                    + ", ".join(sorted({t.kind for t in nominal_terms if t.held_out_share >= DOMINANT}))
                    + f" (discrepancy discovery), which {name} cannot produce, and no "
                    + ", ".join(sorted(SIGNATURES[name]))
                    + f"; {rivals[0]} explains it comparably",
                }
            )
    vetoed += fast_creep_vetoes(ranked, prep.info, fits, scores, dt)
    if vetoed:
        out_ = {v["id"] for v in vetoed}
        ranked = [k for k in ranked if k not in out_] + [k for k in ranked if k in out_]
    # forward selection
    sel = (
        forward_select(prep, base, fits, ranked, scores, screening, opts, rng)
        if gap_significant
        else Forward([], [], base)
    )
    if gap_significant:
        sel = backward_eliminate(prep, refine_forms(prep, sel, fits, scores, opts, rng), base, opts, rng)
    chosen, steps, current = sel.chosen, sel.steps, sel.current
    # the named effects first, in the order they were selected (a provisional first pick that
    # round 2 replaced, or a form revisited, is no longer the diagnosis's first name)
    ranked = [*chosen, *(k for k in ranked if k not in chosen)]
    total = compare(base.hold_resid, current.hold_resid, dt, opts, rng)
    total_fit = {
        "gap_before": g_fit,
        "gap_after": gap(current.fit_resid),
        "closed_fraction": closed_fraction(g_fit, gap(current.fit_resid)),
    }
    channels = channel_changes(prep, base.hold_resid, current.hold_resid, dt, opts, rng)
    refit = (
        refit_intervals(prep, current, opts, np.random.default_rng(opts.seed + 1))
        if chosen and opts.interval_refits > 0
        else None
    )
    worse = [c for c in channels if c["worsened"]] if chosen else []
    # what the selected effects leave: described by kind, never absorbed silently
    g_after = gap(current.hold_resid)
    remaining_terms = (
        discover(prep, current.fit_resid, current.hold_resid)
        if gap_significant and g_after > NOISE_LEVEL
        else []
    )
    unexplained = describe_remaining(remaining_terms) if total["closed_fraction"] < 0.9 or not chosen else []
    ambiguity = _ambiguity(chosen, fits, scores, notes, prep, better) if chosen else None
    flags = [
        f"the selected effects make channel {c['channel']} worse on held-out data "
        f"(gap {c['gap_before']:.3g} -> {c['gap_after']:.3g}, {c['change']:+.0%})"
        for c in worse
    ]
    if not gap_significant:
        flags += _fit_only_gap(base, fits, g_fit, g_hold, dt, opts, rng)
    if not gap_significant:
        verdict = "no_significant_gap"
    elif (
        chosen
        and not worse
        and not unexplained
        and (g_after < NOISE_LEVEL or total["closed_fraction"] >= 0.8)
    ):
        verdict = "ambiguous" if ambiguity else "explained"
    else:
        verdict = "partially_explained"
    effects_out = []
    for k in ranked:
        c = fits[k]
        sc = scores[k]
        info = prep.info[k]
        effects_out.append(
            {
                "name": info["effect"],
                "id": k,
                "site": info["site"],
                "form": info["form"],
                "sentence": info["sentence"],
                "selected": k in chosen,
                "status": _status(c, screened_out.get(k)),
                "description": info["sentence"],
                "parameters": parameters_out(c) if not c.error else [],
                "fit": {
                    "gap_before": g_fit,
                    "gap_after": gap(c.fit_resid) if not c.error else None,
                    "closed_fraction": closed_fraction(g_fit, gap(c.fit_resid)) if not c.error else None,
                    "bic": bic(c, n_eff) if not c.error else None,
                },
                "held_out": sc
                | {
                    "closed_fraction": sc["closed_fraction"] if math.isfinite(sc["closed_fraction"]) else None
                },
                "identifiability": notes.get(k, []),
                "converged": c.converged,
                "bound": c.bound,
                "error": c.error,
            }
        )
    cond_after = localise.conditions_table(
        [np.sum(r * r, axis=1) for r in current.hold_resid], where["_hold_masks"]
    )
    cond_before = {
        (c.family, c.name): c
        for c in localise.conditions_table(
            [np.sum(r * r, axis=1) for r in base.hold_resid], where["_hold_masks"]
        )
    }
    e_total_b = sum(float(np.sum(r * r)) for r in base.hold_resid)
    e_total_a = sum(float(np.sum(r * r)) for r in current.hold_resid)
    per_condition = []
    for c in cond_after:
        b = cond_before[(c.family, c.name)]
        eb, ea = b.energy_share * e_total_b, c.energy_share * e_total_a
        per_condition.append(
            {
                "family": c.family,
                "condition": c.name,
                "energy_before": eb,
                "energy_after": ea,
                "reduction": (eb - ea) / eb if eb > 0 else 0.0,
            }
        )
    result = {
        "schema": SCHEMA,
        "verdict": verdict,
        "flags": flags,
        "effects": effects_out,
        "selected": {
            "effects": chosen,
            "steps": steps,
            "parameters": parameters_out(current, refit) if chosen else [],
            "held_out": total,
            "fit": total_fit,
            "channels_held_out": channels,
            "per_channel": {
                "held_out_before": _per_channel(prep, base.hold_resid),
                "held_out_after": _per_channel(prep, current.hold_resid),
                "fit_before": _per_channel(prep, base.fit_resid),
                "fit_after": _per_channel(prep, current.fit_resid),
            },
            "per_condition_held_out": per_condition,
            "unexplained_gap": gap(current.hold_resid) - 1.0,
        },
        "where": {k: v for k, v in where.items() if not k.startswith("_")},  # masks: internal
        "gap": {
            "fit": g_fit,
            "held_out": g_hold,
            "held_out_lower": g_lo,
            "noise_level": NOISE_LEVEL,
            "significant": gap_significant,
        },
        "skipped": prep.skipped,
        "discovery": {
            "nominal": [t.to_dict() for t in nominal_terms],
            "remaining": [t.to_dict() for t in remaining_terms],
        },
        "unexplained": unexplained,
        "ambiguity": ambiguity,
        "vetoed": vetoed,
        "meta": {
            "model": spec.to_dict(),
            "fit_runs": [_run_info(r) for r in fit_runs],
            "held_out_runs": [_run_info(r) for r in hold_runs],
            "channels": [
                {
                    "output": o,
                    "column": c,
                    "noise_sigma": float(s),
                    "interference_hz": hz,
                    "residual_window": w,
                }
                for o, c, s, hz, w in zip(
                    prep.channel_names,
                    prep.columns,
                    prep.sigma,
                    prep.interference_hz,
                    prep.windows or [1] * prep.q,
                    strict=False,
                )
            ],
            "substeps": prep.substeps,
            "candidates": prep.candidates,
            "screened_out": screened_out,
            "warnings": prep.warnings,
            "options": {k: v for k, v in vars(opts).items() if k not in ("progress", "executor")},
        },
    }
    internal = {
        "prep": prep,
        "base": base,
        "current": current,
        "fits": fits,
        "hold_masks": where["_hold_masks"],
    }
    return Diagnosis.from_json(jsonable(result), internal)


def _ambiguity(
    chosen: list[str],
    fits: dict[str, CandidateFit],
    scores: dict[str, dict[str, Any]],
    notes: dict[str, list[dict[str, Any]]],
    prep: Prepared,
    better: Any,
) -> dict[str, Any] | None:
    """The first selected candidate and another effect the runs cannot tell apart: collinear
    residual signatures (an identifiability note, |cos| > 0.9), held-out closures within 5 points,
    and neither significantly better than the other on the held-out runs (paired bootstrap)."""
    a = chosen[0]
    ea = prep.info[a]["effect"]
    ca = scores[a]["closed_fraction"]
    for note in notes.get(a, []):
        b = note["with"]
        if b not in fits or prep.info[b]["effect"] == ea or not scores[b]["significant"]:
            continue
        cb = scores[b]["closed_fraction"]
        if abs(ca - cb) > 0.05 or better(a, b) or better(b, a):
            continue
        return {
            "between": [a, b],
            "closed_fractions": [ca, cb],
            "signature_cosine": note["signature_cosine"],
            "experiment": separating_experiment(a, b),
        }
    return None


def _gap_lower(resid: list[_F], dt: float, opts: Options, rng: np.random.Generator) -> float:
    """The 2.5 % bound of a gap by a bootstrap over ~``opts.segment_s`` segments of ``resid``."""
    sb, cnt = segments(resid, dt, opts.segment_s)
    idx = rng.integers(0, len(sb), size=(opts.bootstrap, len(sb)))
    return float(np.quantile(sb[idx].sum(axis=1) / cnt[idx].sum(axis=1), 0.025))


def _fit_only_gap(
    base: CandidateFit,
    fits: dict[str, CandidateFit],
    g_fit: float,
    g_hold: float,
    dt: float,
    opts: Options,
    rng: np.random.Generator,
) -> list[str]:
    """A flag when the fit runs show a significant gap that the held-out runs do not (the verdict
    is then ``no_significant_gap``, which the held-out runs decide): an effect that settled before
    them (a freshly loaded cable's creep, a warm-up) or one they do not excite. No effect is named
    from the fit runs alone; the flag says which candidate closes most of the fit runs' gap."""
    if not g_fit > NOISE_LEVEL:
        return []
    if not _gap_lower(base.fit_resid, dt, opts, rng) > 1.0:
        return []
    closed = {k: closed_fraction(g_fit, gap(c.fit_resid)) for k, c in fits.items() if not c.error}
    best = max(closed, key=lambda k: closed[k], default=None)
    hint = f"; the candidate closing most of it there: {best} ({closed[best]:.0%})" if best else ""
    return [
        f"the fit runs show a significant gap ({g_fit:.3g} x noise) that the held-out runs do not "
        f"({g_hold:.3g}): an effect that settled before them (a freshly loaded cable's creep, a "
        f"warm-up) or that they do not excite — nothing is named from the fit runs alone; hold out "
        f"a run recorded as the fit runs were{hint}"
    ]


#: a creep whose time constant is at most this many samples is vetoed (a stiffness, not creep)
FAST_CREEP_SAMPLES = 10


def _creep_time(fit: CandidateFit, k: str) -> float | None:
    """The fitted time constant of candidate ``k``'s creep (``None`` without one)."""
    for spec, v in zip(fit.specs, fit.params, strict=False):
        if spec.effect == k and spec.name == "tau":
            return float(v)
    return None


def fast_creep_vetoes(
    ranked: list[str], info: dict[str, Any], fits: dict[str, Any], scores: dict[str, Any], dt: float
) -> list[dict[str, str]]:
    """Veto each significant creep that relaxes within :data:`FAST_CREEP_SAMPLES` samples (its
    score set not significant; the vetoes returned). With the cable's reference at the run's
    start such a creep is a softer cable about that reference — the stiffness scale's candidate,
    which pivots about the same reference: a relaxation the samples cannot resolve is no creep
    (the Mini CDPR twin's softer cables were named creep at τ's lower bound)."""
    out = []
    for k in ranked:
        if info[k]["effect"] != "creep" or not scores[k]["significant"]:
            continue
        tau = _creep_time(fits[k], k)
        if tau is not None and tau <= FAST_CREEP_SAMPLES * dt:
            scores[k]["significant"] = False
            out.append(
                {
                    "id": k,
                    "reason": f"closes {scores[k]['closed_fraction']:.0%} of the held-out gap, but relaxes "
                    f"within {FAST_CREEP_SAMPLES} samples (τ = {tau:.3g} s): an instantaneous softening of "
                    "the cable about its reference, its stiffness, not creep",
                }
            )
    return out


def _status(c: CandidateFit, screened: str | None) -> str:
    """``failed`` (the fit raised), ``screened_out`` (not on the shortlist), ``at_bound`` (a
    parameter ended on a bound away from its "off" value, listed in ``bound``),
    ``not_converged`` or ``converged``."""
    if c.error:
        return "failed"
    if screened:
        return "screened_out"
    if c.bound:
        return "at_bound"
    return "converged" if c.converged else "not_converged"
