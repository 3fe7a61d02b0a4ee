"""Self-test of the diagnosis on data whose effect is withheld.

Each case draws a nominal antagonistic joint (pulley radius, cable stiffness, pretension,
natural frequency, damping ratio vary), a fit trajectory and a different held-out trajectory,
and generates "real" runs from a **higher-fidelity configuration** of the simulator with one
effect, a pair of effects, or none (controls):

* integration at 10 kHz with an analytic input (the diagnoser sees 1 kHz samples and
  differentiates them), then decimation;
* effect forms that differ from the candidates' where the physics allows: Coulomb and capstan
  signs 10× sharper than the nominal smoothing, Stribeck exponent 1.5 (candidate: 2), Dahl
  exponent 1.5 (candidate: 1), a **two-pole** force sensor for ``sensor_lag`` (candidate: one
  pole), an HX711-like 8–12 Hz sample-and-hold with noise before the hold and quantisation for
  ``sensor_sampling``, a delay applied to the continuous input for ``time_delay``;
* white measurement noise on every channel (about 2 % of the pretension on tensions, 0.3 mrad
  on the joint angle, when it is measured).

The diagnoser gets only the nominal model file and the runs. Scores: top-1 attribution on
single-effect cases, the selected set on pairs, false alarms on controls (a verdict other than
``no_significant_gap``), and the held-out share of the gap closed.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

import cablekit as ck
from cablekit import _log
from cablekit.diagnose.data import Run
from cablekit.diagnose.engine import Options, diagnose
from cablekit.diagnose.spec import ModelSpec, model_spec_from_dict

__all__ = ["CONTROLS", "PAIRS", "SINGLE", "Case", "make_case", "run_self_test"]

SINGLE = [
    "coulomb_friction",
    "viscous_friction",
    "stribeck_friction",
    "dahl_hysteresis",
    "capstan_friction",
    "nonlinear_stiffness",
    "cable_damping",
    "creep",
    "backlash",
    "slack",
    "coupling",
    "sensor_lag",
    "sensor_sampling",
    "time_delay",
    "sensor_gain_bias",
    "inertia_error",
]
PAIRS = [
    ("coulomb_friction", "sensor_lag"),
    ("backlash", "sensor_gain_bias"),
    ("creep", "capstan_friction"),
]
CONTROLS = 3

DT = 1e-3
FINE = 10  # generator samples per recorded sample


@dataclass
class Case:
    """One generated diagnosis problem and its withheld truth."""

    label: str
    effects: tuple[str, ...]
    spec: ModelSpec
    fit: list[Run]
    hold: list[Run]
    truth: dict[str, Any]


def _nominal(rng: np.random.Generator) -> dict[str, float]:
    r = rng.uniform(2e-3, 6e-3)
    k = 10 ** rng.uniform(math.log10(8e3), math.log10(4e4))
    t0 = rng.uniform(8.0, 25.0)
    wn = rng.uniform(120.0, 300.0)  # rad/s, joint on its two cables
    kt = 2.0 * k * r * r  # torsional stiffness, N·m/rad
    j = kt / wn**2
    zeta = rng.uniform(0.05, 0.2)
    crit = 2.0 * math.sqrt(kt * j)
    c = zeta * crit / (2.0 * r * r)
    # the jaw closes on an object part of the time: a contact at 0.15-0.3 rad through a 10 mm
    # lever, stiff enough to load the cables to about twice the pretension; without a load the
    # cables of a position-driven free joint barely stretch and stretch-dependent effects hide
    lever = 0.01
    k_contact = rng.uniform(0.3, 0.6) * kt / lever**2
    return {
        "radius": r,
        "stiffness": k,
        "inertia": j,
        "damping": c,
        "pretension": t0,
        "viscous": 0.05 * crit,
        "smoothing": 0.05,
        "contact_angle": rng.uniform(0.15, 0.3),
        "contact_stiffness": k_contact,
        "contact_damping": 0.02 * k_contact * 0.01,
        "contact_lever_arm": lever,
    }


def _trajectory(rng: np.random.Generator, t: np.ndarray, held_out: bool) -> tuple[np.ndarray, np.ndarray]:
    """Joint-angle reference θ(t) (rad) and its rate: slow + medium + fast sines. The held-out
    run uses other frequencies and amplitudes."""
    f1 = rng.uniform(0.3, 0.6) if not held_out else rng.uniform(0.7, 1.1)
    f2 = rng.uniform(2.0, 3.0) if not held_out else rng.uniform(3.2, 4.5)
    f3 = rng.uniform(10.0, 16.0) if not held_out else rng.uniform(17.0, 24.0)
    a1 = rng.uniform(0.35, 0.6)
    a2, a3 = rng.uniform(0.05, 0.12), rng.uniform(0.01, 0.02)
    ph = rng.uniform(0, 2 * np.pi, 3)
    w = 2 * np.pi * np.array([f1, f2, f3])
    a = np.array([a1, a2, a3])
    th = sum(a[i] * np.sin(w[i] * t + ph[i]) for i in range(3))
    dth = sum(a[i] * w[i] * np.cos(w[i] * t + ph[i]) for i in range(3))
    return th, dth


def _coupled(rng: np.random.Generator, t: np.ndarray) -> np.ndarray:
    f = rng.uniform(0.15, 0.25)
    return 0.3 * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))


def _lag2(y: np.ndarray, tau1: float, tau2: float, dt: float) -> np.ndarray:
    out = y.copy()
    for tau in (tau1, tau2):
        a = math.exp(-dt / tau)
        z = np.empty_like(out)
        z[0] = out[0]
        for k in range(1, len(out)):
            z[k] = a * z[k - 1] + (1 - a) * out[k]
        out = z
    return out


def _draw_truth(
    effect: str, rng: np.random.Generator, nom: dict[str, float], rms_rate: float
) -> dict[str, float]:
    r, t0, c = nom["radius"], nom["pretension"], nom["damping"]
    tq = r * t0
    if effect == "coulomb_friction":
        return {"F_c": rng.uniform(0.1, 0.25) * tq}
    if effect == "viscous_friction":
        return {"delta_b": rng.uniform(0.1, 0.25) * tq / rms_rate}
    if effect == "stribeck_friction":
        return {
            "F_c": 0.05 * tq,
            "F_s_minus_F_c": rng.uniform(0.15, 0.25) * tq,
            "v_s": rng.uniform(0.05, 0.15) * rms_rate,
        }
    if effect == "dahl_hysteresis":
        return {"F_d": rng.uniform(0.12, 0.25) * tq, "theta_d": rng.uniform(0.02, 0.05)}
    if effect == "capstan_friction":
        return {"mu_phi": rng.uniform(0.1, 0.25)}
    if effect == "nonlinear_stiffness":
        return {"beta": rng.uniform(0.6, 1.5) * nom["stiffness"] / t0}
    if effect == "cable_damping":
        return {"delta_c": rng.uniform(5.0, 10.0) * c}
    if effect == "creep":
        return {"kappa": rng.uniform(0.1, 0.3), "tau": rng.uniform(0.2, 1.0)}
    if effect == "backlash":
        return {"delta": rng.uniform(0.01, 0.03) * r}
    if effect == "slack":
        return {"delta_T0": rng.uniform(0.5, 0.8) * t0}
    if effect == "coupling":
        return {"kappa_c": rng.uniform(0.3, 1.0) * r}
    if effect == "sensor_lag":
        return {"tau_s": rng.uniform(0.005, 0.015)}
    if effect == "sensor_sampling":
        return {"period": 1.0 / rng.uniform(8.0, 12.0), "phase_frac": rng.uniform()}
    if effect == "time_delay":
        return {"d": rng.uniform(0.003, 0.008)}
    if effect == "sensor_gain_bias":
        # gain and bias errors of one sensor that do not cancel at the pretension
        s = rng.choice([-1.0, 1.0])
        return {
            "gain0": s * rng.uniform(0.04, 0.08),
            "gain1": -s * rng.uniform(0.04, 0.08),
            "bias0": s * rng.uniform(0.02, 0.05) * t0,
            "bias1": -s * rng.uniform(0.02, 0.05) * t0,
        }
    if effect == "inertia_error":
        return {"epsilon": rng.uniform(2.0, 4.0)}
    raise ValueError(effect)


def _generate_run(
    name: str,
    nom: dict[str, float],
    truth: dict[str, dict[str, float]],
    rng: np.random.Generator,
    duration: float,
    held_out: bool,
    measure_theta: bool,
    noise: dict[str, float],
) -> Run:
    r = nom["radius"]
    n = round(duration / DT)
    fine_dt = DT / FINE
    tf = np.arange(n * FINE) * fine_dt
    th, dth = _trajectory(rng, tf, held_out)
    xc = _coupled(rng, tf)
    x_m, v_m = r * th, r * dth
    p = dict(nom)
    p["smoothing"] = nom["smoothing"]
    # --- input side
    if "coupling" in truth:
        kc = truth["coupling"]["kappa_c"]
        x_m = x_m + kc * xc
        v_m = v_m + kc * np.gradient(xc, fine_dt)
    if "backlash" in truth:
        d = truth["backlash"]["delta"]
        y = np.empty_like(x_m)
        prev = x_m[0]
        for k, xv in enumerate(x_m):
            prev = min(max(prev, xv - d), xv + d)
            y[k] = prev
        x_m, v_m = y, np.gradient(y, fine_dt)
    if "time_delay" in truth:
        d = truth["time_delay"]["d"]
        x_m = np.interp(tf - d, tf, x_m)
        v_m = np.interp(tf - d, tf, v_m)
    # --- plant
    if "coulomb_friction" in truth:
        p["coulomb"] = truth["coulomb_friction"]["F_c"]
        p["smoothing"] = nom["smoothing"] / 10
    if "viscous_friction" in truth:
        p["viscous"] = nom["viscous"] + truth["viscous_friction"]["delta_b"]
    if "stribeck_friction" in truth:
        s = truth["stribeck_friction"]
        p.update(
            coulomb=s["F_c"],
            static_friction=s["F_c"] + s["F_s_minus_F_c"],
            stribeck_velocity=s["v_s"],
            stribeck_exponent=1.5,
        )
    if "dahl_hysteresis" in truth:
        s = truth["dahl_hysteresis"]
        p.update(dahl_coulomb=s["F_d"], dahl_sigma0=s["F_d"] / s["theta_d"], dahl_exponent=1.5)
    if "capstan_friction" in truth:
        p.update(capstan_mu=truth["capstan_friction"]["mu_phi"], capstan_wrap=1.0, capstan_smoothing=1e-4)
    if "nonlinear_stiffness" in truth:
        p.update(cable_law="exponential", length_scale=1.0 / truth["nonlinear_stiffness"]["beta"])
    if "cable_damping" in truth:
        p["damping"] = nom["damping"] + truth["cable_damping"]["delta_c"]
    if "creep" in truth:
        p.update(creep_fraction=truth["creep"]["kappa"], creep_time_constant=truth["creep"]["tau"])
    if "slack" in truth:
        p["pretension"] = nom["pretension"] - truth["slack"]["delta_T0"]
    if "inertia_error" in truth:
        p["inertia"] = nom["inertia"] * (1 + truth["inertia_error"]["epsilon"])
    model = ck.AntagonisticJoint(**p)
    u = np.ascontiguousarray(np.column_stack([x_m, v_m]))
    x0 = np.zeros(model.n_states)
    x0[0] = x_m[0] / r
    sub = max(1, ck.propose_step(model, fine_dt, x0, u[0]).substeps)
    res = ck.simulate(model, u, fine_dt, x0, substeps=sub, hold="foh")
    keep = slice(0, None, FINE)
    t = tf[keep]
    tens = np.column_stack([res["tension_motor_drive"], res["tension_motor_return"]])
    theta = res["theta"]
    # --- sensor side, at the fine rate
    if "sensor_lag" in truth:
        tau = truth["sensor_lag"]["tau_s"]
        tens = np.column_stack([_lag2(tens[:, i], tau, tau / 3, fine_dt) for i in range(2)])
    tens = tens[keep]
    theta = theta[keep]
    if "sensor_gain_bias" in truth:
        s = truth["sensor_gain_bias"]
        tens = tens * (1 + np.array([s["gain0"], s["gain1"]])) + np.array([s["bias0"], s["bias1"]])
    tens = tens + rng.normal(0.0, noise["tension"], tens.shape)
    if "sensor_sampling" in truth:
        s = truth["sensor_sampling"]
        period, phase = s["period"], s["phase_frac"] * s["period"]
        idx = np.floor((t - phase) / period)
        src = np.clip(np.round((phase + idx * period) / DT).astype(int), 0, len(t) - 1)
        src[idx < 0] = 0
        lsb = noise["tension"] / 2
        tens = np.round(tens[src] / lsb) * lsb
    cols = {
        "x_m": _sampled_input(t, tf, r * th),
        "x_c": xc[keep],
        "T_drive": tens[:, 0],
        "T_return": tens[:, 1],
    }
    if measure_theta:
        cols["theta"] = theta + rng.normal(0.0, noise["theta"], theta.shape)
    return Run(name, t, {k: np.ascontiguousarray(v) for k, v in cols.items()})


def _sampled_input(t: np.ndarray, tf: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The commanded motor displacement as a controller logs it: sampled, no effect applied."""
    return np.interp(t, tf, x)


