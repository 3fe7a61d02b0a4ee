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
import os
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cablekit._cablekit import JointProblem, effect_catalogue
from cablekit.diagnose import localise
from cablekit.diagnose.data import Run, check_units
from cablekit.diagnose.progress import Progress
from cablekit.diagnose.report import SCHEMA
from cablekit.diagnose.spec import NOT_IN_TRANSMISSION, OUTPUTS, ModelSpec
from cablekit.errors import CablekitError, DataError

__all__ = ["CandidateFit", "Options", "Prepared", "diagnose", "prepare"]

_F = NDArray[np.float64]

#: held-out mean squared residual (noise units) below which the gap counts as noise
NOISE_LEVEL = 1.15
#: smallest held-out share of the gap an effect must close to count
MIN_CLOSED = 0.05
#: RK4 substeps per sample a candidate may use; beyond, the stiff trial points diverge and the
#: fit rejects them, which bounds e.g. how sharp a fitted friction sign can get
MAX_SUBSTEPS = 16


@dataclass
class Options:
    """Knobs of the diagnosis (defaults are what the self-test and the docs use)."""

    max_effects: int = 3
    #: candidates fitted in full after the screen (by fit cost of a short fit); 0 = all
    shortlist: int = 14
    #: and the best of each channel's own fit cost, however they rank pooled
    shortlist_per_channel: int = 2
    #: iterations of the screening fits
    screen_fit_iter: int = 4
    #: iterations of the screening fits of later selection rounds, and how many are refined
    screen_iter: int = 5
    refine: int = 3
    bootstrap: int = 1000
    segment_s: float = 1.0
    max_iter: int = 30
    workers: int = 0
    seed: int = 0
    progress: bool = True


@dataclass
class Prepared:
    """Data and problems shared by every candidate fit."""

    spec: ModelSpec
    fit_runs: list[Run]
    hold_runs: list[Run]
    channel_names: list[str]
    columns: list[str]
    sigma: _F
    substeps: int
    fit0: JointProblem
    hold0: JointProblem
    candidates: list[str]
    skipped: dict[str, str]
    warnings: list[str] = field(default_factory=list)
    #: candidate id → its description from the core (effect, site, form, sentence, parameters)
    info: dict[str, dict[str, Any]] = field(default_factory=dict)

    @property
    def q(self) -> int:
        return len(self.channel_names)


@dataclass
class CandidateFit:
    """One fitted candidate (a set of effects) and its scores."""

    effects: list[str]
    params: _F
    specs: list[dict[str, Any]]
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


def _run_dict(spec: ModelSpec, run: Run, columns: list[str], model: Any = None) -> dict[str, Any]:
    measured = np.column_stack([run.column(c) for c in columns])
    cols = [run.column(c) for c in spec.inputs]
    if spec.servo():  # references: angles then rates (given, or the angles' derivative)
        rates = spec.extra.get("dq_m_ref")
        cols += [run.column(c) for c in rates] if rates else [np.gradient(c, run.dt) for c in cols]
    d: dict[str, Any] = {
        "dt": run.dt,
        "input": np.ascontiguousarray(cols[0] if len(cols) == 1 else np.column_stack(cols)),
        "measured": np.ascontiguousarray(measured),
        "start": round(spec.warmup / run.dt),
    }
    if spec.coupled:
        d["coupled"] = np.ascontiguousarray(run.column(spec.coupled))
    if spec.external:
        ext = [run.column(c) for c in spec.external]
        d["external"] = np.ascontiguousarray(ext[0] if len(ext) == 1 else np.column_stack(ext))
    if spec.kind == "cable_transmission" and model is not None:
        d["x0"] = _transmission_x0(spec, run, model)
    return d


def _transmission_x0(spec: ModelSpec, run: Run, model: Any) -> _F:
    """Initial state of a transmission run from its first measured angles, at rest: a link's
    missing motor (joint) angle follows from its joint (motor) angle through the rigid-cable
    kinematics ``q_m = T·q_l``; unmeasured links start at 0."""
    n = spec.links
    q_m = np.full(n, np.nan)
    q_l = np.full(n, np.nan)
    for out, col in spec.outputs:
        base, idx = out.rstrip("0123456789"), out[len(out.rstrip("0123456789")) :]
        if base == "q_m":
            q_m[int(idx) - 1] = run.column(col)[0]
        elif base == "q_l":
            q_l[int(idx) - 1] = run.column(col)[0]
    if not np.isnan(q_m).any():
        # motor encoders resolve the cable stretch ~100x better than joint encoders: start
        # from the motor angles with the cables at rest length
        q_l = model.motor_to_joint(q_m)
    else:
        q_l = np.where(np.isnan(q_l), 0.0, q_l)
        q_m = np.where(np.isnan(q_m), model.joint_to_motor(q_l), q_m)
    x0 = np.zeros(4 * n)
    x0[0::4], x0[2::4] = q_m, q_l
    return x0


