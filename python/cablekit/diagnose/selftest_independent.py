"""An independent self-test: runs from a simulator that shares no code with the candidates.

The regression self-test (:mod:`cablekit.diagnose.selftest`) generates its "real" runs with a
higher-fidelity configuration of cablekit's own simulator, so it mostly measures agreement with
ourselves. This generator is written separately, from the physics literature rather than from
``identify/effects.rs``:

* its own integrator: SciPy's LSODA (switches to BDF on stiff stretches: LuGre bristles,
  Bouc–Wen states, tight cables, stiff backlash contacts; restarted at the stick/slip events of
  Karnopp friction, a hybrid system), never cablekit's RK4;
* its own effect forms, at least two per effect, each different from the candidate's law:
  LuGre and load-dependent Coulomb friction, LuGre–Stribeck, Tustin's exponential map and
  Karnopp's stick–slip model (a velocity dead band with a true stick at the static level, a
  Stribeck drop to the Coulomb level outside it), power-law viscous drag, Bouc–Wen and
  Maxwell-slip (multi-element) hysteresis in the joint and in the cable–pulley contacts,
  linearised capstan with bearing drag, toe-region power-law and bilinear (soft below a knee
  tension) cables, tension-proportional damping, Prony-series and whole-tension creep, rounded
  backlash, play between the joint pulley and the link (two inertias, a dead zone with a stiff,
  damped contact), an asymmetric routing coupling, Butterworth, RC + averaging and underdamped
  second-order (load-cell resonance) amplifiers, HX711 holds at 10 and 80 Hz with noise **after**
  the hold and a plain 20–50 Hz sample-and-hold with the noise **before** it (held noise), delays
  in the command path, the force sensors' bus or the encoder alone, gain/bias on one or every load
  cell, heavier and lighter links and a payload;
* realistic sensors on every case: a quantised quadrature encoder on the joint, load cells with
  white noise and a small mains hum, the command logged as sent;
* two scales (forceps: r 2–6 mm, T₀ 8–25 N; pulley board: r 12–30 mm, T₀ 20–60 N) and four
  trajectory families (multisine, chirp, minimum-jerk pick-and-place with dwells, smoothed
  triangle), the held-out run always from another family than the fit run.

Three kinds of case:

* singles (:data:`CASES`): one effect withheld at one site; the diagnosis is scored on the effect
  name and, as a separate figure, on the site (``sensors.force``, ``contact.both``, …) of its
  top-ranked candidate;
* pairs (:data:`PAIRS`): two effects at once (LuGre Coulomb friction + a Butterworth load-cell
  lag, saturated capstan friction + whole-tension creep, input play + gain/bias on both cells,
  power-law viscous drag + an encoder-clock delay), each scaled until it is visible on its own;
  the top-ranked candidate must name one of the two (its site scored against that one), and
  both names should be among the selected effects;
* out-of-library cases (:data:`OUTSIDE`): effects a library of cable-drive effects would not hold
  — an eccentric joint pulley (lever arm and wrapped length varying with the angle), a thermal
  drift of the drive load cell's zero (a warm-up, different in the two runs) and a cogging-like
  torque periodic in the joint angle; the honest answer is "not (fully) explained"
  (``ambiguous`` or ``partially_explained``), never ``explained``.

Seeds: the 36 original singles and the controls keep the seeds of their original positions
(``seed + 131·i``); singles appended later, pairs and out-of-library cases have seeds from their
own offsets (:func:`case_plan`), so adding cases never moves an existing case's data.
The only cablekit code used here is the diagnosis under test and the :class:`Run` container.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cablekit import _log
from cablekit.diagnose.data import Run
from cablekit.diagnose.selftest import MIN_VISIBLE_GAP, visible_runs
from cablekit.diagnose.spec import ModelSpec, model_spec_from_dict
from cablekit.errors import CablekitError

__all__ = [
    "CASES",
    "CI_SUBSET",
    "OUTSIDE",
    "PAIRS",
    "IndependentCase",
    "case_plan",
    "make_independent_case",
    "make_independent_pair",
    "run_independent",
]

DT = 1e-3  # recorded sample period (s)
FINE = 10  # input grid points per recorded sample

#: (effect, site, form) of every case. Sites use the diagnosis vocabulary (docs/diagnosis.md).
CASES: list[tuple[str, str, str]] = [
    ("coulomb_friction", "joint", "lugre"),
    ("coulomb_friction", "joint", "bearing_load"),
    ("viscous_friction", "joint", "linear"),
    ("viscous_friction", "joint", "power_law"),
    ("stribeck_friction", "joint", "lugre_stribeck"),
    ("stribeck_friction", "joint", "tustin"),
    ("dahl_hysteresis", "joint", "bouc_wen"),
    ("dahl_hysteresis", "joint", "maxwell_slip"),
    ("dahl_hysteresis", "contact.both", "bouc_wen_capstan"),
    ("dahl_hysteresis", "contact.both", "maxwell_slip"),
    ("capstan_friction", "contact.both", "saturated_exponential"),
    ("capstan_friction", "contact.both", "linear_bearing_drag"),
    ("capstan_friction", "contact.drive", "saturated_exponential"),
    ("nonlinear_stiffness", "cable.both", "toe_power_law"),
    ("nonlinear_stiffness", "cable.drive", "toe_power_law"),
    ("cable_damping", "cable.both", "linear"),
    ("cable_damping", "cable.both", "tension_proportional"),
    ("creep", "cable.both", "prony2"),
    ("creep", "cable.both", "whole_tension"),
    ("backlash", "input", "play"),
    ("backlash", "input", "rounded"),
    ("slack", "cable.both", "lost_pretension"),
    ("slack", "cable.drive", "lost_pretension"),
    ("coupling", "input", "linear"),
    ("coupling", "input", "asymmetric_routing"),
    ("sensor_lag", "sensors.force", "butterworth2"),
    ("sensor_lag", "sensor.tension_motor_drive", "rc_average"),
    ("sensor_sampling", "sensors.force", "hx711_10hz"),
    ("sensor_sampling", "sensors.force", "hx711_80hz"),
    ("time_delay", "input", "transport"),
    ("time_delay", "sensors.force", "bus"),
    ("time_delay", "sensor.theta", "encoder_clock"),
    ("sensor_gain_bias", "sensors.force", "both_cells"),
    ("sensor_gain_bias", "sensor.tension_motor_drive", "one_cell"),
    ("inertia_error", "joint", "heavier"),
    ("inertia_error", "joint", "lighter"),
    # appended later: seeds from their own offset (see `case_plan`), the ones above keep theirs
    ("backlash", "joint", "joint_play"),
    ("sensor_lag", "sensors.force", "underdamped"),
    ("stribeck_friction", "joint", "karnopp"),
    ("inertia_error", "joint", "payload"),
    ("nonlinear_stiffness", "cable.both", "bilinear"),
    ("sensor_sampling", "sensors.force", "plain_hold_noise_before"),
]
#: how many of `CASES` had their seeds from their position in the plan (before the controls)
ORIGINAL_CASES = 36
CONTROLS = 4
#: two effects at once, each from an existing form and each visible on its own
PAIRS: list[tuple[tuple[str, str, str], tuple[str, str, str]]] = [
    (("coulomb_friction", "joint", "lugre"), ("sensor_lag", "sensors.force", "butterworth2")),
    (("capstan_friction", "contact.both", "saturated_exponential"), ("creep", "cable.both", "whole_tension")),
    (("backlash", "input", "play"), ("sensor_gain_bias", "sensors.force", "both_cells")),
    (("viscous_friction", "joint", "power_law"), ("time_delay", "sensor.theta", "encoder_clock")),
]
#: effects outside any reasonable library of cable-drive effects: the honest answer is "not
#: (fully) explained"
OUTSIDE: list[tuple[str, str, str]] = [
    ("eccentric_pulley", "joint", "eccentric"),
    ("thermal_drift", "sensor.tension_motor_drive", "bias_warmup"),
    ("cogging", "joint", "angle_periodic"),
]
#: seed offsets of the cases added after the original plan (singles, pairs, outside)
_NEW_SINGLE_OFFSET = 1_000_000
_PAIR_OFFSET = 2_000_000
_OUTSIDE_OFFSET = 3_000_000
#: the cases `.ci/run` prints (one form of most effects, every site kind, a pair, a case outside
#: the library, two controls)
CI_SUBSET = [
    "stribeck_friction@joint/tustin",
    "dahl_hysteresis@contact.both/bouc_wen_capstan",
    "creep@cable.both/whole_tension",
    "sensor_sampling@sensors.force/hx711_10hz",
    "time_delay@sensors.force/bus",
    "slack@cable.drive/lost_pretension",
    "viscous_friction@joint/power_law+time_delay@sensor.theta/encoder_clock",
    "eccentric_pulley@joint/eccentric",
    "control/0",
    "control/1",
]


def _label(effects: list[tuple[str, str, str]] | tuple[tuple[str, str, str], ...]) -> str:
    return "+".join(f"{e}@{s}/{f}" for e, s, f in effects) if effects else "control"


def case_plan(seed: int = 4242, controls: int = CONTROLS) -> list[dict[str, Any]]:
    """Every case of the independent self-test in run order: ``label``, ``kind`` (``single``,
    ``pair``, ``outside``, ``control``), ``effects`` (a list of (effect, site, form)) and ``seed``.

    The original singles (``CASES[:ORIGINAL_CASES]``) and the controls after them keep the seeds
    of their positions in the original plan, ``seed + 131·i``; singles appended to ``CASES``
    later, the pairs and the out-of-library cases take ``seed + offset + 131·j`` with an offset of
    their own kind, so that appending a case never moves another one's data."""
    original: list[tuple[str, str, list[tuple[str, str, str]]]] = [
        (_label([c]), "single", [c]) for c in CASES[:ORIGINAL_CASES]
    ] + [(f"control/{i}", "control", []) for i in range(controls)]
    seeds = {label: seed + 131 * i for i, (label, _k, _e) in enumerate(original)}
    plan: list[dict[str, Any]] = [{"label": _label([c]), "kind": "single", "effects": [c]} for c in CASES]
    for j, c in enumerate(CASES[ORIGINAL_CASES:]):
        seeds[_label([c])] = seed + _NEW_SINGLE_OFFSET + 131 * j
    for j, pair in enumerate(PAIRS):
        plan.append({"label": _label(pair), "kind": "pair", "effects": list(pair)})
        seeds[_label(pair)] = seed + _PAIR_OFFSET + 131 * j
    for j, c in enumerate(OUTSIDE):
        plan.append({"label": _label([c]), "kind": "outside", "effects": [c]})
        seeds[_label([c])] = seed + _OUTSIDE_OFFSET + 131 * j
    plan += [{"label": f"control/{i}", "kind": "control", "effects": []} for i in range(controls)]
    for case in plan:
        case["seed"] = seeds[case["label"]]
    return plan