#: the parameters that set each effect's size (scaled up when an effect would hide in the noise)
_MAGNITUDE = {
    "coulomb_friction": ("F_c",),
    "viscous_friction": ("delta_b",),
    "stribeck_friction": ("F_s_minus_F_c",),
    "dahl_hysteresis": ("F_d",),
    "capstan_friction": ("mu_phi",),
    "nonlinear_stiffness": ("beta",),
    "cable_damping": ("delta_c",),
    "creep": ("kappa",),
    "backlash": ("delta",),
    "slack": ("delta_T0",),
    "coupling": ("kappa_c",),
    "sensor_lag": ("tau_s",),
    "sensor_sampling": (),
    "time_delay": ("d",),
    "sensor_gain_bias": ("gain0", "gain1", "bias0", "bias1"),
    "inertia_error": ("epsilon",),
}
_CAPS = {"kappa": 0.6, "delta_T0": 0.95}


def _scaled(truth: dict[str, dict[str, float]], factor: float, t0: float) -> dict[str, dict[str, float]]:
    out = {}
    for e, params in truth.items():
        q = dict(params)
        for k in _MAGNITUDE[e]:
            q[k] = q[k] * factor
            if k in _CAPS:
                q[k] = min(q[k], _CAPS[k] * (t0 if k == "delta_T0" else 1.0))
        out[e] = q
    return out


