"""Where a cable robot's winch-side tensions disagree with its motors: (effect, cable) candidates
located from the residual between the motor-current tension estimate and the sensor (issue #23,
"CDPRs in the diagnosis").

The nominal drum balance (seed 003 eqs 16–19, 34–35) gives the tension at each drum from the
motor current and the drum's motion::

    T̂_drum = (k_φ·r_gb·i − J_l·α̈ − B_l·α̇ − τ_st·σ_ε(α̇)) / r,     residual  e_j = T̂_drum,j − T_PUL,j

With nothing between the drum and the sensor, ``e`` is noise. Each candidate effect has a
physical signature in ``e`` at one cable ``j`` (its regressors, fitted by least squares with the
signs physics allows):

* ``pulley_friction`` — a pulley between the drum and the sensor: ``μN·T_PUL·sgn(v) + σ_v·v``
  with ``v = r·α̇`` (seed 002 eq. 7: proportional to the tension, against the motion);
* ``sensor_lag`` — a converter's hold and a link's latency (HX711, BLE; seed 003 §4): the sensor
  reads ``T(t − τ)``, so ``e ≈ c·(T̂_drum(t) − T̂_drum(t − τ))`` (the motor's estimate does not
  lag; ``τ`` from 5 to 300 ms, chosen on the fit half; coefficients ``[c, τ]``);
* ``sensor_gain`` — a calibration error (eq. 33): ``e = a·T_PUL + b``;
* ``drum_friction`` — the drum's own friction differs from nominal: ``Δτ·σ_ε(α̇)/r + ΔB·α̇/r``
  (no tension dependence — what tells it from a pulley).

Each candidate is fitted on the first half of the run and scored on the second (held out): the
fraction of the held-out residual energy (all cables) it removes. The best candidate is reported
when the held-out residual stands above the noise (its RMS more than ``3×`` the noise estimated
from the residual's sample-to-sample differences) and the candidate removes at least half of
it; otherwise "nothing found".

:func:`self_test` runs the plant (:class:`cablekit.cdpr.CdprPlant`, seed 002's robot with seed
003's winches) with one withheld effect at a time, at a drawn cable, the internal forces excited
so that the tensions vary: a Dahl pulley (the candidate assumes Coulomb), an HX711 + BLE signal
chain (sample-and-hold and latency; the candidate assumes a pure delay), a calibration error,
and none (false alarms). Its settings are fixed here and not tuned on its result.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cablekit._cablekit import PulleyFriction, SignalChain
from cablekit.cdpr import Winch
from cablekit.errors import ParameterError, ShapeError

EFFECTS = ("pulley_friction", "sensor_lag", "sensor_gain", "drum_friction")
#: the delays a sensor lag is tried at (s; chosen on the fit half)
LAGS = tuple(np.arange(0.005, 0.3001, 0.005))
_SIGNS = {"pulley_friction": (1, 1), "sensor_lag": (1,), "sensor_gain": (0, 0), "drum_friction": (0, 0)}


def _sgn(v: np.ndarray, eps: float) -> np.ndarray:
    return v / np.sqrt(v * v + eps * eps)


def drum_residual(
    winch: Winch,
    t: np.ndarray,
    alpha: np.ndarray,
    current: np.ndarray,
    sensor: np.ndarray,
    *,
    smoothing: float = 0.01,
) -> np.ndarray:
    """``T̂_drum − T_PUL`` ``(T, m)`` from drum angles (rad), currents (A) and the sensors (N)."""
    t = np.asarray(t, float)
    arrays = [np.asarray(a, float) for a in (alpha, current, sensor)]
    if (
        t.ndim != 1
        or t.size < 8
        or any(a.ndim != 2 or a.shape != arrays[0].shape or a.shape[0] != t.size for a in arrays)
    ):
        raise ShapeError("t (T ≥ 8,) and alpha, current, sensor (T, m) of one shape are needed")
    if not all(np.isfinite(a).all() for a in (t, *arrays)):
        raise ParameterError("the run has non-finite samples")
    if not (np.diff(t) > 0).all():
        raise ParameterError("t must increase")
    alpha, current, sensor = arrays
    w = dict(zip(Winch.NAMES, winch.values, strict=True))
    r = w["drum_radius"]
    jl, bl = winch.load  # J_l, B_l (eq. 17)
    rate = np.gradient(alpha, t, axis=0)
    acc = np.gradient(rate, t, axis=0)
    drum = (
        w["torque_constant"] * w["gear_ratio"] * current
        - jl * acc
        - bl * rate
        - w["static_friction"] * _sgn(rate, smoothing)
    ) / r
    return drum - sensor


def _regressors(
    effect: str,
    j: int,
    t: np.ndarray,
    alpha: np.ndarray,
    sensor: np.ndarray,
    drum_smooth: np.ndarray,
    r: float,
    smoothing: float,
    lag: float = 0.0,
) -> np.ndarray:
    rate = np.gradient(alpha[:, j], t)
    p = sensor[:, j]
    if effect == "pulley_friction":
        v = r * rate
        return np.column_stack([p * _sgn(v, 1e-3), v])
    if effect == "sensor_lag":
        # what a delay `lag` takes off the drum-side tension (the motor's estimate, which does not
        # lag; smoothed, see `diagnose`)
        d = drum_smooth[:, j]
        shift = max(1, round(lag / float(np.median(np.diff(t)))))
        return (d - np.concatenate([np.full(shift, d[0]), d[:-shift]]))[:, None]
    if effect == "sensor_gain":
        return np.column_stack([p, np.ones_like(p)])
    if effect == "drum_friction":
        return np.column_stack([_sgn(rate, smoothing) / r, rate / r])
    raise ParameterError(f"unknown effect {effect!r}; expected one of {EFFECTS}")


def _fit(x: np.ndarray, y: np.ndarray, signs: tuple[int, ...]) -> np.ndarray:
    """Least squares with the coefficients whose sign is 1 kept ≥ 0 (every subset tried)."""
    best, best_ss = np.zeros(x.shape[1]), float(y @ y)
    for mask in range(1, 2 ** x.shape[1]):
        cols = [c for c in range(x.shape[1]) if mask >> c & 1]
        coef, *_ = np.linalg.lstsq(x[:, cols], y, rcond=None)
        if any(signs[c] and v < 0 for c, v in zip(cols, coef, strict=True)):
            continue
        full = np.zeros(x.shape[1])
        full[cols] = coef
        ss = float(np.sum((y - x @ full) ** 2))
        if ss < best_ss:
            best, best_ss = full, ss
    return best


@dataclass(frozen=True)
class Candidate:
    """One (effect, cable) candidate: its coefficients (fitted on the first half) and the fraction
    of the held-out residual energy it removes."""

    effect: str
    cable: int
    coefficients: np.ndarray
    closed: float


@dataclass(frozen=True)
class CdprDiagnosis:
    """The ranked candidates, the held-out residual RMS per cable and the noise estimate (N), and
    the verdict: the best candidate, or ``None`` when the gap is noise or unexplained."""

    candidates: list[Candidate]
    residual_rms: np.ndarray
    noise: float
    found: Candidate | None

    @property
    def status(self) -> str:
        """``"found"``, ``"no gap"`` (the held-out residual is noise) or ``"unexplained"`` (a gap
        no candidate removes half of)."""
        if self.found is not None:
            return "found"
        return "unexplained" if (self.residual_rms > 3 * self.noise).any() else "no gap"

    def summary(self) -> str:
        """One line."""
        if self.found is None:
            worst = int(np.argmax(self.residual_rms))
            return (
                f"nothing found, {self.status} (largest held-out residual {self.residual_rms[worst]:.3f} N "
                f"at cable {worst + 1}, noise {self.noise:.3f} N)"
            )
        c = self.found
        return f"{c.effect} at cable {c.cable + 1}: closes {100 * c.closed:.0f} % of the held-out gap"


def diagnose(
    winch: Winch,
    t: np.ndarray,
    alpha: np.ndarray,
    current: np.ndarray,
    sensor: np.ndarray,
    *,
    effects: tuple[str, ...] = EFFECTS,
    smoothing: float = 0.01,
) -> CdprDiagnosis:
    """Locate the effect behind the motor-current vs sensor residual; see the module docs."""
    for e in effects:
        if e not in EFFECTS:
            raise ParameterError(f"unknown effect {e!r}; expected one of {EFFECTS}")
    res = drum_residual(winch, t, alpha, current, sensor, smoothing=smoothing)
    t, alpha, sensor = np.asarray(t, float), np.asarray(alpha, float), np.asarray(sensor, float)
    r = float(dict(zip(Winch.NAMES, winch.values, strict=True))["drum_radius"])
    half = t.size // 2
    held = res[half:]
    total = float(np.sum(held**2))
    noise = float(
        np.median(
            [1.4826 * np.median(np.abs(np.diff(held[:, j]))) / np.sqrt(2) for j in range(held.shape[1])]
        )
    )
    rms = np.sqrt(np.mean(held**2, axis=0))
    # the motor's drum-side tension, smoothed over 21 samples against its noise (the lag's regressor)
    kernel = np.ones(21) / 21
    drum = res + sensor
    drum_smooth = np.column_stack(
        [np.convolve(np.pad(drum[:, j], 10, mode="edge"), kernel, "valid") for j in range(drum.shape[1])]
    )
    cands = []
    for e in effects:
        for j in range(res.shape[1]):
            lags = LAGS if e == "sensor_lag" else (0.0,)
            fits = []
            for lag in lags:
                x = _regressors(e, j, t, alpha, sensor, drum_smooth, r, smoothing, lag)
                coef = _fit(x[:half], res[:half, j], _SIGNS[e])
                fits.append((float(np.sum((res[:half, j] - x[:half] @ coef) ** 2)), lag, x, coef))
            _, lag, x, coef = min(fits, key=lambda f: f[0])
            if e == "sensor_lag":
                coef = np.array([coef[0], lag])
            after = held[:, j] - x[half:] @ coef[: x.shape[1]]
            gain = float(np.sum(held[:, j] ** 2) - np.sum(after**2))
            cands.append(Candidate(e, j, coef, gain / total if total > 0 else 0.0))
    cands.sort(key=lambda c: -c.closed)
    best = cands[0]
    significant = bool((rms > 3 * noise).any())
    return CdprDiagnosis(cands, rms, noise, best if significant and best.closed >= 0.5 else None)


# ---- self-test on the plant ----------------------------------------------------------------


@dataclass(frozen=True)
class SelfTestCase:
    """A withheld effect (``None``: none) at a cable, and what the diagnosis found."""

    effect: str | None
    cable: int | None
    diagnosis: CdprDiagnosis

    @property
    def correct_effect(self) -> bool:
        f = self.diagnosis.found
        return (f is None) if self.effect is None else (f is not None and f.effect == self.effect)

    @property
    def correct_site(self) -> bool:
        f = self.diagnosis.found
        return (f is None) if self.effect is None else (f is not None and f.cable == self.cable)


def twin_run(
    effect: str | None, cable: int, *, seed: int = 0
) -> tuple[Winch, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One plant run along test 2's lines (30 s) with ``effect`` withheld at ``cable``: the winch,
    times, drum angles, currents (with 3 mA noise) and the sensors as read (0.1 N noise and any
    sensor effect)."""
    from cablekit.cdpr.compensate import TWIN_FRICTION, second_test_trajectory
    from cablekit.cdpr.force import excitation, mini_plant, plant_robot

    rng = np.random.default_rng(seed)
    poses = second_test_trajectory(dt=1e-3).poses[:30_000]
    drum_side = None
    if effect == "pulley_friction":
        mu, visc = np.zeros(8), np.zeros(8)
        mu[cable], visc[cable] = 0.06, 3.0
        drum_side = PulleyFriction(mu, visc, np.full(8, np.pi), law="dahl", presliding=2e-3)
    plant = mini_plant(home=poses[0], drum_side=drum_side)
    run = plant.closed_loop(poses, 1e-3, tension_offset=excitation(plant_robot(), poses, rng))
    t = np.arange(poses.shape[0]) * 1e-3
    sensor = run.sensor.copy()
    if effect == "sensor_lag":
        sensor[:, cable] = SignalChain.hx711_ble().apply(t, np.ascontiguousarray(sensor[:, cable]))
    elif effect == "sensor_gain":
        sensor[:, cable] = 1.04 * sensor[:, cable] + 0.4
    elif effect not in (None, "pulley_friction"):
        raise ParameterError(f"the twin cannot withhold {effect!r}")
    sensor += rng.normal(0.0, float(TWIN_FRICTION["noise"]), sensor.shape)
    current = run.current + rng.normal(0.0, 0.003, run.current.shape)
    return plant.winch, t, run.alpha, current, sensor


