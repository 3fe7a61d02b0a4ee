"""Discrepancy discovery: which *kind* of term the gap needs, on which channel, before any
candidate is named — and what is left once the selected effects are in.

In the manner of Kaheman et al. (2019, "Learning discrepancy models from experimental data",
the discrepancy form of SINDy), the residual of the nominal replay is regressed on a library of
physically meaningful features built from the recorded inputs and the nominal model's own
predictions, never from the measurement it explains. The library is grouped by physical kind
(a step at each reversal, a term that builds up over a sliding distance, one proportional to
acceleration, to the channel's rate of change, to its level, a slow memory of tension changes,
a drift with time, a ripple periodic in the joint angle, ...). Group-sparse selection: kinds are
added greedily, each fitted by least squares **on the fit runs** and kept only while it removes
a real share of the gap **on the held-out runs** — a kind that only fits noise or one run's
peculiarity does not survive the cross-validation.

The result says where the gap concentrates by physics rather than by candidate, so that

* a flexible candidate (creep, which can imitate anything slow) is not named when the gap
  follows a kind it cannot produce (an acceleration, a step at every reversal) and none it can
  (a memory, a drift, an offset, a level) (:func:`signature_missing`);
* once the selected effects are in, the structure that remains is described in words
  (:func:`describe_remaining`): a ripple periodic in the joint angle or a drift that no
  candidate models is reported as unexplained structure, not silently absorbed.

It is plant-agnostic: features come from the run's input columns and each channel's nominal
prediction, which every plant provides.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cablekit.diagnose.data import scored_start
from cablekit.diagnose.fit import CandidateFit
from cablekit.diagnose.localise import smooth_velocity
from cablekit.diagnose.prepare import Prepared

__all__ = [
    "KINDS",
    "MEASUREMENT_SIGNATURES",
    "DiscoveredTerm",
    "describe_remaining",
    "discover",
    "revealed",
    "signature_missing",
]

_F = NDArray[np.float64]

#: kind → (what the gap then follows, in words)
KINDS: dict[str, str] = {
    "offset": "a constant offset",
    "level": "the channel's own level (a gain or a stiffness error)",
    "curvature": "the square and cube of the channel's level (a nonlinear law)",
    "rate": "the channel's rate of change or a lag of it (a sensor lag, a hold or a delay)",
    "velocity": "the velocity (viscous damping)",
    "acceleration": "the acceleration (an inertia error)",
    "reversal_step": "a step at every reversal of the motion (dry friction)",
    "presliding": "a term that builds up over a sliding distance after each reversal (hysteresis)",
    "tension_direction": "the level signed by the direction of motion (friction growing with tension)",
    "memory": "a slow memory of the level's changes, relaxing over seconds (creep)",
    "drift": "a drift with time over each run (thermal or slow sensor drift)",
    "angle_ripple": "a ripple periodic in the joint angle (eccentric pulley, cogging)",
}

#: kinds a flexible candidate can produce: creep relaxes over seconds (memory), over a run
#: (drift), or has relaxed before the held-out run starts (an offset, a changed level)
SIGNATURES: dict[str, set[str]] = {"creep": {"memory", "drift", "offset", "level"}}

#: kinds an effect of the measurement path leaves behind *whatever model* predicts the channel:
#: a lag, a hold or a delay the rate of change of the prediction, a gain or bias its level. They
#: follow the prediction, so a dominant plant effect hides them until it is in the model; once
#: it is, :func:`discover` on that model's predictions (``model=``) shows them
MEASUREMENT_SIGNATURES: dict[str, set[str]] = {
    "sensor_lag": {"rate"},
    "sensor_sampling": {"rate"},
    "time_delay": {"rate"},
    "sensor_gain_bias": {"level", "offset"},
}

#: time constants (s) of the lag columns of the "rate" kind: sensor filters, converters, holds
LAG_TIMES = (0.005, 0.02, 0.08)

#: share of a channel's held-out excess a kind must remove to count as the gap's structure
DOMINANT = 0.3


@dataclass(frozen=True)
class DiscoveredTerm:
    """A kind of term the gap of one channel needs, with the held-out share it removes."""

    channel: str
    kind: str
    #: share of the channel's held-out excess (above the noise) this kind removes, on top of the
    #: kinds found before it
    held_out_share: float
    description: str

    def to_dict(self) -> dict[str, object]:
        return {
            "channel": self.channel,
            "kind": self.kind,
            "held_out_share": self.held_out_share,
            "description": self.description,
        }


def _lowpass(x: _F, tau: float, dt: float) -> _F:
    a = math.exp(-dt / tau)
    y = np.empty_like(x)
    acc = float(x[0])
    for k, v in enumerate(x):
        acc = a * acc + (1.0 - a) * float(v)
        y[k] = acc
    return y


def _presliding(u: _F, width: float) -> _F:
    """Rate-independent Dahl state of ``u`` with break-away distance ``width``: it saturates at
    ±1 a few widths after each reversal."""
    z = np.empty_like(u)
    acc = 0.0
    du = np.diff(u, prepend=u[0])
    decay = np.exp(-np.abs(du) / width)
    sgn = np.sign(du)
    for k in range(len(u)):
        if sgn[k] != 0.0:
            acc = float(sgn[k]) + (acc - float(sgn[k])) * float(decay[k])
        z[k] = acc
    return z


def _features(prep: Prepared, hold: bool, model: CandidateFit | None = None) -> list[dict[str, list[_F]]]:
    """Per run: kind → feature columns (each over the scored samples), per channel where the
    kind depends on the channel (keys ``kind`` or ``kind:channel``). The channel features come
    from the nominal model's predictions, or from ``model``'s (the effects selected so far)."""
    runs = prep.hold_runs if hold else prep.fit_runs
    problem = prep.hold0 if hold else prep.fit0
    theta = np.zeros(0)
    if model is not None and model.effects:
        problem, theta = problem.with_effects(model.effects, model.substeps), model.params
    out = []
    angle_cols = [
        c
        for o, c in zip(prep.channel_names, prep.columns, strict=True)
        if o in ("theta", "q_l1") or o.startswith("q:")
    ]
    for i, run in enumerate(runs):
        start = scored_start(prep.spec.warmup, run)
        pred = np.asarray(problem.predict(theta, i))
        t = run.t - run.t[0]
        inputs = [run.column(c) for c in prep.spec.inputs][:4]
        feats: dict[str, list[_F]] = {}
        vel, acc, dry, pre = [], [], [], []
        for u in inputs:
            v = smooth_velocity(u, run.dt)
            a = np.gradient(v, run.dt)
            scale = float(np.sqrt(np.mean(v * v))) or 1.0
            vel.append(v)
            acc.append(a)
            dry.append(np.tanh(v / (0.05 * scale)))
            span = float(np.ptp(u)) or 1.0
            pre += [_presliding(u, w * span) for w in (0.003, 0.01, 0.03)]
        feats["velocity"] = vel
        feats["acceleration"] = acc
        feats["reversal_step"] = dry
        feats["presliding"] = pre
        feats["offset"] = [np.ones(len(run))]
        feats["drift"] = [t / (t[-1] or 1.0), (t / (t[-1] or 1.0)) ** 2]
        if angle_cols:
            th = run.column(angle_cols[0])
            feats["angle_ripple"] = [f(n * th) for n in range(1, 17) for f in (np.sin, np.cos)]
        for c, name in enumerate(prep.channel_names):
            y = pred[:, c]
            yc = y - float(np.mean(y))
            sd = float(np.std(yc)) or 1.0
            z = yc / sd
            feats[f"level:{name}"] = [z]
            feats[f"curvature:{name}"] = [z * z, z**3]
            # a lag of the channel: its rate of change (a short lag of a smooth signal) and the
            # first-order lags of the prediction over the time constants of sensors and
            # converters (a lag of the steps a dry-friction model puts in the tension is an
            # exponential after each step, not a derivative)
            feats[f"rate:{name}"] = [np.gradient(y, run.dt) * (run.dt / sd) * 100.0] + [
                (_lowpass(z, tau, run.dt) - z) for tau in LAG_TIMES if tau > 2.0 * run.dt
            ]
            feats[f"tension_direction:{name}"] = [z * d for d in dry]
            feats[f"memory:{name}"] = [(_lowpass(z, tau, run.dt) - z) for tau in (1.0, 3.0, 10.0)]
        out.append({k: [np.asarray(col[start:], dtype=float) for col in v] for k, v in feats.items()})
    return out


def _design(per_run: list[dict[str, list[_F]]], kinds: list[str], channel: str) -> _F:
    cols = []
    for k in kinds:
        key = f"{k}:{channel}" if f"{k}:{channel}" in per_run[0] else k
        n_cols = len(per_run[0][key])
        cols.append(
            np.column_stack([np.concatenate([run[key][j] for run in per_run]) for j in range(n_cols)])
        )
    return np.column_stack(cols)


def _available(per_run: list[dict[str, list[_F]]], channel: str) -> list[str]:
    return [k for k in KINDS if k in per_run[0] or f"{k}:{channel}" in per_run[0]]


def discover(
    prep: Prepared,
    fit_resid: list[_F],
    hold_resid: list[_F],
    min_share: float = 0.05,
    max_kinds: int = 4,
    model: CandidateFit | None = None,
) -> list[DiscoveredTerm]:
    """Kinds of term each channel's gap needs (greedy group selection, fitted on the fit runs,
    kept while each removes at least ``min_share`` of the channel's held-out excess). With
    ``model`` (the residuals are then its residuals) the channel features follow its
    predictions: a sensor lag behind a dry-friction model is the rate of change of the friction
    model's output, which the nominal output does not have."""
    f_fit = _features(prep, hold=False, model=model)
    f_hold = _features(prep, hold=True, model=model)
    out: list[DiscoveredTerm] = []
    for c, name in enumerate(prep.channel_names):
        y_fit = np.concatenate([r[:, c] for r in fit_resid])
        y_hold = np.concatenate([r[:, c] for r in hold_resid])
        n_hold = y_hold.size
        sse0 = float(y_hold @ y_hold)
        excess = sse0 - n_hold
        if not excess > 0.15 * n_hold:  # this channel is at the noise level: nothing to explain
            continue
        chosen: list[str] = []
        sse = sse0
        for _ in range(max_kinds):
            best: tuple[float, str] | None = None
            for k in _available(f_fit, name):
                if k in chosen:
                    continue
                trial = [*chosen, k]
                a_fit = _design(f_fit, trial, name)
                a_hold = _design(f_hold, trial, name)
                # least squares on standardised columns (an orthogonal factorisation, not the
                # normal equations: the presliding and memory columns are nearly collinear)
                s = a_fit.std(axis=0)
                s[s == 0] = 1.0
                af, ah = a_fit / s, a_hold / s
                coef = np.linalg.lstsq(af, y_fit, rcond=1e-10)[0]
                e = y_hold - ah @ coef
                val = float(e @ e)
                if np.isfinite(val) and (best is None or val < best[0]):
                    best = (val, k)
            if best is None or (sse - best[0]) < min_share * excess:
                break
            out.append(DiscoveredTerm(name, best[1], (sse - best[0]) / excess, KINDS[best[1]]))
            chosen.append(best[1])
            sse = best[0]
    return out


