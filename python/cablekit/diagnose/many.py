"""Many runs: diagnose a whole campaign (``cablekit diagnose --many DIR``).

A campaign folder holds recorded runs and a ``manifest.toml`` that groups them — per group the
nominal model file, the fit runs and the held-out runs::

    model = "model.toml"          # default model file for every group (optional)

    [[group]]
    name = "tool4-day1"
    model = "tool4.toml"          # this group's model file (else the default)
    fit = ["day1/a.csv", "day1/b.csv"]
    held_out = ["day1/c.csv"]

Paths are relative to the folder. Every group is diagnosed exactly as ``cablekit diagnose`` would
diagnose it alone; the results stream into one summary table as groups finish. A group's model
file may be a joint, transmission or cable-network model file (the grey-box engine) or a cable
robot's file (``motion`` and ``[[cables]]``; its runs are CDPR run tables: with measured poses
its drives go through the same engine as a cable network, :mod:`cablekit.cdpr.drives`; without,
the drum-side force check of :mod:`cablekit.cdpr.diagnose`) — one campaign can hold all of them.

**Ray.** With Ray installed (``pip install 'cablekit[scale]'``) the candidate fits of every group
fan out as Ray tasks — locally by default (``ray.init()`` with this machine's cores) or on a
cluster (``--address``). Each task receives its group's runs and model from Ray's object store
(put once per group), prepares the group's problems once per worker process, and fits one
candidate; the driver keeps several groups in flight so the cluster stays busy while a group waits
for its slowest fit. Without Ray the same command runs serially (groups one after another, the
candidates of a group in this machine's threads). A parallel-robot group without poses is one Ray
task (its runs, read by the driver, and its robot file's text go through the object store; its
candidate fits are closed-form and take seconds). Both paths give the same numbers.
"""

from __future__ import annotations

import json
import threading
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cablekit._files import load_toml, read_text
from cablekit.cdpr.diagnose import CdprDiagnosis, is_robot_file
from cablekit.diagnose.data import Run, load_run
from cablekit.diagnose.engine import diagnose
from cablekit.diagnose.fit import CandidateFit, fit_candidate
from cablekit.diagnose.prepare import Options, Prepared, prepare
from cablekit.diagnose.progress import Progress
from cablekit.diagnose.result import Diagnosis
from cablekit.diagnose.spec import ModelSpec, load_model_spec
from cablekit.errors import DataError

__all__ = [
    "Group",
    "GroupResult",
    "RayFits",
    "load_manifest",
    "manifest_from_dict",
    "run_many",
    "summary_table",
]

_GROUP_KEYS = {"name", "model", "fit", "held_out"}
_TOP_KEYS = {"model", "group"}


@dataclass(frozen=True)
class Group:
    """One diagnosis of a campaign: a model file, fit runs, held-out runs."""

    name: str
    model: Path
    fit: tuple[Path, ...]
    held_out: tuple[Path, ...]


@dataclass(frozen=True)
class GroupResult:
    """A group's diagnosis (or the error that stopped it) and its wall time."""

    group: Group
    #: the grey-box engine's diagnosis, or a parallel robot's
    diagnosis: Diagnosis | CdprDiagnosis | None
    error: str | None
    seconds: float

    def row(self) -> dict[str, Any]:
        """The group's line of the summary (a parallel robot's: its status as the verdict, each
        channel's finding as ``effect@cable.<j>``, the least of the findings' closed shares)."""
        d = self.diagnosis
        if isinstance(d, CdprDiagnosis):
            found = d.findings
            return {
                "group": self.group.name,
                "verdict": d.status,
                "selected": [f"{c.effect}@cable.{c.cable + 1}" for c in found],
                "held_out_closed": min((float(c.closed) for c in found), default=None),
                "gap_held_out": None,
                "flags": [],
                "error": self.error,
                "seconds": self.seconds,
            }
        return {
            "group": self.group.name,
            "verdict": d.verdict if d else "error",
            "selected": d.selected.effects if d else [],
            "held_out_closed": d.selected.held_out.closed_fraction if d else None,
            "gap_held_out": d.gap.held_out if d else None,
            "flags": d.flags if d else [],
            "error": self.error,
            "seconds": self.seconds,
        }