def prepare(spec: ModelSpec, fit_runs: list[Run], hold_runs: list[Run]) -> Prepared:
    """Validate runs against the model file, estimate noise, build the base problems."""
    if not fit_runs:
        raise DataError("the diagnosis needs at least one fit run")
    if not hold_runs:
        raise DataError("the diagnosis needs at least one held-out run (a different trajectory, load or rig)")
    for run in fit_runs + hold_runs:
        check_units(run, spec.units())
        if spec.warmup >= 0.5 * run.duration:
            raise DataError(
                f"run {run.name!r} ({run.duration:g} s) is too short for a warm-up of {spec.warmup:g} s"
            )
    dts = {round(r.dt, 12) for r in fit_runs + hold_runs}
    if max(dts) > 1.01 * min(dts):
        raise DataError(f"runs have different sample intervals {sorted(dts)}; resample them to one")
    names = [o for o, _ in spec.outputs]
    columns = [c for _, c in spec.outputs]
    sigma = np.array(
        [math.sqrt(np.mean([localise.noise_sigma(r.column(c)) ** 2 for r in fit_runs])) for c in columns]
    )
    chans = [(spec.output(o)[0], 1.0 / s, spec.output(o)[2]) for o, s in zip(names, sigma, strict=False)]
    model = spec.model()
    fit_dicts = [_run_dict(spec, r, columns, model) for r in fit_runs]
    hold_dicts = [_run_dict(spec, r, columns, model) for r in hold_runs]
    servo = spec.servo()
    probe = JointProblem(model, chans, fit_dicts, [], 1, servo)
    substeps = spec.substeps or max(1, probe.advised_substeps(np.zeros(0)))
    fit0 = JointProblem(model, chans, fit_dicts, [], substeps, servo)
    hold0 = JointProblem(model, chans, hold_dicts, [], substeps, servo)
    all_effects = [e["name"] for e in effect_catalogue()]
    wanted = spec.effects or []
    library = [
        c for c in probe.candidate_library() if not wanted or c["effect"] in wanted or c["id"] in wanted
    ]
    # explicitly named candidates outside the default library (a form or site the user asks for)
    for w in wanted:
        if "@" in w and all(c["id"] != w for c in library):
            library.append(probe.describe(w))
    info = {c["id"]: c for c in library}
    skipped: dict[str, str] = {}
    has_sensor = any(spec.output(o)[2] for o in names)
    motor_tension = any(o.startswith("tension_motor") or o == "net_motor_force" for o in names)
    offered = {c["effect"] for c in library}
    for e in all_effects:
        if e in offered:
            continue
        if wanted and not any(w.split("@")[0] == e for w in wanted):
            skipped[e] = "not in the model file's [diagnosis] effects"
        elif spec.kind == "cable_transmission" and e in NOT_IN_TRANSMISSION:
            skipped[e] = "no counterpart in the cable transmission model"
        elif e == "coupling" and spec.kind == "cable_transmission" and spec.links < 2:
            skipped[e] = "a single link has no coupling"
        elif e == "coupling" and spec.kind == "antagonistic_joint" and not spec.coupled:
            skipped[e] = "no coupled-axis column in [inputs]"
        elif e in ("sensor_lag", "sensor_sampling", "sensor_gain_bias") and not has_sensor:
            skipped[e] = "no force-sensor channel measured"
        elif e == "capstan_friction" and not motor_tension:
            skipped[e] = "no motor-side tension measured"
        else:
            skipped[e] = "no site of this plant where it can act on the measured channels"
    candidates = list(info)
    warnings = _servo_saturation(spec, model, fit_runs + hold_runs, fit_dicts + hold_dicts, substeps)
    return Prepared(
        spec,
        fit_runs,
        hold_runs,
        names,
        columns,
        sigma,
        substeps,
        fit0,
        hold0,
        candidates,
        skipped,
        warnings,
        info,
    )


#: share of a run's samples at the servo's torque limit above which the replay is flagged
SATURATION_WARN = 0.02


def _servo_saturation(
    spec: ModelSpec, model: Any, runs: list[Run], dicts: list[dict[str, Any]], substeps: int
) -> list[str]:
    """Warnings for runs whose nominal servo replay sits at the torque limit: a saturated servo
    is open loop, and an open-loop replay of a frictional transmission amplifies any initial
    error (docs/diagnosis.md)."""
    servo = spec.servo()
    if not servo:
        return []
    n = spec.links
    limit = np.asarray(servo[2])
    chans = [(5 * n + i, 1.0, False) for i in range(n)]
    out = []
    for run, d in zip(runs, dicts, strict=True):
        probe = JointProblem(model, chans, [{**d, "measured": np.zeros((len(run), n))}], [], substeps, servo)
        tau = probe.predict(np.zeros(0), 0)
        share = np.mean(np.abs(tau) >= 0.99 * limit, axis=0)
        for i in np.flatnonzero(share > SATURATION_WARN):
            out.append(
                f"run {run.name!r}: the nominal servo replay holds axis {i + 1} at its torque limit "
                f"{100 * share[i]:.0f} % of the time; a saturated servo is open loop and its replay "
                "is sensitive to the initial state: slow the references or raise the limit"
            )
    return out


