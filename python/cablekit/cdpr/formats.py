"""The parallel robots' run-file formats: trajectory tables (the poses a robot is driven
through, with optional external wrenches) and recorded runs (drum angles, motor currents,
winch-side sensors, optional measured poses). The command line, the diagnosis and the tension
reports read them here, and nothing here imports them back."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cablekit._args import checked, choice
from cablekit.cdpr import Robot
from cablekit.errors import DataError

__all__ = ["POSE_COLUMNS", "WRENCH_COLUMNS", "RunFile", "Trajectory", "load_cdpr_run", "read_trajectory"]

#: trajectory CSV columns: the pose, then optional external wrench columns and time
POSE_COLUMNS = {"planar": ("x", "y", "theta"), "spatial": ("x", "y", "z", "roll", "pitch", "yaw")}
WRENCH_COLUMNS = {"planar": ("fx", "fy", "mz"), "spatial": ("fx", "fy", "fz", "mx", "my", "mz")}


@dataclass(frozen=True)
class Trajectory:
    """Poses ``(T, n)``, optional external wrenches ``(T, n)`` and times ``(T,)``."""

    poses: np.ndarray
    wrenches: np.ndarray | None
    t: np.ndarray | None


@checked
def read_trajectory(path: str | Path, motion: str) -> Trajectory:
    """A trajectory table (CSV, ``.csv.gz`` or Parquet, read like a run file): the pose columns
    (planar ``x, y, theta``; spatial ``x, y, z, roll, pitch, yaw``), optionally all the wrench
    columns (planar ``fx, fy, mz``; spatial ``fx, fy, fz, mx, my, mz``) and ``t``. Other
    columns, missing ones and cells that are not finite numbers are ``DataError``s naming them."""
    from cablekit.diagnose.data import read_table, require_finite_cells

    choice(motion, "motion", sorted(POSE_COLUMNS))
    p = Path(path)
    header, data = read_table(p)
    pose_cols, wrench_cols = POSE_COLUMNS[motion], WRENCH_COLUMNS[motion]
    missing = [c for c in pose_cols if c not in header]
    if missing:
        raise DataError(f"{p}: missing column(s) {missing} (a {motion} pose is {', '.join(pose_cols)})")
    known = {*pose_cols, *wrench_cols, "t"}
    unknown = [c for c in header if c not in known]
    if unknown:
        raise DataError(f"{p}: unknown column(s) {unknown}; known: {sorted(known)}")
    given = [c for c in wrench_cols if c in header]
    if given and len(given) != len(wrench_cols):
        raise DataError(f"{p}: give all wrench columns {list(wrench_cols)} or none, got {given}")
    if data.shape[0] == 0:
        raise DataError(f"{p}: no rows after the header")
    require_finite_cells(p, header, data)
    col = {c: data[:, header.index(c)] for c in header}
    return Trajectory(
        poses=np.ascontiguousarray(np.column_stack([col[c] for c in pose_cols])),
        wrenches=np.ascontiguousarray(np.column_stack([col[c] for c in wrench_cols])) if given else None,
        t=col.get("t"),
    )


@dataclass(frozen=True)
class RunFile:
    """A CDPR run read from a table: times (s), drum angles (rad), motor currents (A), the
    winch-side sensors (N), each ``(T, m)``, and the measured poses ``(T, n)`` if given."""

    t: np.ndarray
    alpha: np.ndarray
    current: np.ndarray
    sensor: np.ndarray
    poses: np.ndarray | None
    #: what the loader did to the table (a resampling onto a uniform time grid)
    notes: tuple[str, ...] = ()


@checked
def load_cdpr_run(path: str | Path, robot: Robot) -> RunFile:
    """A run table (CSV, ``.csv.gz`` or Parquet) for ``robot``: ``t``; per cable ``j = 1..m``
    ``alpha_j``, ``current_j`` and ``sensor_j``; and, for the length channel, all the pose columns
    (planar ``x, y, theta``; spatial ``x, y, z, roll, pitch, yaw``) or none. Missing, unknown or
    duplicate columns, non-finite cells, a time that does not increase and fewer than 100 rows
    are :class:`~cablekit.errors.DataError` errors naming them. Jittered time stamps are put on
    a uniform grid as a joint model's run files are (:func:`cablekit.diagnose.data.uniform_time`:
    kept on their clock when only the stamps jitter, else resampled), with a note."""
    from cablekit.diagnose.data import read_table, require_finite_cells, uniform_time

    p = Path(path)
    header, data = read_table(p)
    m = robot.n_cables
    drums = [f"{k}_{j + 1}" for k in ("alpha", "current", "sensor") for j in range(m)]
    pose = list(POSE_COLUMNS[robot.motion])
    if len(set(header)) != len(header):
        raise DataError(f"{p}: duplicate column(s) {sorted({c for c in header if header.count(c) > 1})}")
    missing = [c for c in ["t", *drums] if c not in header]
    if missing:
        raise DataError(f"{p}: missing column(s) {missing} (a run of {robot.name!r} has {m} cables)")
    unknown = [c for c in header if c not in {"t", *drums, *pose}]
    if unknown:
        raise DataError(f"{p}: unknown column(s) {unknown}; known: t, alpha_j, current_j, sensor_j, {pose}")
    given = [c for c in pose if c in header]
    if given and given != pose:
        raise DataError(f"{p}: give all pose columns {pose} or none, got {given}")
    if data.shape[0] < 100:
        raise DataError(f"{p}: needs at least 100 rows, got {data.shape[0]}")
    require_finite_cells(p, header, data)
    ti = header.index("t")
    if not (np.diff(data[:, ti]) > 0).all():
        k = int(np.argmax(np.diff(data[:, ti]) <= 0))
        raise DataError(f"{p}: t must increase (row {k + 3} is not after row {k + 2})")
    notes: list[str] = []
    t, data = uniform_time(str(p), data, ti, notes)
    if len(t) < 100:
        raise DataError(f"{p}: needs at least 100 samples on a uniform grid, got {len(t)}")
    t = np.ascontiguousarray(t)
    col = {c: data[:, header.index(c)] for c in header}

    def block(kind: str) -> np.ndarray:
        return np.ascontiguousarray(np.column_stack([col[f"{kind}_{j + 1}"] for j in range(m)]))

    poses = np.ascontiguousarray(np.column_stack([col[c] for c in pose])) if given else None
    return RunFile(t, block("alpha"), block("current"), block("sensor"), poses, tuple(notes))
