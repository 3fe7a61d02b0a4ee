"""Screen the candidate library: a short fit of every candidate ranks them, the shortlist is
fitted in full."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cablekit.diagnose.fit import CandidateFit, fit_many
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
        singles += [c for c in quick if c.effects[0] in screened_out]
    else:
        singles = fit_many(prep, [([e], None) for e in prep.candidates], opts, "candidates")
    return Screening(singles, screened_out, second_chance)