def _split(prep: Prepared, runs: list[Run], r: _F) -> list[_F]:
    """Flat weighted residual → per run ``(T − start, q)``."""
    out, off = [], 0
    for run in runs:
        n = (len(run) - round(prep.spec.warmup / run.dt)) * prep.q
        out.append(r[off : off + n].reshape(-1, prep.q))
        off += n
    return out


def _integrated_time(r: _F) -> float:
    """Integrated autocorrelation time (samples) of a residual, ≥ 1 (for effective sample size)."""
    r = r - r.mean()
    n = min(len(r), 1 << 15)
    spec = np.fft.rfft(r[:n], 2 * n)
    ac = np.fft.irfft(spec * np.conj(spec))[:n]
    if ac[0] <= 0:
        return 1.0
    rho = ac / ac[0]
    neg = np.flatnonzero(rho < 0.05)
    cut = int(neg[0]) if neg.size else n
    return max(1.0, 1.0 + 2.0 * float(rho[1:cut].sum()))


#: a fit whose cost fell by less than this share from its start made no progress
STUCK = 1.0 - 1e-6


def fit_candidate(
    prep: Prepared, effects: list[str], theta0: _F | None = None, max_iter: int = 40
) -> CandidateFit:
    """Fit ``effects`` on the fit runs, then evaluate on the held-out runs (never fitted)."""
    base = prep.fit0.with_effects(effects, prep.substeps)
    specs = base.param_specs()
    start = (
        np.array([s["initial"] for s in specs]) if theta0 is None else np.asarray(theta0, dtype=np.float64)
    )
    try:
        # substeps for the stiffest starting point (largest start of every parameter), so the
        # search does not begin in a coarsely integrated, distorted landscape
        corner = np.array([max([s["initial"], *s["starts"]]) for s in specs]) if theta0 is None else start
        sub = min(
            MAX_SUBSTEPS, max(prep.substeps, base.advised_substeps(start), base.advised_substeps(corner))
        )
        problem = base.with_effects(effects, sub)
        res = problem.fit(start, max_iter=max_iter)
        if theta0 is None and res["cost"] >= STUCK * res["initial_cost"] and any(s["starts"] for s in specs):
            # the cost is flat at the default start (a pretension loss before any cable
            # slackens): search the parameters' start grid, refine the best start
            res = problem.fit(None, max_iter=max_iter)
        theta = res["params"]
        need = min(MAX_SUBSTEPS, problem.advised_substeps(theta))
        if need > sub:  # the fitted model is stiffer than the start: refit with enough substeps
            sub = need
            problem = base.with_effects(effects, sub)
            res = problem.fit(theta, max_iter=max_iter)
            theta = res["params"]
        hold = prep.hold0.with_effects(effects, sub)
        r_hold = hold.residuals(theta)
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
    r_fit = res["residuals"]
    p = len(theta)
    try:
        sd = np.sqrt(np.clip(np.diag(_sandwich(prep, res["jacobian"], r_fit)), 0.0, None))
    except np.linalg.LinAlgError:
        sd = np.full(p, np.nan)
    for j, s in enumerate(specs):
        if s["grid"]:
            sd[j] = np.nan
    return CandidateFit(
        effects,
        theta,
        specs,
        sub,
        bool(res["converged"]),
        _split(prep, prep.fit_runs, r_fit),
        _split(prep, prep.hold_runs, r_hold),
        float(res["cost"]),
        sd,
        int(res["iterations"]),
        at_bound=bool(np.any(res["at_bound"])),
    )


def _sandwich(prep: Prepared, jac: _F, r: _F, seconds: float = 1.0) -> _F:
    """Parameter covariance robust to autocorrelation and to a model that is still wrong: the
    cluster (segment) sandwich ``B·(Σ_s g_s g_sᵀ)·B`` with ``B = (JᵀJ)⁺`` and the score
    ``g_s = J_sᵀ r_s`` of each ~1 s segment of the fit runs (Huber–White with segments as
    clusters). With the model right and white residuals it reduces to ``σ²(JᵀJ)⁻¹``."""
    bread = np.linalg.pinv(jac.T @ jac)
    meat = np.zeros_like(bread)
    off = 0
    for run in prep.fit_runs:
        rows = (len(run) - round(prep.spec.warmup / run.dt)) * prep.q
        seg = max(prep.q, round(seconds / run.dt) * prep.q)
        for a in range(off, off + rows, seg):
            b = min(a + seg, off + rows)
            g = jac[a:b].T @ r[a:b]
            meat += np.outer(g, g)
        off += rows
    return bread @ meat @ bread


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


def _segments(resid: list[_F], dt: float, seconds: float) -> tuple[_F, _F]:
    """Per-segment sum of squared residuals (all channels) and sample counts."""
    sse, cnt = [], []
    n_seg = max(1, round(seconds / dt))
    for r in resid:
        e = np.sum(r * r, axis=1)
        for i in range(0, len(e), n_seg):
            chunk = e[i : i + n_seg]
            if len(chunk) >= n_seg // 2:
                sse.append(float(chunk.sum()))
                cnt.append(float(chunk.size * r.shape[1]))
    return np.array(sse), np.array(cnt)


