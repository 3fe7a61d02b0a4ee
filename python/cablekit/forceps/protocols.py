"""The strict protocols a user meets with a real instrument (issue #37 §1): every estimator of
:mod:`cablekit.forceps.davinci` trained on one bench folder and scored on another — another
recording session of the same instrument, the other input spindle (a second cable transmission),
another wrist posture — under four calibrations on the new folder's own calibration runs.

* **none** — the trained estimator as it is;
* **offset** — the torque offset re-identified on the slowest run at the lightest load (``00``;
  ``000`` in a wrist folder's ``ZXY`` names), the documented new-instrument default;
* **offset + friction** — the offset and a common scale of the friction (physics model only);
* **refit** — the estimator fitted again on a load step of the new folder alone: ``00`` and
  ``03`` (``000`` and ``003``), the slowest motion at the lightest and the heaviest of the first
  four load levels.

The calibration runs are never scored. RMSE in mN·m after the 1 s warm-up, pooled over the
scored runs, and the worst run's; the goal of issue #37 is every held-out run ≤ 4.42 mN·m.
``cablekit forceps protocols DATA`` writes the table (docs/forceps.md, "Strict protocols").
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from cablekit.errors import DataError
from cablekit.forceps.davinci import (
    OUTSIDE_WARN,
    PUBLISHED_RMSE,
    WARMUP_S,
    BenchRun,
    Estimator,
    Physics,
    Score,
    _skip,
    read_bench_folder,
    score,
)

__all__ = [
    "CALIBRATIONS",
    "FOLDERS",
    "Transfer",
    "calibration_runs",
    "markdown",
    "protocols",
    "protocols_present",
    "transfer",
]

#: the calibrations compared, in the table's order
CALIBRATIONS = ("none", "offset", "offset + friction", "refit")

#: (protocol, trained on, scored on) folder pairs of the da Vinci bench, relative to its root;
#: ``tool4_wrist/*`` stands for every posture folder present
FOLDERS: tuple[tuple[str, str, str], ...] = (
    ("session", "tool4_load_sweep", "tool4_L4_paper_sweep"),
    ("session", "tool4_L4_paper_sweep", "tool4_load_sweep"),
    ("spindle", "tool4_load_sweep", "tool4_right_spindle"),
    ("spindle", "tool4_right_spindle", "tool4_load_sweep"),
    ("posture", "tool4_load_sweep", "tool4_wrist/*"),
)


@dataclass(frozen=True)
class Transfer:
    """One estimator trained on ``train`` and scored on ``test``'s runs (its calibration runs
    left out): a :class:`~cablekit.forceps.davinci.Score` per calibration, None where the
    calibration does not apply to the estimator."""

    protocol: str
    train: str
    test: str
    estimator: str
    n_scored: int
    scores: dict[str, Score | None]
    warnings: list[str] = field(default_factory=list)


def _check_runs(runs: object, what: str) -> None:
    if (
        isinstance(runs, (str, bytes))
        or not isinstance(runs, Sequence)
        or not all(isinstance(r, BenchRun) for r in runs)
    ):
        raise DataError(f"{what} needs a sequence of bench runs, got {type(runs).__name__}")


def calibration_runs(runs: Sequence[BenchRun]) -> tuple[BenchRun, BenchRun]:
    """The load step a folder is calibrated on: the runs named all zeros (``00``, ``000``) and
    the same with a last digit 3 (``03``, ``003``)."""
    _check_runs(runs, "calibration_runs")
    by_name = {r.name: r for r in runs}
    for width in sorted({len(r.name) for r in runs if r.name.isdigit()}):
        light, heavy = "0" * width, "0" * (width - 1) + "3"
        if light in by_name and heavy in by_name:
            return by_name[light], by_name[heavy]
    raise DataError(
        "no calibration load step among the runs: need the runs 00 and 03 (or 000 and 003: the "
        f"slowest motion at the lightest and the fourth load level); present: {sorted(by_name)}"
    )


def transfer(
    protocol: str,
    train: tuple[str, Sequence[BenchRun]],
    test: tuple[str, Sequence[BenchRun]],
    fitters: dict[str, Callable[[Sequence[BenchRun]], Estimator]],
) -> list[Transfer]:
    """Every estimator of ``fitters`` trained on ``train`` = (label, runs) and scored on the runs
    of ``test`` = (label, runs) that are not its calibration runs, under each of
    :data:`CALIBRATIONS`."""
    for what, pair in (("train", train), ("test", test)):
        if not (isinstance(pair, tuple) and len(pair) == 2 and isinstance(pair[0], str)):
            raise DataError(f"{what} must be a (label, runs) pair, got {type(pair).__name__}")
        _check_runs(pair[1], what)
        if not pair[1]:
            raise DataError(f"{what} ({pair[0]}): no runs")
        short = [r.name for r in pair[1] if len(r.jaw_torque) <= _skip(r) + 10]
        if short:
            raise DataError(f"{what} ({pair[0]}): runs {short} end within the {WARMUP_S:g} s warm-up")
    cal = calibration_runs(test[1])
    scored = [r for r in test[1] if all(r is not c for c in cal)]
    if not scored:
        raise DataError(f"{test[0]}: no runs to score besides the calibration runs")
    out = []
    for name, fit in fitters.items():
        est = fit(train[1])
        scores: dict[str, Score | None] = {
            "none": score(est, scored),
            "offset": score(est.recalibrated(cal[0]), scored),
            "offset + friction": (
                score(Physics(est.model, friction=True).recalibrated(cal[0]), scored)
                if isinstance(est, Physics)
                else None
            ),
            "refit": score(fit(list(cal)), scored),
        }
        notes = [
            f"{protocol} {train[0]} → {test[0]}, {name}, {c}: up to {100 * s.outside_share:.0f} % of a run "
            "outside the training ranges"
            for c, s in scores.items()
            if s is not None and s.outside_share > OUTSIDE_WARN
        ]
        out.append(Transfer(protocol, train[0], test[0], name, len(scored), scores, notes))
    return out


def _pairs(root: Path) -> list[tuple[str, Path, Path]]:
    pairs = []
    for protocol, a, b in FOLDERS:
        if b.endswith("/*"):
            tests = sorted(p for p in (root / b.removesuffix("/*")).glob("*") if p.is_dir())
        else:
            tests = [root / b]
        pairs += [(protocol, root / a, t) for t in tests if (root / a).is_dir() and t.is_dir()]
    return pairs


def protocols_present(root: str | Path, only: Sequence[str] | None = None) -> list[tuple[str, Path, Path]]:
    """The (protocol, trained-on folder, scored-on folder) pairs of :data:`FOLDERS` present under
    ``root``, or only those of the protocols named in ``only``; a ``DataError`` for a root that is
    not a path, an unknown protocol, or no pair present."""
    if not isinstance(root, (str, Path)):
        raise DataError(f"the bench folder must be a path, got {type(root).__name__}")
    if only is not None and (isinstance(only, (str, bytes)) or not all(isinstance(p, str) for p in only)):
        raise DataError(f"only must be a list of protocol names, got {only!r}")
    base = Path(root)
    known = {p for p, _, _ in FOLDERS}
    bad = sorted(set(only or ()) - known)
    if bad:
        raise DataError(f"unknown protocol(s) {bad}; known: {sorted(known)}")
    pairs = [p for p in _pairs(base) if only is None or p[0] in only]
    if not pairs:
        raise DataError(
            f"{base}: none of the folder pairs of the protocols is present "
            f"({', '.join(f'{a} → {b}' for _, a, b in FOLDERS)})"
        )
    return pairs


def protocols(
    root: str | Path,
    fitters: dict[str, Callable[[Sequence[BenchRun]], Estimator]],
    only: Sequence[str] | None = None,
    advance: Callable[[str], None] = lambda _: None,
) -> list[Transfer]:
    """Every pair of :data:`FOLDERS` present under ``root`` (the bench's folder,
    ``../shared/data/davinci-maryland-bench``), or only the protocols named in ``only``
    (:func:`protocols_present`)."""
    pairs = protocols_present(root, only)
    base = Path(root)
    cache: dict[Path, list[BenchRun]] = {}

    def runs(p: Path) -> list[BenchRun]:
        if p not in cache:
            cache[p] = read_bench_folder(p)
        return cache[p]

    out = []
    for protocol, a, b in pairs:
        label = str(b.relative_to(base))
        out += transfer(protocol, (str(a.relative_to(base)), runs(a)), (label, runs(b)), fitters)
        advance(f"{protocol}: {a.name} → {label}")
    return out


def markdown(rows: Sequence[Transfer]) -> str:
    """The table: per protocol, folder pair and estimator, each calibration's pooled RMSE and
    worst run (mN·m; ✗ where a run is above the published 4.42)."""
    head = "| protocol | trained on | scored on (runs) | estimator | " + " | ".join(CALIBRATIONS) + " |"
    lines = [head, "|---|---|---|---|" + "---|" * len(CALIBRATIONS)]
    for t in rows:
        cells = []
        for c in CALIBRATIONS:
            s = t.scores[c]
            if s is None:
                cells.append("—")
            else:
                mark = "" if s.worst_run_mnm <= PUBLISHED_RMSE else " ✗"
                cells.append(f"{s.rmse_mnm:.2f} / {s.worst_run_mnm:.2f}{mark}")
        row = f"| {t.protocol} | {t.train} | {t.test} ({t.n_scored}) | {t.estimator} | "
        lines.append(row + " | ".join(cells) + " |")
    return "\n".join(lines)
