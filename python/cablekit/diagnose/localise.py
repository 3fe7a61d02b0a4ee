"""Where the gap lies: residual energy by operating condition, whiteness and input
cross-correlation tests, and hysteresis loops.

All functions take residuals in **noise units** (residual / noise standard deviation of its
channel), so channels of different units add up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "Condition",
    "conditions_table",
    "cross_correlation",
    "loop_area",
    "mains_interference",
    "measurement_sigma",
    "noise_sigma",
    "smooth_velocity",
    "turning_points",
    "whiteness",
]

_F = NDArray[np.float64]


def noise_sigma(y: _F) -> float:
    """Measurement-noise standard deviation of a sampled signal from its differences of order
    ``k = 2…5``: for white noise ``Var(Δᵏy) = C(2k, k)·σ²``, each estimated robustly (median
    absolute deviation, so rare jumps do not count). A smooth signal leaks into ``Δᵏ`` as
    ``(ω·dt)ᵏ``, so the smallest of the four estimates is the one the signal spoils least —
    this matters for encoders whose range is 10⁶ times their noise (a geared motor turning tens of
    radians). A held or quantised signal whose differences are mostly zero falls back to their
    root mean square; the floor (1e-10 of the spread) keeps a noise-free signal from an infinite
    weight."""
    spread = float(np.std(y))
    estimates = []
    for k in range(2, 6):
        dk = np.diff(y, k)
        if dk.size == 0:
            continue
        mad = float(np.median(np.abs(dk - np.median(dk))))
        s = 1.4826 * mad / math.sqrt(math.comb(2 * k, k))
        if s <= 1e-12 * spread:
            s = float(np.sqrt(np.mean(dk * dk) / math.comb(2 * k, k)))
        estimates.append(s)
    sigma = min(estimates) if estimates else 0.0
    # a quantised signal (an encoder's counts, an ADC's codes) is off its true value by up to
    # half a step however smoothly it moves, a rounding error of rms q/√12 that the differences
    # of a slowly moving signal do not see (they are mostly zero)
    sigma = max(sigma, quantum(y) / math.sqrt(12.0))
    return max(sigma, 1e-10 * spread, 1e-12)


#: mains frequencies (Hz) whose harmonics are searched for interference lines
MAINS_HZ = (50.0, 60.0)
#: Rayleigh statistic above which a line counts as present (chance ~e^-25 per frequency)
LINE_Z = 25.0


def mains_interference(y: _F, dt: float, block_s: float = 1.0) -> list[tuple[float, float]]:
    """Stationary mains-interference lines in a measured signal: ``[(frequency, rms), ...]`` for
    each harmonic ``k·50`` or ``k·60`` Hz below 0.45 of the sample rate (``k ≤ 10``) that holds a
    tone of constant amplitude and phase through the run.

    A load cell's or an amplifier's pick-up of the supply is measurement error, not a model gap,
    but the difference-based :func:`noise_sigma` barely sees it (a 50 Hz tone at 1 kHz is 10 % of
    its power in a second difference). Each frequency is demodulated on blocks of ``block_s``
    with a cubic removed and a Blackman–Harris window (both keep the slow motion out, whose
    amplitude is 10⁴ times the noise); a tone keeps one phasor from block to
    block, noise and anything the motion modulates (a sample-and-hold staircase, stick–slip
    ringing) do not. The Rayleigh statistic ``Z = n·|mean c|² / mean |c − mean c|²`` must exceed
    :data:`LINE_Z`; the line's rms is ``|mean c|/√2``."""
    n_block = round(block_s / dt)
    n = len(y) // n_block if n_block >= 8 else 0
    if n < 4:
        return []
    # 4-term Blackman–Harris window (side lobes −92 dB) after a cubic fit per block is removed:
    # a joint's motion is 10⁴ times the noise, and a Hann window's leakage of it is not
    k = 2.0 * np.pi * np.arange(n_block) / (n_block - 1)
    w = 0.35875 - 0.48829 * np.cos(k) + 0.14128 * np.cos(2 * k) - 0.01168 * np.cos(3 * k)
    w = w / w.sum()
    s = np.linspace(-1.0, 1.0, n_block)
    vander = np.vander(s, 4)
    t = np.arange(n * n_block) * dt
    blocks = y[: n * n_block].reshape(n, n_block)
    blocks = blocks - blocks @ (vander @ np.linalg.pinv(vander)).T
    tb = t.reshape(n, n_block)

    def line(f: float) -> float | None:
        c = 2.0 * np.sum(blocks * w * np.exp(-2j * np.pi * f * tb), axis=1)
        mean = c.mean()
        spread = float(np.mean(np.abs(c - mean) ** 2))
        z = n * abs(mean) ** 2 / spread if spread > 0 else math.inf
        return abs(mean) / math.sqrt(2.0) if z > LINE_Z else None

    found: dict[float, float] = {}
    for base in MAINS_HZ:
        # the supply has no sub-harmonics: a coherent line at base/m ≥ 10 Hz (a 10 Hz
        # sample-and-hold on a steady ramp, a periodic process of its own) owns the harmonics
        if any(line(base / m) is not None for m in range(2, 11) if base / m >= 10.0):
            continue
        for k in range(1, 11):
            f = k * base
            if f >= 0.45 / dt or f in found:
                continue
            a = line(f)
            if a is not None:
                found[f] = a
    return sorted(found.items())


