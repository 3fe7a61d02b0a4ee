"""A trained jaw-torque estimator carried to a new instrument, session or posture by a short
calibration recording of it, and the calibration's own check (issue #37 §2).

The procedure a user follows (docs/forceps.md, *A new instrument*): record on the new instrument
the **load step** — the slowest motion at the lightest and at the heaviest load it will see (the
bench's runs ``00`` and ``03``) — and, if the bench allows, the same step at the fastest motion
(``40`` and ``43``); at a wrist posture, the load step at the jaw's first and last stopping
positions (``000`` + ``003`` and, e.g., ``400`` + ``403``); then

```bash
cablekit forceps davinci TRAIN_DIR --calibrate-on NEW/00.TXT.gz NEW/03.TXT.gz [NEW/40... NEW/43...] --test NEW
```

**Methods** (:data:`METHODS`), chosen by cross-validation over every pair of transmissions,
sessions and postures in ../shared (each one "a new instrument" for the others; the table is in
docs/forceps.md):

* ``prior`` (the default): the estimator fitted again on the training runs **and** the
  calibration runs, the calibration runs weighted to ``share`` times the training runs' total
  weight — a least-squares fit with the training instrument as its prior. Every coefficient may
  move (offset, transmission ratio, friction, elastic return), as far as the calibration's
  evidence outweighs the prior; the physics estimator's angle-dependent friction is held inside
  the spindle angles the calibration runs cover (the training instrument's angles are in another
  frame);
* ``refit``: the estimator fitted on the calibration runs alone (needs two load levels; no prior);
* ``offset`` and ``offset + friction``: the training coefficients with the offsets (and a common
  friction scale) re-identified — the defaults of earlier versions.

**The check** (:class:`CalibrationCheck`): the calibrated estimate on its own calibration runs
(RMSE, correlation) and, with two or more runs, each calibration run predicted by a calibration on
the others; a calibration whose estimate does not follow its own data, or whose runs do not
predict each other, is flagged with what to record instead, never silently used.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from cablekit._args import checked
from cablekit.errors import DataError, ParameterError
from cablekit.forceps.davinci import BenchRun, Estimator, Physics, _skip, score

__all__ = [
    "DEFAULT_METHOD",
    "DEFAULT_SHARE",
    "METHODS",
    "Calibrated",
    "CalibrationCheck",
    "calibrate",
]

METHODS = ("prior", "refit", "offset", "offset + friction")
#: chosen by cross-validation over the pairs of ../shared (docs/forceps.md)
DEFAULT_METHOD = "prior"
#: the calibration runs' total weight as a multiple of the training runs' (cross-validated)
DEFAULT_SHARE = 256.0
#: the check's limits: the estimate's correlation with the measured jaw torque on its own
#: calibration runs, as a fraction of its correlation on the training runs (and always > 0), and
#: the RMSE (own or cross-predicted) as a multiple of the training instrument's own residual
MIN_CORRELATION = 0.8
MAX_RMSE_FACTOR = 3.0

#: the most times a calibration run is repeated for an estimator without sample weights
MAX_REPEAT = 8

RECORD = (
    "record the load step on the new instrument — the slowest motion at the lightest and at the "
    "heaviest load it will see (the bench's runs 00 and 03) — and, if the bench allows, the same at the "
    "fastest motion (40 and 43); at a wrist posture, the load step at the jaw's first and last "
    "stopping positions (000 + 003 and, e.g., 400 + 403); calibrate on all of them"
)


@dataclass(frozen=True)
class CalibrationCheck:
    """How the calibrated estimator fits the calibration runs themselves (mN·m)."""

    runs: list[str]
    rmse_mnm: float
    correlation: float
    #: each calibration run predicted by a calibration on the others (None with one run)
    cross_rmse_mnm: float | None
    training_rmse_mnm: float
    problems: list[str] = field(default_factory=list)
    #: whether the recording holds what the protocol asks for (two load levels and, for runs
    #: named by jaw stop, two stops): a flag then says the estimator fits this instrument less
    #: well than its training one, not that the recording is short
    complete: bool = False

    @property
    def ok(self) -> bool:
        return not self.problems

    @checked
    def message(self) -> str:
        head = (
            f"calibration on {', '.join(self.runs)}: RMSE {self.rmse_mnm:.2f} mN·m on its own runs "
            f"(correlation {self.correlation:.2f})"
            + (f", {self.cross_rmse_mnm:.2f} mN·m cross-predicted" if self.cross_rmse_mnm is not None else "")
            + f"; the training instrument's own fit {self.training_rmse_mnm:.2f} mN·m"
        )
        if self.ok:
            return head + " — passes"
        flagged = head + " — FLAGGED: " + "; ".join(self.problems)
        if not self.correlation > 0:
            return flagged + (
                ". What to do: check the jaw torque sensor's sign and wiring and the run files (the "
                f"estimate runs against the measured torque); then {RECORD}."
            )
        if self.complete:
            return flagged + (
                ". The recording holds what the protocol asks for: the estimator does not fit this "
                "instrument (or posture) as well as its training one — expect held-out errors near the "
                "cross-predicted figure, not the training fit's"
            )
        return flagged + f". What to do: {RECORD}."


@dataclass(frozen=True)
class Calibrated:
    """An estimator calibrated to a new instrument, how, and its check."""

    estimator: Estimator
    method: str
    share: float
    check: CalibrationCheck


def _fit(est: Estimator, runs: Sequence[BenchRun]) -> tuple[float, float]:
    """Pooled RMSE (mN·m) and correlation of the estimated and the measured jaw torque over
    ``runs`` after the warm-up, from one prediction per run (correlation 0 when either is
    constant)."""
    pred = np.concatenate([est.predict(r)[0][_skip(r) :] for r in runs])
    meas = np.concatenate([r.jaw_torque[_skip(r) :] for r in runs])
    rmse = float(np.sqrt(np.mean((pred - meas) ** 2))) * 1e3
    corr = float(np.corrcoef(pred, meas)[0, 1]) if pred.std() > 0 and meas.std() > 0 else 0.0
    return rmse, corr


def _stops(runs: Sequence[BenchRun]) -> set[str]:
    """The jaw stops of runs named ``ZXY``."""
    return {r.name[0] for r in runs if r.name.isdigit() and len(r.name) == 3}


def _complete(runs: Sequence[BenchRun]) -> bool:
    """Two load levels and, where the runs are named by jaw stop, two stops."""
    stops = _stops(runs)
    return len(_loads(runs)) >= 2 and (not stops or len(stops) >= 2)


def _loads(runs: Sequence[BenchRun]) -> set[str]:
    return {r.name[-1] for r in runs if r.name.isdigit()}


def _weighted(
    fit: Callable[[Sequence[BenchRun]], Estimator],
    base: Estimator,
    train: Sequence[BenchRun],
    cal: Sequence[BenchRun],
    share: float,
) -> Estimator:
    n_train = sum(len(r.jaw_torque) - _skip(r) for r in train)
    n_cal = sum(len(r.jaw_torque) - _skip(r) for r in cal)
    w = share * n_train / max(n_cal, 1)
    if isinstance(base, Physics):
        # the friction's angle dependence held inside the angles the recording covers: the
        # training instrument's angles are another instrument's (or posture's) frame
        angles = np.concatenate([r.signals[_skip(r) :, 0] for r in cal])
        span = (float(angles.min()), float(angles.max())) if np.ptp(angles) > 0 else None
        weights = [1.0] * len(train) + [w] * len(cal)
        return Physics.fit([*train, *cal], base.friction, weights=weights, span=span)
    # estimators without sample weights (the baselines): the calibration runs repeated, at most
    # MAX_REPEAT times (a network's training time grows with the rows)
    return fit([*train, *list(cal) * max(1, min(MAX_REPEAT, round(w)))])


def _calibrated(
    method: str,
    fit: Callable[[Sequence[BenchRun]], Estimator],
    base: Estimator,
    train: Sequence[BenchRun],
    cal: Sequence[BenchRun],
    share: float,
) -> Estimator:
    if method == "prior":
        return _weighted(fit, base, train, cal, share)
    if method == "refit":
        if len(_loads(cal)) < 2:
            raise DataError(
                "a refit on one load level cannot separate the transmission ratio from the offset; " + RECORD
            )
        return fit(list(cal))
    if method == "offset":
        return base.recalibrated_on(cal)
    if method == "offset + friction":
        if not isinstance(base, Physics):
            raise ParameterError("'offset + friction' applies to the physics estimator only")
        return Physics(base.model, friction=True).recalibrated_on(cal)
    raise ParameterError(f"method must be one of {METHODS}, got {method!r}")


@checked
def calibrate(
    fit: Callable[[Sequence[BenchRun]], Estimator],
    train: Sequence[BenchRun],
    cal: Sequence[BenchRun],
    method: str = DEFAULT_METHOD,
    share: float = DEFAULT_SHARE,
) -> Calibrated:
    """``fit`` (an estimator's fitter) trained on ``train`` and calibrated on ``cal`` (runs of the
    new instrument with their jaw torque) by ``method``; checked on ``cal`` (see the module
    docs). Raises :class:`DataError` for a calibration that cannot work (no runs, a refit on one
    load level); a calibration that works but does not fit is returned flagged."""
    if method not in METHODS:
        raise ParameterError(f"method must be one of {METHODS}, got {method!r}")
    if not (isinstance(share, (int, float)) and math.isfinite(share) and share > 0):
        raise ParameterError(f"share must be a finite number > 0, got {share!r}")
    for what, runs in (("training", train), ("calibration", cal)):
        if isinstance(runs, (str, bytes)) or not all(isinstance(r, BenchRun) for r in runs) or not runs:
            raise DataError(f"{what} runs: need a non-empty sequence of bench runs")
    base = fit(train)
    est = _calibrated(method, fit, base, train, cal, share)
    own, corr = _fit(est, cal)
    trained, trained_corr = _fit(base, train)
    cross = None
    if len(cal) >= 2 and (
        method != "refit" or all(len(_loads([c for c in cal if c is not r])) >= 2 for r in cal)
    ):
        sq, n = 0.0, 0
        for r in cal:
            rest = [c for c in cal if c is not r]
            s = score(_calibrated(method, fit, base, train, rest, share), [r])
            m = len(r.jaw_torque) - _skip(r)
            sq += s.rmse_mnm**2 * m
            n += m
        cross = math.sqrt(sq / n)
    problems = []
    if not (corr > 0 and corr >= MIN_CORRELATION * trained_corr):
        problems.append(
            f"the estimate follows its own calibration runs poorly (correlation {corr:.2f}; "
            f"{trained_corr:.2f} on the training runs)"
        )
    limit = MAX_RMSE_FACTOR * trained
    if own > limit:
        problems.append(f"its error on its own calibration runs is {own / trained:.1f}x the training fit's")
    if cross is not None and cross > limit:
        problems.append(
            f"each calibration run predicted from the others is off by {cross / trained:.1f}x "
            "the training fit"
        )
    if len(_loads(cal)) < 2:
        problems.append("the calibration holds one load level only")
    if len(_stops(cal)) == 1:
        problems.append(
            "the calibration holds one jaw stop only (the friction changes with the spindle angle the "
            "stop sets: runs at other stops are estimated outside the recording's angles)"
        )
    check = CalibrationCheck([r.name for r in cal], own, corr, cross, trained, problems, _complete(cal))
    return Calibrated(est, method, float(share), check)