@dataclass
class IndependentCase:
    """One independent case: the nominal model file, the runs and the withheld truth.

    For a pair, ``effect``, ``site`` and ``form`` join the two with ``+``; ``effects`` lists
    every withheld (effect, site, form)."""

    label: str
    effect: str | None
    site: str | None
    form: str | None
    spec: ModelSpec
    fit: list[Run]
    hold: list[Run]
    truth: dict[str, Any]
    effects: list[tuple[str, str, str]] = field(default_factory=list)


# ---------------------------------------------------------------------------------------------
# nominal plants


def _nominal(rng: np.random.Generator, scale: str) -> dict[str, float]:
    if scale == "forceps":
        r = rng.uniform(2e-3, 6e-3)
        k = 10 ** rng.uniform(math.log10(8e3), math.log10(4e4))
        t0 = rng.uniform(8.0, 25.0)
        wn = rng.uniform(120.0, 300.0)
        lever = 0.01
    else:  # pulley board
        r = rng.uniform(12e-3, 30e-3)
        k = 10 ** rng.uniform(math.log10(5e3), math.log10(3e4))
        t0 = rng.uniform(20.0, 60.0)
        wn = rng.uniform(40.0, 120.0)
        lever = 0.05
    kt = 2.0 * k * r * r
    j = kt / wn**2
    zeta = rng.uniform(0.05, 0.2)
    crit = 2.0 * math.sqrt(kt * j)
    k_contact = rng.uniform(0.3, 0.6) * kt / lever**2
    return {
        "radius": r,
        "stiffness": k,
        "inertia": j,
        "damping": zeta * crit / (2.0 * r * r),
        "pretension": t0,
        "viscous": 0.05 * crit,
        "smoothing": 0.05,
        "contact_angle": rng.uniform(0.15, 0.3),
        "contact_stiffness": k_contact,
        "contact_damping": 0.02 * k_contact * 0.01,
        "contact_lever_arm": lever,
    }


# ---------------------------------------------------------------------------------------------
# trajectories: joint-angle references θ_ref(t) on the fine grid

FAMILIES = ("multisine", "chirp", "pick_and_place", "triangle")


def _min_jerk(u: np.ndarray) -> np.ndarray:
    return u**3 * (10 - 15 * u + 6 * u * u)


def _trajectory(family: str, rng: np.random.Generator, t: np.ndarray) -> np.ndarray:
    dur = t[-1] + (t[1] - t[0])
    if family == "multisine":
        f = [rng.uniform(0.2, 0.5), rng.uniform(1.5, 3.0), rng.uniform(8.0, 14.0)]
        a = [rng.uniform(0.35, 0.55), rng.uniform(0.05, 0.1), rng.uniform(0.008, 0.015)]
        return sum(a[i] * np.sin(2 * np.pi * f[i] * t + rng.uniform(0, 2 * np.pi)) for i in range(3))
    if family == "chirp":
        f0, f1 = rng.uniform(0.1, 0.3), rng.uniform(4.0, 8.0)
        phase = 2 * np.pi * (f0 * t + 0.5 * (f1 - f0) / dur * t * t)
        amp = 0.5 / (1.0 + 2.0 * t / dur)  # smaller amplitude at high frequency
        return amp * np.sin(phase) + 0.05 * np.sin(2 * np.pi * 0.07 * t)
    if family == "pick_and_place":
        th = np.zeros_like(t)
        k0, cur, tk = 0, 0.0, 0.0
        while tk < dur:
            move = rng.uniform(0.4, 1.2)
            dwell = rng.uniform(0.2, 0.8)
            target = rng.uniform(-0.5, 0.5)
            m = (t >= tk) & (t < tk + move)
            th[m] = cur + (target - cur) * _min_jerk((t[m] - tk) / move)
            d = (t >= tk + move) & (t < tk + move + dwell)
            th[d] = target
            cur, tk, k0 = target, tk + move + dwell, k0 + 1
        return th
    if family == "triangle":
        f = rng.uniform(0.25, 0.6)
        amp = rng.uniform(0.35, 0.55)
        tri = (2 * amp / np.pi) * np.arcsin(np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi)))
        # round the corners (a 40 ms moving average): real position loops cannot turn instantly
        w = max(1, round(0.04 / (t[1] - t[0])))
        pad = np.pad(tri, (w, w), mode="edge")
        return np.convolve(pad, np.ones(w) / w, mode="same")[w:-w] + 0.01 * np.sin(2 * np.pi * 9.0 * t)
    raise ValueError(family)


# ---------------------------------------------------------------------------------------------
# the plant: θ, ω and the states of the withheld effect, integrated by LSODA


def _sat(x: float) -> float:
    return 1.0 if x > 1.0 else -1.0 if x < -1.0 else x


def _sgn(x: float) -> float:
    return 1.0 if x > 0 else -1.0 if x < 0 else 0.0


def _slip_rate(v: float, load: float) -> float:
    """Rate of one Maxwell-slip element's deflection: it sticks (follows v) until its spring
    force reaches its slip force (|load| = 1), then slides; the transition is steep but
    continuous so that the implicit integrator is not forced to step through a switch."""
    if v * load <= 0.0:
        return v
    return v * max(0.0, 1.0 - abs(load) ** 8)


@dataclass
class _Effect:
    """One withheld effect inside the plant and where its states sit in the state vector."""

    effect: str
    site: str
    form: str
    p: dict
    base: int  # index of its first internal state
    n: int  # number of internal states

    @property
    def key(self) -> str:
        return f"{self.effect}@{self.site}/{self.form}"


def _n_states(key: str, p: dict) -> int:
    """Internal states an effect adds beyond [θ, ω]."""
    if key in ("coulomb_friction@joint/lugre", "stribeck_friction@joint/lugre_stribeck"):
        return 1
    if key == "dahl_hysteresis@joint/bouc_wen":
        return 1
    if key == "dahl_hysteresis@joint/maxwell_slip":
        return len(p["k_i"])
    if key == "dahl_hysteresis@contact.both/bouc_wen_capstan":
        return 2
    if key == "dahl_hysteresis@contact.both/maxwell_slip":
        return 2 * len(p["k_i"])
    if key == "creep@cable.both/prony2":
        return 4
    if key == "creep@cable.both/whole_tension":
        return 2
    if key == "backlash@joint/joint_play":
        return 2  # the link's angle and rate (θ, ω are the joint pulley's)
    return 0