#: a non-control case is regenerated with larger effects until its held-out gap (mean squared
#: residual of the nominal model in noise units) reaches this: an effect smaller than the noise
#: is not attributable by any method, and would only measure the noise
MIN_VISIBLE_GAP = 1.5


def visible_runs(
    spec: ModelSpec,
    generate: Callable[[Any, np.random.Generator], tuple[list[Run], list[Run]]],
    truth: Any,
    doubled: Callable[[Any], Any],
    run_seed: int,
    fit_too: bool = False,
) -> tuple[list[Run], list[Run], Any, float]:
    """Generate fit and held-out runs, doubling the effects (up to 4 times) until the nominal
    model's held-out gap — and with ``fit_too`` the fit gap — reaches ``MIN_VISIBLE_GAP``.
    Every attempt replays the same random stream. Returns the runs, the truth used and its
    scale factor. A control (empty truth) is generated once."""
    from cablekit.diagnose.fit import baseline
    from cablekit.diagnose.prepare import prepare
    from cablekit.diagnose.select import gap

    scale = 1.0
    for attempt in range(5):
        if attempt:
            truth, scale = doubled(truth), 2.0 * scale
        fit, hold = generate(truth, np.random.default_rng(run_seed))
        if not truth:
            break
        base = baseline(prepare(spec, fit, hold))
        seen = gap(base.hold_resid) if not fit_too else min(gap(base.fit_resid), gap(base.hold_resid))
        if seen >= MIN_VISIBLE_GAP:
            break
    return fit, hold, truth, scale


