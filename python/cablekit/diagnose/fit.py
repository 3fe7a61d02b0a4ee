"""Fit candidates: grey-box least squares of one set of effects on the fit runs through the
Rust simulator, scored on the held-out runs it never sees; many fits in parallel threads."""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cablekit._cablekit import ParamSpec
from cablekit.diagnose.data import Run, scored_start
from cablekit.diagnose.prepare import MAX_SUBSTEPS, Options, Prepared
from cablekit.diagnose.progress import Progress
from cablekit.errors import CablekitError, ParameterError, SimulationDivergedError

__all__ = [
    "NESTED",
    "CandidateFit",
    "baseline",
    "carried",
    "combinable",
    "fit_candidate",
    "fit_many",
    "n_free",
    "parameters_out",
    "warm_start",
]

_F = NDArray[np.float64]


@dataclass
class CandidateFit:
    """One fitted candidate (a set of effects) and its scores."""

    effects: list[str]
    params: _F
    specs: list[ParamSpec]
    substeps: int
    converged: bool
    fit_resid: list[_F]
    hold_resid: list[_F]
    cost: float
    param_sd: _F
    iterations: int
    error: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    at_bound: bool = False
    #: parameters left on a bound away from their "off" value
    bound: list[str] = field(default_factory=list)


def _split(prep: Prepared, runs: list[Run], r: _F) -> list[_F]:
    """Flat weighted residual → per run ``(T − start, q)``."""
    out, off = [], 0
    for run in runs:
        n = (len(run) - scored_start(prep.spec.warmup, run)) * prep.q
        out.append(r[off : off + n].reshape(-1, prep.q))
        off += n
    return out


#: full fits (not screens) with at least this many iterations go on once when they run out
RETRY_ITER = 20
#: a fit has converged when two accepted steps in a row each lower the mean squared residual
#: (noise units) by less than this: 50 times finer than the finest difference any decision of
#: the diagnosis resolves (5 % of the noise variance)
GAP_TOL = 1e-3


def fit_candidate(
    prep: Prepared, effects: list[str], theta0: _F | None = None, max_iter: int = 40, head_s: float = 0.0
) -> CandidateFit:
    """Fit ``effects`` on the fit runs, then evaluate on the held-out runs (never fitted).

    With ``head_s > 0`` (a screening fit) the search uses only the first ``head_s`` seconds of
    every fit run — the cheap objective of the core's global stage — and the candidate is then
    scored on the whole fit and held-out runs; its parameters get no standard errors."""
    base = prep.fit0.with_effects(effects, prep.substeps)
    specs = base.param_specs()
    start = np.array([s.initial for s in specs]) if theta0 is None else np.asarray(theta0, dtype=np.float64)
    try:
        # substeps for the stiffest starting point (largest start of every parameter), so the
        # search does not begin in a coarsely integrated, distorted landscape
        corner = np.array([max([s.initial, *s.starts]) for s in specs]) if theta0 is None else start
        sub = min(
            MAX_SUBSTEPS, max(prep.substeps, base.advised_substeps(start), base.advised_substeps(corner))
        )
        problem = base.with_effects(effects, sub)
        search = _search(problem, head_s)
        # without a start: the core's global stage over every parameter (its starts, or a
        # spread of its own), then the local search from the best points; a warm start (a
        # screen's end, a combination's previous fits) goes straight to the local search
        atol = 0.5 * GAP_TOL * search.n_residuals  # GAP_TOL in cost units
        res = search.fit(None if theta0 is None else start, max_iter=max_iter, atol=atol)
        if not res.converged and max_iter >= RETRY_ITER:
            # a full fit that ran out of iterations goes on once from where it stopped
            res = search.fit(res.params, max_iter=max_iter, atol=atol)
        theta = res.params
        need = min(MAX_SUBSTEPS, problem.advised_substeps(theta))
        if need > sub:  # the fitted model is stiffer than the start: refit with enough substeps
            sub = need
            problem = base.with_effects(effects, sub)
            search = _search(problem, head_s)
            res = search.fit(theta, max_iter=max_iter, atol=0.5 * GAP_TOL * search.n_residuals)
            theta = res.params
        # a screen on the head is scored on the whole fit runs
        r_fit = res.residuals if search is problem else problem.residuals(theta)
        r_hold = _held_out_residuals(prep, effects, theta, sub)
    except CablekitError as exc:
        return CandidateFit(
            effects,
            start,
            specs,
            prep.substeps,
            False,
            [],
            [],
            math.inf,
            np.full(len(start), np.nan),
            0,
            error=f"{type(exc).__name__}: {exc}",
        )
    p = len(theta)
    try:
        sd = (
            np.sqrt(np.clip(np.diag(_sandwich(prep, res.jacobian, r_fit)), 0.0, None))
            if search is problem
            else np.full(p, np.nan)
        )
    except np.linalg.LinAlgError:
        sd = np.full(p, np.nan)
    for j, s in enumerate(specs):
        if s.grid:
            sd[j] = np.nan
    return CandidateFit(
        effects,
        theta,
        specs,
        sub,
        bool(res.converged),
        _split(prep, prep.fit_runs, r_fit),
        _split(prep, prep.hold_runs, r_hold),
        0.5 * float(r_fit @ r_fit),
        sd,
        int(res.iterations),
        at_bound=bool(np.any(res.at_bound)),
        bound=_bound_away(res.params, res.at_bound, specs),
    )