class _Plant:
    """Antagonistic joint with the withheld effects, written from the physics (see module).

    ``_Plant(nom, effect, site, form, p)`` for one effect (``effect`` None: the nominal plant)
    or ``_Plant(nom, effects=[(effect, site, form, p), ...])`` for several (one form per effect
    name). The states are [θ, ω] of the joint pulley, then each effect's own, in order."""

    def __init__(
        self,
        nom: dict[str, float],
        effect: str | None = None,
        site: str | None = None,
        form: str | None = None,
        p: dict | None = None,
        *,
        effects: list[tuple[Any, Any, Any, dict]] | None = None,
    ):
        if effects is None:
            effects = [(effect, site, form, p or {})] if effect else []
        self.nom = nom
        self.effects: list[_Effect] = []
        base = 2
        for e, s, f, q in effects:
            eff = _Effect(e, s, f, q, base, _n_states(f"{e}@{s}/{f}", q))
            base += eff.n
            self.effects.append(eff)
        self.n_extra = base - 2
        self.by_key = {e.key: e for e in self.effects}
        self.by_name = {e.effect: e for e in self.effects}
        if len(self.by_name) != len(self.effects):
            raise ValueError("independent generator: at most one form of each effect at a time")
        self.play = self.by_key.get("backlash@joint/joint_play")
        self.karnopp = self.by_key.get("stribeck_friction@joint/karnopp")
        self.mode = 0  # Karnopp friction: 0 sticking, ±1 sliding that way
        self.applied = 0.0  # Karnopp friction: the torque on the joint besides friction
        #: index of the rate of the body the joint friction acts on (the link's with joint play)
        self.rate_index = 1 if self.play is None else self.play.base + 1

    # cable tension of one cable from its stretch, rate and relaxation
    def _cable(self, which: int, s: float, sd: float, relax: float) -> float:
        nom = self.nom
        k, c, t0 = nom["stiffness"], nom["damping"], nom["pretension"]
        e = self.by_name.get("slack")
        if e is not None and (e.site == "cable.both" or which == 0):
            t0 = t0 - e.p["delta_T0"]
        e = self.by_name.get("nonlinear_stiffness")
        if e is not None and (e.site == "cable.both" or which == 0):
            if e.form == "bilinear":
                # piecewise-linear cable (a braided rope's constructional stretch): stiffness
                # ratio·k below the knee tension, the nominal k above it (around the preload)
                t_knee = e.p["knee"] * t0
                s_knee = (t_knee - t0) / k
                elastic = k * s if s >= s_knee else (t_knee - t0) + e.p["ratio"] * k * (s - s_knee)
            else:
                # toe-region power law T = K·e^q of the total strain e, tangent k at the nominal
                # preload (so the nominal model is its linearisation): e₀ = q·T₀/k
                q = e.p["q"]
                e0 = q * t0 / k
                ee = max(e0 + s, 0.0)
                elastic = t0 * (ee / e0) ** q - t0
        else:
            elastic = k * s
        damp = c
        e = self.by_key.get("cable_damping@cable.both/linear")
        if e is not None:
            damp = c + e.p["delta_c"]
        e = self.by_key.get("cable_damping@cable.both/tension_proportional")
        if e is not None:
            damp = c + e.p["delta_c"] * max(t0 + elastic, 0.0) / t0
        return max(0.0, t0 + elastic + damp * sd - relax)

    def _joint_side(
        self, x: np.ndarray, xm: float, vm: float, xc: float
    ) -> tuple[float, float, float, float]:
        """Stretches (s₁, s₂) and joint-side tensions (T_j,1, T_j,2) at one state."""
        r = self.nom["radius"]
        s1, sd1 = xm - r * x[0], vm - r * x[1]
        s2, sd2 = -s1, -sd1
        e = self.by_name.get("coupling")
        if e is not None:
            # asymmetric form: the return cable is routed over the coupled axis on a smaller radius
            c2 = 1.0 if e.form == "linear" else 0.4
            s1, s2 = s1 + e.p["kappa_c"] * xc, s2 - c2 * e.p["kappa_c"] * xc
        e = self.by_name.get("eccentric_pulley")
        if e is not None:
            # pulley centre offset ε from the axis: both cables (leaving on the same side, at the
            # top and bottom tangents) wrap an extra ε(cos φ − cos(θ+φ)), taken up as a
            # common-mode stretch; the pretension was set at θ = 0
            eps, phi = e.p["e_frac"] * r, e.p["phi"]
            g = eps * (math.cos(phi) - math.cos(x[0] + phi))
            gd = eps * math.sin(x[0] + phi) * x[1]
            s1, s2, sd1, sd2 = s1 - g, s2 - g, sd1 - gd, sd2 - gd
        relax = (0.0, 0.0)
        e = self.by_key.get("creep@cable.both/prony2")
        if e is not None:
            b = e.base
            relax = (x[b] + x[b + 1], x[b + 2] + x[b + 3])
        e = self.by_key.get("creep@cable.both/whole_tension")
        if e is not None:
            relax = (x[e.base], x[e.base + 1])
        return s1, s2, self._cable(0, s1, sd1, relax[0]), self._cable(1, s2, sd2, relax[1])

    def _play_torque(self, x: np.ndarray) -> tuple[float, float, float]:
        """Joint play: contact torque between the pulley and the link (a dead zone of the drawn
        width, then a stiff spring with damping that can push but never pull), and the two
        inertias (pulley, link)."""
        e = self.play
        assert e is not None
        p, b = e.p, e.base
        jt = self.inertia()
        jp = p["share"] * jt
        jl = jt - jp
        half = 0.5 * p["gap"]
        ph, phd = x[0] - x[b], x[1] - x[b + 1]
        kc = p["k_c"]
        cc = 2.0 * p["zeta_c"] * math.sqrt(kc * jp * jl / jt)
        if ph > half:
            tau = max(0.0, kc * (ph - half) + cc * phd)
        elif ph < -half:
            tau = min(0.0, kc * (ph + half) + cc * phd)
        else:
            tau = 0.0
        return tau, jp, jl

    def rhs(self, t: float, x: np.ndarray, xm: float, vm: float, xc: float) -> np.ndarray:
        nom = self.nom
        r = nom["radius"]
        th, om = x[0], x[1]
        dx = np.zeros_like(x)
        s1, s2, t1, t2 = self._joint_side(x, xm, vm, xc)
        tq_cable = r * (t1 - t2)
        ecc = self.by_name.get("eccentric_pulley")
        if ecc is not None:
            # the offset centre lengthens one lever arm and shortens the other: r ± ε sin(θ+φ)
            tq_cable = tq_cable + ecc.p["e_frac"] * r * math.sin(th + ecc.p["phi"]) * (t1 + t2)
        # `torque` collects what acts on the link: with joint play a body of its own behind the
        # dead zone, otherwise one body with the pulley
        if self.play is not None:
            tau_c, jp, j_link = self._play_torque(x)
            th_l, om_l = x[self.play.base], x[self.play.base + 1]
            torque = tau_c - nom["viscous"] * om_l
        else:
            th_l, om_l = th, om
            torque = tq_cable - nom["viscous"] * om
        # contact with the object
        lever = nom["contact_lever_arm"]
        pen = lever * (th_l - nom["contact_angle"])
        if pen > 0:
            torque -= lever * max(0.0, nom["contact_stiffness"] * pen + nom["contact_damping"] * lever * om_l)
        # joint friction and hysteresis
        for e in self.effects:
            key, p, b = e.key, e.p, e.base
            if key in ("coulomb_friction@joint/lugre", "stribeck_friction@joint/lugre_stribeck"):
                # LuGre (Canudas de Wit et al. 1995): ż = ω − σ₀|ω| z / g(ω), F = σ₀z + σ₁ż
                fc = p["F_c"]
                g = (
                    fc
                    if e.effect == "coulomb_friction"
                    else fc + p["dF"] * math.exp(-((om_l / p["v_s"]) ** 2))
                )
                z = x[b]
                zd = om_l - p["sigma0"] * abs(om_l) * z / g
                dx[b] = zd
                torque -= p["sigma0"] * z + p["sigma1"] * zd
            elif key == "coulomb_friction@joint/bearing_load":
                # bearing friction grows with the radial load the two cables put on the joint shaft
                torque -= p["mu_b"] * (t1 + t2) * math.tanh(om_l / 2e-3)
            elif key == "viscous_friction@joint/linear":
                torque -= p["delta_b"] * om_l
            elif key == "viscous_friction@joint/power_law":
                torque -= p["b_p"] * abs(om_l) ** 0.7 * _sgn(om_l)
            elif key == "stribeck_friction@joint/tustin":
                # Tustin's exponential Stribeck map (exponent 1), sharp sign
                f = p["F_c"] + p["dF"] * math.exp(-abs(om_l) / p["v_s"])
                torque -= f * math.tanh(om_l / 1e-3)
            elif key == "dahl_hysteresis@joint/bouc_wen":
                # Bouc–Wen: ż = (ω/θ_y)(1 − |z|ⁿ(β sgn(ωz) + γ)), torque F_y·z
                z = x[b]
                dx[b] = (om_l / p["theta_y"]) * (1 - abs(z) ** 2 * (0.7 * _sgn(om_l * z) + 0.3))
                torque -= p["F_y"] * z
            elif key == "dahl_hysteresis@joint/maxwell_slip":
                # Maxwell-slip: elasto-plastic elements k_i with slip torques f_i, in parallel
                for i, (ki, fi) in enumerate(zip(p["k_i"], p["f_i"], strict=True)):
                    zi = x[b + i]
                    dx[b + i] = _slip_rate(om_l, ki * zi / fi)
                    torque -= ki * zi
            elif e.effect == "cogging":
                # a detent torque periodic in the joint angle (n periods per revolution)
                torque -= p["amp"] * math.sin(p["n"] * th_l + p["phi"])
        kp = self.karnopp
        if kp is not None:
            # Karnopp (1985): the joint sticks at zero speed while the applied torque stays within
            # the static level F_s (friction cancels it); sliding, friction opposes the motion
            # and falls from F_s to the Coulomb level F_c along a Gaussian Stribeck curve
            # (Armstrong-Hélouvry 1991). The modes switch on events (see `_stick_slip`): a speed
            # entering the dead band |ω| < Δv with |applied| ≤ F_s is reset to zero and sticks
            self.applied = torque
            if self.mode == 0:
                torque = 0.0
            else:
                p = kp.p
                torque -= self.mode * (p["F_c"] + (p["F_s"] - p["F_c"]) * math.exp(-((om_l / p["v_s"]) ** 2)))
        # creep states
        for e in self.effects:
            key, p, b = e.key, e.p, e.base
            if key == "creep@cable.both/prony2":
                k = nom["stiffness"]
                for j, s in enumerate((s1, s2)):
                    for m, (kap, tau) in enumerate(zip(p["kappa"], p["tau"], strict=True)):
                        idx = b + 2 * j + m
                        dx[idx] = (kap * k * s - x[idx]) / tau
            elif key == "creep@cable.both/whole_tension":
                for j, tj in enumerate((t1, t2)):
                    dx[b + j] = (p["kappa"] * (tj + x[b + j]) - x[b + j]) / p["tau"]
        # contact hysteresis states (driven by the cable's sliding speed on the pulleys, ẋ_m)
        for e in self.effects:
            key, p, b = e.key, e.p, e.base
            if key == "dahl_hysteresis@contact.both/bouc_wen_capstan":
                for j, v in enumerate((vm, -vm)):
                    z = x[b + j]
                    dx[b + j] = (v / p["x_y"]) * (1 - abs(z) ** 2 * (0.7 * _sgn(v * z) + 0.3))
            elif key == "dahl_hysteresis@contact.both/maxwell_slip":
                n = len(p["k_i"])
                for j, v in enumerate((vm, -vm)):
                    for i, (ki, fi) in enumerate(zip(p["k_i"], p["f_i"], strict=True)):
                        zi = x[b + j * n + i]
                        dx[b + j * n + i] = _slip_rate(v, ki * zi / fi)
        dx[0] = om
        if self.play is not None:
            dx[1] = (tq_cable - tau_c) / jp
            dx[self.play.base] = om_l
            dx[self.play.base + 1] = torque / j_link
        else:
            dx[1] = torque / self.inertia()
        return dx

    def inertia(self) -> float:
        """The joint's whole inertia (pulley and link)."""
        j = self.nom["inertia"]
        e = self.by_name.get("inertia_error")
        if e is not None:
            j *= 1 + e.p["epsilon"]
        return j

    def initial_state(self, theta0: float) -> np.ndarray:
        x0 = np.zeros(2 + self.n_extra)
        x0[0] = theta0
        if self.play is not None:
            x0[self.play.base] = theta0
        return x0

    def motor_tensions(self, x: np.ndarray, xm: float, vm: float, xc: float) -> tuple[float, float, float]:
        """(T_m,drive, T_m,return, θ) at one state; θ is the link's (what the encoder reads)."""
        nom = self.nom
        th = x[0] if self.play is None else x[self.play.base]
        _, _, t1, t2 = self._joint_side(x, xm, vm, xc)
        for e in self.effects:
            p, key = e.p, e.key
            if e.effect == "capstan_friction":
                # the cable slides over the routing pulleys at ẋ_m; the drive side is hauled in
                if e.form == "saturated_exponential":
                    a = p["mu_phi"] * _sat(vm / p["v0"])
                    t1 = t1 * math.exp(a)
                    if e.site == "contact.both":
                        t2 = t2 * math.exp(-a)
                else:  # linearised capstan plus pulley-bearing drag
                    sg = _sat(vm / p["v0"])
                    t1 = t1 * (1 + p["mu_phi"] * sg) + p["drag"] * sg
                    t2 = t2 * (1 - p["mu_phi"] * sg) - p["drag"] * sg
            elif key == "dahl_hysteresis@contact.both/bouc_wen_capstan":
                t1 = t1 * math.exp(p["mu_phi"] * x[e.base])
                t2 = t2 * math.exp(p["mu_phi"] * x[e.base + 1])
            elif key == "dahl_hysteresis@contact.both/maxwell_slip":
                n = len(p["k_i"])
                h1 = sum(ki * x[e.base + i] for i, ki in enumerate(p["k_i"]))
                h2 = sum(ki * x[e.base + n + i] for i, ki in enumerate(p["k_i"]))
                # slip forces scale with the tension pressing the cable on the pulley
                t0 = nom["pretension"]
                t1, t2 = t1 * (1 + h1 / t0), t2 * (1 + h2 / t0)
        return t1, t2, th


