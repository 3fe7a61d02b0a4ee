"""Where a cable robot disagrees with its nominal model, and why: (effect, cable) candidates
located on two residual channels (issue #23, "CDPRs in the diagnosis").

**Force channel** — the motors against the winch-side sensors. The nominal drum balance (seed
003 eqs 16–19, 34–35) gives the tension at each drum from the motor current and the drum's
motion::

    T̂_drum = (k_φ·r_gb·i − J_l·α̈ − B_l·α̇ − τ_st·σ_ε(α̇)) / r,     e_j = T̂_drum,j − T_PUL,j   (N)

With nothing between the drum and the sensor, ``e`` is noise. Candidates, each with its
physical signature in ``e`` at one cable ``j`` (regressors fitted by least squares with the signs
physics allows):

* ``pulley_friction`` — a pulley between the drum and the sensor: ``μN·T_PUL·sgn(v) + σ_v·v``
  with ``v = r·α̇`` (seed 002 eq. 7: proportional to the tension, against the motion);
* ``sensor_lag`` — a converter's hold and a link's latency (HX711, BLE; seed 003 §4): the sensor
  reads ``T(t − τ)``, so ``e ≈ c·(T̂_drum(t) − T̂_drum(t − τ))`` (``τ`` from 5 to 300 ms, chosen
  on the fit half; coefficients ``[c, τ]``);
* ``sensor_gain`` — a calibration error (eq. 33): ``e = a·T_PUL + b``;
* ``drum_friction`` — the drum's own friction differs from nominal: ``Δτ·σ_ε(α̇)/r + ΔB·α̇/r``
  (no tension dependence — what tells it from a pulley).

**Length channel** — the cables' lengths against a measured platform pose (a laser tracker or
camera; without one this channel is off). The nominal cable is elastic (seed 002 eq. 15)::

    e_j = l_j(q) − L_j(α) − T_j·L_j/(E·A)_j     (m),   L_j(α) = L0_j − r·α_j

with ``l_j(q)`` the geometric length at the measured pose, ``L0`` the unstretched lengths at
``α = 0`` and ``T`` the platform-side tension: the sensor's, taken back through the nominal
platform-side pulley friction when one is given (``platform_side``, seed 002 eq. 8). ``e`` is
averaged over 20 ms blocks against the tracker's noise. Candidates, each with a constant (a
length calibration):

* ``cable_elasticity`` — the cable's stiffness differs from nominal: ``e = ΔC·T·L + b``;
* ``cable_creep`` — a polymer cable's creep as a Burgers body: a Kelvin–Voigt element (the load
  low-passed with time constant ``τ``, 0.5–60 s) and a dashpot's irreversible flow (the load
  integrated), started from an unknown state:
  ``e = c·LP_τ(T·L) + f·∫T·L dt + d·e^(−t/τ) + b`` with ``c, f ≥ 0`` (coefficients
  ``[c, f, d, b, τ]``). ``τ`` and whether the flow is there are chosen inside the fit half
  (fitted on its first half, scored on its second): an integral fitted to noise extrapolates
  badly;
* ``length_offset`` — a cable's length calibration only: ``e = b``.

Each candidate is fitted on the first half of the run and scored on the second (held out): the
fraction of its channel's held-out gap it removes — the residual energy above the noise
(estimated from the residual's sample-to-sample differences), summed over the cables. Per
channel, the best candidate is reported when some cable's gap is significant (its held-out
energy exceeds the noise's by 5 standard deviations of a χ² with one degree of freedom per
sample) and the candidate removes at least half of the gap. A candidate with fewer parameters
wins unless the better one removes at least a quarter of the gap it leaves, and more than the
noise could (a creep with a short ``τ`` is an elasticity, an elasticity under a nearly constant
load is an offset). When the force
channel finds a calibration error, the length channel uses the corrected sensor.

:func:`self_test` runs the plant (:class:`cablekit.cdpr.CdprPlant`, seed 002's robot with seed
003's winches and the twin's platform-side friction) with one withheld effect at a time, at a
drawn cable, the internal forces excited so that the tensions vary: a Dahl pulley (the candidate
assumes Coulomb), an HX711 + BLE signal chain (sample-and-hold and latency; the candidate
assumes a pure delay), a calibration error, a winch with 50 % more static friction, a cable 40 %
softer than nominal, a creeping cable, and none (false alarms). Its settings are fixed here and
not tuned on its result.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from cablekit import _log
from cablekit._args import Seed, Stride, checked, instance, real, signal
from cablekit._cablekit import PulleyFriction, SignalChain
from cablekit.cdpr import Robot, Winch
from cablekit.cdpr.formats import RunFile, load_cdpr_run
from cablekit.errors import ParameterError, ShapeError

FORCE_EFFECTS = ("pulley_friction", "sensor_lag", "sensor_gain", "drum_friction")
LENGTH_EFFECTS = ("cable_elasticity", "cable_creep", "length_offset")
EFFECTS = FORCE_EFFECTS + LENGTH_EFFECTS
#: the delays a sensor lag is tried at (s; chosen on the fit half)
LAGS = tuple(np.arange(0.005, 0.3001, 0.005))
#: the time constants a creep is tried at (s; chosen on the fit half)
CREEP_TIMES = tuple(np.geomspace(0.5, 60.0, 22))
#: the length channel's averaging block (s) and the fewest blocks it fits
BLOCK = 0.02
MIN_BLOCKS = 40
#: with estimated rest lengths, a held-out run's offsets come from its first seconds (not scored)
CALIBRATION = 2.0
_SIGNS = {
    "pulley_friction": (1, 1),
    "sensor_lag": (1,),
    "sensor_gain": (0, 0),
    "drum_friction": (0, 0),
    "cable_elasticity": (0, 0),
    "cable_creep": (1, 1, 0, 0),
    "length_offset": (0,),
}
# parameters, a searched time counting as one: among tied candidates the smallest wins
_SIZE = {
    "pulley_friction": 2,
    "sensor_lag": 2,
    "sensor_gain": 2,
    "drum_friction": 2,
    "cable_elasticity": 2,
    "cable_creep": 5,
    "length_offset": 1,
}
_KEEP = 0.75
_Z = 5.0


def _sgn(v: np.ndarray, eps: float) -> np.ndarray:
    return v / np.sqrt(v * v + eps * eps)


def _run_arrays(t: Any, *arrays: Any) -> tuple[np.ndarray, ...]:
    t = signal(t, "t")
    out = [signal(a, name) for a, name in zip(arrays, ("alpha", "current", "sensor"), strict=False)]
    if (
        t.ndim != 1
        or t.size < 8
        or any(a.ndim != 2 or a.shape != out[0].shape or a.shape[0] != t.size for a in out)
    ):
        raise ShapeError("t (T ≥ 8,) and alpha, current, sensor (T, m) of one shape are needed")
    if not all(np.isfinite(a).all() for a in (t, *out)):
        raise ParameterError("the run has non-finite samples")
    if not (np.diff(t) > 0).all():
        raise ParameterError("t must increase")
    return (t, *out)


@checked
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
    instance(winch, "winch", Winch)
    smoothing = real(smoothing, "smoothing", lo=0.0, lo_open=True)
    t, alpha, current, sensor = _run_arrays(t, alpha, current, sensor)
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


@dataclass(frozen=True)
class Lengths:
    """What the length channel needs besides the run: the nominal ``robot``, the unstretched
    lengths ``rest_length`` ``(m,)`` at ``α = 0`` (m), the measured platform ``poses`` ``(T, n)``
    and, optionally, the nominal platform-side pulley friction (``coefficient``, ``viscous``,
    ``guide_wrap`` per cable, ``presliding``: seed 002's Dahl law, as in
    :data:`cablekit.cdpr.compensate.TWIN_FRICTION`). With ``estimated_rest`` the rest lengths are
    only estimates: each cable's offset, fitted on the fit data, is part of the nominal model
    (and ``length_offset`` is no candidate)."""

    robot: Robot
    rest_length: np.ndarray
    poses: np.ndarray
    platform_side: Mapping[str, Any] | None = None
    estimated_rest: bool = False


@checked
def length_residual(
    lengths: Lengths, winch: Winch, t: np.ndarray, alpha: np.ndarray, sensor: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(e, s)`` ``(T, m)``: the stretch the elastic law leaves unexplained,
    ``e = l(q) − L(α) − T·L/(E·A)`` (m), and the load ``s = T·L`` (N·m) with ``T`` the
    platform-side tension (see the module docs)."""
    t, alpha, sensor = _run_arrays(t, alpha, sensor)
    robot = lengths.robot
    m = alpha.shape[1]
    rest = np.asarray(lengths.rest_length, float)
    poses = np.asarray(lengths.poses, float)
    if robot.n_cables != m or rest.shape != (m,) or poses.shape != (t.size, robot.dof):
        raise ShapeError(
            f"the length channel needs a robot of {m} cables, rest_length ({m},) and poses "
            f"({t.size}, {robot.dof}); got {robot.n_cables} cables, {rest.shape} and {poses.shape}"
        )
    if not (np.isfinite(rest).all() and np.isfinite(poses).all()):
        raise ParameterError("rest_length and poses must be finite")
    r = float(dict(zip(Winch.NAMES, winch.values, strict=True))["drum_radius"])
    unstretched = rest[None, :] - r * alpha
    ee = sensor
    fr = lengths.platform_side
    if fr is not None:
        dt = float(np.median(np.diff(t)))
        args = [np.asarray(fr[k], float) for k in ("coefficient", "viscous", "guide_wrap")]
        presliding = float(fr["presliding"])
        # the friction's direction from poses smoothed over a block (a tracker's noise would
        # chatter the speed)
        smooth = _moving_average(poses, max(1, round(BLOCK / dt)) | 1)
        # T_PUL = T_EE + F(T_EE): three fixed-point steps (F is affine in T_EE for a given
        # motion, with a slope μN·z ≪ 1)
        for _ in range(3):
            pul = robot.path_friction(smooth, ee, dt, *args, law="dahl", presliding=presliding).pul
            ee = ee - (pul - sensor)
    load = ee * unstretched
    e = robot.inverse_kinematics(poses).length - unstretched - load / robot.ea[None, :]
    return e, load


