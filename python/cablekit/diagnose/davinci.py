"""The da Vinci Maryland forceps bench (O'Neill, Stephens, Kowalewski, RA-L 2018; data ODbL 1.0,
contents DbCL 1.0, from github.com/MRDLab/mis-tool-characterization): raw files → SI runs, a
nominal model calibrated on some conditions, and the diagnosis on others.

The files are **never copied into the project**; they are read from wherever the user keeps
them (``../shared/data/davinci-maryland-bench`` in our CI).

Bench: a back-end motor drives the instrument's input spindle (a ±30° sine at 0.1–0.5 Hz); the
spindle's cables close and open one jaw, which a front-end motor loads with a resistive torque
(10–40 %). Mapping onto the antagonistic joint:

* ``x_m = r_s·(θ_s − θ_s(0))`` with the spindle angle ``θ_s`` (CUI encoder, 8192 counts/rev)
  and an assumed spindle capstan radius ``r_s`` (only ratios are observable from angles and
  torques; 4 mm is assumed, which fixes the unit of forces);
* ``theta = −(θ_j − θ_j,ref)`` with the jaw angle ``θ_j`` (Maxon encoder, 4000 counts/rev; the
  reference is the calibration run's first sample, for every run): the jaw closes as the spindle
  turns positive;
* ``net_motor_force = −τ_s / r_s`` with the spindle torque ``τ_s`` (Futek, 3.9811e-5 N·m/count;
  its sign convention is opposite to the spindle angle, seen from the direction-dependent
  friction);
* ``tau_load = −τ_j`` with the jaw torque ``τ_j`` (Futek): the measured torque between the jaw
  and the front-end motor enters the joint as an external torque.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cablekit._files import bench_runs, text_runs
from cablekit.diagnose.data import Run
from cablekit.diagnose.spec import ModelSpec, model_spec_from_dict
from cablekit.errors import DataError
from cablekit.forceps.bench import BENCH_PATTERN, CITATION, FREQS, LOADS, condition, read_raw
from cablekit.forceps.posture import Posture, folder_posture, run_posture

__all__ = [
    "BENCH_PATTERN",
    "CITATION",
    "DEFAULT_SPLIT",
    "SPLITS",
    "BenchSplit",
    "bench_directory",
    "calibrate",
    "load_bench_run",
    "split_for",
]

SPINDLE_RADIUS = 4e-3  # m, assumed (see module docs)


def load_bench_run(
    path: str | Path, jaw_reference: float | None = None, posture: Posture | None = None
) -> Run:
    """One ``XY.TXT.gz`` file → a run with ``t``, ``x_m`` (m), ``theta`` (rad), ``net_motor_force``
    (N), ``tau_load`` (N·m) and the raw SI signals ``spindle_angle``, ``spindle_torque``,
    ``jaw_angle``, ``jaw_torque``, ``motor_current`` (back-end, A). ``jaw_reference`` (rad, raw
    encoder angle) is the jaw angle taken as ``theta = 0``; by default the run's first sample.
    ``x_m`` is the spindle's travel from the run's first sample (the encoder's zero is the
    bench's: ``tool4_load_sweep``'s runs start at 0, the paper's sweep's at 60°, and a wrist
    folder's stops share one frame, each stop's runs starting 30° further); the jaw encoder is
    not zeroed either, so one reference for all runs keeps their jaw angles comparable. ``posture`` (the
    folder's, :func:`cablekit.forceps.posture.folder_posture`) becomes the run's attributes, with
    the jaw stopping position of a ``ZXY`` name."""
    raw = read_raw(path)
    t, d = raw.t, raw.data
    th_s, tau_s = raw.spindle_angle, raw.spindle_torque
    th_j, tau_j = raw.jaw_angle, raw.jaw_torque
    # every count is within ±2^53 (read_raw): the conversions stay finite
    cols = {
        "x_m": SPINDLE_RADIUS * (th_s - th_s[0]),
        "theta": -(th_j - (th_j[0] if jaw_reference is None else jaw_reference)),
        "net_motor_force": -tau_s / SPINDLE_RADIUS,
        "tau_load": -tau_j,
        "spindle_angle": th_s,
        "spindle_torque": tau_s,
        "jaw_angle": th_j,
        "jaw_torque": tau_j,
        "motor_current": d[:, 3],
    }
    name = raw.name
    notes = list(raw.notes)
    freq, load = condition(name) if len(name) in (2, 3) else (None, None)
    if freq is not None:
        level = f"{LOADS[load]} %" if load is not None else f"level {name[-1]}"
        notes.append(f"{FREQS[freq]} Hz, {level} resistive torque")
    attributes: dict[str, float] = {}
    if posture is not None:
        here = run_posture(posture, name)
        attributes = here.attributes()
        if attributes:
            notes.append(f"wrist: {here.describe()}")
    return Run(name, t, {k: np.ascontiguousarray(v) for k, v in cols.items()}, notes, attributes)


def calibrate(runs: list[Run], warmup: float = 1.0) -> dict[str, Any]:
    """Nominal parameters from calibration runs by linear regressions (the "nominal model a user
    would build"): transmission ratio from the angles, then a linear elastic cable and viscous
    joint friction from the quasi-static balance ``ΔT = 2k·s`` and ``r·ΔT = b·θ̇ − τ_load``.
    No dry friction, hysteresis or losses: finding those is the diagnosis' job."""
    th = np.concatenate([r.column("theta")[int(warmup / r.dt) :] for r in runs])
    xm = np.concatenate([r.column("x_m")[int(warmup / r.dt) :] for r in runs])
    f = np.concatenate([r.column("net_motor_force")[int(warmup / r.dt) :] for r in runs])
    load = np.concatenate([r.column("tau_load")[int(warmup / r.dt) :] for r in runs])
    w = np.concatenate([np.gradient(r.column("theta"), r.dt)[int(warmup / r.dt) :] for r in runs])
    if th.size < 100:
        raise DataError(
            f"calibration runs {[r.name for r in runs]}: {th.size} samples after the {warmup:g} s warm-up "
            "(need at least 100)"
        )
    # θ = x_m / r + c: ratio
    a = np.linalg.lstsq(np.column_stack([xm, np.ones_like(xm)]), th, rcond=None)[0]
    if not (np.ptp(xm) > 0.0 and np.isfinite(a[0]) and a[0] > 0.0):
        raise DataError(
            f"calibration runs {[r.name for r in runs]}: the jaw does not follow the spindle "
            f"(fitted jaw/spindle slope {a[0]:.3g}); check the encoder columns and signs"
        )
    radius = 1.0 / a[0]
    # quasi-static joint balance: r·F = b·θ̇ − τ_load + c  → b
    m = np.column_stack([w / radius, -load / radius, np.ones_like(w)])
    coef = np.linalg.lstsq(m, f, rcond=None)[0]
    viscous = max(coef[0], 0.0)
    # cable: F = 2k·s with s = x_m − r·θ (both cables taut)
    s = xm - radius * th
    k2 = np.linalg.lstsq(np.column_stack([s, np.ones_like(s)]), f, rcond=None)[0][0]
    stiffness = max(k2 / 2.0, 1e3)
    params = {
        "radius": float(radius),
        "stiffness": float(stiffness),
        "inertia": 1e-5,
        "damping": 0.0,
        "pretension": 20.0,
        "viscous": float(viscous),
        "smoothing": 0.05,
    }
    return params


@dataclass(frozen=True)
class BenchSplit:
    """Which bench files calibrate the nominal, which the diagnosis fits, which it holds out
    (file stems, e.g. ``"43"`` for 0.5 Hz at 40 % load)."""

    calibration: tuple[str, ...]
    fit: tuple[str, ...]
    held_out: tuple[str, ...]

    def __post_init__(self) -> None:
        for what, names in (
            ("calibration", self.calibration),
            ("fit", self.fit),
            ("held-out", self.held_out),
        ):
            if not names:
                raise DataError(f"bench split: no {what} runs given")
        both = set(self.held_out) & (set(self.fit) | set(self.calibration))
        if both:
            raise DataError(f"bench split: run(s) {sorted(both)} are both held out and fitted/calibrated")


#: calibrate at the slowest, lightest condition; fit at middle frequencies and loads; hold out the
#: fastest frequency at the heaviest and the lightest load (new frequency and new load)
DEFAULT_SPLIT = BenchSplit(calibration=("00",), fit=("11", "22"), held_out=("43", "40"))
#: named splits (``--bench-split``): ``frequency`` holds out 0.5 Hz at the fit runs' loads (20 and
#: 30 %), ``load`` holds out 40 % at the fit runs' frequencies (0.2 and 0.3 Hz)
SPLITS = {
    "default": DEFAULT_SPLIT,
    "frequency": BenchSplit(calibration=("00",), fit=("11", "22"), held_out=("41", "42")),
    "load": BenchSplit(calibration=("00",), fit=("11", "22"), held_out=("13", "23")),
}


def _code(stem: str) -> tuple[str, int, int] | None:
    """``(prefix, frequency index, load index)`` of a run named ``XY`` or ``ZXY``."""
    if len(stem) in (2, 3) and stem.isascii() and stem.isdigit():
        return stem[:-2], int(stem[-2]), int(stem[-1])
    return None


def split_for(split: BenchSplit, stems: set[str] | dict[str, Path]) -> BenchSplit:
    """``split`` as it applies to a folder whose runs are ``stems``: as named when they all exist;
    in a wrist folder (``ZXY`` names) the same conditions at its first jaw stopping position
    (``Z = 0``) when they all exist there; otherwise — for the default split only — the same
    design on the conditions the folder has: calibrated at its slowest, lightest run, held out
    at its fastest motion under the heaviest and the lightest load (the heaviest alone when
    there is one frequency), fitted on up to two runs between them. Other splits whose runs are
    missing are returned as named (:func:`bench_file` then names what is missing)."""
    names = split.calibration + split.fit + split.held_out
    have = set(stems)
    if all(n in have for n in names):
        return split
    codes = {st: c for st in have if (c := _code(st)) is not None}
    prefixes = sorted({c[0] for c in codes.values()})
    if not prefixes:
        return split
    z = prefixes[0]
    if all(z + n in have for n in names):
        return BenchSplit(
            *(tuple(z + n for n in part) for part in (split.calibration, split.fit, split.held_out))
        )
    if split != DEFAULT_SPLIT:
        return split
    grid = {(c[1], c[2]): st for st, c in codes.items() if c[0] == z}
    xs, ys = sorted({x for x, _ in grid}), sorted({y for _, y in grid})
    cal = min(grid, key=lambda k: (k[0], k[1]))
    hold = [k for k in ((xs[-1], ys[-1]), (xs[-1], ys[0])) if k in grid and k != cal]
    hold = list(dict.fromkeys(hold))
    mid = 0.5 * (ys[0] + ys[-1])
    rest = sorted(
        (k for k in grid if k != cal and k not in hold), key=lambda k: (abs(k[1] - mid), -k[0], k[1])
    )
    fit: list[tuple[int, int]] = []
    for k in rest:
        if len(fit) < 2 and all(k[1] != f[1] for f in fit):
            fit.append(k)
    if not hold or not fit:
        raise DataError(
            f"bench folder with runs {sorted(have)}: too few conditions for a split (calibration, fit "
            "and held-out runs); name them with --bench-calibration, --bench-fit and --bench-holdout"
        )
    return BenchSplit((grid[cal],), tuple(grid[k] for k in fit), tuple(grid[k] for k in hold))


def bench_directory(directory: str | Path, names: tuple[str, ...] = ()) -> Path:
    """The folder that holds the bench files: ``directory`` itself, or its ``tool4_load_sweep``
    (the shared layout), or its only sub-folder with bench files — files named by their
    condition digits, or any of the stems ``names`` a split asks for (a missing one is then named
    by :func:`bench_file`). A clear error names the expected file pattern otherwise."""
    directory = Path(directory)
    if not directory.is_dir():
        raise DataError(f"{directory}: not a folder (expected a bench folder with {BENCH_PATTERN})")
    candidates = [directory / "tool4_load_sweep", directory]
    candidates += [d for d in sorted(directory.iterdir()) if d.is_dir() and d.name != "tool4_load_sweep"]
    with_files = [d for d in candidates if bench_runs(d) or any(n in text_runs(d) for n in names)]
    if not with_files:
        raise DataError(f"{directory}: no bench files found; expected {BENCH_PATTERN}")
    if with_files[0] in candidates[:2] or len(with_files) == 1:
        return with_files[0]
    raise DataError(
        f"{directory}: several sub-folders hold bench files ({', '.join(d.name for d in with_files)}); "
        "pass one of them"
    )


def bench_file(folder: Path, stem: str) -> Path:
    """The file of run ``stem`` in a bench folder (``.TXT.gz`` or ``.TXT``)."""
    stems = text_runs(folder)
    if stem not in stems:
        have = ", ".join(sorted(stems)) or "none"
        raise DataError(f"{folder}: no bench run {stem!r} (have {have}); expected {BENCH_PATTERN}")
    return stems[stem]


def bench_spec(params: dict[str, Any], warmup: float = 1.0) -> ModelSpec:
    return model_spec_from_dict(
        {
            "model": "antagonistic_joint",
            "parameters": params,
            "inputs": {"x_m": "x_m", "external": "tau_load"},
            "outputs": {"net_motor_force": "net_motor_force", "theta": "theta"},
            "diagnosis": {"warmup": warmup},
        },
        source="da Vinci Maryland bench (calibrated nominal)",
    )


def prepare_bench(
    directory: str | Path,
    split: BenchSplit = DEFAULT_SPLIT,
    decimate: int = 1,
    posture: Posture | None = None,
) -> tuple[ModelSpec, list[Run], list[Run]]:
    """Load the split (:func:`split_for` the folder's runs), calibrate the nominal on its
    calibration runs, return (spec, fit, held-out). Every run carries the wrist posture — the
    folder README's (:func:`~cablekit.forceps.posture.folder_posture`) or ``posture`` — and its
    jaw stopping position as attributes; the nominal's ``conditions`` are its calibration runs',
    so the diagnosis warns about a run at a posture the nominal was not calibrated at."""
    sub = bench_directory(directory, split.calibration + split.fit + split.held_out)
    split = split_for(split, text_runs(sub))
    where = posture if posture is not None else folder_posture(sub)
    first = load_bench_run(bench_file(sub, split.calibration[0]))
    jaw_ref = float(first.column("jaw_angle")[0])

    def load(name: str) -> Run:
        run = load_bench_run(bench_file(sub, name), jaw_reference=jaw_ref, posture=where)
        if decimate > 1:
            run = Run(
                run.name,
                run.t[::decimate],
                {k: v[::decimate].copy() for k, v in run.columns.items()},
                run.notes,
                dict(run.attributes),
            )
        return run

    cal = [load(n) for n in split.calibration]
    fit = [load(n) for n in split.fit]
    hold = [load(n) for n in split.held_out]
    spec = bench_spec(calibrate(cal))
    conditions: dict[str, set[float]] = {}
    for r in cal:
        for k, v in r.attributes.items():
            conditions.setdefault(k, set()).add(v)
    spec.conditions = {k: tuple(sorted(v)) for k, v in conditions.items()}
    return spec, fit, hold


def describe(spec: ModelSpec) -> str:
    p = spec.parameters
    return (
        f"nominal (calibrated): joint radius {p['radius'] * 1e3:.3f} mm "
        f"(spindle {SPINDLE_RADIUS * 1e3:g} mm, "
        f"ratio {SPINDLE_RADIUS / p['radius']:.3f}), cable stiffness {p['stiffness']:.4g} N/m, "
        f"viscous {p['viscous']:.3g} N·m·s/rad, pretension {p['pretension']:g} N (assumed), "
        f"inertia {p['inertia']:g} kg·m² (assumed)"
    )