def load_manifest(directory: str | Path) -> list[Group]:
    """Read ``DIR/manifest.toml``: typed errors for a missing file, unknown keys, a group without
    fit or held-out runs, duplicate group names, or a run file that does not exist."""
    directory = Path(directory)
    path = directory / "manifest.toml"
    if not path.is_file():
        raise DataError(
            f"{directory}: no manifest.toml (see `cablekit diagnose --help` and docs/diagnosis.md)"
        )
    return manifest_from_dict(load_toml(path, "manifest"), directory, str(path))


def manifest_from_dict(doc: dict[str, Any], directory: str | Path, path: str = "manifest") -> list[Group]:
    """The groups of a parsed manifest (paths relative to ``directory``); see :func:`load_manifest`."""
    directory = Path(directory)
    unknown = sorted(set(doc) - _TOP_KEYS)
    if unknown:
        raise DataError(f"{path}: unknown keys {unknown} (allowed: {sorted(_TOP_KEYS)})")
    groups = doc.get("group")
    if not isinstance(groups, list) or not groups:
        raise DataError(f"{path}: no [[group]] tables")
    default_model = doc.get("model")
    out: list[Group] = []
    for i, g in enumerate(groups):
        where = f"{path}: group {i + 1}"
        if not isinstance(g, dict):
            raise DataError(f"{where}: not a table")
        unknown = sorted(set(g) - _GROUP_KEYS)
        if unknown:
            raise DataError(f"{where}: unknown keys {unknown} (allowed: {sorted(_GROUP_KEYS)})")
        name = g.get("name")
        if not isinstance(name, str) or not name or "/" in name or name.startswith("."):
            raise DataError(f"{where}: 'name' must be a non-empty string without '/'")
        model = g.get("model", default_model)
        if not isinstance(model, str):
            raise DataError(f"{where} ({name}): no model file (give 'model' here or at the top)")
        runs: dict[str, tuple[Path, ...]] = {}
        for key in ("fit", "held_out"):
            v = g.get(key)
            if not isinstance(v, list) or not v or not all(isinstance(p, str) for p in v):
                raise DataError(f"{where} ({name}): '{key}' must be a non-empty list of run files")
            runs[key] = tuple(directory / p for p in v)
        both = set(runs["fit"]) & set(runs["held_out"])
        if both:
            raise DataError(f"{where} ({name}): {sorted(str(p) for p in both)} both fitted and held out")
        for p in (directory / model, *runs["fit"], *runs["held_out"]):
            try:
                exists = p.is_file()
            except (OSError, ValueError):  # a NUL byte or an over-long name
                exists = False
            if not exists:
                raise DataError(f"{where} ({name}): no such file {p!s:.200}")
        out.append(Group(name, directory / model, runs["fit"], runs["held_out"]))
    names = [g.name for g in out]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise DataError(f"{path}: duplicate group names {dup}")
    return out


# ---- Ray -----------------------------------------------------------------------------------------

#: per worker process: the prepared problems of the groups it has fitted for (token → Prepared)
_PREPARED: dict[str, Prepared] = {}
_PREPARED_LOCK = threading.Lock()


def _fit_task(
    data: tuple[str, ModelSpec, list[Run], list[Run]],
    effects: list[str],
    theta0: Any,
    max_iter: int,
    head_s: float = 0.0,
) -> CandidateFit:
    """A Ray task: fit one candidate of one group (the group is prepared once per worker)."""
    token, spec, fit_runs, hold_runs = data
    with _PREPARED_LOCK:
        prep = _PREPARED.get(token)
        if prep is None:
            if len(_PREPARED) >= 8:  # a worker serves groups one after another: keep a few
                _PREPARED.pop(next(iter(_PREPARED)))
            prep = _PREPARED[token] = prepare(spec, fit_runs, hold_runs)
    return fit_candidate(prep, effects, theta0, max_iter, head_s)