def make_case(effects: tuple[str, ...], seed: int, duration: float = 8.0) -> Case:
    """Generate one case; ``effects`` empty for a control. See the module for the recipe."""
    rng = np.random.default_rng(seed)
    nom = _nominal(rng)
    rms_rate = 0.5 * 2 * np.pi * 0.6  # rad/s, order of the slow component's peak rate
    truth = {e: _draw_truth(e, rng, nom, rms_rate) for e in effects}
    measure_theta = bool(rng.uniform() < 0.6)
    noise = {"tension": 0.02 * nom["pretension"] * rng.uniform(0.5, 1.5), "theta": 3e-4}
    outputs = {"tension_motor_drive": "T_drive", "tension_motor_return": "T_return"}
    if measure_theta:
        outputs["theta"] = "theta"
    spec = model_spec_from_dict(
        {
            "model": "antagonistic_joint",
            "parameters": nom,
            "inputs": {"x_m": "x_m", "coupled": "x_c"},
            "outputs": outputs,
            "diagnosis": {"warmup": 0.3},
        },
        source=f"self-test case {seed}",
    )

    def generate(truth: dict[str, dict[str, float]], gen: np.random.Generator) -> tuple[list[Run], list[Run]]:
        fit = [_generate_run("fit", nom, truth, gen, duration, False, measure_theta, noise)]
        hold = [_generate_run("held_out", nom, truth, gen, duration, True, measure_theta, noise)]
        return fit, hold

    fit, hold, truth, scale = visible_runs(
        spec, generate, truth, lambda t: _scaled(t, 2.0, nom["pretension"]), int(rng.integers(1 << 31))
    )
    label = "+".join(effects) if effects else "control"
    return Case(
        label, effects, spec, fit, hold, {"nominal": nom, "effects": truth, "noise": noise, "scaled": scale}
    )


