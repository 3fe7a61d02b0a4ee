"""Jaw torque of a real instrument from drive-side signals (issue #22 §3), on the da Vinci
Maryland bench of O'Neill et al. (RA-L 2018; ODbL 1.0 / DbCL 1.0, read from where the user
keeps it, never copied) or any folder in its format.

* :func:`read_bench_file` — one run: ``%`` header lines skipped, units from the bench's README,
  a malformed file, a short row or a non-numeric cell a ``DataError`` naming the line (and
  column); rows whose time does not increase are dropped with a note.
* Estimators, each fitted on training runs and scored on others: the **physics** model
  (``cablekit.DriveModel``, Rust: transmission with Maxwell-slip friction driven by the motor
  angle, inverted per sample); the **JTDO** idea (the drive torque a low-load model learned
  from the lightest training runs predicts, the disturbance scaled to the jaw by a fitted
  transmission ratio); and plain learned baselines (a linear map, and a 4-10-1 network of the
  same signals with the ``train`` extra).
* Protocols: leave one frequency out, leave one load out, and the **new-instrument** protocol:
  train on every run of one instrument, recalibrate on one run of the new one (its ``00``: 0.1
  Hz, 10 % load), score on the new instrument's other runs — ``cablekit forceps davinci DIR
  --calibrate-on NEW/00.TXT.gz --test NEW``.

RMSE in mN·m after a 1 s warm-up per run; the jaw angle's RMSE in degrees (physics model).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cablekit._args import checked
from cablekit._cablekit import DriveModel
from cablekit._files import bench_runs, text_runs
from cablekit.errors import DataError
from cablekit.forceps.bench import FREQS, LOADS, condition, read_raw

F64 = NDArray[np.float64]

#: Maxwell-slip element travels of the physics model (degrees of motor angle)
TRAVELS_DEG = (0.1, 0.5, 2.0, 8.0, 32.0)
#: ... and of the elements driven by the spindle angle (degrees of spindle angle): the same
#: travels, chosen by the all-pairs calibration cross-validation (docs/forceps.md)
SPINDLE_TRAVELS_DEG = TRAVELS_DEG
WARMUP_S = 1.0
VELOCITY_WINDOW = 20
#: the published figure on this bench (O'Neill et al. 2018), mN·m
PUBLISHED_RMSE = 4.42
#: warn when more than this share of a run's samples leaves the training ranges
OUTSIDE_WARN = 0.05


@dataclass(frozen=True)
class BenchRun:
    """One bench run in SI units: ``signals`` ``(T, 5)`` = spindle angle (rad), spindle torque
    (N·m), motor angle at the spindle's scale and sign (rad), jaw torque (N·m), jaw angle (rad);
    the motor current (A); the condition from a name ``FL`` (frequency, load index) if any."""

    name: str
    path: Path
    dt: float
    signals: F64
    motor_current: F64
    frequency: int | None
    load: int | None
    notes: tuple[str, ...] = ()

    @property
    def jaw_torque(self) -> F64:
        return self.signals[:, 3]

    @property
    def jaw_angle(self) -> F64:
        return self.signals[:, 4]

    @checked
    def label(self) -> str:
        if self.frequency is None or self.load is None:
            return self.name
        return f"{self.name} ({FREQS[self.frequency]} Hz, {LOADS[self.load]} %)"


@checked
def read_bench_file(path: str | Path) -> BenchRun:
    """One run of the bench format (:func:`cablekit.forceps.bench.read_raw`, with the motor
    encoder's ninth column)."""
    raw = read_raw(path, columns=9)
    dt = float(np.median(np.diff(raw.t)))
    spindle, motor = raw.spindle_angle, raw.motor_angle
    # the motor turns the spindle through a coupling: take its sign from the data
    sign = 1.0 if float(np.dot(np.diff(spindle), np.diff(motor))) >= 0 else -1.0
    signals = np.column_stack([spindle, raw.spindle_torque, sign * motor, raw.jaw_torque, raw.jaw_angle])
    freq, load = condition(raw.name) if len(raw.name) == 2 else (None, None)
    signals = np.ascontiguousarray(signals)
    return BenchRun(raw.name, raw.path, dt, signals, raw.motor_current, freq, load, raw.notes)


@checked
def bench_folder(directory: str | Path) -> Path:
    """The folder holding the runs: ``directory`` or its ``tool4_load_sweep``."""
    p = Path(directory)
    sub = p / "tool4_load_sweep"
    p = sub if sub.is_dir() else p
    if not p.is_dir():
        raise DataError(f"{directory}: not a folder of bench runs")
    return p


@checked
def read_bench_folder(directory: str | Path, names: Sequence[str] | None = None) -> list[BenchRun]:
    """The runs of a folder (``XY.TXT`` / ``XY.TXT.gz``, :func:`cablekit._files.bench_runs`), all
    or the stems ``names`` (any stem)."""
    folder = bench_folder(directory)
    files = bench_runs(folder) if names is None else text_runs(folder)
    if not files:
        raise DataError(
            f"{folder}: no bench runs (files named by their condition digits, XY.TXT or XY.TXT.gz)"
        )
    if names is not None:
        missing = [n for n in names if n not in files]
        if missing:
            raise DataError(f"{folder}: no run(s) {missing}; present: {sorted(files)}")
        files = {n: files[n] for n in names}
    return [read_bench_file(p) for p in files.values()]


def _skip(run: BenchRun) -> int:
    return math.ceil(WARMUP_S / run.dt)


def _velocity(run: BenchRun) -> F64:
    """Causal spindle velocity over ``VELOCITY_WINDOW`` samples (as the Rust model computes it)."""
    th = run.signals[:, 0]
    w = np.zeros_like(th)
    k = np.arange(th.size)
    span = np.minimum(k, VELOCITY_WINDOW)
    past = th[k - span]
    w[1:] = (th[1:] - past[1:]) / (span[1:] * run.dt)
    return w


class Estimator:
    """Fitted on training runs, then ``predict`` (jaw torque N·m, jaw angle rad or None, share
    of samples outside the training ranges) and ``recalibrated`` on one run of a new instrument."""

    name = ""

    @checked
    def predict(self, run: BenchRun) -> tuple[F64, F64 | None, float]:
        raise NotImplementedError

    @checked
    def recalibrated(self, run: BenchRun) -> Estimator:
        """The default: remove the mean torque error on the calibration run (an offset)."""
        return self.recalibrated_on([run])

    @checked
    def recalibrated_on(self, runs: Sequence[BenchRun]) -> Estimator:
        """:meth:`recalibrated` on several runs of the new instrument, their samples pooled."""
        err = [r.jaw_torque[_skip(r) :] - self.predict(r)[0][_skip(r) :] for r in runs]
        return _Shifted(self, float(np.mean(np.concatenate(err))))


@dataclass
class _Shifted(Estimator):
    base: Estimator
    shift: float

    def __post_init__(self) -> None:
        self.name = self.base.name

    def predict(self, run: BenchRun) -> tuple[F64, F64 | None, float]:
        torque, angle, outside = self.base.predict(run)
        return torque + self.shift, angle, outside


@dataclass
class Physics(Estimator):
    """The drive model (``cablekit.DriveModel``)."""

    model: DriveModel
    friction: bool = False
    name: str = "physics (drive model, Rust)"

    @classmethod
    @checked
    def fit(
        cls,
        runs: Sequence[BenchRun],
        friction: bool = False,
        weights: Sequence[F64 | float] | None = None,
        span: tuple[float, float] | None = None,
        spindle: bool = True,
    ) -> Physics:
        """Fitted on ``runs``; ``weights``: per run a weight or an array of sample weights (≥ 0;
        0 leaves a sample out of the fit); ``span``: the spindle angles (rad) the friction's angle
        dependence is held in (by default the fitted samples' range; a new instrument's
        calibration recording's range when it is fitted beside the training runs); ``spindle``:
        with the friction elements driven by the spindle angle (the default; samples that move
        the spindle one way only cannot identify them)."""
        dts = {round(r.dt, 9) for r in runs}
        if len(dts) != 1:
            raise DataError(f"training runs have different sample periods {sorted(dts)}")
        per_sample = None
        if weights is not None:
            if len(weights) != len(runs):
                raise DataError(f"{len(weights)} weights for {len(runs)} runs")
            per_sample = [
                np.full(len(r.jaw_torque), float(w)) if np.ndim(w) == 0 else np.asarray(w, dtype=np.float64)
                for r, w in zip(runs, weights, strict=True)
            ]
        model = DriveModel.fit(
            [r.signals for r in runs],
            [math.radians(d) for d in TRAVELS_DEG],
            dt=runs[0].dt,
            window=VELOCITY_WINDOW,
            warmup=WARMUP_S,
            weights=per_sample,
            angle_friction=span,
            spindle_travels=[math.radians(d) for d in SPINDLE_TRAVELS_DEG] if spindle else [],
        )
        return cls(model, friction)

    @checked
    def predict(self, run: BenchRun) -> tuple[F64, F64 | None, float]:
        e = self.model.estimate(run.signals[:, :3].copy(), dt=run.dt)
        return e.torque, e.angle, e.outside_share

    @checked
    def recalibrated_on(self, runs: Sequence[BenchRun]) -> Estimator:
        dts = {round(r.dt, 9) for r in runs}
        if len(dts) != 1:
            raise DataError(f"calibration runs need one sample period, got {sorted(dts)}")
        dt = runs[0].dt
        model = self.model.recalibrated([r.signals for r in runs], dt=dt, friction=self.friction)
        return Physics(model, self.friction)


def _outside(x: F64, lo: F64, hi: F64) -> float:
    """Share of rows of ``x`` with a value outside the training range ``[lo, hi]``."""
    return float(((x < lo - 1e-12) | (x > hi + 1e-12)).any(axis=1).mean())


def _drive_features(run: BenchRun) -> F64:
    s = run.signals
    return np.column_stack([np.ones(len(s)), s[:, 0], _velocity(run), s[:, 1], run.motor_current])


@dataclass
class Linear(Estimator):
    """The best linear map of the drive-side signals (spindle angle, velocity, torque, motor
    current) to the jaw torque, fitted by least squares."""

    coef: F64
    lo: F64
    hi: F64
    name: str = "linear map of drive-side signals"

    @classmethod
    @checked
    def fit(cls, runs: Sequence[BenchRun]) -> Linear:
        x = np.vstack([_drive_features(r)[_skip(r) :] for r in runs])
        y = np.concatenate([r.jaw_torque[_skip(r) :] for r in runs])
        return cls(np.linalg.lstsq(x, y, rcond=None)[0], x.min(axis=0), x.max(axis=0))

    @checked
    def predict(self, run: BenchRun) -> tuple[F64, F64 | None, float]:
        x = _drive_features(run)
        return x @ self.coef, None, _outside(x, self.lo, self.hi)


@dataclass
class Network(Estimator):
    """A 4-10-1 network (LM, ``cablekit.nn``) of the same signals as :class:`Linear`, inference
    in Rust; the plain learned baseline the issue's first measurement used."""

    mlp: object
    lo: F64
    hi: F64
    name: str = "network 4-10-1 of drive-side signals"

    @classmethod
    @checked
    def fit(cls, runs: Sequence[BenchRun], every: int = 20, seed: int = 0) -> Network:
        x = np.vstack([_drive_features(r)[_skip(r) :: every, 1:] for r in runs])
        y = np.concatenate([r.jaw_torque[_skip(r) :: every] for r in runs])[:, None] * 1e3
        return cls(_train(x, y, seed), x.min(axis=0), x.max(axis=0))

    @checked
    def predict(self, run: BenchRun) -> tuple[F64, F64 | None, float]:
        x = np.ascontiguousarray(_drive_features(run)[:, 1:])
        return self.mlp.predict(x)[:, 0] * 1e-3, None, _outside(x, self.lo, self.hi)  # type: ignore[attr-defined]


def _train(x: F64, y: F64, seed: int) -> object:
    from cablekit.nn import to_mlp, train_mlp

    return to_mlp(train_mlp(x, y, method="lm", seed=seed, progress=False))


@dataclass
class Jtdo(Estimator):
    """Seed 000's idea on the real instrument: a low-load model learned from the lightest
    training runs predicts the drive torque the motion needs (``[θ_s, ω_s]`` → ``τ_s``, a
    4-10-1 network as the seed's free-motion model, here 2-10-1); the disturbance
    ``τ_s − τ̂_s`` times a transmission ratio fitted on all training runs, plus the low-load
    runs' mean jaw torque, is the jaw torque."""

    mlp: object
    ratio: float
    base: float
    lo: F64
    hi: F64
    name: str = "JTDO with a learned low-load model"

    @classmethod
    @checked
    def fit(cls, runs: Sequence[BenchRun], every: int = 20, seed: int = 0) -> Jtdo:
        light = min(r.load if r.load is not None else 0 for r in runs)
        low = [r for r in runs if (r.load if r.load is not None else 0) == light]

        def kin(r: BenchRun) -> F64:
            return np.column_stack([r.signals[:, 0], _velocity(r)])

        x = np.vstack([kin(r)[_skip(r) :: every] for r in low])
        y = np.concatenate([r.signals[_skip(r) :: every, 1] for r in low])[:, None] * 1e3
        mlp = _train(x, y, seed)
        base = float(np.mean(np.concatenate([r.jaw_torque[_skip(r) :] for r in low])))
        dist = np.concatenate(
            [r.signals[_skip(r) :, 1] - mlp.predict(kin(r))[_skip(r) :, 0] * 1e-3 for r in runs]  # type: ignore[attr-defined]
        )
        target = np.concatenate([r.jaw_torque[_skip(r) :] for r in runs]) - base
        ratio = float(np.dot(dist, target) / np.dot(dist, dist))
        xs = np.vstack([kin(r) for r in runs])
        return cls(mlp, ratio, base, xs.min(axis=0), xs.max(axis=0))

    @checked
    def predict(self, run: BenchRun) -> tuple[F64, F64 | None, float]:
        x = np.column_stack([run.signals[:, 0], _velocity(run)])
        free = self.mlp.predict(np.ascontiguousarray(x))[:, 0] * 1e-3  # type: ignore[attr-defined]
        return self.base + self.ratio * (run.signals[:, 1] - free), None, _outside(x, self.lo, self.hi)


#: estimator name → fit(runs); the networks need torch (the ``train`` extra)
@checked
def estimator_fitters(
    networks: bool = True, friction: bool = False
) -> dict[str, Callable[[Sequence[BenchRun]], Estimator]]:
    """``friction``: the physics model's recalibration also rescales its friction."""
    fitters: dict[str, Callable[[Sequence[BenchRun]], Estimator]] = {
        Physics.name: lambda runs: Physics.fit(runs, friction=friction),
        Linear.name: Linear.fit,
    }
    if networks:
        fitters[Jtdo.name] = Jtdo.fit
        fitters[Network.name] = Network.fit
    return fitters


@dataclass(frozen=True)
class Score:
    """One estimator on one group of test runs: torque RMSE (mN·m), jaw-angle RMSE (degrees,
    physics only), the worst run's torque RMSE, and the largest share outside the training
    ranges."""

    rmse_mnm: float
    angle_rmse_deg: float | None
    worst_run_mnm: float
    outside_share: float


@checked
def score(est: Estimator, runs: Sequence[BenchRun], angle_offset: bool = True) -> Score:
    """Pooled over ``runs`` after each run's warm-up. The jaw encoder is not zeroed between runs
    by the bench, so with ``angle_offset`` each run's angle error is taken about its mean (the
    angle's shape and scale are scored, not the encoder's zero)."""
    sq, n, worst, outside = 0.0, 0, 0.0, 0.0
    asq, an = 0.0, 0
    for r in runs:
        torque, angle, out = est.predict(r)
        k = _skip(r)
        e = (torque[k:] - r.jaw_torque[k:]) * 1e3
        sq += float(e @ e)
        n += e.size
        worst = max(worst, float(np.sqrt(np.mean(e**2))))
        outside = max(outside, out)
        if angle is not None:
            ea = np.degrees(angle[k:] - r.jaw_angle[k:])
            if angle_offset:
                ea = ea - ea.mean()
            asq += float(ea @ ea)
            an += ea.size
    return Score(math.sqrt(sq / n), math.sqrt(asq / an) if an else None, worst, outside)


@dataclass
class FoldResult:
    """A protocol's folds: per fold and estimator the score on the held-out runs."""

    protocol: str
    folds: dict[str, dict[str, Score]] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    #: per estimator, the calibration's check (new-instrument protocol only)
    checks: dict[str, Any] = field(default_factory=dict)


def _folds(runs: Sequence[BenchRun], key: str) -> dict[str, list[BenchRun]]:
    groups: dict[str, list[BenchRun]] = {}
    for r in runs:
        v = getattr(r, key)
        if v is None:
            continue
        label = f"{FREQS[v]} Hz" if key == "frequency" else f"{LOADS[v]} % load"
        groups.setdefault(label, []).append(r)
    return dict(sorted(groups.items()))


@checked
def leave_one_out(
    runs: Sequence[BenchRun],
    key: str,
    fitters: dict[str, Callable[[Sequence[BenchRun]], Estimator]],
    advance: Callable[[str], None] = lambda _: None,
) -> FoldResult:
    """Leave one frequency (``key="frequency"``) or load (``"load"``) out: train on the rest."""
    res = FoldResult(f"leave one {key} out")
    groups = _folds(runs, key)
    if len(groups) < 2:
        raise DataError(f"leave one {key} out needs runs named FL of at least two {key}s")
    for label, test in groups.items():
        train = [r for r in runs if r not in test]
        res.folds[label] = {}
        for name, fit in fitters.items():
            s = score(fit(train), test)
            res.folds[label][name] = s
            if s.outside_share > OUTSIDE_WARN:
                share = 100 * s.outside_share
                res.warnings.append(f"{label}, {name}: {share:.0f} % of a run outside the training range")
        advance(label)
    return res


@checked
def new_instrument(
    train: Sequence[BenchRun],
    calibration: BenchRun | Sequence[BenchRun],
    test: Sequence[BenchRun],
    fitters: dict[str, Callable[[Sequence[BenchRun]], Estimator]],
    method: str | None = None,
    share: float | None = None,
) -> FoldResult:
    """Train on ``train`` (one instrument), calibrate on ``calibration`` (one or more runs of
    the new instrument, :func:`cablekit.forceps.calibrate.calibrate` with ``method`` and
    ``share``, by default the cross-validated ones), score on ``test`` (its other runs). Every
    estimator's calibration check goes into ``checks``; a flagged one and new runs outside the
    training ranges are warnings."""
    from cablekit.forceps.calibrate import DEFAULT_METHOD, DEFAULT_SHARE, calibrate

    cal = [calibration] if isinstance(calibration, BenchRun) else list(calibration)
    res = FoldResult("new instrument")
    scores = {}
    for name, fit in fitters.items():
        c = calibrate(fit, train, cal, method or DEFAULT_METHOD, DEFAULT_SHARE if share is None else share)
        res.checks[name] = c.check
        if not c.check.ok:
            msg = f"{name}: {c.check.message()}"
            res.warnings.append(msg)
            warnings.warn(msg, stacklevel=2)
        s = score(c.estimator, test)
        scores[name] = s
        if s.outside_share > OUTSIDE_WARN:
            angles = (
                " or the spindle angles its calibration recording covered" if name == Physics.name else ""
            )
            msg = (
                f"{name}: up to {100 * s.outside_share:.0f} % of a test run's samples lie outside the "
                f"training ranges (spindle angle, torque or velocity){angles}: the estimate extrapolates "
                "there (record the load step where the runs go: a heavier load, another jaw stop)"
            )
            res.warnings.append(msg)
            warnings.warn(msg, stacklevel=2)
    names = " + ".join(r.name for r in cal)
    res.folds[f"calibrated on {names} ({method or DEFAULT_METHOD}), scored on {len(test)} runs"] = scores
    return res