def gap(resid: list[_F]) -> float:
    """Mean squared weighted residual (noise units; 1 = noise only)."""
    num = sum(float(np.sum(r * r)) for r in resid)
    den = sum(r.size for r in resid)
    return num / den if den else math.nan


def closed_fraction(before: float, after: float) -> float:
    """Share of the excess gap ``G − 1`` that closed (≤ 1; negative if it grew)."""
    eb = before - 1.0
    if eb <= 1e-12:
        return 0.0
    return min(1.0, (before - after) / eb)


def compare(
    before: list[_F], after: list[_F], dt: float, opts: Options, rng: np.random.Generator
) -> dict[str, Any]:
    """Held-out comparison with a segment bootstrap: closed fraction, interval, significance."""
    sb, cnt = _segments(before, dt, opts.segment_s)
    sa, _ = _segments(after, dt, opts.segment_s)
    g_b, g_a = sb.sum() / cnt.sum(), sa.sum() / cnt.sum()
    point = closed_fraction(g_b, g_a)
    idx = rng.integers(0, len(sb), size=(opts.bootstrap, len(sb)))
    bb = sb[idx].sum(axis=1) / cnt[idx].sum(axis=1)
    ba = sa[idx].sum(axis=1) / cnt[idx].sum(axis=1)
    closed = np.array([closed_fraction(x, y) for x, y in zip(bb, ba, strict=False)])
    improvement = bb - ba
    lo, hi = np.quantile(closed, [0.025, 0.975])
    p_worse = float(np.mean(improvement <= 0.0))
    return {
        "gap_before": g_b,
        "gap_after": g_a,
        "closed_fraction": point,
        "interval": [float(lo), float(hi)],
        "p_no_improvement": p_worse,
        "significant": bool(p_worse < 0.025 and point >= MIN_CLOSED),
    }


def _bic(c: CandidateFit, n_eff: float) -> float:
    g = gap(c.fit_resid)
    return n_eff * math.log(max(g, 1e-300)) + len(c.params) * math.log(n_eff)


#: pairs of effects that look alike on some data, and the experiment that separates them
SEPARATING = {
    frozenset({"dahl_hysteresis", "stribeck_friction"}): (
        "add small-amplitude motions (below the break-away angle) and steady sliding at several speeds: "
        "Dahl shows pre-sliding stiffness, Stribeck friction falls with speed"
    ),
    frozenset(
        {"sensor_lag", "time_delay"}
    ): "excite at several frequencies (a chirp): a delay's phase grows linearly with frequency, a "
    "lag's saturates at 90°",
    frozenset(
        {"sensor_lag", "cable_damping"}
    ): "vary the speed at a fixed frequency content and add a second sensor: damping scales with "
    "speed, a sensor lag with the signal's rate of change at every load",
    frozenset(
        {"sensor_lag", "viscous_friction"}
    ): "record the joint angle too: viscous friction changes the motion, a sensor lag does not",
    frozenset(
        {"coulomb_friction", "dahl_hysteresis"}
    ): "add small-amplitude motions (below the break-away angle) and slow reversals: Dahl shows "
    "pre-sliding stiffness, Coulomb does not",
    frozenset(
        {"coulomb_friction", "stribeck_friction"}
    ): "add slow reversals (under 10 % of the present speed): Stribeck friction peaks at low speed",
    frozenset(
        {"coulomb_friction", "capstan_friction"}
    ): "add slow reversals at two load levels: capstan loss scales with tension, Coulomb friction does not",
    frozenset(
        {"dahl_hysteresis", "backlash"}
    ): "add slow reversals at two load levels: play gives a fixed dead band, Dahl friction a "
    "load-independent rounded loop",
    frozenset(
        {"coulomb_friction", "backlash"}
    ): "add slow reversals at two load levels and record the joint angle: play shows as a dead "
    "band in angle, friction does not",
    frozenset(
        {"slack", "sensor_gain_bias"}
    ): "repeat at two pretension levels: a sensor bias stays, lost pretension changes where the "
    "cables slacken",
    frozenset(
        {"creep", "sensor_gain_bias"}
    ): "hold still at two tension levels for longer than the creep time constant: creep relaxes, a "
    "bias does not",
    frozenset(
        {"inertia_error", "cable_damping"}
    ): "add faster accelerations (higher-frequency content): inertia scales with acceleration, "
    "damping with speed",
    frozenset(
        {"nonlinear_stiffness", "sensor_gain_bias"}
    ): "repeat at two pretension levels: a stiffening law changes with the tension level, a gain "
    "error does not",
}


def separating_experiment(a: str, b: str) -> str:
    """The experiment that separates two candidates (ids or effect names)."""
    ea, eb = a.split("@")[0], b.split("@")[0]
    if ea == eb:
        return (
            "the same effect at two sites: add a sensor on each side of the suspected sites (motor "
            "side and joint side), or repeat with one cable's pretension changed"
        )
    return SEPARATING.get(
        frozenset({ea, eb}),
        "repeat the run at another frequency and another load level, and add an independent sensor "
        "(for example the joint angle)",
    )