class RayFits:
    """Fans candidate fits out as Ray tasks (the ``executor`` of :class:`Options`)."""

    def __init__(self, ray: Any):
        self._ray = ray
        self._task = ray.remote(_fit_task)
        self._refs: dict[str, Any] = {}
        self._lock = threading.Lock()

    def _data(self, prep: Prepared) -> Any:
        with self._lock:
            ref = self._refs.get(prep.token)
            if ref is None:
                data = (prep.token, prep.spec, prep.fit_runs, prep.hold_runs)
                ref = self._refs[prep.token] = self._ray.put(data)
            return ref

    def forget(self, prep: Prepared) -> None:
        """Drop a finished group's data from the object store."""
        with self._lock:
            self._refs.pop(prep.token, None)

    def map(
        self,
        prep: Prepared,
        jobs: list[tuple[list[str], Any]],
        max_iter: int,
        bar: Progress,
        head_s: float = 0.0,
    ) -> list[CandidateFit]:
        ref = self._data(prep)
        futures = [self._task.remote(ref, eff, th, max_iter, head_s) for eff, th in jobs]
        index = {f: i for i, f in enumerate(futures)}
        out: list[CandidateFit | None] = [None] * len(jobs)
        pending = list(futures)
        while pending:
            ready, pending = self._ray.wait(pending, num_returns=1)
            for f in ready:
                i = index[f]
                out[i] = self._ray.get(f)
                bar.advance("+".join(jobs[i][0]))
        return [c for c in out if c is not None]


def _cdpr_task(robot_text: str, source: str, runs: list[Any], n_fit: int) -> CdprDiagnosis:
    """A parallel-robot group's diagnosis (a Ray task, or called directly without Ray)."""
    from cablekit.cdpr import Robot
    from cablekit.cdpr.diagnose import diagnose_loaded

    return diagnose_loaded(runs, n_fit, Robot.from_toml(robot_text, source))


def _robot_drives(g: Group) -> tuple[Any, list[Any], list[Any]] | None:
    """A parallel-robot group whose runs all have poses as the one engine reads it (its drives
    as a network, :func:`cablekit.cdpr.drives.drive_runs`); ``None`` without poses."""
    from cablekit._files import parse_toml
    from cablekit.cdpr import Robot, Winch, path_friction_of
    from cablekit.cdpr.drives import drive_runs
    from cablekit.cdpr.formats import load_cdpr_run

    text = read_text(g.model, "robot file")
    robot = Robot.from_toml(text, str(g.model))
    runs = [(p.name, load_cdpr_run(p, robot)) for p in (*g.fit, *g.held_out)]
    if any(r.poses is None for _, r in runs):
        return None
    friction = path_friction_of(parse_toml(text, str(g.model)))
    spec, loaded = drive_runs(robot, Winch.seed003(), runs, friction)
    return spec, loaded[: len(g.fit)], loaded[len(g.fit) :]


def _cdpr_group(g: Group, ray: Any, out: Path, html: bool) -> CdprDiagnosis:
    """Diagnose a parallel-robot group (on Ray when given) and write its ``diagnosis.json`` and
    ``diagnose.md`` (and ``diagnose.png`` with ``html``)."""
    from cablekit.cdpr import Robot
    from cablekit.cdpr.diagnose import plot, run_report
    from cablekit.cdpr.formats import load_cdpr_run

    text = read_text(g.model, "robot file")
    robot = Robot.from_toml(text, str(g.model))
    runs = [(p.name, load_cdpr_run(p, robot)) for p in (*g.fit, *g.held_out)]
    if ray is not None:
        task = ray.remote(_cdpr_task)
        d = ray.get(task.remote(text, str(g.model), runs, len(g.fit)))
    else:
        d = _cdpr_task(text, str(g.model), runs, len(g.fit))
    gdir = out / g.name
    gdir.mkdir(parents=True, exist_ok=True)
    (gdir / "diagnosis.json").write_text(json.dumps(d.to_dict(), indent=2))
    fig = plot(d, gdir / "diagnose.png") if html else None
    fit, hold = [str(p) for p in g.fit], [str(p) for p in g.held_out]
    page = run_report(robot.name, d, fit, hold, fig.name if fig else None)
    (gdir / "diagnose.md").write_text(page, encoding="utf-8")
    return d


def _import_ray() -> Any:
    try:
        import ray
    except ImportError:
        return None
    return ray