def signature_missing(effect: str, terms: list[DiscoveredTerm]) -> bool:
    """Whether the nominal gap contradicts a flexible effect (creep): a kind it cannot produce
    (an acceleration, a step at reversals, a curvature, ...) removes at least ``DOMINANT`` of some
    channel's gap, and no kind it can produce was found on any channel."""
    need = SIGNATURES.get(effect)
    if not need:
        return False
    other = any(t.kind not in need and t.held_out_share >= DOMINANT for t in terms)
    return other and not any(t.kind in need for t in terms)


def revealed(terms: list[DiscoveredTerm], min_share: float = 0.2) -> set[str]:
    """Measurement-path effects whose signature (:data:`MEASUREMENT_SIGNATURES`) removes at
    least ``min_share`` of some channel's remaining held-out excess."""
    kinds = {t.kind for t in terms if t.held_out_share >= min_share}
    return {e for e, sig in MEASUREMENT_SIGNATURES.items() if sig & kinds}


def describe_remaining(terms: list[DiscoveredTerm], min_share: float = 0.2) -> list[str]:
    """Sentences for the structure left after the selected effects: each kind that removes at
    least ``min_share`` of a channel's remaining held-out excess."""
    return [
        f"the remaining gap on {t.channel} follows {t.description} ({t.held_out_share:.0%} of it)"
        for t in terms
        if t.held_out_share >= min_share
    ]
