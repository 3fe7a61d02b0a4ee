"""Parameter intervals by refitting on bootstrap segments.

The linearised intervals (``ci95``, a segment-cluster sandwich around the fitted point) collapse
for sharp friction laws: the finite-difference Jacobian is dominated by the few samples at
stick–slip transitions. Here the selected model is refitted on block-bootstrap resamples of the
fit runs instead: every fit run is cut into blocks (each long enough for the warm-up plus three
times as much data), a replicate draws as many blocks as there are, with replacement, and the
selected effects are refitted on it from the fitted point. The 2.5 and 97.5 percentiles of the
refitted values are ``ci95_refit``. No linearisation; the price is one short fit per replicate.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor, as_completed

import numpy as np

from cablekit.diagnose.data import Run
from cablekit.diagnose.fit import CandidateFit, fit_candidate
from cablekit.diagnose.prepare import Options, Prepared, prepare
from cablekit.diagnose.progress import Progress
from cablekit.errors import CablekitError

__all__ = ["blocks", "refit_intervals"]

#: iterations of each replicate's refit (it starts at the fitted point)
REFIT_ITER = 15


def blocks(runs: list[Run], warmup: float, n_per_run: int = 4) -> list[Run]:
    """Cut each run into up to ``n_per_run`` blocks of at least ``4·warmup`` (and 1 s)."""
    out = []
    for run in runs:
        least = max(4.0 * warmup, 1.0)
        n = max(1, min(n_per_run, int(run.duration // least)))
        edges = np.linspace(run.t[0], run.t[-1] + run.dt, n + 1)
        for i in range(n):
            out.append(run.segment(float(edges[i]), float(edges[i + 1]), f"{run.name}#{i}"))
    return out


def refit_intervals(
    prep: Prepared, current: CandidateFit, opts: Options, rng: np.random.Generator
) -> list[list[float] | None]:
    """Per parameter of ``current``: ``[lo, hi]`` from ``opts.interval_refits`` replicates, or
    None when fewer than half of them could be refitted, the parameter is a grid one, or no
    replicate moved it (a flat direction of the cost: a zero-width interval would read as
    certainty where the data say nothing)."""
    pieces = blocks(prep.fit_runs, prep.spec.warmup)
    # the resamples are drawn first, in order, so the intervals do not depend on the threads
    picks = [rng.integers(0, len(pieces), size=len(pieces)) for _ in range(opts.interval_refits)]

    def refit(pick: np.ndarray) -> np.ndarray | None:
        try:
            rep = prepare(prep.spec, [pieces[i] for i in pick], prep.hold_runs[:1])
            c = fit_candidate(rep, current.effects, current.params, REFIT_ITER)
        except CablekitError:
            return None
        return None if c.error else c.params

    workers = opts.workers or min(len(picks), os.cpu_count() or 1)
    got: list[np.ndarray | None] = [None] * len(picks)
    with (
        Progress(opts.interval_refits, "intervals", enabled=opts.progress) as bar,
        ThreadPoolExecutor(max_workers=max(1, workers)) as ex,
    ):
        futs = {ex.submit(refit, pick): i for i, pick in enumerate(picks)}
        for f in as_completed(futs):
            got[futs[f]] = f.result()
            bar.advance()
    draws = [d for d in got if d is not None]
    out: list[list[float] | None] = []
    p = np.array(draws)
    for j, s in enumerate(current.specs):
        v = float(current.params[j])
        if (
            s.grid
            or len(draws) < max(2, opts.interval_refits // 2)
            or float(np.ptp(p[:, j])) <= 1e-9 * max(1.0, abs(v))
        ):
            out.append(None)
        else:
            lo, hi = np.quantile(p[:, j], [0.025, 0.975])
            out.append([float(lo), float(hi)])
    return out
