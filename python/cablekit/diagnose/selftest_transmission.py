"""Self-test cases on a servo-driven cable transmission (Raven-II-like, 2 links).

Each case draws a nominal transmission (Raven-II's transmission parameters, each scaled by a
factor in 0.7–1.4), a fit and a held-out joint trajectory (multi-sines at other frequencies),
and generates "real" runs from a **higher-fidelity configuration**:

* the references are computed analytically; the recorded references are the commanded ones,
  a ``time_delay`` is applied to the analytic signal (not by resampling); a trajectory whose
  servo would spend over 0.5 % of the run at the current limit is shrunk until it does not;
* the servo (Raven-II's PD at 1 kHz with its current limit) runs on the true plant integrated
  with 4× the substeps the diagnoser is advised to use;
* injected Coulomb friction has a 10× sharper sign than the nominal smoothing;
* white noise on the encoders (0.1 mrad) and on the applied torques (about 0.4 % of the
  current limit, as a current sensor reads them).

The diagnoser gets the nominal model file (parameters and servo gains) and the runs: motor and
link encoders and applied motor torques, references as inputs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

import cablekit as ck
from cablekit.diagnose.data import Run
from cablekit.diagnose.spec import model_spec_from_dict

if TYPE_CHECKING:
    from cablekit.diagnose.selftest import Case

__all__ = ["TRANSMISSION_CONTROLS", "TRANSMISSION_PAIRS", "TRANSMISSION_SINGLE", "make_transmission_case"]

#: effects a servo-driven transmission observed by encoders and motor currents can show
TRANSMISSION_SINGLE = [
    "coulomb_friction",
    "viscous_friction",
    "inertia_error",
    "cable_damping",
    "slack",
    "coupling",
    "time_delay",
]
TRANSMISSION_PAIRS = [("coulomb_friction", "time_delay")]
TRANSMISSION_CONTROLS = 2

DT = 1e-3
LINKS = 2
NOISE_ANGLE = 1e-4  # rad
NOISE_TORQUE = 2.5e-3  # N·m
MAX_SATURATION = 0.005  # share of samples a run may spend at the servo's current limit

_SCALED = (
    "motor_inertia",
    "link_inertia",
    "cable_stiffness",
    "cable_damping",
    "link_coulomb",
    "link_viscous",
)


def _nominal(rng: np.random.Generator) -> dict[str, Any]:
    p = ck.CableTransmission.raven2(LINKS).params()
    for key in _SCALED:
        p[key] = [float(v * rng.uniform(0.7, 1.4)) for v in p[key]]
    p["pretension"] = [float(rng.uniform(25.0, 55.0))] * LINKS
    return p


def _joint_trajectory(rng: np.random.Generator, held_out: bool) -> list[tuple[float, float, float]]:
    """Per link, a list of sine components (amplitude rad, frequency Hz, phase) of the joint
    angle; the held-out run uses other frequencies. Accelerations stay inside the servo's
    current limit (a saturated servo is open loop and replays nothing)."""
    comps = []
    for amp in (0.45, 0.35):
        a = amp * rng.uniform(0.7, 1.0)
        f1 = rng.uniform(0.2, 0.4) if not held_out else rng.uniform(0.45, 0.6)
        f2 = rng.uniform(1.0, 1.4) if not held_out else rng.uniform(1.5, 1.8)
        comps.append([(a, f1, rng.uniform(0, 2 * np.pi)), (0.1 * a, f2, rng.uniform(0, 2 * np.pi))])
    return comps


#: the trajectories fade in over this time (s) from rest: a velocity step at the start would
#: saturate the servo, and a saturated servo is open loop (it replays nothing reliably)
FADE = 0.5


def _eval(comps: list[list[tuple[float, float, float]]], t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles and rates of the components, faded in by ``(1 − cos(πt/FADE))/2``."""
    q = np.zeros((len(t), len(comps)))
    dq = np.zeros_like(q)
    for i, link in enumerate(comps):
        for a, f, ph in link:
            w = 2 * np.pi * f
            q[:, i] += a * (np.sin(w * t + ph) - np.sin(ph))
            dq[:, i] += a * w * np.cos(w * t + ph)
    inside = t < FADE
    win = np.where(inside, 0.5 * (1 - np.cos(np.pi * t / FADE)), 1.0)
    dwin = np.where(inside, 0.5 * np.pi / FADE * np.sin(np.pi * t / FADE), 0.0)
    return win[:, None] * q, dwin[:, None] * q + win[:, None] * dq