def run_self_test(
    seed: int = 2026, duration: float = 8.0, progress: bool = True, only: list[str] | None = None
) -> dict[str, Any]:
    """Run every case; returns per-case results, the confusion table and the scores."""
    from cablekit.diagnose import selftest_transmission as tx

    cases: list[tuple[str, str, tuple[str, ...]]] = [("joint", "single", (e,)) for e in SINGLE]
    cases += [("joint", "pair", p) for p in PAIRS]
    cases += [("joint", "control", ())] * CONTROLS
    cases += [("raven", "single", (e,)) for e in tx.TRANSMISSION_SINGLE]
    cases += [("raven", "pair", p) for p in tx.TRANSMISSION_PAIRS]
    cases += [("raven", "control", ())] * tx.TRANSMISSION_CONTROLS
    if only:
        cases = [c for c in cases if _case_label(c[0], c[2]) in only or ("+".join(c[2]) or "control") in only]
    rows = []
    t_start = time.perf_counter()
    for i, (plant, kind, effects) in enumerate(cases):
        make = make_case if plant == "joint" else tx.make_transmission_case
        case = make(effects, seed + 97 * i, duration)
        t0 = time.perf_counter()
        res = diagnose(case.spec, case.fit, case.hold, Options(progress=False))
        elapsed = time.perf_counter() - t0
        top = res.effects[0].name if res.effects else None
        selected = res.selected.effects
        row = {
            "plant": plant,
            "kind": kind,
            "injected": list(effects),
            "verdict": res.verdict,
            "top1": top,
            "selected": selected,
            "held_out_closed": res.selected.held_out.closed_fraction,
            "gap_held_out": res.gap.held_out,
            "seconds": elapsed,
            "correct": (
                top == effects[0] and res.verdict != "no_significant_gap"
                if kind == "single"
                else set(effects) <= {s.split("@")[0] for s in selected}
                if kind == "pair"
                else res.verdict == "no_significant_gap"
            ),
        }
        rows.append(row)
        if progress:
            mark = "ok " if row["correct"] else "MISS"
            _log.info(
                f"[{i + 1:>2}/{len(cases)}] {mark} {case.label:<36} verdict={res.verdict:<20} "
                f"top1={top!s:<20} "
                f"selected={','.join(selected) or '-':<34} closed={row['held_out_closed']:.2f} "
                f"({elapsed:.1f}s)"
            )
    singles = [r for r in rows if r["kind"] == "single"]
    pairs = [r for r in rows if r["kind"] == "pair"]
    controls = [r for r in rows if r["kind"] == "control"]
    closed = [r["held_out_closed"] for r in rows if r["kind"] != "control"]
    confusion: dict[str, dict[str, int]] = {}
    for r in singles:
        row_key = _case_label(r["plant"], tuple(r["injected"]))
        key = r["top1"] if r["verdict"] != "no_significant_gap" else "no_significant_gap"
        confusion.setdefault(row_key, {})
        confusion[row_key][key] = confusion[row_key].get(key, 0) + 1
    scores = {
        "top1_accuracy": float(np.mean([r["correct"] for r in singles])) if singles else math.nan,
        "top1_by_plant": {
            plant: float(np.mean([r["correct"] for r in singles if r["plant"] == plant]))
            for plant in sorted({r["plant"] for r in singles})
        },
        "pairs_found": float(np.mean([r["correct"] for r in pairs])) if pairs else math.nan,
        "control_false_alarms": int(sum(not r["correct"] for r in controls)),
        "median_held_out_closed": float(np.median(closed)) if closed else math.nan,
        "seconds": time.perf_counter() - t_start,
    }
    goals = {"top1_accuracy": 0.9, "control_false_alarms": 0, "median_held_out_closed": 0.8}
    passed = (
        (not singles or scores["top1_accuracy"] >= goals["top1_accuracy"])
        and scores["control_false_alarms"] <= goals["control_false_alarms"]
        and (not closed or scores["median_held_out_closed"] >= goals["median_held_out_closed"])
    )
    return {"cases": rows, "confusion": confusion, "scores": scores, "goals": goals, "passed": passed}


