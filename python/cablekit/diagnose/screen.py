"""Screen the candidate library: a short fit of every candidate ranks them, the shortlist is
fitted in full."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cablekit.diagnose.fit import CandidateFit, carried, fit_many
from cablekit.diagnose.prepare import Options, Prepared

__all__ = ["Screening", "channel_cost", "screen", "shortlist"]

_F = NDArray[np.float64]


def channel_cost(c: CandidateFit, ch: int) -> float:
    return float(sum(float(np.sum(r[:, ch] ** 2)) for r in c.fit_resid))


def shortlist(cands: list[CandidateFit], n: int, per_channel: int) -> list[CandidateFit]:
    """The ``n`` candidates of lowest pooled fit cost, then the ``per_channel`` best of each
    channel's own cost not yet in: the pooled cost is dominated by the channel with the largest
    gap in noise units, and an effect that shows on another channel only (a compliance seen by
    the joint encoder, not by the force sensor) must still reach the full fit."""
    ranked = sorted(cands, key=lambda c: c.cost)
    keep = ranked[:n]
    q = min((c.fit_resid[0].shape[1] if c.fit_resid else 0) for c in cands) if cands else 0
    for ch in range(q if per_channel > 0 else 0):
        for c in sorted(ranked[n:], key=lambda c: channel_cost(c, ch))[:per_channel]:
            if not any(c is k for k in keep):
                keep.append(c)
    return keep


#: (effect, form) → the richer laws, at the same site, that contain it as a special case with
#: every one of its parameters (by name) and the rest at their "off" value: LuGre-Stribeck with
#: F_s = F_c is the sticking Coulomb law; the generalised Dahl element with n = 1 is Dahl's
CONTAINED_IN = {
    ("coulomb_friction", "sticking"): (("stribeck_friction", "lugre"),),
    ("dahl_hysteresis", "standard"): (("dahl_hysteresis", "generalised"),),
}


def _contained_pairs(prep: Prepared) -> list[tuple[str, str]]:
    """(contained, richer) candidate ids at one site, from :data:`CONTAINED_IN`."""
    out = []
    for c, ci in prep.info.items():
        for eff, form in CONTAINED_IN.get((ci["effect"], ci["form"]), ()):
            out += [
                (c, r)
                for r, ri in prep.info.items()
                if (ri["effect"], ri["form"], ri["site"]) == (eff, form, ci["site"])
            ]
    return out


def _nest(
    prep: Prepared, singles: list[CandidateFit], full: set[str], opts: Options
) -> tuple[list[CandidateFit], set[str]]:
    """A richer law that contains a fully fitted one (:data:`CONTAINED_IN`) cannot be worse than
    it from the right start: when its fit (full or screen) ended with a higher cost, its short
    or full fit fell into another basin — a search failure, not evidence. It is fitted in full
    again from the contained law's values of the parameters the two share by name and its own
    values of the rest, and the better of its two fits is kept. Returns the singles and the ids
    whose kept fit is a full one."""
    by_id = {c.effects[0]: c for c in singles if not c.error}
    jobs: list[tuple[list[str], _F | None]] = []
    for c, r in _contained_pairs(prep):
        if c not in full or c not in by_id or r not in by_id or by_id[r].cost <= by_id[c].cost:
            continue
        jobs.append(([r], carried(by_id[r].specs, by_id[r].params, by_id[c], c, r)))
    if not jobs:
        return singles, full
    again = {t.effects[0]: t for t in fit_many(prep, jobs, opts, "nested") if not t.error}
    out, full = [], set(full)
    for t in singles:
        new = again.get(t.effects[0])
        if new is not None and (t.error or new.cost < t.cost):
            out.append(new)
            full.add(new.effects[0])
        else:
            out.append(t)
    return out, full


@dataclass
class Screening:
    """Every candidate fitted alone: in full for the shortlist, from the screen for the rest."""

    singles: list[CandidateFit]
    #: candidate id → why it was not fitted in full
    screened_out: dict[str, str]
    #: screened-out candidates still offered to later selection rounds: among the best few on one
    #: channel's own cost, they may matter once the dominant channel's effect is in
    second_chance: set[str]


def screen(prep: Prepared, opts: Options) -> Screening:
    """With more candidates than ``opts.shortlist``, fit each for ``opts.screen_fit_iter``
    iterations (after the core's global stage over every parameter), keep the :func:`shortlist`
    and fit it in full from where its screen ended; a candidate whose screen fit failed is
    fitted in full too. Otherwise fit every candidate in full."""
    screened_out: dict[str, str] = {}
    second_chance: set[str] = set()
    if opts.shortlist and len(prep.candidates) > opts.shortlist:
        quick = fit_many(
            prep,
            [([e], None) for e in prep.candidates],
            opts,
            "screen",
            opts.screen_fit_iter,
            opts.screen_head_s,
        )
        ok = [c for c in quick if not c.error]
        keep = shortlist(ok, opts.shortlist, opts.shortlist_per_channel)
        second_chance = {c.effects[0] for c in shortlist(ok, 0, 2 * opts.shortlist_per_channel)}
        best_cost = keep[0].cost if keep else math.nan
        cut = keep[min(opts.shortlist, len(keep)) - 1].cost if keep else math.nan
        for c in quick:
            if c.error:
                continue  # a failed fit is no reason to screen a candidate out: fitted in full below
            if not any(c is k for k in keep):
                screened_out[c.effects[0]] = (
                    f"screened out: after a {opts.screen_fit_iter}-iteration fit"
                    + (f" on the first {opts.screen_head_s:g} s" if opts.screen_head_s > 0 else "")
                    + f" its cost on the whole fit runs was {c.cost:.4g} "
                    f"(shortlist of {opts.shortlist} ends at {cut:.4g}, "
                    f"best {best_cost:.4g}) and it was not among the best {opts.shortlist_per_channel} "
                    "on any channel"
                )
        # the shortlist goes on from where its screen ended; a candidate whose screen failed is
        # fitted in full from its own global stage (and reported as failed if that fails too)
        jobs = [(c.effects, c.params) for c in keep] + [(c.effects, None) for c in quick if c.error]
        singles = fit_many(prep, jobs, opts, "candidates")
        full = {c.effects[0] for c in singles}
        singles += [c for c in quick if c.effects[0] in screened_out]
    else:
        singles = fit_many(prep, [([e], None) for e in prep.candidates], opts, "candidates")
        full = set(prep.candidates)
    singles, full = _nest(prep, singles, full, opts)
    for k in full:
        screened_out.pop(k, None)
    return Screening(singles, screened_out, second_chance)
