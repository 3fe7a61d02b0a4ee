"""An independent self-test: runs from a simulator that shares no code with the candidates.

The regression self-test (:mod:`cablekit.diagnose.selftest`) generates its "real" runs with a
higher-fidelity configuration of cablekit's own simulator, so it mostly measures agreement with
ourselves. This generator is written separately, from the physics literature rather than from
``identify/effects.rs``:

* its own integrator: SciPy's LSODA (switches to BDF on stiff stretches: LuGre bristles,
  Bouc–Wen states, tight cables), never cablekit's RK4;
* its own effect forms, at least two per effect, each different from the candidate's law:
  LuGre and load-dependent Coulomb friction, LuGre–Stribeck and Tustin's exponential map,
  power-law viscous drag, Bouc–Wen and Maxwell-slip (multi-element) hysteresis in the joint and in
  the cable–pulley contacts, linearised capstan with bearing drag, toe-region power-law cables,
  tension-proportional damping, Prony-series and whole-tension creep, rounded backlash, an
  asymmetric routing coupling, Butterworth and RC + averaging amplifiers, HX711 holds at 10 and
  80 Hz with noise **after** the hold, delays in the command path, the force sensors' bus or the
  encoder alone, gain/bias on one or every load cell, heavier and lighter links;
* realistic sensors on every case: a quantised quadrature encoder on the joint, load cells with
  white noise and a small mains hum, the command logged as sent;
* two scales (forceps: r 2–6 mm, T₀ 8–25 N; pulley board: r 12–30 mm, T₀ 20–60 N) and four
  trajectory families (multisine, chirp, minimum-jerk pick-and-place with dwells, smoothed
  triangle), the held-out run always from another family than the fit run.

Each case withholds one effect at one site; the diagnosis is scored on the effect name and, as a
separate figure, on the site (``sensors.force``, ``contact.both``, …) of its top-ranked candidate.
The only cablekit code used here is the diagnosis under test and the :class:`Run` container.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from cablekit.diagnose.data import Run
from cablekit.diagnose.selftest import MIN_VISIBLE_GAP, visible_runs
from cablekit.diagnose.spec import ModelSpec, model_spec_from_dict
from cablekit.errors import CablekitError

__all__ = ["CASES", "CI_SUBSET", "IndependentCase", "make_independent_case", "run_independent"]

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
]
CONTROLS = 4
#: the cases `.ci/run` prints (one form of most effects, every site kind, two controls)
CI_SUBSET = [
    "stribeck_friction@joint/tustin",
    "dahl_hysteresis@contact.both/bouc_wen_capstan",
    "creep@cable.both/whole_tension",
    "sensor_sampling@sensors.force/hx711_10hz",
    "time_delay@sensors.force/bus",
    "slack@cable.drive/lost_pretension",
    "control/0",
    "control/1",
]


@dataclass
class IndependentCase:
    """One independent case: the nominal model file, the runs and the withheld truth."""

    label: str
    effect: str | None
    site: str | None
    form: str | None
    spec: ModelSpec
    fit: list[Run]
    hold: list[Run]
    truth: dict[str, Any]


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


class _Plant:
    """Antagonistic joint with one withheld effect, written from the physics (see module)."""

    def __init__(
        self, nom: dict[str, float], effect: str | None, site: str | None, form: str | None, p: dict
    ):
        self.nom, self.effect, self.site, self.form, self.p = nom, effect, site, form, p
        self.key = f"{effect}@{site}/{form}" if effect else "control"
        # internal states beyond [θ, ω]
        n = 0
        if self.key in ("coulomb_friction@joint/lugre", "stribeck_friction@joint/lugre_stribeck"):
            n = 1
        elif self.key == "dahl_hysteresis@joint/bouc_wen":
            n = 1
        elif self.key == "dahl_hysteresis@joint/maxwell_slip":
            n = len(p["k_i"])
        elif self.key == "dahl_hysteresis@contact.both/bouc_wen_capstan":
            n = 2
        elif self.key == "dahl_hysteresis@contact.both/maxwell_slip":
            n = 2 * len(p["k_i"])
        elif self.key == "creep@cable.both/prony2":
            n = 4
        elif self.key == "creep@cable.both/whole_tension":
            n = 2
        self.n_extra = n

    # cable tension of one cable from its stretch, rate and relaxation
    def _cable(self, which: int, s: float, sd: float, relax: float) -> float:
        nom, p, key = self.nom, self.p, self.key
        k, c, t0 = nom["stiffness"], nom["damping"], nom["pretension"]
        if self.effect == "slack" and (self.site == "cable.both" or which == 0):
            t0 = t0 - p["delta_T0"]
        if self.effect == "nonlinear_stiffness" and (self.site == "cable.both" or which == 0):
            # toe-region power law T = K·e^q of the total strain e, tangent k at the nominal
            # preload (so the nominal model is its linearisation): e₀ = q·T₀/k
            q = p["q"]
            e0 = q * t0 / k
            e = max(e0 + s, 0.0)
            elastic = t0 * (e / e0) ** q - t0
        else:
            elastic = k * s
        damp = c
        if key == "cable_damping@cable.both/linear":
            damp = c + p["delta_c"]
        elif key == "cable_damping@cable.both/tension_proportional":
            damp = c + p["delta_c"] * max(t0 + elastic, 0.0) / t0
        return max(0.0, t0 + elastic + damp * sd - relax)

    def _joint_side(
        self, x: np.ndarray, xm: float, vm: float, xc: float
    ) -> tuple[float, float, float, float]:
        """Stretches (s₁, s₂) and joint-side tensions (T_j,1, T_j,2) at one state."""
        p, key, r = self.p, self.key, self.nom["radius"]
        s1, sd1 = xm - r * x[0], vm - r * x[1]
        s2, sd2 = -s1, -sd1
        if self.effect == "coupling":
            # asymmetric form: the return cable is routed over the coupled axis on a smaller radius
            c2 = 1.0 if self.form == "linear" else 0.4
            s1, s2 = s1 + p["kappa_c"] * xc, s2 - c2 * p["kappa_c"] * xc
        relax = (0.0, 0.0)
        if key == "creep@cable.both/prony2":
            relax = (x[2] + x[3], x[4] + x[5])
        elif key == "creep@cable.both/whole_tension":
            relax = (x[2], x[3])
        return s1, s2, self._cable(0, s1, sd1, relax[0]), self._cable(1, s2, sd2, relax[1])

    def rhs(self, t: float, x: np.ndarray, xm: float, vm: float, xc: float) -> np.ndarray:
        nom, p, key = self.nom, self.p, self.key
        r = nom["radius"]
        th, om = x[0], x[1]
        dx = np.zeros_like(x)
        s1, s2, t1, t2 = self._joint_side(x, xm, vm, xc)
        torque = r * (t1 - t2) - nom["viscous"] * om
        # contact with the object
        lever = nom["contact_lever_arm"]
        pen = lever * (th - nom["contact_angle"])
        if pen > 0:
            torque -= lever * max(0.0, nom["contact_stiffness"] * pen + nom["contact_damping"] * lever * om)
        # joint friction and hysteresis
        if key in ("coulomb_friction@joint/lugre", "stribeck_friction@joint/lugre_stribeck"):
            # LuGre (Canudas de Wit et al. 1995): ż = ω − σ₀|ω| z / g(ω), F = σ₀z + σ₁ż
            fc = p["F_c"]
            g = fc if self.effect == "coulomb_friction" else fc + p["dF"] * math.exp(-((om / p["v_s"]) ** 2))
            z = x[2]
            zd = om - p["sigma0"] * abs(om) * z / g
            dx[2] = zd
            torque -= p["sigma0"] * z + p["sigma1"] * zd
        elif key == "coulomb_friction@joint/bearing_load":
            # bearing friction grows with the radial load the two cables put on the joint shaft
            torque -= p["mu_b"] * (t1 + t2) * math.tanh(om / 2e-3)
        elif key == "viscous_friction@joint/linear":
            torque -= p["delta_b"] * om
        elif key == "viscous_friction@joint/power_law":
            torque -= p["b_p"] * abs(om) ** 0.7 * _sgn(om)
        elif key == "stribeck_friction@joint/tustin":
            # Tustin's exponential Stribeck map (exponent 1), sharp sign
            f = p["F_c"] + p["dF"] * math.exp(-abs(om) / p["v_s"])
            torque -= f * math.tanh(om / 1e-3)
        elif key == "dahl_hysteresis@joint/bouc_wen":
            # Bouc–Wen: ż = (ω/θ_y)(1 − |z|ⁿ(β sgn(ωz) + γ)), torque F_y·z
            z = x[2]
            dx[2] = (om / p["theta_y"]) * (1 - abs(z) ** 2 * (0.7 * _sgn(om * z) + 0.3))
            torque -= p["F_y"] * z
        elif key == "dahl_hysteresis@joint/maxwell_slip":
            # Maxwell-slip: elasto-plastic elements k_i with slip torques f_i, in parallel
            for i, (ki, fi) in enumerate(zip(p["k_i"], p["f_i"], strict=True)):
                zi = x[2 + i]
                dx[2 + i] = _slip_rate(om, ki * zi / fi)
                torque -= ki * zi
        # creep states
        if key == "creep@cable.both/prony2":
            k = nom["stiffness"]
            for j, s in enumerate((s1, s2)):
                for m, (kap, tau) in enumerate(zip(p["kappa"], p["tau"], strict=True)):
                    idx = 2 + 2 * j + m
                    dx[idx] = (kap * k * s - x[idx]) / tau
        elif key == "creep@cable.both/whole_tension":
            for j, tj in enumerate((t1, t2)):
                dx[2 + j] = (p["kappa"] * (tj + x[2 + j]) - x[2 + j]) / p["tau"]
        # contact hysteresis states (driven by the cable's sliding speed on the pulleys, ẋ_m)
        if key == "dahl_hysteresis@contact.both/bouc_wen_capstan":
            for j, v in enumerate((vm, -vm)):
                z = x[2 + j]
                dx[2 + j] = (v / p["x_y"]) * (1 - abs(z) ** 2 * (0.7 * _sgn(v * z) + 0.3))
        elif key == "dahl_hysteresis@contact.both/maxwell_slip":
            n = len(p["k_i"])
            for j, v in enumerate((vm, -vm)):
                for i, (ki, fi) in enumerate(zip(p["k_i"], p["f_i"], strict=True)):
                    zi = x[2 + j * n + i]
                    dx[2 + j * n + i] = _slip_rate(v, ki * zi / fi)
        dx[0] = om
        dx[1] = torque / self.inertia()
        return dx

    def inertia(self) -> float:
        j = self.nom["inertia"]
        if self.effect == "inertia_error":
            j *= 1 + self.p["epsilon"]
        return j

    def motor_tensions(self, x: np.ndarray, xm: float, vm: float, xc: float) -> tuple[float, float, float]:
        """(T_m,drive, T_m,return, θ) at one state."""
        nom, p, key = self.nom, self.p, self.key
        th = x[0]
        _, _, t1, t2 = self._joint_side(x, xm, vm, xc)
        if self.effect == "capstan_friction":
            # the cable slides over the routing pulleys at ẋ_m; the drive side is hauled in
            if self.form == "saturated_exponential":
                a = p["mu_phi"] * _sat(vm / p["v0"])
                t1 = t1 * math.exp(a)
                if self.site == "contact.both":
                    t2 = t2 * math.exp(-a)
            else:  # linearised capstan plus pulley-bearing drag
                sg = _sat(vm / p["v0"])
                t1 = t1 * (1 + p["mu_phi"] * sg) + p["drag"] * sg
                t2 = t2 * (1 - p["mu_phi"] * sg) - p["drag"] * sg
        elif key == "dahl_hysteresis@contact.both/bouc_wen_capstan":
            t1 = t1 * math.exp(p["mu_phi"] * x[2])
            t2 = t2 * math.exp(p["mu_phi"] * x[3])
        elif key == "dahl_hysteresis@contact.both/maxwell_slip":
            n = len(p["k_i"])
            h1 = sum(ki * x[2 + i] for i, ki in enumerate(p["k_i"]))
            h2 = sum(ki * x[2 + n + i] for i, ki in enumerate(p["k_i"]))
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

    x0 = np.zeros(2 + plant.n_extra)
    x0[0] = xm[0] / plant.nom["radius"]
    t_rec = tf[::FINE]
    sol = solve_ivp(
        f, (tf[0], tf[-1]), x0, method="LSODA", t_eval=t_rec, rtol=1e-6, atol=1e-9, max_step=DT / 2
    )
    if not sol.success or sol.y.shape[1] != len(t_rec):
        raise RuntimeError(f"independent generator: LSODA failed ({sol.message})")
    out = np.empty((len(t_rec), 3))
    for k in range(len(t_rec)):
        out[k] = plant.motor_tensions(sol.y[:, k], *inp(t_rec[k]))
    return out


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


def _sensors(
    truth: dict[str, Any], t: np.ndarray, raw: np.ndarray, nom: dict[str, float], sens: dict, rng
) -> dict[str, np.ndarray]:
    effect, site, form, p = truth["effect"], truth["site"], truth["form"], truth["params"]
    tens = [raw[:, 0].copy(), raw[:, 1].copy()]
    theta = raw[:, 2].copy()
    force_sites = [0, 1] if site == "sensors.force" else [0] if site == "sensor.tension_motor_drive" else []
    if effect == "sensor_lag":
        for i in force_sites:
            tens[i] = (
                _butter2(tens[i], p["fc"]) if form == "butterworth2" else _rc_average(tens[i], p["tau"], 4)
            )
    if effect == "time_delay" and site != "input":
        if site == "sensor.theta":
            theta = np.interp(t - p["d"], t, theta)
        else:
            for i in force_sites:
                tens[i] = np.interp(t - p["d"], t, tens[i])
    if effect == "sensor_gain_bias":
        for i in force_sites:
            tens[i] = tens[i] * (1 + p["gain"][i]) + p["bias"][i]
    # load-cell noise, mains hum, ADC quantisation
    t0 = nom["pretension"]
    for i in range(2):
        if effect == "sensor_sampling" and i in force_sites:
            tens[i] = _hold(t, tens[i], p["rate"], p["phase"], 0.002, rng)
        hum = sens["hum"] * math.sqrt(2) * np.sin(2 * np.pi * 50.0 * t + rng.uniform(0, 2 * np.pi))
        tens[i] = tens[i] + rng.normal(0.0, sens["tension_noise"], len(t)) + hum
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
        return {"q": rng.uniform(1.4, 2.0)}
    if effect == "cable_damping":
        return {"delta_c": rng.uniform(5.0, 10.0) * nom["damping"]}
    if effect == "creep":
        if form == "prony2":
            return {"kappa": [rng.uniform(0.08, 0.15), rng.uniform(0.08, 0.15)], "tau": [0.2, 2.0]}
        return {"kappa": rng.uniform(0.1, 0.25), "tau": rng.uniform(1.0, 4.0)}
    if effect == "backlash":
        return {"delta": rng.uniform(0.01, 0.03) * r}
    if effect == "slack":
        return {"delta_T0": rng.uniform(0.5, 0.8) * t0}
    if effect == "coupling":
        return {"kappa_c": rng.uniform(0.3, 1.0) * r}
    if effect == "sensor_lag":
        return (
            {"fc": rng.uniform(8.0, 20.0)} if form == "butterworth2" else {"tau": rng.uniform(0.006, 0.015)}
        )
    if effect == "sensor_sampling":
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
        return {"epsilon": rng.uniform(1.5, 3.0) if form == "heavier" else -rng.uniform(0.5, 0.7)}
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
    "backlash": ("delta",),
    "slack": ("delta_T0",),
    "coupling": ("kappa_c",),
    "sensor_lag": ("tau",),
    "sensor_sampling": (),
    "time_delay": ("d",),
    "sensor_gain_bias": ("gain", "bias"),
    "inertia_error": (),
}


def _bigger(truth: dict[str, Any], t0: float) -> dict[str, Any]:
    q = dict(truth["params"])
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
        q["q"] = min(1.0 + 2.0 * (q["q"] - 1.0), 4.0)
    if truth["effect"] == "inertia_error":
        q["epsilon"] = 2 * q["epsilon"] if q["epsilon"] > 0 else max(2 * q["epsilon"], -0.85)
    if truth["effect"] == "sensor_lag" and "fc" in q:
        q["fc"] = q["fc"] / 2
    if truth["effect"] == "dahl_hysteresis" and "k_i" in q:
        q["k_i"] = [2 * a for a in q["k_i"]]  # same widths, twice the slip forces
    if truth["effect"] == "coulomb_friction" and "sigma0" in q:
        q["sigma0"] *= 2
    if truth["effect"] == "stribeck_friction" and "sigma0" in q:
        q["sigma0"] = (q["F_c"] + q["dF"]) / 2e-4
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
    effect, form, p = truth["effect"], truth["form"], truth["params"]
    if effect == "backlash":
        xm = _play(xm, p["delta"]) if form == "play" else _rounded_play(xm, p["delta"])
    if effect == "coupling" and form == "linear":
        pass  # acts on the cable stretch inside the plant (both cables, equal and opposite)
    if effect == "time_delay" and truth["site"] == "input":
        xm = np.interp(tf - p["d"], tf, xm)
    plant = _Plant(nom, effect, truth["site"], form, p)
    raw = _simulate(plant, tf, xm, xc)
    t = tf[::FINE]
    meas = _sensors(truth, t, raw, nom, sens, rng)
    cols = {
        "x_m": xm_cmd[::FINE],
        "x_c": xc[::FINE],
        "T_drive": meas["T_drive"],
        "T_return": meas["T_return"],
    }
    if theta_measured:
        cols["theta"] = meas["theta"]
    return Run(name, t, {k: np.ascontiguousarray(v) for k, v in cols.items()})


def make_independent_case(
    effect: str | None, site: str | None, form: str | None, seed: int, duration: float = 20.0
) -> IndependentCase:
    """Generate one case (``effect`` None for a control): fit and held-out runs of ``duration``
    seconds each from different trajectory families."""
    rng = np.random.default_rng(seed)
    scale = "forceps" if rng.uniform() < 0.5 else "pulley_board"
    nom = _nominal(rng, scale)
    fams = rng.choice(len(FAMILIES), 2, replace=False)
    fit_family, hold_family = FAMILIES[fams[0]], FAMILIES[fams[1]]
    theta_measured = bool(rng.uniform() < 0.7) or site == "sensor.theta"
    sens = {
        "tension_noise": 0.015 * nom["pretension"] * rng.uniform(0.6, 1.4),
        "encoder_counts": 4096 if scale == "forceps" else 8000,
    }
    sens["hum"] = 0.3 * sens["tension_noise"]
    params = _draw(effect, site, form, nom, rng) if effect else {}
    truth: dict[str, Any] = {"effect": effect, "site": site, "form": form, "params": params}
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

    def generate(tr: dict[str, Any], gen: np.random.Generator) -> tuple[list[Run], list[Run]]:
        if not tr:
            tr = {"effect": None, "site": None, "form": None, "params": {}}
        fit = [_run("fit", fit_family, nom, tr, sens, duration, gen, theta_measured)]
        hold = [_run("held_out", hold_family, nom, tr, sens, duration, gen, theta_measured)]
        return fit, hold

    fit, hold, truth_used, size = visible_runs(
        spec,
        generate,
        truth if effect else {},
        lambda tr: _bigger(tr, nom["pretension"]),
        int(rng.integers(1 << 31)),
    )
    label = f"{effect}@{site}/{form}" if effect else "control"
    info = {
        "scale": scale,
        "fit_family": fit_family,
        "held_out_family": hold_family,
        "theta_measured": theta_measured,
        "size_factor": size,
        "params": (truth_used or {}).get("params", {}),
        "nominal": nom,
        "sensors": sens,
    }
    return IndependentCase(label, effect, site, form, spec, fit, hold, info)


def run_independent(
    seed: int = 4242,
    duration: float = 20.0,
    progress: bool = True,
    only: list[str] | None = None,
    controls: int = CONTROLS,
) -> dict[str, Any]:
    """Generate and diagnose every case (or those labelled in ``only``, e.g.
    ``"creep@cable.both/whole_tension"``, ``"control/0"``); scores effect and site separately."""
    from cablekit.diagnose.engine import Options, diagnose

    try:
        import scipy  # noqa: F401  (the generator's integrator and filters)
    except ImportError as exc:
        raise CablekitError(
            "the independent self-test integrates with SciPy: pip install 'cablekit[test]'"
        ) from exc
    plan: list[tuple[str, str | None, str | None, str | None]] = [
        (f"{e}@{s}/{f}", e, s, f) for e, s, f in CASES
    ] + [(f"control/{i}", None, None, None) for i in range(controls)]
    seeds = {label: seed + 131 * i for i, (label, *_rest) in enumerate(plan)}
    if only:
        plan = [c for c in plan if c[0] in only]
    rows = []
    t_start = time.perf_counter()
    for i, (label, effect, site, form) in enumerate(plan):
        t_gen = time.perf_counter()
        case = make_independent_case(effect, site, form, seeds[label], duration)
        gen_s = time.perf_counter() - t_gen
        t0 = time.perf_counter()
        res = diagnose(case.spec, case.fit, case.hold, Options(progress=False))
        elapsed = time.perf_counter() - t0
        top = res.effects[0] if res.effects and res.verdict != "no_significant_gap" else None
        row = {
            "label": label,
            "effect": effect,
            "site": site,
            "form": form,
            "scale": case.truth["scale"],
            "verdict": res.verdict,
            "top1": top.name if top else None,
            "top1_site": top.site if top else None,
            "top1_id": top.id if top else None,
            "selected": res.selected.effects,
            "held_out_closed": res.selected.held_out.closed_fraction,
            "gap_held_out": res.gap.held_out,
            "seconds": elapsed,
            "generate_seconds": gen_s,
        }
        # an effect that stays below the noise even at 16x its drawn size cannot be attributed
        # by any method: listed, not scored
        row["visible"] = effect is None or res.gap.held_out >= MIN_VISIBLE_GAP
        if effect:
            row["effect_correct"] = row["top1"] == effect
            row["site_correct"] = row["effect_correct"] and row["top1_site"] == site
        else:
            row["effect_correct"] = row["site_correct"] = res.verdict == "no_significant_gap"
        rows.append(row)
        if progress:
            mark = "ok " if row["effect_correct"] else "MISS"
            smark = "" if not effect else (" site-ok" if row["site_correct"] else " site-MISS")
            print(
                f"[{i + 1:>2}/{len(plan)}] {mark}{smark:<10} {label:<48} {case.truth['scale']:<12} "
                f"verdict={res.verdict:<20} top1={row['top1_id']!s:<40} "
                f"closed={row['held_out_closed']:.2f} "
                f"({gen_s:.0f}+{elapsed:.0f}s)",
                flush=True,
            )
    singles = [r for r in rows if r["effect"] and r["visible"]]
    controls_rows = [r for r in rows if not r["effect"]]
    closed = [r["held_out_closed"] for r in singles]
    scores: dict[str, Any] = {
        "top1_effect": float(np.mean([r["effect_correct"] for r in singles])) if singles else math.nan,
        "top1_site": float(np.mean([r["site_correct"] for r in singles])) if singles else math.nan,
        "control_false_alarms": int(sum(not r["effect_correct"] for r in controls_rows)),
        "median_held_out_closed": float(np.median(closed)) if closed else math.nan,
        "slowest_diagnosis_seconds": max((r["seconds"] for r in rows), default=math.nan),
        "seconds": time.perf_counter() - t_start,
        "not_visible": [r["label"] for r in rows if not r["visible"]],
    }
    goals = {"top1_effect": 0.9, "top1_site": 0.8, "control_false_alarms": 0, "median_held_out_closed": 0.8}
    passed = (
        (not singles or (scores["top1_effect"] >= 0.9 and scores["top1_site"] >= 0.8))
        and scores["control_false_alarms"] == 0
        and (not closed or scores["median_held_out_closed"] >= 0.8)
    )
    return {"cases": rows, "scores": scores, "goals": goals, "passed": passed}


def format_independent(result: dict[str, Any]) -> str:
    """Both confusion tables (effect, and site) as text."""
    lines = [f"{'withheld (effect@site/form)':<50} {'top-1 named':<44} {'effect':<6} {'site':<6} closed"]
    for r in result["cases"]:
        lines.append(
            f"{r['label']:<50} {r['top1_id'] or r['verdict']!s:<44} "
            f"{'ok' if r['effect_correct'] else 'MISS':<6} "
            f"{('ok' if r['site_correct'] else 'MISS') if r['effect'] else '-':<6} "
            f"{r['held_out_closed']:.2f}"
            f"{'' if r['visible'] else '   (below the noise at 16x its size: not scored)'}"
        )
    s = result["scores"]
    lines.append("")
    lines.append(
        f"top-1 effect {s['top1_effect']:.0%} (goal >= 90%), site {s['top1_site']:.0%} (goal >= 80%), "
        f"control false alarms {s['control_false_alarms']} (goal 0), median held-out gap closed "
        f"{s['median_held_out_closed']:.0%} (goal >= 80%), "
        f"slowest diagnosis {s['slowest_diagnosis_seconds']:.0f} s, "
        f"{s['seconds']:.0f} s in all"
    )
    if s["not_visible"]:
        lines.append(f"not scored (effect below the noise): {', '.join(s['not_visible'])}")
    return "\n".join(lines)