def measurement_sigma(y: _F, dt: float) -> tuple[float, list[tuple[float, float]]]:
    """Measurement error of a sampled signal: white noise (:func:`noise_sigma`) and stationary
    mains lines (:func:`mains_interference`) added in power; also returns the lines."""
    lines = mains_interference(y, dt)
    s = noise_sigma(y)
    return math.sqrt(s * s + sum(a * a for _, a in lines)), lines


def quantum(y: _F) -> float:
    """The step ``q`` of the lattice a quantised signal lives on (its smallest non-zero
    sample-to-sample change, when 99 % of the changes are whole multiples of it within 1 %),
    else 0."""
    spread = float(np.ptp(y)) if y.size else 0.0
    d = np.abs(np.diff(y))
    nz = d[d > 1e-9 * spread]
    if nz.size < 20 or spread == 0.0:
        return 0.0
    q = float(np.min(nz))
    ratio = nz / q
    if np.max(ratio) > 1e6:  # finer than any converter: a continuous signal
        return 0.0
    on_lattice = np.abs(ratio - np.round(ratio)) < 0.01
    return q if float(np.mean(on_lattice)) >= 0.99 else 0.0


@dataclass
class Condition:
    """One operating condition: which samples, and how much of the residual energy they hold."""

    family: str
    name: str
    time_share: float
    energy_share: float

    @property
    def concentration(self) -> float:
        """Energy share / time share: > 1 means the gap concentrates here."""
        return self.energy_share / self.time_share if self.time_share > 0 else 0.0

    def to_dict(self) -> dict[str, Any]:
        return {
            "family": self.family,
            "condition": self.name,
            "time_share": self.time_share,
            "energy_share": self.energy_share,
            "concentration": self.concentration,
        }


def _terciles(v: _F, names: tuple[str, str, str]) -> list[tuple[str, NDArray[np.bool_]]]:
    lo, hi = np.quantile(v, [1 / 3, 2 / 3])
    return [(names[0], v <= lo), (names[1], (v > lo) & (v <= hi)), (names[2], v > hi)]


def smooth_velocity(x: _F, dt: float) -> _F:
    """Velocity of a sampled, possibly quantised or noisy position: a central difference over
    ``±w`` samples, ``w`` the smallest power of two over which the signal typically moves ten
    times its resolution (its lattice step or noise), at most 1/20 of the record. A plain
    ``np.gradient`` of a slow 4000-count encoder is zero between counts and one count per sample
    at each step, which makes speed terciles meaningless."""
    n = len(x)
    if n < 3:
        return np.zeros(n)
    res = max(quantum(x), noise_sigma(x))
    w = 1
    while 2 * w < n // 20 and float(np.median(np.abs(x[2 * w :] - x[: -2 * w]))) < 10.0 * res:
        w *= 2
    xp = np.concatenate([np.full(w, x[0]), x, np.full(w, x[-1])])
    v = (xp[2 * w :] - xp[: -2 * w]) / (2 * w * dt)
    # the padded edges see half the displacement over the full window: one-sided there
    v[:w] = (x[w : 2 * w] - x[:w]) / (w * dt) if n >= 2 * w else v[:w]
    v[n - w :] = (x[n - w :] - x[n - 2 * w : n - w]) / (w * dt) if n >= 2 * w else v[n - w :]
    return v