def identifiability(
    prep: Prepared, base: CandidateFit, fits: dict[str, CandidateFit], scores: dict[str, dict[str, Any]]
) -> dict[str, list[dict[str, Any]]]:
    """Collinear residual signatures among the candidates that close a real share of the gap."""
    r0 = np.concatenate([r.ravel() for r in base.fit_resid])
    sig = {}
    for name, c in fits.items():
        if c.error or scores[name]["closed_fraction"] < MIN_CLOSED:
            continue
        v = r0 - np.concatenate([r.ravel() for r in c.fit_resid])
        n = np.linalg.norm(v)
        if n > 0:
            sig[name] = v / n
    notes: dict[str, list[dict[str, Any]]] = {k: [] for k in fits}
    names = sorted(sig, key=lambda k: -scores[k]["closed_fraction"])
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            cos = float(sig[a] @ sig[b])
            ca, cb = scores[a]["closed_fraction"], scores[b]["closed_fraction"]
            if abs(cos) > 0.9 and cb >= 0.8 * ca:
                exp = separating_experiment(a, b)
                notes[a].append({"with": b, "signature_cosine": cos, "experiment": exp})
                notes[b].append({"with": a, "signature_cosine": cos, "experiment": exp})
    return notes


def _pmap(
    prep: Prepared, jobs: list[tuple[list[str], _F | None]], opts: Options, label: str, max_iter: int = 0
) -> list[CandidateFit]:
    workers = opts.workers or min(len(jobs), os.cpu_count() or 1)
    out: list[CandidateFit | None] = [None] * len(jobs)
    with Progress(len(jobs), label, enabled=opts.progress) as bar:
        with ThreadPoolExecutor(max_workers=max(1, workers)) as ex:
            futs = {
                ex.submit(fit_candidate, prep, eff, th, max_iter or opts.max_iter): i
                for i, (eff, th) in enumerate(jobs)
            }
            for f in as_completed(futs):
                i = futs[f]
                out[i] = f.result()
                bar.advance("+".join(jobs[i][0]))
    return [c for c in out if c is not None]


def _params_out(c: CandidateFit) -> list[dict[str, Any]]:
    rows = []
    for s, v, sd in zip(c.specs, c.params, c.param_sd, strict=False):
        half = 1.96 * sd if np.isfinite(sd) else None
        rows.append(
            {
                "effect": s["effect"],
                "name": s["name"],
                "unit": s["unit"],
                "value": float(v),
                "ci95": [float(v - half), float(v + half)] if half is not None else None,
            }
        )
    return rows


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


def _channel_cost(c: CandidateFit, ch: int) -> float:
    return float(sum(float(np.sum(r[:, ch] ** 2)) for r in c.fit_resid))


def _shortlist(cands: list[CandidateFit], n: int, per_channel: int) -> list[CandidateFit]:
    """The ``n`` candidates of lowest pooled fit cost, then the ``per_channel`` best of each
    channel's own cost not yet in: the pooled cost is dominated by the channel with the largest
    gap in noise units, and an effect that shows on another channel only (a compliance seen by
    the joint encoder, not by the force sensor) must still reach the full fit."""
    ranked = sorted(cands, key=lambda c: c.cost)
    keep = ranked[:n]
    q = min((c.fit_resid[0].shape[1] if c.fit_resid else 0) for c in cands) if cands else 0
    for ch in range(q if per_channel > 0 else 0):
        for c in sorted(ranked[n:], key=lambda c: _channel_cost(c, ch))[:per_channel]:
            if not any(c is k for k in keep):
                keep.append(c)
    return keep


def channel_changes(
    prep: Prepared, before: list[_F], after: list[_F], dt: float, opts: Options, rng: np.random.Generator
) -> list[dict[str, Any]]:
    """Held-out gap of each channel before and after, with the segment bootstrap of
    :func:`compare`. A channel is ``worsened`` when its gap ends above the noise level and grew by
    at least 10 %, or by at least 5 % when the growth is significant (in 97.5 % of the bootstrap
    resamples): the pooled gap is dominated by the channel with the largest gap in noise units,
    so a selected effect can make a small channel worse while the headline improves, and a slow
    residual (a hysteresis loop at 0.2 Hz) leaves few independent segments to prove it."""
    out = []
    for c, name in enumerate(prep.channel_names):
        cmp_ = compare([r[:, [c]] for r in before], [r[:, [c]] for r in after], dt, opts, rng)
        g_b, g_a = cmp_["gap_before"], cmp_["gap_after"]
        p_better = 1.0 - cmp_["p_no_improvement"]  # share of resamples in which it improved
        significantly_worse = bool(p_better < 0.025)
        worsened = bool(g_a > NOISE_LEVEL and g_a > (1.05 if significantly_worse else 1.10) * g_b)
        out.append(
            {
                "channel": name,
                "gap_before": g_b,
                "gap_after": g_a,
                "change": g_a / g_b - 1.0 if g_b > 0 else 0.0,
                "closed_fraction": cmp_["closed_fraction"],
                "interval": cmp_["interval"],
                "worsened": worsened,
                "significantly_worse": significantly_worse,
                # a significant improvement of a channel whose gap is above the noise
                "better": bool(cmp_["significant"] and g_b > NOISE_LEVEL),
            }
        )
    return out