def _moving_average(a: np.ndarray, k: int) -> np.ndarray:
    """Centred moving average of the columns of ``a`` ``(T, c)`` over an odd ``k``, edges held."""
    pad = np.pad(a, ((k // 2, k // 2), (0, 0)), mode="edge")
    return np.ascontiguousarray(
        np.stack([np.convolve(pad[:, i], np.ones(k) / k, "valid") for i in range(a.shape[1])], 1)
    )


def _blocks(a: np.ndarray, k: int) -> np.ndarray:
    n = a.shape[0] // k * k
    return a[:n].reshape(n // k, k, *a.shape[1:]).mean(axis=1)


def _low_pass(s: np.ndarray, dt: float, tau: float) -> np.ndarray:
    """First-order low-pass of ``s`` ``(T, m)`` started settled."""
    a = np.exp(-dt / tau)
    out = np.empty_like(s)
    out[0] = s[0]
    for k in range(1, s.shape[0]):
        out[k] = a * out[k - 1] + (1 - a) * s[k]
    return out


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
    """One (effect, cable) candidate: its coefficients (fitted on the first half; a searched
    time last) and the fraction of its channel's held-out gap (the residual energy above the
    noise) it removes."""

    effect: str
    cable: int
    coefficients: np.ndarray
    closed: float


@dataclass(frozen=True)
class Channel:
    """One residual channel (``"force"``, N; ``"length"``, m): its ranked candidates; per cable
    the held-out residual RMS, the part of it above the noise (``gap_rms``) and whether that part
    is significant; the noise estimate; its verdict (``None``: nothing found); and for plots the
    residual ``(T, m)`` (rows before ``split`` fitted), the finding's fitted signature at its
    cable ``(T,)``."""

    name: str
    candidates: list[Candidate]
    residual_rms: np.ndarray
    gap_rms: np.ndarray
    significant: np.ndarray
    noise: float
    found: Candidate | None
    residual: np.ndarray
    split: int
    explained: np.ndarray | None

    @property
    def status(self) -> str:
        """``"found"``, ``"no gap"`` (the held-out residual is noise) or ``"unexplained"`` (a gap
        no candidate removes half of)."""
        if self.found is not None:
            return "found"
        return "unexplained" if self.significant.any() else "no gap"

    @checked
    def summary(self) -> str:
        """One line."""
        unit, scale = ("N", 1.0) if self.name == "force" else ("µm", 1e6)
        if self.found is None:
            worst = int(np.argmax(self.gap_rms))
            return (
                f"{self.name}: nothing found, {self.status} (largest held-out gap "
                f"{scale * self.gap_rms[worst]:.3g} {unit} RMS above the noise at cable {worst + 1}, "
                f"noise {scale * self.noise:.3g} {unit})"
            )
        c = self.found
        return (
            f"{self.name}: {c.effect} at cable {c.cable + 1}, closes {100 * c.closed:.0f} % of the "
            "held-out gap"
        )


@dataclass(frozen=True)
class CdprDiagnosis:
    """The force channel and, with measured poses, the length channel."""

    force: Channel
    length: Channel | None
    #: what the run loader did to the files (``"run.csv: resampled ..."``)
    notes: tuple[str, ...] = ()

    @property
    def channels(self) -> list[Channel]:
        """The channels that ran."""
        return [c for c in (self.force, self.length) if c is not None]

    @property
    def findings(self) -> list[Candidate]:
        """What was found, one per channel at most."""
        return [c.found for c in self.channels if c.found is not None]

    @property
    def status(self) -> str:
        """``"found"`` if a channel found an effect, else ``"unexplained"`` if a channel has a gap,
        else ``"no gap"``."""
        states = [c.status for c in self.channels]
        return next((s for s in ("found", "unexplained") if s in states), "no gap")

    @checked
    def summary(self) -> str:
        """One line per channel, joined."""
        return "; ".join(c.summary() for c in self.channels)

    @checked
    def to_dict(self) -> dict[str, Any]:
        """The diagnosis as JSON-ready data (``diagnosis.json`` of a campaign group): status,
        findings (cables 1-based) and, per channel, its verdict, noise, per-cable held-out gaps and
        ranked candidates; not the residual time series."""

        def cand(c: Candidate) -> dict[str, Any]:
            return {
                "effect": c.effect,
                "cable": c.cable + 1,
                "closed": float(c.closed),
                "coefficients": [float(v) for v in c.coefficients],
            }

        return {
            "kind": "cable_robot",
            "status": self.status,
            "findings": [cand(c) for c in self.findings],
            "channels": [
                {
                    "name": ch.name,
                    "status": ch.status,
                    "noise": float(ch.noise),
                    "residual_rms": [float(v) for v in ch.residual_rms],
                    "gap_rms": [float(v) for v in ch.gap_rms],
                    "significant": [bool(v) for v in ch.significant],
                    "candidates": [cand(c) for c in ch.candidates],
                }
                for ch in self.channels
            ],
            "notes": list(self.notes),
        }


def _locate(
    name: str,
    res: np.ndarray,
    half: int,
    effects: tuple[str, ...],
    regress: Callable[[str, int, Any], np.ndarray],
    grids: Mapping[str, tuple[Any, ...]],
    validated: frozenset[str] = frozenset(),
) -> Channel:
    """Fit, score and rank every (effect, cable); a grid's point is chosen on the fit half by its
    residual, or, for the ``validated`` effects, by fitting on the fit half's first half and
    scoring on its second. Rows before ``half`` are fitted, the rest held out."""
    held = res[half:]
    noise = float(
        np.median(
            [1.4826 * np.median(np.abs(np.diff(held[:, j]))) / np.sqrt(2) for j in range(held.shape[1])]
        )
    )
    # the gap: held-out energy above the noise's; significant where it exceeds the noise's by
    # Z standard deviations of a χ² with as many degrees of freedom as samples
    size = held.shape[0]
    energy = np.sum(held**2, axis=0)
    floor = size * noise**2
    significant = energy > floor * (1 + _Z * np.sqrt(2 / size))
    total = float(np.sum(np.maximum(energy - floor, 0.0)))
    rms = np.sqrt(energy / size)
    cands = []
    chosen: dict[tuple[str, int], tuple[Any, np.ndarray]] = {}
    for e in effects:
        for j in range(res.shape[1]):
            fits = []
            for h in grids.get(e, (0.0,)):
                x = regress(e, j, h)
                if e in validated:
                    q = half // 2
                    c = _fit(x[:q], res[:q, j], _SIGNS[e])
                    score = float(np.sum((res[q:half, j] - x[q:half] @ c) ** 2))
                    coef = _fit(x[:half], res[:half, j], _SIGNS[e])
                else:
                    coef = _fit(x[:half], res[:half, j], _SIGNS[e])
                    score = float(np.sum((res[:half, j] - x[:half] @ coef) ** 2))
                fits.append((score, h, x, coef))
            _, h, x, coef = min(fits, key=lambda f: f[0])
            chosen[e, j] = (h, coef)
            after = held[:, j] - x[half:] @ coef
            gain = float(np.sum(held[:, j] ** 2) - np.sum(after**2))
            if e in grids:
                coef = np.append(coef, h[0] if isinstance(h, tuple) else h)
            cands.append(Candidate(e, j, coef, gain / total if total > 0 else 0.0))
    cands.sort(key=lambda c: -c.closed)
    found = None
    if cands and significant.any() and cands[0].closed >= 0.5:
        found = cands[0]
        # a simpler candidate wins unless this one removes a quarter of the gap it leaves and
        # more than noise would (Z standard deviations of one cable's noise energy)
        resolvable = _Z * noise**2 * np.sqrt(2 * size) / total if total > 0 else np.inf
        while True:
            simpler = [c for c in cands if _SIZE[c.effect] < _SIZE[found.effect]]
            if not simpler:
                break
            s = simpler[0]  # the best of them (sorted)
            better = found.closed - s.closed
            if s.closed < 0.5 or (better >= (1 - _KEEP) * (1 - s.closed) and better > resolvable):
                break
            found = s
    gap = np.sqrt(np.maximum(energy - floor, 0.0) / size)
    explained = None
    if found is not None:
        h, coef = chosen[found.effect, found.cable]
        explained = regress(found.effect, found.cable, h) @ coef
    return Channel(name, cands, rms, gap, significant, noise, found, res, half, explained)


@checked
def diagnose(
    winch: Winch,
    t: np.ndarray,
    alpha: np.ndarray,
    current: np.ndarray,
    sensor: np.ndarray,
    *,
    lengths: Lengths | None = None,
    effects: tuple[str, ...] = EFFECTS,
    smoothing: float = 0.01,
) -> CdprDiagnosis:
    """Locate the effects behind the force residual and, given ``lengths`` (measured poses and
    the nominal geometry), the length residual; see the module docs. Values so large that the
    residuals or their energies overflow are a :class:`~cablekit.errors.ParameterError`."""
    return _checked(winch, [_Segment(t, alpha, current, sensor, lengths)], None, effects, smoothing)


def _checked(
    winch: Winch, runs: list[_Segment], n_fit: int | None, effects: tuple[str, ...], smoothing: float
) -> CdprDiagnosis:
    """:func:`_channels` after checking the effects, with an overflow a ``ParameterError``."""
    for e in effects:
        if e not in EFFECTS:
            raise ParameterError(f"unknown effect {e!r}; expected one of {EFFECTS}")
    try:
        with np.errstate(over="raise", invalid="raise"):
            return _channels(winch, runs, n_fit, effects, smoothing)
    except FloatingPointError as e:
        raise ParameterError(f"the run's values overflow the residuals ({e}); check its units") from None


@dataclass(frozen=True)
class _Segment:
    """One run as the channels read it."""

    t: np.ndarray
    alpha: np.ndarray
    current: np.ndarray
    sensor: np.ndarray
    lengths: Lengths | None


def _channels(
    winch: Winch,
    runs: list[_Segment],
    n_fit: int | None,
    effects: tuple[str, ...],
    smoothing: float,
) -> CdprDiagnosis:
    """Both channels over ``runs``: fitted on the first ``n_fit`` runs and scored on the rest, or
    (``None``) on the first and second half of a single run."""
    r = float(dict(zip(Winch.NAMES, winch.values, strict=True))["drum_radius"])
    force_runs = []
    for run in runs:
        res = drum_residual(winch, run.t, run.alpha, run.current, run.sensor, smoothing=smoothing)
        t, alpha, sensor = (np.asarray(a, float) for a in (run.t, run.alpha, run.sensor))
        dt = float(np.median(np.diff(t)))
        rate = np.gradient(alpha, t, axis=0)
        # the motor's drum-side tension, smoothed over 21 samples against its noise (the lag's
        # regressor)
        drum_smooth = _moving_average(res + sensor, 21)
        force_runs.append((res, sensor, rate, drum_smooth, dt))

    def force_one(run: tuple[np.ndarray, ...], effect: str, j: int, lag: float) -> np.ndarray:
        _, sensor, rate, drum_smooth, dt = run
        p = sensor[:, j]
        if effect == "pulley_friction":
            v = r * rate[:, j]
            return np.column_stack([p * _sgn(v, 1e-3), v])
        if effect == "sensor_lag":
            # what a delay `lag` takes off the drum-side tension (the motor's estimate, which
            # does not lag)
            d = drum_smooth[:, j]
            shift = min(max(1, round(lag / dt)), d.size - 1)
            return (d - np.concatenate([np.full(shift, d[0]), d[:-shift]]))[:, None]
        if effect == "sensor_gain":
            return np.column_stack([p, np.ones_like(p)])
        return np.column_stack([_sgn(rate[:, j], smoothing) / r, rate[:, j] / r])

    def split(sizes: list[int]) -> int:
        return sizes[0] // 2 if n_fit is None else sum(sizes[:n_fit])

    res = np.concatenate([f[0] for f in force_runs])
    force_effects = tuple(e for e in effects if e in FORCE_EFFECTS)
    force = _locate(
        "force",
        res,
        split([f[0].shape[0] for f in force_runs]),
        force_effects,
        lambda e, j, h: np.concatenate([force_one(f, e, j, h) for f in force_runs]),
        {"sensor_lag": LAGS},
    )
    length_effects = tuple(e for e in effects if e in LENGTH_EFFECTS)
    if any(run.lengths is None for run in runs) or not length_effects:
        return CdprDiagnosis(force, None)
    length_runs = []
    for run, (_, sensor, _, _, dt) in zip(runs, force_runs, strict=True):
        read = sensor.copy()
        if force.found is not None and force.found.effect == "sensor_gain":
            a, b = force.found.coefficients[:2]
            read[:, force.found.cable] = (1 + a) * read[:, force.found.cable] + b
        assert run.lengths is not None
        e, load = length_residual(run.lengths, winch, run.t, run.alpha, read)
        k = max(1, round(BLOCK / dt))
        e_b, load_b = _blocks(e, k), _blocks(load, k)
        if e_b.shape[0] < MIN_BLOCKS:
            raise ParameterError(
                f"the length channel needs at least {MIN_BLOCKS} blocks of {BLOCK * 1e3:.0f} ms "
                f"({MIN_BLOCKS * BLOCK:.1f} s) per run; a run has {e_b.shape[0]}"
            )
        creep = {tau: _low_pass(load_b, k * dt, tau) for tau in CREEP_TIMES}
        flow = np.cumsum(load_b, axis=0) * k * dt
        length_runs.append((e_b, load_b, creep, flow, np.arange(e_b.shape[0]) * k * dt))

    def length_one(run: tuple[Any, ...], effect: str, j: int, h: Any) -> np.ndarray:
        e_b, load_b, creep, flow, tb = run
        one = np.ones(e_b.shape[0])
        if effect == "cable_elasticity":
            return np.column_stack([load_b[:, j], one])
        if effect == "cable_creep":
            tau, flows = h
            start = np.exp(-tb / tau)  # the creep state at a run's start is unknown
            return np.column_stack([creep[tau][:, j], flow[:, j] if flows else 0 * one, start, one])
        return one[:, None]

    grid = {"cable_creep": tuple((tau, flows) for tau in CREEP_TIMES for flows in (False, True))}
    estimated = any(run.lengths is not None and run.lengths.estimated_rest for run in runs)
    # (rows an offset is taken over, rows dropped from the front) per run
    centring: list[tuple[slice, int] | None] = [None] * len(length_runs)
    if estimated:
        # estimated rest lengths: each cable's offset is part of the nominal model
        length_effects = tuple(e for e in length_effects if e != "length_offset")
        if n_fit is not None:
            # each run has its own: a fit run's is its mean; a held-out run's is the mean of a
            # calibration prefix, which is then not scored
            for i, lr in enumerate(length_runs):
                prefix = min(round(CALIBRATION / BLOCK), lr[0].shape[0] // 2)
                centring[i] = (slice(None), 0) if i < n_fit else (slice(0, prefix), prefix)

    def centred(a: np.ndarray, c: tuple[slice, int] | None) -> np.ndarray:
        return a if c is None else (a - a[c[0]].mean(axis=0))[c[1] :]

    e_all = np.concatenate([centred(lr[0], c) for lr, c in zip(length_runs, centring, strict=True)])
    half = split([centred(lr[0], c).shape[0] for lr, c in zip(length_runs, centring, strict=True)])
    if estimated and n_fit is None:
        e_all = e_all - e_all[:half].mean(axis=0)
    length = _locate(
        "length",
        e_all,
        half,
        length_effects,
        lambda e, j, h: np.concatenate(
            [centred(length_one(lr, e, j, h), c) for lr, c in zip(length_runs, centring, strict=True)]
        ),
        grid,
        frozenset({"cable_creep"}),
    )
    return CdprDiagnosis(force, length)


# ---- a measured run --------------------------------------------------------------------------


@checked
def rest_from_first_sample(robot: Robot, winch: Winch, run: RunFile) -> np.ndarray:
    """The unstretched lengths at ``α = 0`` (m) taking the first sample as a rest: its pose, its
    drum angles and its sensors' tensions through the nominal elastic law. An error here is a
    constant per cable, which every length candidate's constant takes up (so a length offset
    cannot be seen this way)."""
    if run.poses is None:
        raise ParameterError("the run has no pose columns: the length channel needs measured poses")
    r = float(dict(zip(Winch.NAMES, winch.values, strict=True))["drum_radius"])
    l0 = robot.inverse_kinematics(np.ascontiguousarray(run.poses[:1])).length[0]
    return l0 / (1 + run.sensor[0] / robot.ea) + r * run.alpha[0]


@checked
def diagnose_file(
    path: str | Path,
    robot: Robot,
    winch: Winch | None = None,
    *,
    rest_length: np.ndarray | None = None,
    platform_side: Mapping[str, Any] | None = None,
    topics: Mapping[str, Any] | None = None,
) -> CdprDiagnosis:
    """:func:`diagnose` on a run file (:func:`load_cdpr_run`, a ROS 2 bag through ``topics``):
    the force channel always, the length channel when the file has poses (``rest_length``
    default: :func:`rest_from_first_sample`)."""
    winch = winch or Winch.seed003()
    run = load_cdpr_run(path, robot, topics=topics)
    lengths = None
    if run.poses is not None:
        rest = rest_from_first_sample(robot, winch, run) if rest_length is None else rest_length
        lengths = Lengths(robot, np.asarray(rest, float), run.poses, platform_side, rest_length is None)
    d = diagnose(winch, run.t, run.alpha, run.current, run.sensor, lengths=lengths)
    return replace(d, notes=tuple(f"{Path(path).name}: {n}" for n in run.notes))


@checked
def is_robot_file(path: str | Path) -> bool:
    """Whether ``path`` is a cable robot's file (``motion`` and ``[[cables]]``) rather than a
    joint, transmission or network model file: the diagnosis then runs the CDPR engine. A file
    that is not TOML is not a robot file (the model loader reports it)."""
    from cablekit._files import load_toml
    from cablekit.errors import DataError

    try:
        doc = load_toml(path, "model file")
    except DataError:
        return False
    return "cables" in doc and "motion" in doc


@checked
def diagnose_runs(
    fit: list[str | Path],
    holdout: list[str | Path],
    robot: Robot,
    winch: Winch | None = None,
    *,
    platform_side: Mapping[str, Any] | None = None,
    effects: tuple[str, ...] = EFFECTS,
    topics: Mapping[str, Any] | None = None,
) -> CdprDiagnosis:
    """:func:`diagnose` with the candidates fitted on the ``fit`` run files and scored on the
    ``holdout`` run files (never fitted), as ``cablekit diagnose`` does for a joint model. The
    length channel runs when every file has poses; each run's rest lengths come from its first
    sample (:func:`rest_from_first_sample`). Bags are read through ``topics``
    (:func:`load_cdpr_run`)."""
    if not fit or not holdout:
        raise ParameterError("give at least one fit run and one held-out run")
    runs = [(Path(p).name, load_cdpr_run(p, robot, topics=topics)) for p in [*fit, *holdout]]
    return diagnose_loaded(runs, len(fit), robot, winch, platform_side=platform_side, effects=effects)


@checked
def diagnose_loaded(
    runs: list[tuple[str, RunFile]],
    n_fit: int,
    robot: Robot,
    winch: Winch | None = None,
    *,
    platform_side: Mapping[str, Any] | None = None,
    effects: tuple[str, ...] = EFFECTS,
) -> CdprDiagnosis:
    """:func:`diagnose_runs` on runs already read (``(name, run)``, the first ``n_fit`` fitted,
    the others held out): a campaign's worker receives them so, not the files."""
    if not 0 < n_fit < len(runs):
        raise ParameterError(
            f"give at least one fit run and one held-out run (n_fit={n_fit} of {len(runs)} runs)"
        )
    winch = winch or Winch.seed003()
    segments, notes = [], []
    for name, run in runs:
        notes += [f"{name}: {n}" for n in run.notes]
        lengths = None
        if run.poses is not None:
            rest = rest_from_first_sample(robot, winch, run)
            lengths = Lengths(robot, rest, run.poses, platform_side, estimated_rest=True)
        segments.append(_Segment(run.t, run.alpha, run.current, run.sensor, lengths))
    return replace(_checked(winch, segments, n_fit, effects, 0.01), notes=tuple(notes))


@checked
def run_report(
    robot_name: str, d: CdprDiagnosis, fit: list[str], holdout: list[str] | None, figure: str | None = None
) -> str:
    """The Markdown page of a run diagnosis (``diagnose.md``): what was fitted and held out, then
    :func:`report`, and the figure's link if one was written."""
    names = ", ".join(Path(p).name for p in fit)
    split = (
        f"fitted on {names}, held out {', '.join(Path(p).name for p in holdout)}"
        if holdout
        else f"{names}, fitted on its first half and held out on its second"
    )
    text = f"# Where {robot_name} disagrees with its nominal model\n\n{split}\n\n" + report(d)
    if figure:
        text += f"\n![each channel's residual and finding]({figure})\n"
    return text


@checked
def report(d: CdprDiagnosis, *, top: Stride = 5) -> str:
    """Markdown: the loader's notes, each channel's verdict and its best candidates."""
    lines = [f"Note: {n}" for n in d.notes] + ([""] if d.notes else [])
    for ch in d.channels:
        unit, scale = ("N", 1.0) if ch.name == "force" else ("µm", 1e6)
        lines += [
            f"## {ch.name} channel: {ch.status}",
            "",
            ch.summary(),
            "",
            f"Held-out gap above the noise ({scale * ch.noise:.3g} {unit}) per cable: "
            + ", ".join(f"{scale * g:.3g}" for g in ch.gap_rms)
            + f" {unit} RMS.",
            "",
            "| candidate | cable | gap closed | coefficients |",
            "|---|---|---|---|",
        ]
        lines += [
            f"| {c.effect} | {c.cable + 1} | {100 * c.closed:.0f} % | "
            + ", ".join(f"{v:.4g}" for v in c.coefficients)
            + " |"
            for c in ch.candidates[:top]
        ]
        lines.append("")
    return "\n".join(lines)


@checked
def plot(d: CdprDiagnosis, path: str | Path) -> Path | None:
    """Per channel, the residual at the finding's cable (else at the largest gap) over the fit
    and held-out samples, with the finding's fitted signature."""
    from cablekit.plotting import pyplot_or_none, save_figure

    plt = pyplot_or_none()
    if plt is None:
        return None
    chans = d.channels
    fig, axes = plt.subplots(len(chans), 1, figsize=(10, 3.2 * len(chans)), squeeze=False)
    for ax, ch in zip(axes[:, 0], chans, strict=True):
        unit, scale = ("N", 1.0) if ch.name == "force" else ("µm", 1e6)
        j = ch.found.cable if ch.found is not None else int(np.argmax(ch.gap_rms))
        k = np.arange(ch.residual.shape[0])
        ax.plot(k, scale * ch.residual[:, j], lw=0.6, color="0.5", label=f"residual, cable {j + 1}")
        if ch.explained is not None and ch.found is not None:
            ax.plot(k, scale * ch.explained, lw=1.0, color="C3", label=f"{ch.found.effect} (fitted)")
        ax.axvspan(ch.split, k[-1], color="C0", alpha=0.08, label="held out")
        ax.set_ylabel(f"{ch.name} residual ({unit})")
        ax.set_xlabel("sample" if ch.name == "force" else "20 ms block")
        ax.set_title(ch.summary(), fontsize=8)
        ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    return save_figure(fig, path)


# ---- self-test on the plant ----------------------------------------------------------------


@dataclass(frozen=True)
class SelfTestCase:
    """A withheld effect (``None``: none) at a cable, and what the diagnosis found."""

    effect: str | None
    cable: int | None
    diagnosis: CdprDiagnosis

    @property
    def correct_effect(self) -> bool:
        """The findings are the withheld effect and nothing else (none when none is withheld)."""
        got = [f.effect for f in self.diagnosis.findings]
        return got == ([] if self.effect is None else [self.effect])

    @property
    def correct_site(self) -> bool:
        """The withheld effect's finding names its cable (no finding when none is withheld)."""
        if self.effect is None:
            return not self.diagnosis.findings
        return any(f.effect == self.effect and f.cable == self.cable for f in self.diagnosis.findings)


@dataclass(frozen=True)
class TwinRun:
    """A run as the diagnosis reads it: the winch, times (s), drum angles (rad), currents (A),
    the winch-side sensors (N) and the length channel's inputs (measured poses and the nominal
    geometry)."""

    winch: Winch
    t: np.ndarray
    alpha: np.ndarray
    current: np.ndarray
    sensor: np.ndarray
    lengths: Lengths

    @checked
    def diagnose(self) -> CdprDiagnosis:
        """:func:`diagnose` on this run, both channels."""
        return diagnose(self.winch, self.t, self.alpha, self.current, self.sensor, lengths=self.lengths)


#: the twin's pose measurement: a laser tracker's noise (m, rad; per coordinate and sample)
TRACKER_NOISE = (10e-6, 20e-6)
#: a withheld softer cable: its E·A as a fraction of nominal
SOFTER = 0.6
#: a withheld creep: ratio and time constant (s)
CREEP = (0.5, 5.0)
#: a withheld worn winch: its static friction as a multiple of nominal
WORN = 1.5


@checked
def twin_run(effect: str | None, cable: int, *, seed: Seed = 0) -> TwinRun:
    """One plant run along test 2's lines (30 s) with ``effect`` withheld at ``cable``: currents
    with 3 mA noise, sensors with 0.1 N noise and any sensor effect, poses through the tracker's
    noise; the nominal geometry is the Mini CDPR's with the twin's platform-side friction."""
    import tomllib
    from importlib import resources

    from cablekit.cdpr.compensate import TWIN_FRICTION, second_test_trajectory
    from cablekit.cdpr.force import excitation, mini_plant, plant_robot

    rng = np.random.default_rng(seed)
    poses = second_test_trajectory(dt=1e-3).poses[:30_000]
    nominal = mini_plant(home=poses[0])
    robot, drum_side, creep, drum = plant_robot(), None, None, None
    if effect == "pulley_friction":
        mu, visc = np.zeros(8), np.zeros(8)
        mu[cable], visc[cable] = 0.06, 3.0
        drum_side = PulleyFriction(mu, visc, np.full(8, np.pi), law="dahl", presliding=2e-3)
    elif effect == "cable_elasticity":
        text = (resources.files("cablekit.cdpr") / "robots" / "seed002_mini.toml").read_text(encoding="utf-8")
        doc = tomllib.loads(text)
        doc["cables"][cable]["youngs_modulus"] = SOFTER * float(doc["cable"]["youngs_modulus"])
        robot = Robot.from_dict(doc, "seed002_mini (softer cable)")
    elif effect == "drum_friction":
        drum = np.ones(8)
        drum[cable] = WORN
    elif effect == "cable_creep":
        ratio = np.zeros(8)
        ratio[cable] = CREEP[0]
        creep = (ratio, np.full(8, CREEP[1]))
    elif effect not in (None, "sensor_lag", "sensor_gain"):
        raise ParameterError(f"the twin cannot withhold {effect!r}")
    plant = mini_plant(robot, home=poses[0], drum_side=drum_side, creep=creep, drum_friction=drum)
    run = plant.closed_loop(poses, 1e-3, tension_offset=excitation(plant_robot(), poses, rng))
    t = np.arange(poses.shape[0]) * 1e-3
    sensor = run.sensor.copy()
    if effect == "sensor_lag":
        sensor[:, cable] = SignalChain.hx711_ble().apply(t, np.ascontiguousarray(sensor[:, cable]))
    elif effect == "sensor_gain":
        sensor[:, cable] = 1.04 * sensor[:, cable] + 0.4
    sensor += rng.normal(0.0, float(TWIN_FRICTION["noise"]), sensor.shape)
    current = run.current + rng.normal(0.0, 0.003, run.current.shape)
    measured = run.pose + rng.normal(0.0, np.repeat(TRACKER_NOISE, 3), run.pose.shape)
    lengths = Lengths(plant_robot(), nominal.rest_length, measured, TWIN_FRICTION)
    return TwinRun(plant.winch, t, run.alpha, current, sensor, lengths)


#: the effects the self-test withholds
WITHHELD = (
    "pulley_friction",
    "sensor_lag",
    "sensor_gain",
    "drum_friction",
    "cable_elasticity",
    "cable_creep",
)


@checked
def self_test(*, cases: Stride = 2, seed: Seed = 0, progress: bool = False) -> list[SelfTestCase]:
    """``cases`` runs per withheld effect (:data:`WITHHELD`) at drawn cables, and ``cases`` runs
    with none."""
    rng = np.random.default_rng(seed)
    plan: list[tuple[str | None, int]] = [(e, int(rng.integers(8))) for e in WITHHELD for _ in range(cases)]
    plan += [(None, 0)] * cases
    out = []
    for k, (effect, cable) in enumerate(plan):
        d = twin_run(effect, cable, seed=seed + k).diagnose()
        out.append(SelfTestCase(effect, None if effect is None else cable, d))
        if progress:
            _log.info(
                f"withheld {effect or 'nothing'}{'' if effect is None else f' at cable {cable + 1}'}: "
                f"{d.summary()}"
            )
    return out


@checked
def markdown(cases: list[SelfTestCase]) -> str:
    """The self-test table and its totals."""
    lines = [
        "| withheld | force channel | length channel | effect | cable |",
        "|---|---|---|---|---|",
    ]

    def cell(ch: Channel | None) -> str:
        if ch is None:
            return "—"
        f = ch.found
        if f is None:
            return f"nothing ({ch.status})"
        return f"{f.effect} at cable {f.cable + 1} ({100 * f.closed:.0f} %)"

    for c in cases:
        what = "nothing" if c.effect is None else f"{c.effect} at cable {c.cable + 1}"
        d = c.diagnosis
        lines.append(
            f"| {what} | {cell(d.force)} | {cell(d.length)} | {'yes' if c.correct_effect else 'NO'} | "
            f"{'yes' if c.correct_site else 'NO'} |"
        )
    withheld = [c for c in cases if c.effect is not None]
    none = [c for c in cases if c.effect is None]
    lines += [
        "",
        "(In brackets: the share of the channel's held-out gap, its residual energy above the noise, "
        "that the finding removes.)",
        "",
        f"Effect right in {sum(c.correct_effect for c in withheld)}/{len(withheld)}, cable right in "
        f"{sum(c.correct_site for c in withheld)}/{len(withheld)}, false alarms "
        f"{sum(not c.correct_effect for c in none)}/{len(none)}.",
    ]
    return "\n".join(lines)