def _search(problem: Any, head_s: float) -> Any:
    """The problem a fit searches: the first ``head_s`` seconds of every run (a screen), or the
    whole runs (``head_s`` 0, or runs too short to cut)."""
    return (problem.head(head_s) if head_s > 0 else None) or problem


def _held_out_residuals(prep: Prepared, effects: list[str], theta: _F, sub: int) -> _F:
    """Residuals of the held-out runs at the fitted ``theta``. The held-out runs may drive the
    fitted model harder than the fit runs did (a stiffening law at a larger stretch): when the
    replay diverges at the fit's substeps it is retried with twice as many, up to
    ``MAX_SUBSTEPS``, before the candidate is reported as failed."""
    while True:
        try:
            return prep.hold0.with_effects(effects, sub).residuals(theta)
        except SimulationDivergedError:
            if sub >= MAX_SUBSTEPS:
                raise
            sub = min(MAX_SUBSTEPS, 2 * sub)


def _bound_away(params: _F, at_bound: NDArray[np.bool_], specs: list[ParamSpec]) -> list[str]:
    """Parameters that ended on a bound of their range other than the effect's "off" value (a
    Coulomb level at 0 is the nested model without the effect and is not listed; a creep time
    constant at its smallest allowed value is)."""
    out = []
    for s, v, hit in zip(specs, params, at_bound, strict=True):
        if hit and not s.grid and abs(float(v) - float(s.reference)) > 1e-12 * max(1.0, abs(float(v))):
            out.append(f"{s.effect}:{s.name}")
    return out


def _sandwich(prep: Prepared, jac: _F, r: _F, seconds: float = 1.0) -> _F:
    """Parameter covariance robust to autocorrelation and to a model that is still wrong: the
    cluster (segment) sandwich ``B·(Σ_s g_s g_sᵀ)·B`` with ``B = (JᵀJ)⁺`` and the score
    ``g_s = J_sᵀ r_s`` of each ~1 s segment of the fit runs (Huber–White with segments as
    clusters). With the model right and white residuals it reduces to ``σ²(JᵀJ)⁻¹``."""
    # in column-scaled coordinates (a finite difference across a switch can leave a column of
    # 1e150 beside one of 1e-3), unscaled at the end; a non-finite covariance is NaN, not a warning
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        norms = np.linalg.norm(jac, axis=0)
        d = np.where(np.isfinite(norms) & (norms > 0), norms, 1.0)
        js = np.where(np.isfinite(jac), jac, 0.0) / d
        bread = np.linalg.pinv(js.T @ js)
        meat = np.zeros_like(bread)
        off = 0
        for run in prep.fit_runs:
            rows = (len(run) - scored_start(prep.spec.warmup, run)) * prep.q
            seg = max(prep.q, round(seconds / run.dt) * prep.q)
            for a in range(off, off + rows, seg):
                b = min(a + seg, off + rows)
                g = js[a:b].T @ r[a:b]
                meat += np.outer(g, g)
            off += rows
        cov = (bread @ meat @ bread) / np.outer(d, d)
    return np.where(np.isfinite(cov), cov, np.nan)


def baseline(prep: Prepared) -> CandidateFit:
    """The nominal model scored like a candidate with no effects."""
    theta = np.zeros(0)
    r_fit = prep.fit0.residuals(theta)
    r_hold = prep.hold0.residuals(theta)
    return CandidateFit(
        [],
        theta,
        [],
        prep.substeps,
        True,
        _split(prep, prep.fit_runs, r_fit),
        _split(prep, prep.hold_runs, r_hold),
        0.5 * float(r_fit @ r_fit),
        np.zeros(0),
        0,
    )


