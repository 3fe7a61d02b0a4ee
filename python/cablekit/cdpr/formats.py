"""The parallel robots' run-file formats: trajectory tables (the poses a robot is driven
through, with optional external wrenches) and recorded runs (drum angles, motor currents,
winch-side sensors, optional measured poses). The command line, the diagnosis and the tension
reports read them here, and nothing here imports them back."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cablekit._args import checked, choice
from cablekit.cdpr import Robot
from cablekit.errors import DataError

__all__ = [
    "POSE_COLUMNS",
    "WRENCH_COLUMNS",
    "RunFile",
    "Trajectory",
    "bag_topics",
    "load_cdpr_run",
    "read_trajectory",
]

#: the per-cable columns of a run: drum angle (rad), motor current (A), winch-side sensor (N)
DRUM_GROUPS = ("alpha", "current", "sensor")

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
@checked
def bag_topics(table: Mapping[str, Any], robot: Robot, where: str = "topics") -> dict[str, str]:
    """The bag fields (``"/topic:field"``, :mod:`cablekit.bags`) of a run's columns from a
    ``[topics]`` table: a group ``alpha``, ``current`` or ``sensor`` names an array field whose
    entries ``0..m−1`` are the cables' (``alpha = "/winches:position"``) or a list of ``m`` fields;
    ``alpha_j``, ``current_j``, ``sensor_j`` and the pose columns name one field each (and
    override a group's entry). Unknown keys, a list of another length and a value that is not a
    field are :class:`~cablekit.errors.DataError` errors naming them."""
    from cablekit.bags import parse_field

    m = robot.n_cables
    pose = POSE_COLUMNS[robot.motion]
    singles = {f"{k}_{j + 1}" for k in DRUM_GROUPS for j in range(m)} | set(pose)
    if not isinstance(table, Mapping):
        raise DataError(f'{where}: a table of column = "/topic:field", got {type(table).__name__}')
    unknown = sorted(k for k in table if k not in singles and k not in DRUM_GROUPS)
    if unknown:
        raise DataError(
            f"{where}: unknown key(s) {unknown}; known: {', '.join(DRUM_GROUPS)}, their columns "
            f"alpha_j/current_j/sensor_j (j = 1..{m}) and the pose columns {', '.join(pose)}"
        )

    def field(v: Any, key: str) -> str:
        if not isinstance(v, str):
            raise DataError(f'{where}.{key}: a bag field "/topic:field", got {v!r}')
        try:
            parse_field(v)
        except DataError as exc:
            raise DataError(f"{where}.{key}: {exc}") from None
        return v

    out: dict[str, str] = {}
    for group in DRUM_GROUPS:
        v = table.get(group)
        if v is None:
            continue
        if isinstance(v, list):
            if len(v) != m:
                raise DataError(f"{where}.{group}: {m} fields (one per cable), got {len(v)}")
            out.update({f"{group}_{j + 1}": field(f, f"{group}[{j}]") for j, f in enumerate(v)})
        else:
            base = field(v, group)
            if base.endswith("]"):
                raise DataError(
                    f"{where}.{group}: an array field without an index (its entries are the cables')"
                )
            out.update({f"{group}_{j + 1}": f"{base}[{j}]" for j in range(m)})
    out.update({k: field(v, k) for k, v in table.items() if k in singles})
    return out


@checked
def load_cdpr_run(path: str | Path, robot: Robot, *, topics: Mapping[str, Any] | None = None) -> RunFile:
    """A run table (CSV, ``.csv.gz`` or Parquet) for ``robot``: ``t``; per cable ``j = 1..m``
    ``alpha_j``, ``current_j`` and ``sensor_j``; and, for the length channel, all the pose columns
    (planar ``x, y, theta``; spatial ``x, y, z, roll, pitch, yaw``) or none. Missing, unknown or
    duplicate columns, non-finite cells, a time that does not increase and fewer than 100 rows
    are :class:`~cablekit.errors.DataError` errors naming them. Jittered time stamps are put on
    a uniform grid as a joint model's run files are (:func:`cablekit.diagnose.data.uniform_time`:
    kept on their clock when only the stamps jitter, else resampled), with a note.

    A ROS 2 bag (a rosbag2 folder, or its ``.mcap``/``.db3``) is read through ``topics``, the
    ``[topics]`` table of :func:`bag_topics` (which fields carry which columns), onto the bag's
    time base (:func:`cablekit.bags.read_bag`), and then checked as a table."""
    from cablekit.bags import is_bag, read_bag
    from cablekit.diagnose.data import read_table, require_finite_cells, uniform_time

    p = Path(path)
    bag_notes: list[str] = []
    if is_bag(p):
        if topics is None:
            raise DataError(f"{p}: a ROS 2 bag needs a [topics] table naming the field of each column")
        fields = bag_topics(topics, robot)
        if not fields:
            raise DataError(f"{p}: the [topics] table names no column")
        names = list(fields)
        unique = list(dict.fromkeys(fields.values()))
        _, bag_data, bag_notes = read_bag(p, unique)
        at = {f: i + 1 for i, f in enumerate(unique)}
        header = ["t", *names]
        data = np.column_stack([bag_data[:, 0], *(bag_data[:, at[fields[c]]] for c in names)])
    else:
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
    notes: list[str] = list(bag_notes)
    t, data = uniform_time(str(p), data, ti, notes)
    if len(t) < 100:
        raise DataError(f"{p}: needs at least 100 samples on a uniform grid, got {len(t)}")
    t = np.ascontiguousarray(t)
    col = {c: data[:, header.index(c)] for c in header}

    def block(kind: str) -> np.ndarray:
        return np.ascontiguousarray(np.column_stack([col[f"{kind}_{j + 1}"] for j in range(m)]))

    poses = np.ascontiguousarray(np.column_stack([col[c] for c in pose])) if given else None
    return RunFile(t, block("alpha"), block("current"), block("sensor"), poses, tuple(notes))