def diagnose(
    spec: ModelSpec, fit_runs: list[Run], hold_runs: list[Run], opts: Options | None = None
) -> dict[str, Any]:
    """Run the whole diagnosis; returns the JSON-ready result (see docs/diagnosis.md)."""
    opts = opts or Options()
    rng = np.random.default_rng(opts.seed)
    prep = prepare(spec, fit_runs, hold_runs)
    base = baseline(prep)
    dt = prep.fit_runs[0].dt
    where = localise_all(prep, base)
    g_hold = gap(base.hold_resid)
    g_fit = gap(base.fit_resid)
    sb, cnt = _segments(base.hold_resid, dt, opts.segment_s)
    idx = rng.integers(0, len(sb), size=(opts.bootstrap, len(sb)))
    g_lo = float(np.quantile(sb[idx].sum(axis=1) / cnt[idx].sum(axis=1), 0.025))
    gap_significant = g_hold > NOISE_LEVEL and g_lo > 1.0
    # every applicable candidate alone: a short fit of each screens, the shortlist is fitted in
    # full from where its screen ended
    screened_out: dict[str, str] = {}
    #: screened-out candidates still offered to later selection rounds: among the best few on
    #: one channel's own cost, they may matter once the dominant channel's effect is in
    second_chance: set[str] = set()
    if opts.shortlist and len(prep.candidates) > opts.shortlist:
        quick = _pmap(prep, [([e], None) for e in prep.candidates], opts, "screen", opts.screen_fit_iter)
        ok = [c for c in quick if not c.error]
        keep = _shortlist(ok, opts.shortlist, opts.shortlist_per_channel)
        second_chance = {c.effects[0] for c in _shortlist(ok, 0, 2 * opts.shortlist_per_channel)}
        best_cost = keep[0].cost if keep else math.nan
        cut = keep[min(opts.shortlist, len(keep)) - 1].cost if keep else math.nan
        for c in quick:
            if c.error:
                screened_out[c.effects[0]] = f"screen fit failed: {c.error}"
            elif c not in keep:
                screened_out[c.effects[0]] = (
                    f"screened out: after a {opts.screen_fit_iter}-iteration fit its fit-run cost was "
                    f"{c.cost:.4g} (shortlist of {opts.shortlist} ends at {cut:.4g}, "
                    f"best {best_cost:.4g}) and it was not among the best {opts.shortlist_per_channel} "
                    "on any channel"
                )
        singles = _pmap(prep, [(c.effects, c.params) for c in keep], opts, "candidates")
        singles += [c for c in quick if c.effects[0] in screened_out]
    else:
        singles = _pmap(prep, [([e], None) for e in prep.candidates], opts, "candidates")
    fits = {c.effects[0]: c for c in singles}
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
    n_eff = sum(r.shape[0] for r in base.fit_resid) / _integrated_time(
        np.concatenate([r[:, 0] for r in base.fit_resid])
    )
    notes = identifiability(prep, base, fits, scores)
    ranked = sorted(
        fits,
        key=lambda k: (
            k in screened_out,
            -scores[k]["closed_fraction"],
            _bic(fits[k], n_eff) if not fits[k].error else math.inf,
        ),
    )
    ranked = parsimony([k for k in ranked if k not in screened_out], fits, scores) + [
        k for k in ranked if k in screened_out
    ]
    # forward selection
    chosen: list[str] = []
    current = base
    current_fit: CandidateFit = base
    steps = []
    if gap_significant:
        pool = [k for k in ranked if scores[k]["significant"]]
        for round_ in range(opts.max_effects):
            if round_ == 0:
                trials = [fits[k] for k in pool[: opts.refine + 2]]
            else:
                # screen every remaining candidate with a few iterations from a warm start, then
                # refine the most promising ones (by fit cost: held-out data stays for scoring)
                others = [
                    k
                    for k in ranked
                    if k not in chosen and not fits[k].error and (k not in screened_out or k in second_chance)
                ]
                jobs = [([*chosen, k], _warm_start(prep, current_fit, [*chosen, k], fits[k])) for k in others]
                screened = _pmap(prep, jobs, opts, f"round {round_ + 1}", opts.screen_iter) if jobs else []
                screened = _shortlist([c for c in screened if not c.error], opts.refine, 1)
                jobs = [(c.effects, c.params) for c in screened]
                trials = _pmap(prep, jobs, opts, "  refine", opts.max_iter) if jobs else []
            # a trial that makes a measured channel significantly worse on held-out data is
            # contradicted by that channel: it is taken only when every trial does so
            best, best_cmp, best_key = None, None, None
            g_cur = gap(current.hold_resid)
            for t in trials:
                if t.error:
                    continue
                cmp_ = compare(current.hold_resid, t.hold_resid, dt, opts, rng)
                ch = channel_changes(prep, current.hold_resid, t.hold_resid, dt, opts, rng)
                worse = any(c["worsened"] for c in ch)
                if worse and round_ > 0:
                    continue  # a later step never trades one channel for another
                # practical significance: a real share of the original gap, most of a remainder
                # that is still above the noise (a small second effect behind a large first
                # one), or a quarter of one channel's remaining gap (an effect the pooled gap,
                # dominated by another channel, cannot see)
                g_new = gap(t.hold_resid)
                practical = (
                    g_cur - g_new >= MIN_CLOSED * (g_hold - 1.0)
                    or (g_cur > NOISE_LEVEL and g_cur - g_new >= 0.5 * (g_cur - 1.0))
                    or any(c["better"] and c["closed_fraction"] >= 0.25 for c in ch)
                )
                ok = cmp_["p_no_improvement"] < 0.025 and practical and not worse
                key = (ok, cmp_["closed_fraction"])
                if best_key is None or key > best_key:
                    best, best_cmp, best_key = t, cmp_, key
            if best is None or best_cmp is None or best_key is None:
                break
            if not best_key[0] and not (round_ == 0 and best_cmp["significant"]):
                break  # round 1 may take a significant effect that worsens a channel (flagged)
            added = [e for e in best.effects if e not in chosen]
            chosen = sorted(set(chosen) | set(added), key=best.effects.index)
            ch = channel_changes(prep, current.hold_resid, best.hold_resid, dt, opts, rng)
            steps.append(
                {
                    "added": added,
                    "held_out": best_cmp,
                    "worsened_channels": [c["channel"] for c in ch if c["worsened"]],
                }
            )
            current = best
            current_fit = best
            if gap(current.hold_resid) < NOISE_LEVEL:
                break
    total = compare(base.hold_resid, current.hold_resid, dt, opts, rng)
    total_fit = {
        "gap_before": g_fit,
        "gap_after": gap(current.fit_resid),
        "closed_fraction": closed_fraction(g_fit, gap(current.fit_resid)),
    }
    channels = channel_changes(prep, base.hold_resid, current.hold_resid, dt, opts, rng)
    worse = [c for c in channels if c["worsened"]] if chosen else []
    flags = [
        f"the selected effects make channel {c['channel']} worse on held-out data "
        f"(gap {c['gap_before']:.3g} -> {c['gap_after']:.3g}, {c['change']:+.0%})"
        for c in worse
    ]
    if not gap_significant:
        verdict = "no_significant_gap"
    elif chosen and not worse and (gap(current.hold_resid) < NOISE_LEVEL or total["closed_fraction"] >= 0.8):
        verdict = "explained"
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
                "parameters": _params_out(c) if not c.error else [],
                "fit": {
                    "gap_before": g_fit,
                    "gap_after": gap(c.fit_resid) if not c.error else None,
                    "closed_fraction": closed_fraction(g_fit, gap(c.fit_resid)) if not c.error else None,
                    "bic": _bic(c, n_eff) if not c.error else None,
                },
                "held_out": sc
                | {
                    "closed_fraction": sc["closed_fraction"] if math.isfinite(sc["closed_fraction"]) else None
                },
                "identifiability": notes.get(k, []),
                "converged": c.converged,
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
            "parameters": _params_out(current) if chosen else [],
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
        "where": {k: v for k, v in where.items() if not k.startswith("_")},
        "gap": {
            "fit": g_fit,
            "held_out": g_hold,
            "held_out_lower": g_lo,
            "noise_level": NOISE_LEVEL,
            "significant": gap_significant,
        },
        "skipped": prep.skipped,
        "meta": {
            "model": spec.to_dict(),
            "fit_runs": [{"name": r.name, "samples": len(r), "dt": r.dt, "notes": r.notes} for r in fit_runs],
            "held_out_runs": [
                {"name": r.name, "samples": len(r), "dt": r.dt, "notes": r.notes} for r in hold_runs
            ],
            "channels": [
                {"output": o, "column": c, "noise_sigma": float(s)}
                for o, c, s in zip(prep.channel_names, prep.columns, prep.sigma, strict=False)
            ],
            "substeps": prep.substeps,
            "candidates": prep.candidates,
            "screened_out": screened_out,
            "warnings": prep.warnings,
            "options": {k: v for k, v in vars(opts).items() if k != "progress"},
        },
    }
    result["_internal"] = {
        "prep": prep,
        "base": base,
        "current": current,
        "fits": fits,
        "hold_masks": where["_hold_masks"],
    }
    return result


