"""Seed 003's tension sensors (§§4–5, issue #23) on the twin: the calibration of Figs 14–15
(masses hung over a redirecting pulley, loading then unloading, eq. 33) and the experiment of
Fig. 18 (the motor-current estimate of eqs 34–35 against the tension an inline sensor reads
through the HX711 and its link, current stepped up and back down at several EE positions).

The sensor models themselves are the core's (:class:`LoadCellPulley`, :class:`Calibration`,
:class:`SignalChain`); what is here drives them and tabulates. Values the seed does not give
are marked as choices where they are set.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cablekit._args import Seed, checked, count, float_array, real
from cablekit._cablekit import Calibration, CalibrationFit, LoadCellPulley, SignalChain, Winch, WinchDrive
from cablekit.errors import DTypeError, ParameterError
from cablekit.simulation import simulate

#: seed 003 §4.3: seven probe masses from 0.10 to 6.70 kg (the intermediate values are a choice)
SEED_MASSES = (0.10, 0.50, 1.20, 2.10, 3.40, 5.00, 6.70)
GRAVITY = 9.80665


@dataclass(frozen=True)
class CalibrationRun:
    """One sensor calibrated as in seed 003 §4.3: the hung ``loads`` (N), the averaged
    ``readings`` up then down, the fit, and the true line it should find."""

    name: str
    loads: np.ndarray
    readings: np.ndarray
    fit: CalibrationFit
    true_gain: float
    true_offset: float
    capstan: float


@checked
def calibrate(
    name: str,
    gain: float,
    offset: float,
    *,
    capstan: float = 0.0,
    noise: float = 0.0,
    readings_per_mass: int = 5,
    masses: tuple[float, ...] = SEED_MASSES,
    seed: Seed = 0,
) -> CalibrationRun:
    """Hang ``masses`` up then down over the calibration rig's redirecting pulley, whose
    friction (``capstan`` = μ·φ) lowers the tension reaching the sensor while a mass settles
    down (``e^(−μφ)``) and raises it while the cable is unloaded (``e^(+μφ)``); the sensor reads
    ``gain·T + offset`` plus ``noise`` (reading units, Gaussian), five readings averaged per
    mass; fit eq. 33."""
    if not isinstance(name, str):
        raise DTypeError(f"name must be a string, got {type(name).__name__}")
    # readings in the sensor's units: any converter's range is far inside ±1e12
    gain = real(gain, "gain", lo=-1e12, hi=1e12)
    if gain == 0.0:
        raise ParameterError("gain must be non-zero (a sensor that reads nothing cannot be calibrated)")
    offset = real(offset, "offset", lo=-1e12, hi=1e12)
    capstan = real(capstan, "capstan", lo=0.0, hi=10.0)
    noise = real(noise, "noise", lo=0.0, hi=1e12)
    readings_per_mass = count(readings_per_mass, "readings_per_mass", lo=1, hi=10_000)
    m = float_array(masses, "masses", 1)
    if m.size < 2 or m.size > 10_000 or not np.all(np.isfinite(m)) or np.any(m <= 0.0) or np.any(m > 1e6):
        raise ParameterError(f"masses must be 2 to 10,000 masses in (0, 1e6] kg, got {m.size} values")
    rng = np.random.default_rng(count(seed, "seed"))
    up = m * GRAVITY
    down = up[::-1].copy()
    t_up, t_down = up * np.exp(-capstan), down * np.exp(capstan)

    def read(t: np.ndarray) -> np.ndarray:
        raw = gain * t[:, None] + offset + noise * rng.standard_normal((t.size, readings_per_mass))
        return raw.mean(axis=1)

    r_up, r_down = read(t_up), read(t_down)
    fit = Calibration.fit(up, r_up, down, r_down)
    return CalibrationRun(
        name, np.concatenate([up, down]), np.concatenate([r_up, r_down]), fit, gain, offset, capstan
    )


@checked
def calibration_table(runs: list[CalibrationRun]) -> str:
    """Markdown: per sensor the fitted line against the true one, correlation, residuals and the
    hysteresis the fit reports against what the pulley's friction puts there."""
    lines = [
        "| sensor | gain fitted / true | offset fitted / true | correlation | residual RMS | "
        "hysteresis (of span) | the rig's pulley at the top load |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        c = r.fit.calibration
        top = r.loads.max()
        rig = top * (np.exp(r.capstan) - np.exp(-r.capstan))
        lines.append(
            f"| {r.name} | {c.gain:.4f} / {r.true_gain:.4f} | {c.offset:.2f} / {r.true_offset:.2f} | "
            f"{r.fit.correlation:.6f} | {r.fit.residual_rms:.3f} N | {r.fit.hysteresis:+.3f} N "
            f"({100 * r.fit.hysteresis_fraction:.2f} %) | {rig:.3f} N |"
        )
    return "\n".join(lines)


@checked
def seed_calibrations() -> list[CalibrationRun]:
    """The four sensors of Figs 14–15: two inline (readings in raw HX711 counts per N, a choice)
    and two load-cell pulleys (their push through ``sin α₁ + sin α₂`` of 5° exits, a choice),
    the load-cell ones through the rig's extra pulley (μφ = 0.01, a choice: the seed sees no
    noticeable hysteresis and correlations above 0.9994)."""
    pulley = LoadCellPulley(np.radians(5.0), np.radians(5.0))
    return [
        calibrate("inline, upper cable", 2150.0, 8400.0, noise=60.0, seed=1),
        calibrate("inline, lower cable", 2080.0, -5100.0, noise=60.0, seed=2),
        calibrate("load-cell pulley, upper", 2150.0 * pulley.ratio, 3100.0, capstan=0.01, noise=30.0, seed=3),
        calibrate("load-cell pulley, lower", 2150.0 * pulley.ratio, -900.0, capstan=0.01, noise=30.0, seed=4),
    ]


@dataclass(frozen=True)
class CurrentSweep:
    """Seed 003's Fig. 18 at one EE position: per current level (A) held, the motor-current
    estimate ``estimate`` (eq. 35, N) and the tension the inline sensor's controller-side
    reading gives (``measured``, N), loading (``up``) then unloading."""

    position: float
    currents: np.ndarray
    up: np.ndarray
    estimate: np.ndarray
    measured: np.ndarray
    true: np.ndarray

    @property
    def hysteresis(self) -> float:
        """Mean of measured(unloading) − measured(loading) at the currents met both ways (N)."""
        lv = np.round(self.currents, 9)
        both = [c for c in np.unique(lv) if np.any((lv == c) & self.up) and np.any((lv == c) & ~self.up)]
        diffs = [
            self.measured[(lv == c) & ~self.up].mean() - self.measured[(lv == c) & self.up].mean()
            for c in both
        ]
        return float(np.mean(diffs)) if diffs else 0.0


@checked
def current_sweep(
    position: float,
    *,
    winch: Winch | None = None,
    total_length: float = 12.0,
    levels: np.ndarray | None = None,
    hold: float = 2.0,
    ramp: float = 0.2,
    chain: SignalChain | None = None,
    calibration: Calibration | None = None,
) -> CurrentSweep:
    """The driven cable's winch under current control, its EE at ``position`` (fraction of the
    ``total_length`` m of cable from the driven drum; the two cables' stiffness ``E·S/L`` follows,
    the seed's 48.9 GPa and 1.89 mm²), the current stepped through ``levels`` up then down (each
    reached by a ``ramp`` s smoothstep, a choice, then held ``hold`` s); at each level's end the
    estimate of eq. 35 and the tension read through ``chain`` (HX711 + BLE by default) and
    ``calibration`` (the sensor's own line, so that only the chain's sampling stands between)."""
    position = real(position, "position", lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    total_length = real(total_length, "total_length", lo=0.0, lo_open=True, hi=1e4)
    hold = real(hold, "hold", lo=1e-3, hi=60.0)
    ramp = real(ramp, "ramp", lo=0.0, hi=hold)
    if winch is not None and not isinstance(winch, Winch):
        raise DTypeError(f"winch must be a Winch, got {type(winch).__name__}")
    w = winch or Winch.seed003()
    v = w.values.copy()
    names = list(Winch.NAMES)
    ea = 48.9e9 * 1.89e-6
    v[names.index("stiffness_a")] = ea / (position * total_length)
    v[names.index("stiffness_b")] = ea / ((1.0 - position) * total_length)
    model = WinchDrive(Winch(v), control="current", friction_smoothing=1e-4, cable_damping=20.0)
    lv = np.r_[np.arange(0.0, 1.75, 0.25), 1.7] if levels is None else float_array(levels, "levels", 1)
    if lv.size < 1 or lv.size > 1000 or not np.all(np.isfinite(lv)):
        raise ParameterError(f"levels must be 1 to 1,000 finite currents (A), got {lv.size} values")
    sweep = np.concatenate([lv, lv[::-1][1:]])
    up = np.r_[np.ones(lv.size, dtype=bool), np.zeros(lv.size - 1, dtype=bool)]
    dt = 1e-3
    per = round(hold / dt)
    n_ramp = round(ramp / dt)
    current = np.empty(sweep.size * per)
    prev = sweep[0]
    for k, level in enumerate(sweep):
        s = np.clip(np.arange(per) / max(n_ramp, 1), 0.0, 1.0)
        current[k * per : (k + 1) * per] = prev + (level - prev) * s * s * (3 - 2 * s)
        prev = level
    run = simulate(model, current[:, None].copy(), dt, substeps=100, hold="foh")
    chain = chain or SignalChain.hx711_ble()
    cal = calibration or Calibration(1.0, 0.0)
    seen = chain.apply(run.t, cal.gain * run["tension_a"] + cal.offset)
    ends = np.arange(1, sweep.size + 1) * per - 1
    return CurrentSweep(
        position=position,
        currents=sweep,
        up=up,
        estimate=run["tension_from_current"][ends],
        measured=cal.tension(seen[ends]),
        true=run["tension_a"][ends],
    )


@checked
def fig18(positions: tuple[float, ...] = (0.3, 0.4, 0.5, 0.6, 0.7)) -> list[CurrentSweep]:
    """Fig. 18's experiment at five EE positions (fractions of the cable from the driven drum)."""
    return [current_sweep(p) for p in positions]


@checked
def fig18_table(sweeps: list[CurrentSweep], w: Winch | None = None) -> str:
    """Markdown: per position the estimate's error loading and unloading and the hysteresis,
    against the static friction's band ``τ_st/r`` either way."""
    w = w or Winch.seed003()
    v = dict(zip(Winch.NAMES, w.values, strict=True))
    band = v["static_friction"] / v["drum_radius"]
    lines = [
        "| EE position | measured − estimate, loading (mean) | unloading (mean) | "
        "hysteresis (unloading − loading) |",
        "|---|---|---|---|",
    ]
    for s in sweeps:
        live = s.currents > 0.9  # above the pretension's holding current: the drum moves both ways
        up = (s.measured - s.estimate)[live & s.up]
        down = (s.measured - s.estimate)[live & ~s.up]
        lines.append(
            f"| {s.position:.1f} of the cable | {up.mean():+.2f} N | {down.mean():+.2f} N | "
            f"{s.hysteresis:+.2f} N |"
        )
    lines.append(
        f"| static friction: −τ_st/r, +τ_st/r, 2τ_st/r | {-band:+.2f} N | {band:+.2f} N | {2 * band:+.2f} N |"
    )
    return "\n".join(lines)


@checked
def plot_fig18(path: str | Path, sweeps: list[CurrentSweep]) -> Path | None:
    """Measured tension against the motor-current estimate, loading and unloading (Fig. 18)."""
    from cablekit.plotting import pyplot_or_none, save_figure

    plt = pyplot_or_none()
    if plt is None:
        return None
    fig, ax = plt.subplots(figsize=(7, 6))
    for k, s in enumerate(sweeps):
        ax.plot(
            s.estimate[s.up], s.measured[s.up], "o-", color=f"C{k}", ms=3, lw=1, label=f"{s.position:.1f}, up"
        )
        ax.plot(
            s.estimate[~s.up],
            s.measured[~s.up],
            "s--",
            color=f"C{k}",
            ms=3,
            lw=1,
            label=f"{s.position:.1f}, down",
        )
    top = max(float(s.estimate.max()) for s in sweeps)
    ax.plot([0, top], [0, top], "k:", lw=0.8, label="estimate = measured")
    ax.set_xlabel("τ_estim = k_φ·I·r_gb / r (N), eq. 35")
    ax.set_ylabel("tension read by the inline sensor (N)")
    ax.set_title("Seed 003 Fig. 18 on the twin: current up, then down")
    ax.legend(fontsize=6, ncol=2)
    return save_figure(fig, path)