def turning_points(x: _F, band: float) -> NDArray[np.intp]:
    """Indices where ``x`` reverses: the running extremum once the signal has retreated from it
    by more than ``band`` (a hysteresis band, so encoder counts flickering at a standstill or
    noise on a plateau are not reversals, and a velocity passing through exact zero between two
    counts is not needed). An extremum next to either end of the record, which the signal cannot
    leave by the whole band before the record stops, counts when it is left by half the band."""
    out: list[int] = []
    if len(x) < 2 or not band > 0.0:
        return np.zeros(0, dtype=np.intp)
    direction = 0  # +1 rising, −1 falling, 0 unknown
    i_ext = j_ext = 0  # first and last sample at the running extremum (a quantised plateau)
    lo_i = hi_i = 0
    for i in range(1, len(x)):
        xi = x[i]
        if direction == 0:
            if xi > x[hi_i]:
                hi_i = i
            if xi < x[lo_i]:
                lo_i = i
            if x[hi_i] - x[lo_i] > band:
                direction = 1 if hi_i > lo_i else -1
                i_ext = j_ext = hi_i if direction > 0 else lo_i
                # the earlier extremum is a turning point too when the record approached it by
                # more than half the band (a reversal close to the start, not the start itself)
                e = lo_i if direction > 0 else hi_i
                if e > 0 and abs(x[e] - (np.max(x[:e]) if direction > 0 else np.min(x[:e]))) > 0.5 * band:
                    at = np.flatnonzero(x[: i + 1] == x[e])
                    out.append(int(at[0] + at[-1]) // 2)
            continue
        d = direction * (xi - x[i_ext])
        if d > 0.0:
            i_ext = j_ext = i
        elif d == 0.0:
            j_ext = i
        elif -d > band:
            out.append((i_ext + j_ext) // 2)
            direction, i_ext, j_ext = -direction, i, i
    # likewise the last extremum, when the record leaves it by more than half the band
    if direction != 0 and j_ext < len(x) - 1 and direction * (x[i_ext] - x[-1]) > 0.5 * band:
        out.append((i_ext + j_ext) // 2)
    return np.asarray([_centre(x, p, band) for p in out], dtype=np.intp)


def _centre(x: _F, p: int, band: float) -> int:
    """The middle of the stretch around the extremum ``p`` that stays within half the band of it
    (a flickering or noisy plateau has no single extreme sample); ``p`` itself when the record
    ends inside that stretch."""
    far = np.abs(x - x[p]) > 0.5 * band
    left = np.flatnonzero(far[:p])
    right = np.flatnonzero(far[p + 1 :])
    if left.size == 0 or right.size == 0:
        return p
    return int(left[-1] + p + 1 + right[0]) // 2


def reversal_band(x: _F) -> float:
    """Hysteresis band of :func:`turning_points` for a measured position: four resolution steps
    (lattice step or noise), at least 1 % of its range."""
    return max(4.0 * max(quantum(x), noise_sigma(x)), 0.01 * float(np.ptp(x)) if len(x) else 0.0)


def condition_masks(
    t: _F, x: _F, dt: float, load: _F, contact: _F | None = None
) -> list[tuple[str, str, NDArray[np.bool_]]]:
    """Masks of the operating conditions of one run: reversals, speed, acceleration, load,
    position, time (drift) and, when given, contact. Velocity and acceleration come from
    :func:`smooth_velocity` and reversals from :func:`turning_points`, so a quantised encoder
    is localised as well as a clean signal."""
    v = smooth_velocity(x, dt)
    a = smooth_velocity(v, dt)
    out: list[tuple[str, str, NDArray[np.bool_]]] = []
    # reversals: within 5 % of the median half-cycle (at least 5 samples) of a turning point
    flips = turning_points(x, reversal_band(x))
    near = np.zeros(len(t), dtype=bool)
    if flips.size >= 2:
        half = float(np.median(np.diff(flips)))
        w = max(5, int(0.05 * half))
        for f in flips:
            near[max(0, f - w) : f + w + 1] = True
    out += [("direction", "near reversal", near), ("direction", "steady motion", ~near)]
    out += [("speed", n, m) for n, m in _terciles(np.abs(v), ("low speed", "mid speed", "high speed"))]
    out += [("acceleration", n, m) for n, m in _terciles(np.abs(a), ("low accel", "mid accel", "high accel"))]
    out += [("load", n, m) for n, m in _terciles(load, ("low load", "mid load", "high load"))]
    out += [("position", n, m) for n, m in _terciles(x, ("low position", "mid position", "high position"))]
    out += [("time", n, m) for n, m in _terciles(t, ("early", "middle", "late"))]
    if contact is not None and contact.any() and (~contact).any():
        out += [("contact", "in contact", contact), ("contact", "free", ~contact)]
    return out


def conditions_table(
    residual_energy: list[_F], masks: list[list[tuple[str, str, NDArray[np.bool_]]]]
) -> list[Condition]:
    """Pool runs: per condition, its share of samples and of the residual energy; sorted by
    concentration, highest first."""
    total_e = sum(float(e.sum()) for e in residual_energy)
    total_n = sum(len(e) for e in residual_energy)
    acc: dict[tuple[str, str], list[float]] = {}
    for e, ms in zip(residual_energy, masks, strict=False):
        for fam, name, m in ms:
            s = acc.setdefault((fam, name), [0.0, 0.0])
            s[0] += float(m.sum())
            s[1] += float(e[m].sum())
    rows = [
        Condition(fam, name, n / total_n, (en / total_e) if total_e > 0 else 0.0)
        for (fam, name), (n, en) in acc.items()
    ]
    return sorted(rows, key=lambda c: -c.concentration)


def _acf(r: _F, lags: int) -> _F:
    r = r - r.mean()
    n = len(r)
    spec = np.fft.rfft(r, 2 * n)
    ac = np.fft.irfft(spec * np.conj(spec))[: lags + 1]
    return ac / ac[0] if ac[0] > 0 else np.zeros(lags + 1)


def _band_test(rho: _F, n: int, confidence: float) -> dict[str, Any]:
    """Correlations ``rho`` of ``n`` samples against the white-noise band ``±z/√n``: how many fall
    outside, and whether that is more than the share the confidence level allows (at least 1)."""
    z = {0.95: 1.96, 0.99: 2.576}[confidence]
    band = z / np.sqrt(n)
    outside = int(np.sum(np.abs(rho) > band))
    allowed = max(1, int(np.ceil((1 - confidence) * len(rho) * 2)))
    return {
        "band": band,
        "max_abs": float(np.max(np.abs(rho))),
        "outside": outside,
        "within": outside <= allowed,
    }


def whiteness(r: _F, lags: int = 25, confidence: float = 0.99) -> dict[str, Any]:
    """Autocorrelation of a residual at lags 1..``lags`` against the band ``±z/√N`` of white
    noise (MATLAB ``resid``). ``white`` is False when more than the expected share of lags
    falls outside."""
    rho = _acf(r, lags)[1:]
    t = _band_test(rho, len(r), confidence)
    return {
        "lags": lags,
        **{k: v for k, v in t.items() if k != "within"},
        "white": t["within"],
        "acf": rho.tolist(),
    }


def cross_correlation(r: _F, u: _F, lags: int = 25, confidence: float = 0.99) -> dict[str, Any]:
    """Cross-correlation of residual and input (its increments, which are closer to white)
    at lags −``lags``..``lags``; ``independent`` is False when the residual depends on the input,
    i.e. the model is wrong rather than the noise coloured."""
    du = np.diff(u, prepend=u[0])
    a = (r - r.mean()) / (r.std() + 1e-300)
    b = (du - du.mean()) / (du.std() + 1e-300)
    n = len(a)
    # ρ(k) = Σ_t a[t]·b[t − k] / n, only the lags asked for (a full correlation is O(n²))
    rho = np.array(
        [a[max(k, 0) : n + min(k, 0)] @ b[max(-k, 0) : n - max(k, 0)] / n for k in range(-lags, lags + 1)]
    )
    t = _band_test(rho, n, confidence)
    return {
        "lags": lags,
        **{k: v for k, v in t.items() if k != "within"},
        "independent": t["within"],
        "ccf": rho.tolist(),
    }


def loop_area(r: _F, x: _F) -> float:
    """Normalised hysteresis of a residual–signal loop: ``|∮ r dx|`` over the record divided by
    the number of cycles times the bounding box ``range(r)·range(x)``. About 0 when the residual
    is a single-valued function of ``x``; up to ~1 for a rectangular loop."""
    dx = np.diff(x)
    area = float(np.sum(0.5 * (r[1:] + r[:-1]) * dx))
    flips = np.sum(np.sign(dx[1:]) * np.sign(dx[:-1]) < 0)
    cycles = max(1.0, flips / 2.0)
    box = float(np.ptp(r) * np.ptp(x))
    return abs(area) / cycles / box if box > 0 else 0.0