def _play(x: np.ndarray, width: float) -> np.ndarray:
    y = np.empty_like(x)
    prev = x[0]
    for k, xv in enumerate(x):
        prev = min(max(prev, xv - width), xv + width)
        y[k] = prev
    return y


def _rounded_play(x: np.ndarray, width: float) -> np.ndarray:
    """Backlash whose engagement is gradual (elastic gear teeth): the output follows the input
    at the rate ẋ·((1 + g·sgn ẋ / δ)/2)⁶ of the gap g = x − y."""
    y = np.empty_like(x)
    y[0] = x[0]
    for k in range(1, len(x)):
        dxk = x[k] - x[k - 1]
        g = x[k - 1] - y[k - 1]
        u = min(max(g * (1 if dxk > 0 else -1) / width, -1.0), 1.0)
        y[k] = y[k - 1] + dxk * ((1 + u) / 2) ** 6
        y[k] = min(max(y[k], x[k] - width), x[k] + width)
    return y


def _simulate(plant: _Plant, tf: np.ndarray, xm: np.ndarray, xc: np.ndarray) -> np.ndarray:
    """LSODA over the fine input grid (linear interpolation between points); returns
    [T_m,drive, T_m,return, θ] at every recorded sample."""
    from scipy.integrate import solve_ivp

    h = tf[1] - tf[0]
    vm = np.gradient(xm, h)
    n = len(tf)

    def inp(t: float) -> tuple[float, float, float]:
        i = min(max(int(t / h), 0), n - 2)
        a = (t - tf[i]) / h
        return (
            xm[i] + a * (xm[i + 1] - xm[i]),
            vm[i] + a * (vm[i + 1] - vm[i]),
            xc[i] + a * (xc[i + 1] - xc[i]),
        )

    def f(t: float, x: np.ndarray) -> np.ndarray:
        return plant.rhs(t, x, *inp(t))

    x0 = plant.initial_state(xm[0] / plant.nom["radius"])
    t_rec = tf[::FINE]
    if plant.karnopp is not None:
        y = _stick_slip(plant, f, inp, tf, t_rec, x0)
    else:
        sol = solve_ivp(
            f, (tf[0], tf[-1]), x0, method="LSODA", t_eval=t_rec, rtol=1e-6, atol=1e-9, max_step=DT / 2
        )
        if not sol.success or sol.y.shape[1] != len(t_rec):
            raise RuntimeError(f"independent generator: LSODA failed ({sol.message})")
        y = sol.y
    out = np.empty((len(t_rec), 3))
    for k in range(len(t_rec)):
        out[k] = plant.motor_tensions(y[:, k], *inp(t_rec[k]))
    return out