def _case_label(plant: str, effects: tuple[str, ...]) -> str:
    name = "+".join(effects) or "control"
    return name if plant == "joint" else f"{plant}:{name}"


def format_confusion(result: dict[str, Any]) -> str:
    """The confusion table (injected → top-1) as text."""
    lines = [f"{'injected':<32} {'top-1 named':<22} {'verdict / selected'}"]
    for r in result["cases"]:
        inj = _case_label(r.get("plant", "joint"), tuple(r["injected"]))
        lines.append(
            f"{inj:<32} {r['top1']!s:<22} {r['verdict']} / {','.join(r['selected']) or '-'}"
            f"{'' if r['correct'] else '   <-- miss'}"
        )
    s = result["scores"]
    lines.append("")
    lines.append(
        f"top-1 {s['top1_accuracy']:.0%} (goal >= 90%), pairs {s['pairs_found']:.0%}, control false alarms "
        f"{s['control_false_alarms']} (goal 0), median held-out gap closed {s['median_held_out_closed']:.0%} "
        f"(goal >= 80%), {s['seconds']:.0f} s"
    )
    by_plant = s.get("top1_by_plant", {})
    if len(by_plant) > 1:
        lines.append("top-1 by plant: " + ", ".join(f"{k} {v:.0%}" for k, v in by_plant.items()))
    return "\n".join(lines)