def self_test(*, cases: int = 2, seed: int = 0, progress: bool = False) -> list[SelfTestCase]:
    """``cases`` runs per withheld effect (pulley friction, sensor lag, sensor gain) at drawn
    cables, and ``cases`` runs with none."""
    rng = np.random.default_rng(seed)
    out = []
    plan = [
        (e, int(rng.integers(8)))
        for e in ("pulley_friction", "sensor_lag", "sensor_gain")
        for _ in range(cases)
    ]
    plan += [(None, 0)] * cases
    for k, (effect, cable) in enumerate(plan):
        winch, t, alpha, current, sensor = twin_run(effect, cable, seed=seed + k)
        d = diagnose(winch, t, alpha, current, sensor)
        out.append(SelfTestCase(effect, None if effect is None else cable, d))
        if progress:
            print(
                f"withheld {effect or 'nothing'}{'' if effect is None else f' at cable {cable + 1}'}: "
                f"{d.summary()}",
                flush=True,
            )
    return out


def markdown(cases: list[SelfTestCase]) -> str:
    """The self-test table and its totals."""
    lines = [
        "| withheld | found | held-out gap closed | effect | cable |",
        "|---|---|---|---|---|",
    ]
    for c in cases:
        f = c.diagnosis.found
        what = "nothing" if c.effect is None else f"{c.effect} at cable {c.cable + 1}"
        got = f"nothing ({c.diagnosis.status})" if f is None else f"{f.effect} at cable {f.cable + 1}"
        closed = "—" if f is None else f"{100 * f.closed:.0f} %"
        lines.append(
            f"| {what} | {got} | {closed} | {'yes' if c.correct_effect else 'NO'} | "
            f"{'yes' if c.correct_site else 'NO'} |"
        )
    withheld = [c for c in cases if c.effect is not None]
    none = [c for c in cases if c.effect is None]
    lines += [
        "",
        f"Effect right in {sum(c.correct_effect for c in withheld)}/{len(withheld)}, cable right in "
        f"{sum(c.correct_site for c in withheld)}/{len(withheld)}, false alarms "
        f"{sum(not c.correct_effect for c in none)}/{len(none)}.",
    ]
    return "\n".join(lines)