def _stick_slip(plant: _Plant, f, inp, tf: np.ndarray, t_rec: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """Karnopp friction as a hybrid system: LSODA on one smooth vector field at a time (sticking,
    or sliding one way), restarted at the events that switch them. Sliding ``m``: the joint
    enters the stick region (|ω| < Δv and |applied| ≤ F_s; its speed is reset to zero) or its
    speed reverses inside the band (sliding on the applied torque's side). Sticking: the applied
    torque reaches F_s (breakaway towards it)."""
    from scipy.integrate import solve_ivp

    e = plant.karnopp
    assert e is not None
    fs, dv, iw = e.p["F_s"], e.p["dv"], plant.rate_index

    def applied(t: float, x: np.ndarray) -> float:
        plant.rhs(t, x, *inp(t))
        return plant.applied

    def breakaway(t: float, x: np.ndarray) -> float:
        return abs(applied(t, x)) - fs

    def sticks(t: float, x: np.ndarray) -> float:
        return max((abs(x[iw]) - dv) / dv, (abs(applied(t, x)) - fs) / fs)

    def reverses(t: float, x: np.ndarray) -> float:
        return plant.mode * x[iw]

    breakaway.terminal, breakaway.direction = True, 1  # type: ignore[attr-defined]
    sticks.terminal, sticks.direction = True, -1  # type: ignore[attr-defined]
    reverses.terminal, reverses.direction = True, -1  # type: ignore[attr-defined]

    def decide(t: float, x: np.ndarray, stick: bool) -> None:
        tau = applied(t, x)
        if stick or abs(tau) <= fs:
            plant.mode = 0
            x[iw] = 0.0
        else:
            plant.mode = 1 if tau > 0 else -1

    t, x = float(tf[0]), x0.copy()
    decide(t, x, False)  # starts at rest
    ys, k, stalls = [], 0, 0
    while k < len(t_rec):
        events = [breakaway] if plant.mode == 0 else [sticks, reverses]
        sol = solve_ivp(
            f,
            (t, tf[-1]),
            x,
            method="LSODA",
            t_eval=t_rec[k:],
            events=events,
            rtol=1e-6,
            atol=1e-9,
            max_step=DT / 2,
        )
        if not sol.success:
            raise RuntimeError(f"independent generator: LSODA failed ({sol.message})")
        ys.append(sol.y)
        k += sol.y.shape[1]
        if sol.status != 1:
            break
        hit = next(i for i, te in enumerate(sol.t_events) if len(te))
        t_new, x = float(sol.t_events[hit][0]), sol.y_events[hit][0].copy()
        stalls = stalls + 1 if t_new <= t else 0
        if stalls > 100:
            raise RuntimeError(f"independent generator: stick-slip switching stalls at t = {t:.6f} s")
        t = t_new
        if plant.mode == 0:  # breakaway, towards the applied torque
            plant.mode = 1 if applied(t, x) > 0 else -1
        else:  # into the stick region, or a reversal inside the band
            decide(t, x, events[hit] is sticks)
    y = np.concatenate(ys, axis=1)
    if y.shape[1] != len(t_rec):
        raise RuntimeError("independent generator: stick-slip integration ended early")
    return y


# ---------------------------------------------------------------------------------------------
# sensors


def _butter2(y: np.ndarray, fc: float) -> np.ndarray:
    from scipy.signal import butter, lfilter, lfilter_zi

    b, a = butter(2, fc, fs=1.0 / DT)
    return lfilter(b, a, y, zi=lfilter_zi(b, a) * y[0])[0]


def _rc_average(y: np.ndarray, tau: float, n_avg: int) -> np.ndarray:
    from scipy.signal import lfilter

    al = math.exp(-DT / tau)
    z = lfilter([1 - al], [1, -al], y - y[0]) + y[0]
    pad = np.concatenate([np.full(n_avg - 1, z[0]), z])
    return np.convolve(pad, np.ones(n_avg) / n_avg, mode="valid")


def _second_order(y: np.ndarray, fn: float, zeta: float) -> np.ndarray:
    """A load cell with its own resonance (the cell's flexure carrying the pulley or clamp
    mass): ω_n²/(s² + 2ζω_n s + ω_n²), unit static gain, discretised for a signal linear between
    samples (first-order hold), starting at rest on the first sample."""
    from scipy.signal import cont2discrete, lfilter, lfilter_zi

    wn = 2.0 * math.pi * fn
    num, den, _ = cont2discrete(([wn * wn], [1.0, 2.0 * zeta * wn, wn * wn]), DT, method="foh")
    b, a = np.ravel(num), np.ravel(den)
    return lfilter(b, a, y, zi=lfilter_zi(b, a) * y[0])[0]


def _hold(t: np.ndarray, y: np.ndarray, rate: float, phase: float, jitter: float, rng) -> np.ndarray:
    """An HX711-like converter: conversions at ``rate`` (with clock jitter), each held until
    the next; the value is the signal at the conversion instant."""
    period = 1.0 / rate
    inst = np.arange(phase, t[-1] + period, period)
    inst = inst + rng.normal(0.0, jitter * period, inst.shape)
    vals = np.interp(inst, t, y)
    idx = np.searchsorted(inst, t, side="right") - 1
    out = np.where(idx >= 0, vals[np.clip(idx, 0, None)], vals[0])
    return out


def _plain_hold(t: np.ndarray, y: np.ndarray, rate: float, phase: float) -> np.ndarray:
    """A plain sample-and-hold on a crystal clock: at each tick it latches the latest sample
    (noise and all) and holds it until the next tick."""
    period = 1.0 / rate
    ticks = np.arange(phase, t[-1] + period, period)
    latched = y[np.clip(np.searchsorted(t, ticks, side="right") - 1, 0, len(y) - 1)]
    idx = np.searchsorted(ticks, t, side="right") - 1
    return np.where(idx >= 0, latched[np.clip(idx, 0, None)], y[0])


def _force_sites(site: str | None) -> list[int]:
    return [0, 1] if site == "sensors.force" else [0] if site == "sensor.tension_motor_drive" else []


def _effects_of(truth: dict[str, Any] | None) -> list[dict[str, Any]]:
    """The withheld effects of a truth: a single one ({effect, site, form, params}), several
    ({"effects": [...]}) or none (empty, or effect None)."""
    if not truth:
        return []
    if "effects" in truth:
        return list(truth["effects"])
    return [truth] if truth.get("effect") else []


def _sensors(
    truth: dict[str, Any],
    t: np.ndarray,
    raw: np.ndarray,
    nom: dict[str, float],
    sens: dict,
    rng,
    run_name: str = "fit",
) -> dict[str, np.ndarray]:
    effs = _effects_of(truth)
    tens = [raw[:, 0].copy(), raw[:, 1].copy()]
    theta = raw[:, 2].copy()
    # the cells' own dynamics, the bus, the calibration, the bridge's zero drift, in this order
    for e in effs:
        if e["effect"] == "sensor_lag":
            p, form = e["params"], e["form"]
            for i in _force_sites(e["site"]):
                if form == "butterworth2":
                    tens[i] = _butter2(tens[i], p["fc"])
                elif form == "underdamped":
                    tens[i] = _second_order(tens[i], p["fn"], p["zeta"])
                else:
                    tens[i] = _rc_average(tens[i], p["tau"], 4)
    for e in effs:
        if e["effect"] == "time_delay" and e["site"] != "input":
            d = e["params"]["d"]
            if e["site"] == "sensor.theta":
                theta = np.interp(t - d, t, theta)
            else:
                for i in _force_sites(e["site"]):
                    tens[i] = np.interp(t - d, t, tens[i])
    for e in effs:
        if e["effect"] == "sensor_gain_bias":
            p = e["params"]
            for i in _force_sites(e["site"]):
                tens[i] = tens[i] * (1 + p["gain"][i]) + p["bias"][i]
    for e in effs:
        if e["effect"] == "thermal_drift":
            # the bridge warms (or cools) after switch-on: its zero creeps towards a new value
            # with the thermal time constant of the cell; each run has its own drift
            k = 0 if run_name == "fit" else 1
            p = e["params"]
            drift = p["amp"][k] * (1.0 - np.exp(-(t - t[0]) / p["tau"][k]))
            for i in _force_sites(e["site"]):
                tens[i] = tens[i] + drift
    # load-cell noise, mains hum, sample-and-hold converters, ADC quantisation
    t0 = nom["pretension"]
    for i in range(2):
        plain = None
        for e in effs:
            if e["effect"] == "sensor_sampling" and i in _force_sites(e["site"]):
                p = e["params"]
                if e["form"] == "plain_hold_noise_before":
                    plain = p
                else:
                    tens[i] = _hold(t, tens[i], p["rate"], p["phase"], 0.002, rng)
        hum = sens["hum"] * math.sqrt(2) * np.sin(2 * np.pi * 50.0 * t + rng.uniform(0, 2 * np.pi))
        tens[i] = tens[i] + rng.normal(0.0, sens["tension_noise"], len(t)) + hum
        if plain is not None:
            # the noise and hum enter before the hold: each held value carries one noise sample
            tens[i] = _plain_hold(t, tens[i], plain["rate"], plain["phase"])
        lsb = 6.0 * t0 / 4096  # a 12-bit converter over 0..6·T₀
        tens[i] = np.round(tens[i] / lsb) * lsb
    counts = sens["encoder_counts"]
    theta_q = np.round(theta / (2 * np.pi / counts)) * (2 * np.pi / counts)
    return {"T_drive": tens[0], "T_return": tens[1], "theta": theta_q}


# ---------------------------------------------------------------------------------------------
# effect sizes, relative to the nominal


def _draw(
    effect: str, site: str, form: str, nom: dict[str, float], rng: np.random.Generator
) -> dict[str, Any]:
    r, t0 = nom["radius"], nom["pretension"]
    tq = r * t0
    w = 1.5  # rad/s, a typical joint speed of these trajectories
    if effect == "coulomb_friction":
        if form == "lugre":
            fc = rng.uniform(0.1, 0.25) * tq
            sigma0 = fc / 2e-4  # bristles deflect ~0.2 mrad before sliding
            return {"F_c": fc, "sigma0": sigma0, "sigma1": 0.3 * math.sqrt(sigma0 * nom["inertia"])}
        return {"mu_b": rng.uniform(0.05, 0.12) * r}
    if effect == "viscous_friction":
        if form == "linear":
            return {"delta_b": rng.uniform(0.1, 0.25) * tq / w}
        return {"b_p": rng.uniform(0.1, 0.25) * tq / w**0.7}
    if effect == "stribeck_friction":
        if form == "karnopp":
            # static level 1.5–3x the Coulomb level; a dead band well inside the Stribeck speed
            fc = rng.uniform(0.08, 0.15) * tq
            v_s = rng.uniform(0.05, 0.15) * w
            return {"F_c": fc, "F_s": rng.uniform(1.5, 3.0) * fc, "v_s": v_s, "dv": 0.05 * v_s}
        fc = 0.05 * tq
        out = {"F_c": fc, "dF": rng.uniform(0.15, 0.25) * tq, "v_s": rng.uniform(0.05, 0.15) * w}
        if form == "lugre_stribeck":
            out["sigma0"] = (fc + out["dF"]) / 2e-4
            out["sigma1"] = 0.3 * math.sqrt(out["sigma0"] * nom["inertia"])
        return out
    if effect == "dahl_hysteresis":
        if site == "joint":
            if form == "bouc_wen":
                return {"F_y": rng.uniform(0.12, 0.25) * tq, "theta_y": rng.uniform(0.02, 0.05)}
            f = rng.uniform(0.12, 0.25) * tq
            widths = np.array([0.005, 0.02, 0.06])
            fi = f * np.array([0.3, 0.4, 0.3])
            return {"k_i": list(fi / widths), "f_i": list(fi)}
        if form == "bouc_wen_capstan":
            return {"mu_phi": rng.uniform(0.1, 0.25), "x_y": rng.uniform(0.02, 0.05) * r}
        f = rng.uniform(0.1, 0.2) * t0
        widths = np.array([0.005, 0.02, 0.05]) * r
        fi = f * np.array([0.3, 0.4, 0.3])
        return {"k_i": list(fi / widths), "f_i": list(fi)}
    if effect == "capstan_friction":
        out = {"mu_phi": rng.uniform(0.1, 0.25), "v0": 0.02 * r * w}
        if form == "linear_bearing_drag":
            out["drag"] = rng.uniform(0.02, 0.05) * t0
        return out
    if effect == "nonlinear_stiffness":
        if form == "bilinear":
            return {"knee": rng.uniform(0.5, 0.8), "ratio": rng.uniform(0.3, 0.5)}
        return {"q": rng.uniform(1.4, 2.0)}
    if effect == "cable_damping":
        return {"delta_c": rng.uniform(5.0, 10.0) * nom["damping"]}
    if effect == "creep":
        if form == "prony2":
            return {"kappa": [rng.uniform(0.08, 0.15), rng.uniform(0.08, 0.15)], "tau": [0.2, 2.0]}
        return {"kappa": rng.uniform(0.1, 0.25), "tau": rng.uniform(1.0, 4.0)}
    if effect == "backlash":
        if form == "joint_play":
            # total free play (rad), the pulley's share of the inertia, a contact 10–30x stiffer
            # than the cables' torsional stiffness, its damping ratio
            kt = 2.0 * nom["stiffness"] * r * r
            return {
                "gap": rng.uniform(0.01, 0.03),
                "share": rng.uniform(0.3, 0.5),
                "k_c": rng.uniform(10.0, 30.0) * kt,
                "zeta_c": rng.uniform(0.2, 0.4),
            }
        return {"delta": rng.uniform(0.01, 0.03) * r}
    if effect == "slack":
        return {"delta_T0": rng.uniform(0.5, 0.8) * t0}
    if effect == "coupling":
        return {"kappa_c": rng.uniform(0.3, 1.0) * r}
    if effect == "sensor_lag":
        if form == "underdamped":
            return {"fn": rng.uniform(15.0, 40.0), "zeta": rng.uniform(0.15, 0.5)}
        return (
            {"fc": rng.uniform(8.0, 20.0)} if form == "butterworth2" else {"tau": rng.uniform(0.006, 0.015)}
        )
    if effect == "sensor_sampling":
        if form == "plain_hold_noise_before":
            rate = rng.uniform(20.0, 50.0)
            return {"rate": rate, "phase": rng.uniform(0, 1 / rate)}
        rate = rng.uniform(9.0, 11.0) if form == "hx711_10hz" else rng.uniform(78.0, 82.0)
        return {"rate": rate, "phase": rng.uniform(0, 1 / rate)}
    if effect == "time_delay":
        return {"d": rng.uniform(0.003, 0.008) if site != "sensor.theta" else rng.uniform(0.004, 0.01)}
    if effect == "sensor_gain_bias":
        s = rng.choice([-1.0, 1.0])
        return {
            "gain": [s * rng.uniform(0.04, 0.08), -s * rng.uniform(0.04, 0.08)],
            "bias": [s * rng.uniform(0.02, 0.05) * t0, -s * rng.uniform(0.02, 0.05) * t0],
        }
    if effect == "inertia_error":
        if form == "payload":
            return {"epsilon": rng.uniform(0.3, 0.6)}  # a payload adding 30–60 % to the inertia
        return {"epsilon": rng.uniform(1.5, 3.0) if form == "heavier" else -rng.uniform(0.5, 0.7)}
    # out of the library
    if effect == "eccentric_pulley":
        # centre offset 3–6 % of the radius, at a random angle
        return {"e_frac": rng.uniform(0.03, 0.06), "phi": rng.uniform(0, 2 * np.pi)}
    if effect == "thermal_drift":
        # the zero of the drive cell drifts by 4–8 % of the pretension with a thermal time
        # constant of 4–12 s, one way in the fit run and the other way in the held-out run
        s = rng.choice([-1.0, 1.0])
        return {
            "amp": [s * rng.uniform(0.04, 0.08) * t0, -s * rng.uniform(0.04, 0.08) * t0],
            "tau": [rng.uniform(4.0, 12.0), rng.uniform(4.0, 12.0)],
        }
    if effect == "cogging":
        # 6–12 % of r·T₀, 18–36 periods per revolution
        return {
            "amp": rng.uniform(0.06, 0.12) * tq,
            "n": int(rng.integers(18, 37)),
            "phi": rng.uniform(0, 2 * np.pi),
        }
    raise ValueError(effect)


#: parameters that set each effect's size (doubled while the effect hides in the noise)
_SIZE = {
    "coulomb_friction": ("F_c", "mu_b"),
    "viscous_friction": ("delta_b", "b_p"),
    "stribeck_friction": ("dF",),
    "dahl_hysteresis": ("F_y", "f_i", "mu_phi"),
    "capstan_friction": ("mu_phi", "drag"),
    "nonlinear_stiffness": (),
    "cable_damping": ("delta_c",),
    "creep": ("kappa",),
    "backlash": ("delta", "gap"),
    "slack": ("delta_T0",),
    "coupling": ("kappa_c",),
    "sensor_lag": ("tau",),
    "sensor_sampling": (),
    "time_delay": ("d",),
    "sensor_gain_bias": ("gain", "bias"),
    "inertia_error": (),
    "eccentric_pulley": (),
    "thermal_drift": ("amp",),
    "cogging": ("amp",),
}


def _bigger(truth: dict[str, Any], t0: float) -> dict[str, Any]:
    q = dict(truth["params"])
    form = truth.get("form")
    for key in _SIZE[truth["effect"]]:
        if key not in q:
            continue
        v = q[key]
        v = [2 * a for a in v] if isinstance(v, list) else 2 * v
        if key == "kappa":
            v = [min(a, 0.3) for a in v] if isinstance(v, list) else min(v, 0.6)
        if key == "delta_T0":
            v = min(v, 0.95 * t0)
        q[key] = v
    if truth["effect"] == "nonlinear_stiffness":
        if form == "bilinear":
            # the knee halfway closer to the preload, the soft branch softer
            q["knee"] = 1.0 - 0.5 * (1.0 - q["knee"])
            q["ratio"] = max(0.5 * q["ratio"], 0.1)
        else:
            q["q"] = min(1.0 + 2.0 * (q["q"] - 1.0), 4.0)
    if truth["effect"] == "inertia_error":
        q["epsilon"] = 2 * q["epsilon"] if q["epsilon"] > 0 else max(2 * q["epsilon"], -0.85)
    if truth["effect"] == "sensor_lag" and "fc" in q:
        q["fc"] = q["fc"] / 2
    if truth["effect"] == "sensor_lag" and "fn" in q:
        q["fn"] = q["fn"] / 2
    if truth["effect"] == "sensor_sampling" and form == "plain_hold_noise_before":
        q["rate"] = max(q["rate"] / 2, 5.0)
    if truth["effect"] == "dahl_hysteresis" and "k_i" in q:
        q["k_i"] = [2 * a for a in q["k_i"]]  # same widths, twice the slip forces
    if truth["effect"] == "coulomb_friction" and "sigma0" in q:
        q["sigma0"] *= 2
    if truth["effect"] == "stribeck_friction" and "sigma0" in q:
        q["sigma0"] = (q["F_c"] + q["dF"]) / 2e-4
    if truth["effect"] == "stribeck_friction" and form == "karnopp":
        q["F_c"], q["F_s"] = 2 * q["F_c"], 2 * q["F_s"]
    if truth["effect"] == "eccentric_pulley":
        q["e_frac"] = min(2 * q["e_frac"], 0.25)
    return {**truth, "params": q}


# ---------------------------------------------------------------------------------------------
# cases


def _run(
    name: str, family: str, nom, truth, sens, duration: float, rng: np.random.Generator, theta_measured: bool
) -> Run:
    n = round(duration / DT)
    tf = np.arange(n * FINE) * (DT / FINE)
    r = nom["radius"]
    th_ref = _trajectory(family, rng, tf)
    xc = 0.3 * np.sin(2 * np.pi * rng.uniform(0.15, 0.25) * tf + rng.uniform(0, 2 * np.pi))
    xm_cmd = r * th_ref
    xm = xm_cmd
    effs = _effects_of(truth)
    # the command path: play in the motor's gear, then a transport delay
    for e in effs:
        if e["effect"] == "backlash" and e["site"] == "input":
            d = e["params"]["delta"]
            xm = _play(xm, d) if e["form"] == "play" else _rounded_play(xm, d)
    for e in effs:
        if e["effect"] == "time_delay" and e["site"] == "input":
            xm = np.interp(tf - e["params"]["d"], tf, xm)
    plant = _Plant(nom, effects=[(e["effect"], e["site"], e["form"], e["params"]) for e in effs])
    raw = _simulate(plant, tf, xm, xc)
    t = tf[::FINE]
    meas = _sensors(truth, t, raw, nom, sens, rng, run_name=name)
    cols = {
        "x_m": xm_cmd[::FINE],
        "x_c": xc[::FINE],
        "T_drive": meas["T_drive"],
        "T_return": meas["T_return"],
    }
    if theta_measured:
        cols["theta"] = meas["theta"]
    return Run(name, t, {k: np.ascontiguousarray(v) for k, v in cols.items()})


@dataclass
class _Setup:
    """Everything of one case before its runs are generated (the test uses it directly)."""

    spec: ModelSpec
    nom: dict[str, float]
    sens: dict[str, float]
    truth: dict[str, Any]  # one effect: {effect, site, form, params}; several: {"effects": [...]}
    run_seed: int
    info: dict[str, Any]
    fit_family: str
    hold_family: str
    theta_measured: bool
    duration: float

    def generate(self, tr: dict[str, Any], gen: np.random.Generator) -> tuple[list[Run], list[Run]]:
        """Fit and held-out runs with the truth ``tr`` (empty: the nominal plant)."""
        if not tr:
            tr = {"effect": None, "site": None, "form": None, "params": {}}
        fit = [_run("fit", self.fit_family, self.nom, tr, self.sens, self.duration, gen, self.theta_measured)]
        hold = [
            _run(
                "held_out", self.hold_family, self.nom, tr, self.sens, self.duration, gen, self.theta_measured
            )
        ]
        return fit, hold


def _setup(effects: list[tuple[str, str, str]], seed: int, duration: float) -> _Setup:
    rng = np.random.default_rng(seed)
    scale = "forceps" if rng.uniform() < 0.5 else "pulley_board"
    nom = _nominal(rng, scale)
    fams = rng.choice(len(FAMILIES), 2, replace=False)
    fit_family, hold_family = FAMILIES[fams[0]], FAMILIES[fams[1]]
    theta_measured = bool(rng.uniform() < 0.7) or any(s == "sensor.theta" for _, s, _ in effects)
    sens = {
        "tension_noise": 0.015 * nom["pretension"] * rng.uniform(0.6, 1.4),
        "encoder_counts": 4096 if scale == "forceps" else 8000,
    }
    sens["hum"] = 0.3 * sens["tension_noise"]
    drawn = [{"effect": e, "site": s, "form": f, "params": _draw(e, s, f, nom, rng)} for e, s, f in effects]
    truth: dict[str, Any] = drawn[0] if len(drawn) == 1 else {"effects": drawn} if drawn else {}
    outputs = {"tension_motor_drive": "T_drive", "tension_motor_return": "T_return"}
    if theta_measured:
        outputs["theta"] = "theta"
    spec = model_spec_from_dict(
        {
            "model": "antagonistic_joint",
            "parameters": nom,
            "inputs": {"x_m": "x_m", "coupled": "x_c"},
            "outputs": outputs,
            "diagnosis": {"warmup": 0.3},
        },
        source=f"independent case {seed}",
    )
    info = {
        "scale": scale,
        "fit_family": fit_family,
        "held_out_family": hold_family,
        "theta_measured": theta_measured,
        "nominal": nom,
        "sensors": sens,
    }
    return _Setup(
        spec,
        nom,
        sens,
        truth,
        int(rng.integers(1 << 31)),
        info,
        fit_family,
        hold_family,
        theta_measured,
        duration,
    )


def make_independent_case(
    effect: str | None, site: str | None, form: str | None, seed: int, duration: float = 20.0
) -> IndependentCase:
    """Generate one case (``effect`` None for a control): fit and held-out runs of ``duration``
    seconds each from different trajectory families. Out-of-library effects (:data:`OUTSIDE`)
    are generated the same way."""
    effects: list[tuple[str, str, str]] = [(effect, str(site), str(form))] if effect else []
    st = _setup(effects, seed, duration)
    fit, hold, truth_used, size = visible_runs(
        st.spec,
        st.generate,
        st.truth,
        lambda tr: _bigger(tr, st.nom["pretension"]),
        st.run_seed,
    )
    info = {
        **st.info,
        "size_factor": size,
        "params": (truth_used or {}).get("params", {}),
    }
    return IndependentCase(_label(effects), effect, site, form, st.spec, fit, hold, info, effects)


def make_independent_pair(
    pair: tuple[tuple[str, str, str], ...] | list[tuple[str, str, str]], seed: int, duration: float = 20.0
) -> IndependentCase:
    """Generate a case with several effects at once: each is first scaled (doubled up to four
    times, on the case's own runs) until it alone makes the nominal model's held-out gap visible,
    then all act together. ``truth['size_factor']`` and ``truth['params']`` are per effect."""
    effects = list(pair)
    st = _setup(effects, seed, duration)
    used, sizes = [], []
    for tr in st.truth["effects"]:
        _f, _h, tr_used, size = visible_runs(
            st.spec, st.generate, tr, lambda q: _bigger(q, st.nom["pretension"]), st.run_seed
        )
        used.append(tr_used)
        sizes.append(size)
    fit, hold = st.generate({"effects": used}, np.random.default_rng(st.run_seed))
    info = {**st.info, "size_factor": sizes, "params": [u["params"] for u in used]}
    return IndependentCase(
        _label(effects),
        "+".join(e for e, _s, _f in effects),
        "+".join(s for _e, s, _f in effects),
        "+".join(f for _e, _s, f in effects),
        st.spec,
        fit,
        hold,
        info,
        effects,
    )


def run_independent(
    seed: int = 4242,
    duration: float = 20.0,
    progress: bool = True,
    only: list[str] | None = None,
    controls: int = CONTROLS,
) -> dict[str, Any]:
    """Generate and diagnose every case (or those labelled in ``only``, e.g.
    ``"creep@cable.both/whole_tension"``, ``"control/0"``, a pair's labels joined by ``+``);
    scores effect and site separately, pairs on one and on both effects, out-of-library cases on
    an honest verdict."""
    from cablekit.diagnose.engine import Options, diagnose

    try:
        import scipy  # noqa: F401  (the generator's integrator and filters)
    except ImportError as exc:
        raise CablekitError(
            "the independent self-test integrates with SciPy: pip install 'cablekit[test]'"
        ) from exc
    plan = case_plan(seed, controls)
    if only:
        plan = [c for c in plan if c["label"] in only]
    rows = []
    t_start = time.perf_counter()
    label_width = max([48, *(len(c["label"]) for c in plan)])
    for i, c in enumerate(plan):
        label, kind, effs = c["label"], c["kind"], c["effects"]
        t_gen = time.perf_counter()
        if kind == "pair":
            case = make_independent_pair(effs, c["seed"], duration)
        else:
            e, s, f = effs[0] if effs else (None, None, None)
            case = make_independent_case(e, s, f, c["seed"], duration)
        gen_s = time.perf_counter() - t_gen
        t0 = time.perf_counter()
        res = diagnose(case.spec, case.fit, case.hold, Options(progress=False))
        elapsed = time.perf_counter() - t0
        top = res.effects[0] if res.effects and res.verdict != "no_significant_gap" else None
        row = {
            "label": label,
            "kind": kind,
            "effect": case.effect,
            "site": case.site,
            "form": case.form,
            "truth": [_label([e]) for e in effs],
            "scale": case.truth["scale"],
            "size_factor": case.truth["size_factor"],
            "verdict": res.verdict,
            "top1": top.name if top else None,
            "top1_site": top.site if top else None,
            "top1_id": top.id if top else None,
            "selected": res.selected.effects,
            "held_out_closed": res.selected.held_out.closed_fraction,
            "gap_held_out": res.gap.held_out,
            "seconds": elapsed,
            "generate_seconds": gen_s,
            "both_found": None,
            "honest": None,
        }
        judge(row, kind, case.effect, case.site, res)
        if kind == "pair":
            names = [e for e, _s, _f in effs]
            row["effect_correct"] = row["top1"] in names
            row["site_correct"] = (
                row["effect_correct"] and row["top1_site"] == effs[names.index(row["top1"])][1]
            )
            found = {sel.split("@")[0] for sel in res.selected.effects}
            row["both_found"] = all(n in found for n in names)
        rows.append(row)
        if progress:
            if kind == "outside":
                mark, smark = ("ok " if row["honest"] else "MISS"), " honest" if row["honest"] else " named"
            else:
                mark = "ok " if row["effect_correct"] else "MISS"
                smark = "" if kind == "control" else (" site-ok" if row["site_correct"] else " site-MISS")
                if kind == "pair":
                    smark += " both" if row["both_found"] else " one"
            _log.info(
                f"[{i + 1:>2}/{len(plan)}] {mark}{smark:<15} {label:<{label_width}} "
                f"{case.truth['scale']:<12} "
                f"verdict={res.verdict:<20} top1={row['top1_id']!s:<40} "
                f"closed={row['held_out_closed']:.2f} "
                f"({gen_s:.0f}+{elapsed:.0f}s)"
            )
    scores, goals, passed = summarise(rows, t_start)
    return {"cases": rows, "scores": scores, "goals": goals, "passed": passed}


def judge(row: dict[str, Any], kind: str, effect: str | None, site: str | None, res: Any) -> None:
    """Score one case's diagnosis ``res`` into ``row``: visible, effect and site right (a
    single), honest (a case outside the library: any verdict but ``explained`` or
    ``no_significant_gap``), clean (a control). A pair's scores are the caller's."""
    # an effect that stays below the noise even at 16x its drawn size cannot be attributed by any
    # method: listed, not scored
    row["visible"] = kind == "control" or res.gap.held_out >= MIN_VISIBLE_GAP
    if kind == "single":
        row["effect_correct"] = row["top1"] == effect
        row["site_correct"] = row["effect_correct"] and row["top1_site"] == site
    elif kind == "outside":
        # nothing in the library is the truth: "explained" names a wrong effect,
        # "no_significant_gap" misses it
        row["honest"] = res.verdict not in ("explained", "no_significant_gap")
        row["effect_correct"] = row["site_correct"] = None
    elif kind == "control":
        row["effect_correct"] = row["site_correct"] = res.verdict == "no_significant_gap"


def summarise(rows: list[dict[str, Any]], t_start: float) -> tuple[dict[str, Any], dict[str, Any], bool]:
    """Scores, goals and pass/fail of judged rows (:func:`judge`)."""
    singles = [r for r in rows if r["kind"] == "single" and r["visible"]]
    pairs = [r for r in rows if r["kind"] == "pair" and r["visible"]]
    outside = [r for r in rows if r["kind"] == "outside" and r["visible"]]
    named = singles + pairs  # top-1 effect and site are scored on both
    controls_rows = [r for r in rows if r["kind"] == "control"]
    closed = [r["held_out_closed"] for r in singles]
    both = [int(sum(bool(r["both_found"]) for r in pairs)), len(pairs)]
    honest = [int(sum(bool(r["honest"]) for r in outside)), len(outside)]
    scores: dict[str, Any] = {
        "top1_effect": float(np.mean([r["effect_correct"] for r in named])) if named else math.nan,
        "top1_site": float(np.mean([r["site_correct"] for r in named])) if named else math.nan,
        "both_found": both,  # [k, n]: pairs with both effects among the selected
        "outside_honest": honest,  # [k, n]: out-of-library cases not "explained"
        "control_false_alarms": int(sum(not r["effect_correct"] for r in controls_rows)),
        "median_held_out_closed": float(np.median(closed)) if closed else math.nan,
        "slowest_diagnosis_seconds": max((r["seconds"] for r in rows), default=math.nan),
        "seconds": time.perf_counter() - t_start,
        "not_visible": [r["label"] for r in rows if not r["visible"]],
    }
    goals = {
        "top1_effect": 0.9,
        "top1_site": 0.8,
        "both_found": 0.5,
        "outside_honest": 1.0,
        "control_false_alarms": 0,
        "median_held_out_closed": 0.8,
    }
    passed = (
        (not named or (scores["top1_effect"] >= 0.9 and scores["top1_site"] >= 0.8))
        and both[0] >= 0.5 * both[1]
        and honest[0] == honest[1]
        and scores["control_false_alarms"] == 0
        and (not closed or scores["median_held_out_closed"] >= 0.8)
    )
    return scores, goals, passed


def _frac(kn: list[int]) -> str:
    return f"{kn[0]}/{kn[1]}" + (f" ({kn[0] / kn[1]:.0%})" if kn[1] else "")


def format_independent(result: dict[str, Any]) -> str:
    """Both confusion tables (effect, and site) as text, with the pairs' second effect and the
    out-of-library cases' verdicts."""
    cells = []
    for r in result["cases"]:
        kind = r.get("kind", "single" if r["effect"] else "control")
        if kind == "outside":
            named = f"{r['verdict']} ({r['top1_id'] or '-'})"
            eff = site = "-"
            extra = "honest" if r["honest"] else "NAMED" if r["verdict"] == "explained" else "MISSED"
        else:
            named = str(r["top1_id"] or r["verdict"])
            eff = "ok" if r["effect_correct"] else "MISS"
            site = ("ok" if r["site_correct"] else "MISS") if kind != "control" else "-"
            extra = ("both" if r["both_found"] else "one") if kind == "pair" else "-"
        cells.append((r, named, eff, site, extra))
    width = max([50, *(len(r["label"]) + 1 for r in result["cases"])])
    width_named = max([44, *(len(c[1]) + 1 for c in cells)])
    lines = [
        f"{'withheld (effect@site/form)':<{width}} {'top-1 named':<{width_named}} {'effect':<6} {'site':<6} "
        f"{'both/honest':<11} closed"
    ]
    for r, named, eff, site, extra in cells:
        lines.append(
            f"{r['label']:<{width}} {named:<{width_named}} {eff:<6} {site:<6} {extra:<11} "
            f"{r['held_out_closed']:.2f}"
            f"{'' if r['visible'] else '   (below the noise at 16x its size: not scored)'}"
        )
    s = result["scores"]
    lines.append("")
    lines.append(
        f"top-1 effect {s['top1_effect']:.0%} (goal >= 90%), site {s['top1_site']:.0%} (goal >= 80%) "
        f"over singles and pairs; pairs with both effects selected {_frac(s['both_found'])} "
        f"(goal >= 50%); out-of-library cases answered honestly {_frac(s['outside_honest'])} "
        f"(goal all); control false alarms {s['control_false_alarms']} (goal 0); median held-out gap "
        f"closed {s['median_held_out_closed']:.0%} over singles (goal >= 80%); "
        f"slowest diagnosis {s['slowest_diagnosis_seconds']:.0f} s, "
        f"{s['seconds']:.0f} s in all"
    )
    if s["not_visible"]:
        lines.append(f"not scored (effect below the noise): {', '.join(s['not_visible'])}")
    return "\n".join(lines)
