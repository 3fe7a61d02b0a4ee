"""Score the diagnosis on a folder of blind cases written by someone else's simulator.

A benchmark folder holds ``caseNN/`` sub-folders, each with ``fit.csv[.gz]``,
``holdout.csv[.gz]``, ``model.toml`` (the nominal, in the model file format of
docs/diagnosis.md) and ``truth.json``: ``{"effects": {name: {parameters}}, ...}`` with the
canonical names of the withheld effects (empty for a control) and, optionally, ``"site"``
(one effect) or ``"sites": {name: site}`` and ``"in_library": false`` for an effect the library
does not have. ``../shared/benchmarks/blind_joint_a`` is such a folder; sets nobody on the
project has seen are scored the same way (``cablekit diagnose --benchmark DIR``).

Scoring, as the benchmark's README states it:

* a single-effect case counts when the first-ranked candidate's effect is the withheld one and the
  verdict is not ``no_significant_gap``; where the truth names the site, the site counts as a
  separate figure;
* a pair counts when the first-ranked effect is one of the two, and separately "both found" when
  each is among the selected effects;
* a control counts when the verdict is ``no_significant_gap`` with nothing selected;
* an effect outside the library (``in_library: false``) counts when the diagnosis does not claim
  it is ``explained`` by a library effect while it still reports a significant gap;
* the held-out share of the gap closed is the selected model's.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cablekit.diagnose.data import load_run
from cablekit.diagnose.engine import diagnose
from cablekit.diagnose.prepare import Options
from cablekit.diagnose.progress import Progress
from cablekit.diagnose.spec import load_model_spec
from cablekit.errors import CablekitError, DataError

__all__ = ["BenchmarkCase", "BenchmarkResult", "format_benchmark", "run_benchmark"]

#: Sites the README of ``blind_joint_a`` states for its cases where its truth.json does not: the
#: simulator's explicit sites (capstan and Dahl on the motor-side tensions of both cables, the
#: delay on the tension channels only, gain and bias on the drive cell only).
README_SITES_A: dict[str, dict[str, str]] = {
    "case02": {"capstan_friction": "contact.both"},
    "case03": {"dahl_hysteresis": "contact.both"},
    "case09": {"time_delay": "sensors.force"},
    "case10": {"sensor_gain_bias": "sensor.tension_motor_drive"},
}


@dataclass(frozen=True)
class BenchmarkCase:
    """One scored case."""

    case: str
    #: canonical names of the withheld effects (empty: a control)
    truth: list[str]
    #: the truth's site per effect, where it names one
    truth_sites: dict[str, str]
    in_library: bool
    verdict: str
    top1_id: str | None
    top1_effect: str | None
    top1_site: str | None
    selected: list[str]
    held_out_closed: float
    #: the nominal held-out gap (noise units)
    gap_held_out: float
    seconds: float
    #: the case counts (see the module's scoring rules)
    correct: bool
    #: the first-ranked site is the truth's (None: the truth names no site)
    site_correct: bool | None
    #: pairs: every withheld effect is among the selected ones (None otherwise)
    both_found: bool | None
    #: candidates whose fit failed (never silently)
    failed: list[str] = field(default_factory=list)
    error: str | None = None

    @property
    def kind(self) -> str:
        if not self.in_library:
            return "outside"
        return {0: "control", 1: "single"}.get(len(self.truth), "pair")


@dataclass(frozen=True)
class BenchmarkResult:
    """Every case and the summary figures."""

    directory: str
    cases: list[BenchmarkCase]

    def _of(self, kind: str) -> list[BenchmarkCase]:
        return [c for c in self.cases if c.kind == kind]

    @property
    def top1(self) -> tuple[int, int]:
        """Single-effect and pair cases whose first-ranked effect is withheld: (right, of)."""
        s = self._of("single") + self._of("pair")
        return sum(c.correct for c in s), len(s)

    @property
    def sites(self) -> tuple[int, int]:
        s = [c for c in self.cases if c.site_correct is not None]
        return sum(bool(c.site_correct) for c in s), len(s)

    @property
    def both_found(self) -> tuple[int, int]:
        p = self._of("pair")
        return sum(bool(c.both_found) for c in p), len(p)

    @property
    def controls_clean(self) -> tuple[int, int]:
        c = self._of("control")
        return sum(x.correct for x in c), len(c)

    @property
    def outside_honest(self) -> tuple[int, int]:
        c = self._of("outside")
        return sum(x.correct for x in c), len(c)

    @property
    def median_closed(self) -> float:
        scored = self._of("single") + self._of("pair")
        v = [c.held_out_closed for c in scored if math.isfinite(c.held_out_closed)]
        return float(np.median(v)) if v else math.nan

    @property
    def seconds(self) -> list[float]:
        return [c.seconds for c in self.cases]

    def to_json(self) -> dict[str, Any]:
        t = self.seconds
        return {
            "schema": "cablekit.benchmark/1",
            "directory": self.directory,
            "cases": [asdict(c) | {"kind": c.kind} for c in self.cases],
            "scores": {
                "top1": list(self.top1),
                "site": list(self.sites),
                "both_found": list(self.both_found),
                "controls_clean": list(self.controls_clean),
                "outside_library_honest": list(self.outside_honest),
                "median_held_out_closed": self.median_closed,
                "seconds": {
                    "min": min(t, default=math.nan),
                    "median": float(np.median(t)) if t else math.nan,
                    "max": max(t, default=math.nan),
                    "total": float(sum(t)),
                },
            },
        }


def _truth(directory: Path) -> tuple[list[str], dict[str, str], bool]:
    path = directory / "truth.json"
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DataError(f"{path}: not a readable truth.json ({exc})") from exc
    if not isinstance(doc, dict):
        raise DataError(f"{path}: a truth.json is a JSON object, not {type(doc).__name__}")
    effects = doc.get("effects")
    if not isinstance(effects, dict):
        raise DataError(f"{path}: 'effects' must be a table of withheld effects (empty for a control)")
    names = [str(k) for k in effects if k != "none_of_library"]
    sites = dict(README_SITES_A.get(directory.name, {})) if "blind_joint_a" in str(directory) else {}
    if isinstance(doc.get("sites"), dict):
        sites.update({str(k): str(v) for k, v in doc["sites"].items()})
    site = doc.get("site")
    if isinstance(site, str) and len(names) == 1:
        sites[names[0]] = site
    elif isinstance(site, list) and len(site) == len(names):  # a pair: one site per effect, in order
        sites.update({n: str(s) for n, s in zip(names, site, strict=True)})
    in_library = bool(doc.get("in_library", True)) and "none_of_library" not in effects
    return names, sites, in_library


def _run_file(directory: Path, stem: str) -> Path:
    for suffix in (".csv.gz", ".csv", ".parquet"):
        p = directory / f"{stem}{suffix}"
        if p.exists():
            return p
    raise DataError(f"{directory}: no {stem}.csv, {stem}.csv.gz or {stem}.parquet")


def _score(
    name: str,
    truth: list[str],
    sites: dict[str, str],
    in_library: bool,
    doc: dict[str, Any],
    seconds: float,
) -> BenchmarkCase:
    effects = doc["effects"]
    top = effects[0] if effects else None
    selected = list(doc["selected"]["effects"])
    by_id = {e["id"]: e for e in effects}
    sel_names = {by_id[s]["name"] for s in selected if s in by_id}
    verdict = doc["verdict"]
    closed = doc["selected"]["held_out"]["closed_fraction"]
    top_effect = top["name"] if top else None
    site_correct: bool | None = None
    both: bool | None = None
    if not in_library:
        correct = verdict != "explained" and bool(doc["gap"]["significant"])
    elif not truth:
        correct = verdict == "no_significant_gap" and not selected
    else:
        correct = verdict != "no_significant_gap" and top_effect in truth
        if len(truth) > 1:
            both = all(t in sel_names for t in truth)
        if top_effect in sites:
            site_correct = bool(correct and top is not None and top["site"] == sites[top_effect])
        elif len(truth) == 1 and truth[0] in sites:
            site_correct = False
    return BenchmarkCase(
        case=name,
        truth=truth,
        truth_sites=sites,
        in_library=in_library,
        verdict=verdict,
        top1_id=top["id"] if top else None,
        top1_effect=top_effect,
        top1_site=top["site"] if top else None,
        selected=selected,
        held_out_closed=float(closed) if closed is not None else math.nan,
        gap_held_out=float(doc["gap"]["held_out"]),
        seconds=seconds,
        correct=bool(correct),
        site_correct=site_correct,
        both_found=both,
        failed=[e["id"] for e in effects if e["status"] == "failed"],
    )


def run_benchmark(
    directory: str | Path,
    cases: list[str] | None = None,
    *,
    out: str | Path | None = None,
    options: Options | None = None,
    progress: bool = True,
) -> BenchmarkResult:
    """Diagnose every case of a benchmark folder (or the named ``cases``) and score it.

    Each case's ``diagnosis.json`` goes to ``out/<case>.json`` when ``out`` is given. A case whose
    diagnosis raises a :class:`CablekitError` is scored as a miss with the error recorded; the
    others go on.
    """
    root = Path(directory)
    if not root.is_dir():
        raise DataError(f"{root}: not a benchmark folder (caseNN/ sub-folders with truth.json)")
    names = sorted(p.name for p in root.iterdir() if p.is_dir() and (p / "truth.json").exists())
    if cases:
        unknown = sorted(set(cases) - set(names))
        if unknown:
            raise DataError(f"{root}: no case {', '.join(unknown)} (cases: {', '.join(names)})")
        names = [n for n in names if n in cases]
    if not names:
        raise DataError(f"{root}: no caseNN/ folder with a truth.json")
    opts = options or Options(progress=False)
    out_dir = Path(out) if out is not None else None
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
    scored: list[BenchmarkCase] = []
    with Progress(len(names), "benchmark", enabled=progress) as bar:
        for name in names:
            d = root / name
            truth, sites, in_library = _truth(d)
            t0 = time.perf_counter()
            try:
                spec = load_model_spec(d / "model.toml")
                res = diagnose(
                    spec, [load_run(_run_file(d, "fit"))], [load_run(_run_file(d, "holdout"))], opts
                )
            except CablekitError as exc:
                scored.append(
                    BenchmarkCase(
                        case=name,
                        truth=truth,
                        truth_sites=sites,
                        in_library=in_library,
                        verdict="error",
                        top1_id=None,
                        top1_effect=None,
                        top1_site=None,
                        selected=[],
                        held_out_closed=math.nan,
                        gap_held_out=math.nan,
                        seconds=time.perf_counter() - t0,
                        correct=False,
                        site_correct=None,
                        both_found=None,
                        error=f"{type(exc).__name__}: {exc}",
                    )
                )
                bar.advance(f"{name}: error")
                continue
            doc = res.to_json()
            if out_dir is not None:
                (out_dir / f"{name}.json").write_text(json.dumps(doc, indent=1))
            case = _score(name, truth, sites, in_library, doc, time.perf_counter() - t0)
            scored.append(case)
            bar.advance(f"{name}: {'ok' if case.correct else 'MISS'}")
    return BenchmarkResult(str(root), scored)


def format_benchmark(result: BenchmarkResult) -> str:
    """The table ``.ci/run`` prints: per case the truth, the first-ranked candidate, the marks,
    the held-out share closed and the time; then the summary figures."""
    lines = [
        f"{'case':<7} {'withheld':<34} {'top-1 named (verdict)':<58} {'effect':<6} {'site':<5} "
        f"{'both':<5} {'closed':>6} {'s':>6}"
    ]
    for c in result.cases:
        truth = "+".join(f"{t}@{c.truth_sites[t]}" if t in c.truth_sites else t for t in c.truth) or (
            "control" if c.in_library else "outside the library"
        )
        named = f"{c.top1_id or '-'} ({c.verdict})"
        mark = lambda v: "-" if v is None else ("ok" if v else "MISS")  # noqa: E731
        lines.append(
            f"{c.case:<7} {truth:<34} {named:<58} {mark(c.correct):<6} {mark(c.site_correct):<5} "
            f"{mark(c.both_found):<5} {c.held_out_closed:>6.2f} {c.seconds:>6.1f}"
        )
        if c.error:
            lines.append(f"        error: {c.error}")
        if c.failed:
            lines.append(f"        failed fits: {', '.join(c.failed)}")
    t1, n1 = result.top1
    s, ns = result.sites
    b, nb = result.both_found
    k, nk = result.controls_clean
    o, no = result.outside_honest
    t = result.seconds
    lines.append("")
    summary = f"top-1 {t1}/{n1}, site {s}/{ns}, both effects found {b}/{nb} pairs, controls clean {k}/{nk}"
    if no:
        summary += f", outside the library not claimed explained {o}/{no}"
    summary += f", median held-out closed {result.median_closed:.0%}"
    lines.append(summary)
    lines.append(
        f"time per case: min {min(t):.1f} s, median {float(np.median(t)):.1f} s, max {max(t):.1f} s, "
        f"{sum(t):.0f} s in all"
    )
    return "\n".join(lines)