def _status(c: CandidateFit, screened: str | None) -> str:
    """``failed`` (the fit raised), ``screened_out`` (not on the shortlist), ``at_bound`` (a
    parameter ended on a bound), ``not_converged`` or ``converged``."""
    if c.error:
        return "failed"
    if screened:
        return "screened_out"
    if c.at_bound:
        return "at_bound"
    return "converged" if c.converged else "not_converged"


def parsimony(
    ranked: list[str], fits: dict[str, CandidateFit], scores: dict[str, dict[str, Any]]
) -> list[str]:
    """Reorder so that, at each rank, the candidate with the fewest parameters among those whose
    held-out remaining gap is equivalent (within 25 % of it plus 5 % of the noise variance) comes
    first: a nested, richer effect must earn its extra parameters on held-out data."""

    def excess(k: str) -> float:
        g = scores[k]["gap_after"]
        return max(float(g) - 1.0, 0.0) if math.isfinite(g) else math.inf

    order = list(ranked)
    for i in range(len(order)):
        ref = excess(order[i])
        if not math.isfinite(ref):
            break
        same = [k for k in order[i:] if excess(k) <= 1.25 * ref + 0.05]
        pick = min(same, key=lambda k: (len(fits[k].params), excess(k)))
        order.remove(pick)
        order.insert(i, pick)
    return order