def fit_many(
    prep: Prepared,
    jobs: list[tuple[list[str], _F | None]],
    opts: Options,
    label: str,
    max_iter: int = 0,
    head_s: float = 0.0,
) -> list[CandidateFit]:
    """Fit every job (effects, start) in parallel (threads, or ``opts.executor``); ``max_iter``
    and ``head_s`` as in :func:`fit_candidate`."""
    workers = opts.workers or min(len(jobs), os.cpu_count() or 1)
    out: list[CandidateFit | None] = [None] * len(jobs)
    with Progress(len(jobs), label, enabled=opts.progress) as bar:
        if opts.executor is not None:
            return list(opts.executor.map(prep, jobs, max_iter or opts.max_iter, bar, head_s))
        with ThreadPoolExecutor(max_workers=max(1, workers)) as ex:
            futs = {
                ex.submit(fit_candidate, prep, eff, th, max_iter or opts.max_iter, head_s): i
                for i, (eff, th) in enumerate(jobs)
            }
            for f in as_completed(futs):
                i = futs[f]
                out[i] = f.result()
                bar.advance("+".join(jobs[i][0]))
    return [c for c in out if c is not None]


def parameters_out(c: CandidateFit, refit: list[list[float] | None] | None = None) -> list[dict[str, Any]]:
    """The fitted parameters with their linearised ``ci95`` and, when given, ``ci95_refit``."""
    rows = []
    for j, (s, v, sd) in enumerate(zip(c.specs, c.params, c.param_sd, strict=False)):
        half = 1.96 * sd if np.isfinite(sd) else None
        rows.append(
            {
                "effect": s.effect,
                "name": s.name,
                "unit": s.unit,
                "value": float(v),
                "ci95": [float(v - half), float(v + half)] if half is not None else None,
                "ci95_refit": refit[j] if refit is not None else None,
            }
        )
    return rows


def n_free(c: CandidateFit) -> int:
    """Parameters the fit may move (a parameter with lower = upper, such as the break-away of
    the sticking and LuGre friction forms, is part of the law, not of the fit)."""
    return sum(1 for s in c.specs if s.lower < s.upper)


#: effects whose law contains another's as a special case (the simpler one is an alternative
#: when the richer is selected): Stribeck with F_s = F_c is Coulomb friction; Dahl with its
#: break-away at the floor is the sticking Coulomb law
NESTED = {"stribeck_friction": ("coulomb_friction",), "dahl_hysteresis": ("coulomb_friction",)}


def _one_law_twice(prep: Prepared, effects: list[str]) -> bool:
    """Two candidates that are alternatives of one law at one site: the same effect in two
    forms, or an effect beside one nested in it (Coulomb beside Stribeck friction at the joint:
    their sum is a Stribeck law with another F_c)."""
    seen: list[tuple[str, str]] = []
    for k in effects:
        info = prep.info.get(k)
        if info is None:
            continue
        eff, site = info["effect"], info["site"]
        for e2, s2 in seen:
            if s2 == site and (e2 == eff or eff in NESTED.get(e2, ()) or e2 in NESTED.get(eff, ())):
                return True
        seen.append((eff, site))
    return False


def combinable(prep: Prepared, effects: list[str]) -> bool:
    """Whether the candidates can be fitted together: never two alternatives of one law at one
    site (:func:`_one_law_twice`), and the core refuses, e.g., two candidates that would share
    the joint's one bristle state (Dahl hysteresis and the sticking Coulomb or LuGre Stribeck
    friction)."""
    if _one_law_twice(prep, effects):
        return False
    try:
        prep.fit0.with_effects(effects, prep.substeps)
    except ParameterError:
        return False
    return True


def carried(specs: list[ParamSpec], start: _F, source: CandidateFit, source_effect: str, effect: str) -> _F:
    """``start`` (for ``specs``) with ``effect``'s parameters set to the values ``source`` has
    for ``source_effect``'s parameters of the same name, clipped to the bounds: a law replacing
    or containing another starts where that one left what they share (``F_c``)."""
    have = {s.name: v for s, v in zip(source.specs, source.params, strict=False) if s.effect == source_effect}
    out = np.array(start, dtype=float)
    for i, s in enumerate(specs):
        if s.effect == effect and s.name in have:
            out[i] = min(max(have[s.name], s.lower), s.upper)
    return out


def warm_start(prep: Prepared, current: CandidateFit, effects: list[str], single: CandidateFit) -> _F | None:
    """Start a combined fit from the current model's and the single fit's parameters — but not
    from a single fit that ended on a bound: alone, a candidate often absorbs another effect by
    running to a bound (a Coulomb smoothing of 7 rad/s imitating a sensor lag), and that start
    keeps the pair away from the optimum; its parameters then start where its own fit does."""
    specs = prep.fit0.with_effects(effects, prep.substeps).param_specs()
    have = {}
    for src in (single, current) if not single.bound else (current,):
        for s, v in zip(src.specs, src.params, strict=False):
            have[(s.effect, s.name)] = v
    return np.array([have.get((s.effect, s.name), s.initial) for s in specs])
