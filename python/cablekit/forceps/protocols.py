"""The strict protocols a user meets with a real instrument (issue #37 §1): every estimator of
:mod:`cablekit.forceps.davinci` trained on one bench folder and scored on another — another
recording session of the same instrument, the other input spindle (a second cable transmission),
another wrist posture — under five calibrations on the new folder's calibration recording
(:func:`calibration_runs`: the load step ``00`` + ``03`` — ``000`` + ``003`` in a wrist folder's
``ZXY`` names — and, where the folder has it, the same step at the fastest motion):

* **none** — the trained estimator as it is;
* **offset** — the torque offset re-identified on the calibration runs (the default before
  issue #37);
* **offset + friction** — the offset and a common scale of the friction (physics model only);
* **refit** — the estimator fitted on the calibration runs alone;
* **prior** — fitted on the training runs and the calibration runs, these weighted to
  :data:`~cablekit.forceps.calibrate.DEFAULT_SHARE` times the training runs' weight: the
  default, chosen by :func:`calibration_cv` over every pair of folders.

**leave-posture-out** (with ``posture``): trained on the straight wrist and every posture folder
but the scored one.

The calibration runs are never scored. RMSE in mN·m after the 1 s warm-up, pooled over the
scored runs, and the worst run's; the goal of issue #37 is every held-out run ≤ 4.42 mN·m.
``cablekit forceps protocols DATA`` writes the table (docs/forceps.md, "Strict protocols").
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from cablekit._args import checked
from cablekit.errors import DataError
from cablekit.forceps.calibrate import DEFAULT_SHARE, _calibrated
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
    "CV_INSTRUMENTS",
    "CV_SHARES",
    "FOLDERS",
    "CvGroup",
    "CvRow",
    "Transfer",
    "calibration_cv",
    "calibration_runs",
    "cv_markdown",
    "markdown",
    "protocols",
    "protocols_present",
    "transfer",
]

#: the protocol that trains on the straight wrist and every posture but the scored one
LEAVE_POSTURE_OUT = "leave-posture-out"

#: the calibrations compared, in the table's order
CALIBRATIONS = ("none", "offset", "offset + friction", "refit", "prior")

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


@checked
def calibration_runs(runs: Sequence[BenchRun]) -> list[BenchRun]:
    """The calibration recording among a folder's runs: the **load step** at the slowest motion
    from the lightest to the heaviest load the folder holds — the run named all zeros (``00``,
    ``000``) and the one with the largest last digit after zeros (``03`` on a four-load bench,
    ``09`` on the paper's ten loads); where the folder has them, the same two loads at its fastest
    motion (``40`` + ``43``; in ``ZXY`` names the largest ``X`` at ``Z = 0``); and, in ``ZXY``
    names, the load step at the last jaw stopping position (``Z00`` + ``Z03`` for the largest
    ``Z``). The friction depends on the load and on the spindle's angle: a recording that stops
    short of the heaviest load or sees one jaw stop only leaves the estimator to extrapolate."""
    _check_runs(runs, "calibration_runs")
    by_name = {r.name: r for r in runs}
    digits = [n for n in by_name if n.isdigit()]
    for width in sorted({len(n) for n in digits}):
        names = [n for n in digits if len(n) == width]
        head = "0" * (width - 1)
        top_load = max((n[-1] for n in names if n.startswith(head)), default="0")
        light, heavy = head + "0", head + top_load
        if light not in by_name or top_load == "0":
            continue
        out = [by_name[light], by_name[heavy]]
        if width < 2:
            return out
        lead = "0" * (width - 2)
        top = max(n[-2] for n in names if n.startswith(lead))
        last = max(n[0] for n in names) if width == 3 else "0"
        # the same step at the fastest motion, then at the last jaw stop, where recorded
        for step, pair in (
            (top, (lead + top + "0", lead + top + top_load)),
            (last, (last + "00", last + "0" + top_load)),
        ):
            if step != "0" and all(p in by_name for p in pair):
                out += [by_name[p] for p in pair]
        return out
    raise DataError(
        "no calibration load step among the runs: need the lightest and the heaviest load at the "
        "slowest motion (runs 00 and 03 on a four-load bench, or 000 and 003); present: "
        f"{sorted(by_name)}"
    )


@checked
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
        scores: dict[str, Score | None] = {"none": score(est, scored)}
        for method in CALIBRATIONS[1:]:
            if method == "offset + friction" and not isinstance(est, Physics):
                scores[method] = None
                continue
            calibrated = _calibrated(method, fit, est, train[1], cal, DEFAULT_SHARE)
            scores[method] = score(calibrated, scored)
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
        if protocol == "posture" and len(tests) > 1:
            # leave one posture out: trained on the straight wrist and every other posture
            pairs += [(LEAVE_POSTURE_OUT, root / a, t) for t in tests if (root / a).is_dir() and t.is_dir()]
    return pairs


@checked
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
    pairs = [
        p
        for p in _pairs(base)
        if only is None or p[0] in only or (p[0] == LEAVE_POSTURE_OUT and "posture" in only)
    ]
    if not pairs:
        raise DataError(
            f"{base}: none of the folder pairs of the protocols is present "
            f"({', '.join(f'{a} → {b}' for _, a, b in FOLDERS)})"
        )
    return pairs


@checked
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
        train = (str(a.relative_to(base)), runs(a))
        if protocol == LEAVE_POSTURE_OUT:
            others = [t for k, _, t in pairs if k == LEAVE_POSTURE_OUT and t != b]
            train = (
                f"{train[0]} + {len(others)} other postures",
                [*runs(a), *(r for t in others for r in runs(t))],
            )
        out += transfer(protocol, train, (label, runs(b)), fitters)
        advance(f"{protocol}: {a.name} → {label}")
    return out


@checked
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


#: the folders each taken as "a new instrument" for the others in :func:`calibration_cv`:
#: two sessions of the left spindle and the right spindle; every posture folder is scored from
#: each of them
CV_INSTRUMENTS = ("tool4_load_sweep", "tool4_L4_paper_sweep", "tool4_right_spindle")
#: the prior's weights tried (the calibration runs' total weight over the training runs')
CV_SHARES = (1.0, 4.0, 16.0, 64.0, 256.0, 1024.0)


@dataclass(frozen=True)
class CvGroup:
    """Scores of one calibration over a group of folder pairs (mN·m)."""

    #: geometric mean of the pairs' pooled RMSE
    gmean: float
    #: the worst run of any pair
    worst: float
    #: pairs with every scored run ≤ 4.42 mN·m, and pairs
    passed: int
    pairs: int


@dataclass(frozen=True)
class CvRow:
    """One calibration (method, share, recording) over the pairs of :func:`calibration_cv`,
    separately over the instrument/session pairs and the posture pairs."""

    method: str
    share: float | None
    recording: str
    instrument: CvGroup
    posture: CvGroup

    @property
    def overall(self) -> float:
        """The selection criterion: the geometric mean of the pooled RMSE over every pair."""
        groups = [g for g in (self.instrument, self.posture) if g.pairs]
        n = sum(g.pairs for g in groups)
        return math.exp(sum(g.pairs * math.log(g.gmean) for g in groups) / n) if n else math.nan


@checked
def calibration_cv(
    root: str | Path,
    shares: Sequence[float] = CV_SHARES,
    advance: Callable[[str], None] = lambda _: None,
) -> list[CvRow]:
    """Cross-validate the calibration of the physics estimator over every pair of folders under
    ``root``: each of :data:`CV_INSTRUMENTS` trained on and every other one of them and every
    ``tool4_wrist/*`` folder calibrated on and scored. Two recordings: the documented one
    (:func:`calibration_runs`) and the minimal load step (its first two runs); the scored runs
    are the same for both (the folder without the documented recording)."""
    if not isinstance(root, (str, Path)) or not Path(root).is_dir():
        raise DataError(f"the bench folder must be an existing folder, got {root!r}")
    base = Path(root)
    trains = [base / n for n in CV_INSTRUMENTS if (base / n).is_dir()]
    wrists = sorted(p for p in (base / "tool4_wrist").glob("*") if p.is_dir())
    if len(trains) < 2:
        raise DataError(f"{base}: calibration_cv needs at least two of {CV_INSTRUMENTS}")
    runs = {p: read_bench_folder(p) for p in [*trains, *wrists]}
    fit = Physics.fit
    methods = [("offset", None), ("offset + friction", None), ("refit", None)] + [
        ("prior", s) for s in shares
    ]
    got: dict[tuple[str, float | None, str, str], list[Score]] = {}
    for a in trains:
        est = fit(runs[a])
        for b in [t for t in trains if t != a] + wrists:
            group = "posture" if b in wrists else "instrument"
            documented = calibration_runs(runs[b])
            scored = [r for r in runs[b] if all(r is not c for c in documented)]
            for recording, cal in (("documented", documented), ("load step", documented[:2])):
                for method, share in methods:
                    c = _calibrated(method, fit, est, runs[a], cal, share or DEFAULT_SHARE)
                    got.setdefault((method, share, recording, group), []).append(score(c, scored))
            advance(f"{a.name} → {b.relative_to(base)}")
    out = []
    for recording in ("documented", "load step"):
        for method, share in methods:
            groups = []
            for group in ("instrument", "posture"):
                s = got.get((method, share, recording, group), [])
                if not s:
                    groups.append(CvGroup(math.nan, math.nan, 0, 0))
                    continue
                g = math.exp(sum(math.log(x.rmse_mnm) for x in s) / len(s))
                ok = sum(x.worst_run_mnm <= PUBLISHED_RMSE for x in s)
                groups.append(CvGroup(g, max(x.worst_run_mnm for x in s), ok, len(s)))
            out.append(CvRow(method, share, recording, *groups))
    return out


def _chosen(rows: Sequence[CvRow]) -> tuple[str, float | None]:
    """The calibration (method, share) the cross-validation chooses: the least geometric mean,
    over the recordings, of the all-pairs criterion — a default that must serve a user who
    records the documented recording as well as one who records the minimal load step."""
    keys = list(dict.fromkeys((r.method, r.share) for r in rows))

    def criterion(key: tuple[str, float | None]) -> float:
        vals = [r.overall for r in rows if (r.method, r.share) == key and math.isfinite(r.overall)]
        return math.exp(sum(math.log(v) for v in vals) / len(vals)) if vals else math.inf

    return min(keys, key=criterion)


@checked
def cv_markdown(rows: Sequence[CvRow]) -> str:
    """The cross-validation table, the chosen calibration (:func:`_chosen`) marked."""
    best = _chosen(rows)
    lines = [
        "| recording | method | share | instrument pairs: gmean / worst / all runs ≤ 4.42 "
        "| posture pairs: gmean / worst / all runs ≤ 4.42 | all pairs gmean |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        mark = " **(chosen)**" if (r.method, r.share) == best else ""
        share = "—" if r.share is None else f"{r.share:g}"
        cells = [
            f"{g.gmean:.2f} / {g.worst:.2f} / {g.passed} of {g.pairs}" if g.pairs else "—"
            for g in (r.instrument, r.posture)
        ]
        lines.append(
            f"| {r.recording} | {r.method}{mark} | {share} | {cells[0]} | {cells[1]} | {r.overall:.2f} |"
        )
    return "\n".join(lines)