def run_many(
    directory: str | Path,
    out: str | Path,
    *,
    engine: str = "auto",
    address: str | None = None,
    workers: int = 0,
    concurrent_groups: int = 4,
    seed: int = 2026,
    progress: bool = True,
    html: bool = True,
    interval_refits: int = 0,
) -> list[GroupResult]:
    """Diagnose every group of ``DIR/manifest.toml``; write ``OUT/<group>/diagnosis.json`` (and
    ``.html``; a parallel robot's group ``diagnose.md`` and its figure), ``OUT/summary.json`` and
    ``OUT/summary.txt``. ``engine``: ``"ray"``, ``"serial"``
    or ``"auto"`` (Ray when installed). A group that fails is reported with its error; the others
    go on."""
    from cablekit.diagnose.report import write_html, write_json

    groups = load_manifest(directory)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    ray = _import_ray() if engine in ("auto", "ray") else None
    if engine == "ray" and ray is None:
        raise DataError("--engine ray needs Ray: pip install 'cablekit[scale]'")
    if address and ray is None:
        raise DataError("--address needs Ray: pip install 'cablekit[scale]'")
    started_ray = False
    executor = None
    if ray is not None:
        if not ray.is_initialized():
            kw: dict[str, Any] = {"address": address} if address else {"include_dashboard": False}
            if not address and workers:
                kw["num_cpus"] = workers
            ray.init(logging_level="ERROR", log_to_driver=False, **kw)
            started_ray = True
        executor = RayFits(ray)
    opts = Options(
        progress=False, workers=workers, seed=seed, executor=executor, interval_refits=interval_refits
    )

    def one(g: Group) -> GroupResult:
        t0 = time.perf_counter()
        drives = None
        if is_robot_file(g.model):
            try:
                drives = _robot_drives(g)
                if drives is None:  # no measured poses: the drum-side force check
                    d = _cdpr_group(g, ray if executor is not None else None, out, html)
                    return GroupResult(g, d, None, time.perf_counter() - t0)
            except Exception as exc:
                return GroupResult(g, None, f"{type(exc).__name__}: {exc}", time.perf_counter() - t0)
        try:
            if drives is not None:  # a parallel robot's drives at its measured poses, as a network
                spec, fit, hold = drives
            else:
                spec = load_model_spec(g.model)
                fit = [load_run(p, columns=list(spec.columns())) for p in g.fit]
                hold = [load_run(p, columns=list(spec.columns())) for p in g.held_out]
            res = diagnose(spec, fit, hold, opts)
        except Exception as exc:
            return GroupResult(g, None, f"{type(exc).__name__}: {exc}", time.perf_counter() - t0)
        if executor is not None and res.internal:
            executor.forget(res.internal["prep"])
        gdir = out / g.name
        gdir.mkdir(parents=True, exist_ok=True)
        write_json(res, gdir / "diagnosis.json")
        if html:
            write_html(res, gdir / "diagnosis.html")
        return GroupResult(g, res, None, time.perf_counter() - t0)

    results: dict[str, GroupResult] = {}
    try:
        with Progress(len(groups), "groups", enabled=progress) as bar:
            if executor is None:
                for g in groups:
                    results[g.name] = r = one(g)
                    bar.advance(f"{g.name}: {r.row()['verdict']}")
            else:
                with ThreadPoolExecutor(max_workers=max(1, min(concurrent_groups, len(groups)))) as pool:
                    futs = {pool.submit(one, g): g for g in groups}
                    for f in as_completed(futs):
                        r = f.result()
                        results[r.group.name] = r
                        bar.advance(f"{r.group.name}: {r.row()['verdict']}")
    finally:
        if started_ray and ray is not None:
            ray.shutdown()
    ordered = [results[g.name] for g in groups]
    rows = [r.row() for r in ordered]
    (out / "summary.json").write_text(
        json.dumps(
            {"engine": "ray" if executor is not None else "serial", "groups": rows}, indent=2, default=float
        )
    )
    (out / "summary.txt").write_text(summary_table(ordered) + "\n")
    return ordered


def summary_table(results: list[GroupResult]) -> str:
    """One line per group: verdict, selected effects, held-out share closed, flags, time."""
    lines = [f"{'group':<24} {'verdict':<20} {'closed':>7} {'time':>7}  selected / error"]
    for r in results:
        row = r.row()
        cf = row["held_out_closed"]
        what = ", ".join(row["selected"]) or "-"
        if row["error"]:
            what = row["error"]
        elif row["flags"]:
            what += f"  [{len(row['flags'])} channel flag(s)]"
        closed = f"{cf:7.1%}" if cf is not None else f"{'-':>7}"
        lines.append(f"{row['group']:<24} {row['verdict']:<20} {closed} {row['seconds']:6.1f}s  {what}")
    return "\n".join(lines)