def _draw_truth(effect: str, rng: np.random.Generator, nom: dict[str, Any]) -> dict[str, Any]:
    link = int(rng.integers(LINKS))  # per-link effects hit one link, the diagnoser fits both
    if effect == "coulomb_friction":
        f = [0.0] * LINKS
        f[link] = rng.uniform(0.05, 0.15) * nom["link_coulomb"][link]
        return {"F_c": f}
    if effect == "viscous_friction":
        b = [0.0] * LINKS
        b[link] = rng.uniform(0.02, 0.05) * nom["link_coulomb"][link] / 1.0  # N·m at 1 rad/s
        return {"delta_b": b}
    if effect == "inertia_error":
        e = [0.0] * LINKS
        e[link] = rng.uniform(0.03, 0.1)
        return {"epsilon": e}
    if effect == "cable_damping":
        return {"factor": rng.uniform(0.5, 1.5)}  # every cable's damping × (1 + factor)
    if effect == "slack":
        return {"fraction": rng.uniform(0.5, 0.7)}  # pretension lost, a share of the nominal
    if effect == "coupling":
        return {"delta_C10": float(rng.choice([-1.0, 1.0]) * rng.uniform(0.02, 0.05) * nom["coupling"][1][0])}
    if effect == "time_delay":
        return {"d": rng.uniform(0.0005, 0.002)}
    raise ValueError(f"no transmission generator for {effect!r}")


def _truth_model(nom: dict[str, Any], truth: dict[str, dict[str, Any]]) -> ck.CableTransmission:
    p = {k: (list(v) if isinstance(v, list) else v) for k, v in nom.items()}
    p["coupling"] = [list(row) for row in nom["coupling"]]
    if "coulomb_friction" in truth:
        extra = truth["coulomb_friction"]["F_c"]
        p["link_coulomb"] = [c + f for c, f in zip(p["link_coulomb"], extra, strict=True)]
        p["link_smoothing"] = [s / 10 for s in p["link_smoothing"]]
    if "viscous_friction" in truth:
        b = truth["viscous_friction"]["delta_b"]
        p["link_viscous"] = [v + d for v, d in zip(p["link_viscous"], b, strict=True)]
    if "inertia_error" in truth:
        e = truth["inertia_error"]["epsilon"]
        p["link_inertia"] = [j * (1 + x) for j, x in zip(p["link_inertia"], e, strict=True)]
    if "cable_damping" in truth:
        p["cable_damping"] = [c * (1 + truth["cable_damping"]["factor"]) for c in p["cable_damping"]]
    if "slack" in truth:
        p["pretension"] = [t * (1 - truth["slack"]["fraction"]) for t in p["pretension"]]
    if "coupling" in truth:
        p["coupling"][1][0] += truth["coupling"]["delta_C10"]
    return ck.CableTransmission(**p)


def _scaled(truth: dict[str, dict[str, Any]], factor: float) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    for e, params in truth.items():
        out[e] = {
            k: [x * factor for x in v] if isinstance(v, list) else v * factor for k, v in params.items()
        }
        if e == "slack":  # a cable cannot lose more than its pretension
            out[e]["fraction"] = min(out[e]["fraction"], 0.95)
    return out