def _warm_start(prep: Prepared, current: CandidateFit, effects: list[str], single: CandidateFit) -> _F | None:
    """Start a combined fit from the current model's and the single fit's parameters."""
    specs = prep.fit0.with_effects(effects, prep.substeps).param_specs()
    have = {}
    for src in (single, current):
        for s, v in zip(src.specs, src.params, strict=False):
            have[(s["effect"], s["name"])] = v
    return np.array([have.get((s["effect"], s["name"]), s["initial"]) for s in specs])


def _nominal_contact(prep: Prepared, runs: list[Run]) -> list[NDArray[np.bool_]] | None:
    """Per run, where the nominal model is in contact (contact force > 0); None without contact."""
    if "contact_angle" not in prep.spec.parameters:
        return None
    model = prep.spec.model()
    dicts = [_run_dict(prep.spec, r, prep.columns, model) for r in runs]
    for d in dicts:
        d["measured"] = np.zeros((len(d["input"]), 1))
    probe = JointProblem(model, [(OUTPUTS["contact_force"][0], 1.0, True)], dicts, [], prep.substeps)
    return [probe.predict(np.zeros(0), i)[:, 0] > 0.0 for i in range(len(runs))]


def localise_all(prep: Prepared, base: CandidateFit) -> dict[str, Any]:
    """Conditions, whiteness, cross-correlation and loops of the nominal residual."""
    out: dict[str, Any] = {}
    for label, runs, resid in (
        ("fit", prep.fit_runs, base.fit_resid),
        ("held_out", prep.hold_runs, base.hold_resid),
    ):
        masks = []
        energies = []
        contact = _nominal_contact(prep, runs)
        for i, (run, r) in enumerate(zip(runs, resid, strict=False)):
            start = round(prep.spec.warmup / run.dt)
            x = run.column(prep.spec.primary()[0])[start:]
            t = run.t[start:]
            sensors = [c for c, n in enumerate(prep.channel_names) if prep.spec.output(n)[2]]
            load = (
                np.sum(
                    np.abs(np.column_stack([run.column(prep.columns[c])[start:] for c in sensors])), axis=1
                )
                if sensors
                else np.abs(x)
            )
            masks.append(
                localise.condition_masks(t, x, run.dt, load, None if contact is None else contact[i][start:])
            )
            energies.append(np.sum(r * r, axis=1))
        table = localise.conditions_table(energies, masks)
        out[f"conditions_{label}"] = [c.to_dict() for c in table]
        if label == "held_out":
            out["_hold_masks"] = masks
    r0 = base.fit_resid[0]
    start0 = round(prep.spec.warmup / prep.fit_runs[0].dt)
    x0 = prep.fit_runs[0].column(prep.spec.primary()[0])[start0:]
    u0 = prep.fit_runs[0].column(prep.spec.inputs[0])[start0:]
    v0 = np.gradient(x0, prep.fit_runs[0].dt)
    out["residual_tests"] = {
        name: {
            "whiteness": {k: v for k, v in localise.whiteness(r0[:, c]).items() if k != "acf"},
            "input_correlation": {
                k: v for k, v in localise.cross_correlation(r0[:, c], u0).items() if k != "ccf"
            },
            "loop_area_velocity": localise.loop_area(r0[:, c], v0),
            "loop_area_position": localise.loop_area(r0[:, c], x0),
        }
        for c, name in enumerate(prep.channel_names)
    }
    for c, t in enumerate(out["residual_tests"].values()):
        w, x = t["whiteness"]["white"], t["input_correlation"]["independent"]
        g = float(np.mean(np.concatenate([r[:, c] for r in base.fit_resid]) ** 2))
        t["gap"] = g
        if w and x:
            t["reading"] = "consistent with white measurement noise"
        elif g < NOISE_LEVEL:
            t["reading"] = "structured, but below the noise level"
        elif x:
            t["reading"] = (
                "coloured but independent of the input: coloured noise or an unmodelled disturbance"
            )
        else:
            t["reading"] = "depends on the input: the model is wrong"
    return out