def _generate_run(
    name: str,
    nom: dict[str, Any],
    truth: dict[str, dict[str, Any]],
    rng: np.random.Generator,
    duration: float,
    held_out: bool,
) -> Run:
    model = _truth_model(nom, truth)
    tmat = ck.CableTransmission(**nom).transmission_matrix  # the references use the nominal kinematics
    comps = _joint_trajectory(rng, held_out)
    n = round(duration / DT)
    t = np.arange(n) * DT
    pd = ck.MotorPD.raven2(LINKS)
    x0 = np.zeros(model.n_states)
    sub = 4 * max(1, ck.propose_step(model, DT, x0, np.zeros(model.n_inputs)).substeps)
    for _ in range(8):
        q, dq = _eval(comps, t)
        ref = np.column_stack([q @ tmat.T, dq @ tmat.T])
        applied_ref = ref
        if "time_delay" in truth:
            qd, dqd = _eval(comps, np.maximum(t - truth["time_delay"]["d"], 0.0))
            applied_ref = np.column_stack([qd @ tmat.T, dqd @ tmat.T])
        res = ck.simulate_servo(model, np.ascontiguousarray(applied_ref), DT, pd, x0=x0, substeps=sub)
        at_limit = np.abs(res.inputs[:, :LINKS]) >= 0.99 * np.asarray(pd.torque_limit)
        if at_limit.mean() <= MAX_SATURATION:
            break
        # a real operator keeps the servo out of its current limit: shrink the motion
        comps = [[(0.8 * a, f, ph) for a, f, ph in link] for link in comps]
    cols: dict[str, np.ndarray] = {}
    for i in range(1, LINKS + 1):
        cols[f"ref{i}"] = ref[:, i - 1]
        cols[f"dref{i}"] = ref[:, LINKS + i - 1]  # the servo logs the rate references it used
        cols[f"qm{i}"] = res[f"q_m{i}"] + rng.normal(0.0, NOISE_ANGLE, n)
        cols[f"ql{i}"] = res[f"q_l{i}"] + rng.normal(0.0, NOISE_ANGLE, n)
        cols[f"u{i}"] = res.inputs[:, i - 1] + rng.normal(0.0, NOISE_TORQUE, n)
    return Run(name, t, {k: np.ascontiguousarray(v) for k, v in cols.items()})


def make_transmission_case(effects: tuple[str, ...], seed: int, duration: float = 8.0) -> Case:
    """Generate one transmission case; ``effects`` empty for a control."""
    from cablekit.diagnose.selftest import Case, visible_runs

    rng = np.random.default_rng(seed)
    nom = _nominal(rng)
    truth = {e: _draw_truth(e, rng, nom) for e in effects}
    outputs = {}
    for i in range(1, LINKS + 1):
        outputs |= {f"q_m{i}": f"qm{i}", f"q_l{i}": f"ql{i}", f"tau_m{i}": f"u{i}"}
    spec = model_spec_from_dict(
        {
            "model": "cable_transmission",
            "parameters": nom,
            "inputs": {
                "q_m_ref": [f"ref{i}" for i in range(1, LINKS + 1)],
                "dq_m_ref": [f"dref{i}" for i in range(1, LINKS + 1)],
            },
            "servo": {"preset": "raven2"},
            "outputs": outputs,
            "diagnosis": {"warmup": 0.05},
        },
        source=f"self-test transmission case {seed}",
    )

    def generate(truth: dict[str, dict[str, Any]], gen: np.random.Generator) -> tuple[list[Run], list[Run]]:
        fit = [_generate_run("fit", nom, truth, gen, duration, False)]
        hold = [_generate_run("held_out", nom, truth, gen, duration, True)]
        return fit, hold

    # visible on the fit runs too: slack, for one, may show only on the faster held-out run
    fit, hold, truth, scale = visible_runs(
        spec, generate, truth, lambda t: _scaled(t, 2.0), int(rng.integers(1 << 31)), fit_too=True
    )
    label = "raven:" + ("+".join(effects) if effects else "control")
    noise = {"angle": NOISE_ANGLE, "torque": NOISE_TORQUE}
    truth_doc = {"nominal": nom, "effects": truth, "noise": noise, "scaled": scale}
    return Case(label, effects, spec, fit, hold, truth_doc)
