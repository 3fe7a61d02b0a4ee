"""ROS 2 logs in (issue #40 §1): a rosbag2 recording (SQLite3 or MCAP) read as a run table.

A model file names a bag's signals where it would name CSV columns: ``"/topic:field"``, the
field a dotted path into the message with optional indices — ``"/joint_states:position[2]"``,
``"/tension/drive:data"``, ``"/wrench:wrench.force.x"``. :func:`read_bag` reads those fields and
puts them on one time base: each topic's message times are its header stamps when its messages
have a ``header`` (``std_msgs/Header``), the recorder's receive times otherwise (the notes say
which); the topic with the most messages is the base, every other field is interpolated linearly
onto it, and the table is cut to the span every topic covers. The run loader then treats it as
it treats a CSV file (:func:`cablekit.diagnose.data.from_arrays`: jitter, gaps, duplicates).
:func:`read_signals` gives the estimators' arrays (``(T,)`` or ``(T, k)`` on that uniform time
base) by name, e.g. a transmission's motor angles and torques for
:func:`cablekit.estimate.estimate_joint_states`.

Types come from the bag (MCAP and SQLite3 version 9 store each type's definition) or from ROS 2
Humble's standard set. Needs the ``ros`` extra (``pip install 'cablekit[ros]'``: ``rosbags``, which
needs no ROS installation). Every defect is a :class:`~cablekit.errors.DataError` naming the bag
and the topic: a bag that is not one, a truncated file, a missing topic, a field the message does
not have or that is not a number, a topic with fewer than two messages, header stamps that go
backwards, a type whose definition the bag does not carry.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cablekit._args import checked, instance
from cablekit.errors import DataError

__all__ = ["BagSignals", "is_bag", "parse_field", "read_bag", "read_signals"]

_FIELD = re.compile(r"^(/[^:\s]*):([A-Za-z_]\w*(?:\[\d+\])*(?:\.[A-Za-z_]\w*(?:\[\d+\])*)*)$")
_PART = re.compile(r"([A-Za-z_]\w*)((?:\[\d+\])*)")


@checked
def is_bag(path: str | Path) -> bool:
    """Whether ``path`` is a rosbag2 recording: a folder with ``metadata.yaml``, or an ``.mcap``
    or ``.db3`` file in such a folder."""
    p = Path(path)
    if p.is_dir():
        return (p / "metadata.yaml").is_file()
    return p.suffix in (".mcap", ".db3") and (p.parent / "metadata.yaml").is_file()


@checked
def parse_field(name: str) -> tuple[str, list[str | int]]:
    """``"/topic:a.b[2]"`` → ``("/topic", ["a", "b", 2])``; anything else is a
    :class:`DataError` saying the form."""
    m = _FIELD.match(name)
    if not m:
        raise DataError(
            f"{name!r} is not a bag field: write /topic:field, the field a dotted path with optional "
            'indices (e.g. "/joint_states:position[2]", "/wrench:wrench.force.x")'
        )
    path: list[str | int] = []
    for part in m.group(2).split("."):
        pm = _PART.fullmatch(part)
        assert pm is not None  # (the whole pattern matched)
        path.append(pm.group(1))
        path += [int(i) for i in re.findall(r"\[(\d+)\]", pm.group(2))]
    return m.group(1), path


def _value(msg: Any, path: list[str | int], where: str) -> float:
    v = msg
    for step in path:
        if isinstance(step, str):
            if not hasattr(v, step) or step.startswith("_"):
                fields = [f for f in getattr(v, "__dataclass_fields__", {}) if not f.startswith("_")]
                raise DataError(f"{where}: the message has no field {step!r} (fields: {fields})")
            v = getattr(v, step)
        else:
            try:
                v = v[step]
            except (IndexError, TypeError, KeyError):
                n = len(v) if hasattr(v, "__len__") else "no"
                raise DataError(f"{where}: index {step} is out of range ({n} elements)") from None
    if isinstance(v, bool | np.bool_) or not isinstance(v, int | float | np.integer | np.floating):
        raise DataError(f"{where}: the field is not a number (got {type(v).__name__})")
    return float(v)


def _stamp(msg: Any) -> int | None:
    header = getattr(msg, "header", None)
    stamp = getattr(header, "stamp", None)
    if stamp is None or not hasattr(stamp, "sec"):
        return None
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


@checked
def read_bag(path: str | Path, fields: list[str]) -> tuple[list[str], NDArray[np.float64], list[str]]:
    """The ``fields`` of the bag at ``path`` on one time base (see the module): ``(header, rows,
    notes)``, the header ``["t", *fields]``, ``t`` in seconds from the first common sample."""
    instance(fields, "fields", list)
    if not fields:
        raise DataError(f"{path}: name the bag fields to read")
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.rosbag2 import Reader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:  # pragma: no cover - the [ros] extra is in the test extra
        raise DataError("reading ROS 2 bags needs the ros extra: pip install 'cablekit[ros]'") from None
    p = Path(path)
    folder = p if p.is_dir() else p.parent
    if not is_bag(folder):
        raise DataError(
            f"{path}: not a rosbag2 recording (a folder with metadata.yaml and its .mcap or .db3)"
        )
    wanted = {f: parse_field(f) for f in fields}
    topics = sorted({t for t, _ in wanted.values()})
    series: dict[str, tuple[NDArray[np.int64], dict[str, list[float]]]] = {}
    notes = []
    store = get_typestore(Stores.ROS2_HUMBLE)
    try:
        # every topic's type defined in the bag or a standard one (the reader builds every
        # type of the bag when it opens it)
        with Reader(folder) as low:
            present = {c.topic: c for c in low.connections}
        for topic in topics:
            if topic not in present:
                raise DataError(f"{path}: no topic {topic!r} in the bag (topics: {sorted(present)})")
        for topic, conn in present.items():
            defined = conn.msgdef is not None and bool(getattr(conn.msgdef, "data", ""))
            if not defined and conn.msgtype not in store.types:
                raise DataError(
                    f"{path}: topic {topic!r} has type {conn.msgtype!r}, whose definition the bag does not "
                    "carry and which is not a standard ROS 2 type (record with a definition: MCAP, or "
                    "SQLite3 of version 9)"
                )
    except DataError:
        raise
    except Exception as exc:  # a truncated or corrupt file, a bad metadata.yaml
        raise DataError(f"{path}: the bag cannot be read: {type(exc).__name__}: {exc}") from None
    try:
        with AnyReader([folder], default_typestore=store) as reader:
            present = {c.topic: c for c in reader.connections}
            for topic in topics:
                conn = present[topic]
                mine = [(f, fp) for f, (t, fp) in wanted.items() if t == topic]
                stamps: list[int] = []
                values: dict[str, list[float]] = {f: [] for f, _ in mine}
                headers = None
                try:
                    for c, received, raw in reader.messages(connections=[conn]):
                        msg = reader.deserialize(raw, c.msgtype)
                        s = _stamp(msg)
                        if headers is None:
                            headers = s is not None
                        stamps.append(s if headers and s is not None else int(received))
                        for f, fp in mine:
                            values[f].append(_value(msg, fp, f"{path}: {f} ({c.msgtype})"))
                except DataError:
                    raise
                except Exception as exc:  # a type without its definition, a corrupt message
                    why = f"{type(exc).__name__}: {exc}"
                    raise DataError(
                        f"{path}: topic {topic!r} ({conn.msgtype}) cannot be read: {why}"
                    ) from None
                if len(stamps) < 2:
                    raise DataError(f"{path}: topic {topic!r} has {len(stamps)} message(s); a run needs many")
                st = np.array(stamps, dtype=np.int64)
                back = np.flatnonzero(np.diff(st) < 0)
                if back.size:
                    k = int(back[0])
                    raise DataError(
                        f"{path}: topic {topic!r}: {'header stamps' if headers else 'receive times'} go "
                        f"backwards at message {k + 2} ({st[k]} ns then {st[k + 1]} ns)"
                    )
                notes.append(f"topic {topic}: {'header stamps' if headers else 'receive times (no header)'}")
                series[topic] = (st, values)
    except DataError:
        raise
    except Exception as exc:  # a corrupt file the first pass did not read far enough to see
        raise DataError(f"{path}: the bag cannot be read: {type(exc).__name__}: {exc}") from None
    base = max(topics, key=lambda t: (len(series[t][0]), -topics.index(t)))
    t0 = max(int(series[t][0][0]) for t in topics)
    t1 = min(int(series[t][0][-1]) for t in topics)
    st = series[base][0]
    keep = (st >= t0) & (st <= t1)
    if keep.sum() < 2:
        raise DataError(f"{path}: the topics {topics} do not overlap in time")
    t_ns = st[keep] - st[keep][0]
    cols = [t_ns.astype(np.float64) * 1e-9]
    for f in fields:
        topic = wanted[f][0]
        ts, values = series[topic]
        v = np.asarray(values[f], dtype=np.float64)
        if topic == base:
            cols.append(v[keep])
        else:
            # interpolated onto the base topic's times, both relative to one origin (exact in float64)
            cols.append(np.interp((st[keep] - t0).astype(np.float64), (ts - t0).astype(np.float64), v))
    if len(topics) > 1:
        notes.append(f"fields of other topics interpolated onto {base}'s times")
    return ["t", *fields], np.column_stack(cols), notes


@dataclass(frozen=True)
class BagSignals:
    """Named signals of a bag on one uniform time base: ``t`` ``(T,)`` s from the first common
    sample, its period ``dt``, each signal ``(T,)`` (one field) or ``(T, k)`` (a list of ``k``
    fields), and what the loader did (``notes``: header stamps or receive times per topic, an
    interpolation, a resampling). ``signals["q_m"]`` is a signal."""

    t: NDArray[np.float64]
    dt: float
    arrays: dict[str, NDArray[np.float64]] = field(repr=False)
    notes: tuple[str, ...] = ()

    def __getitem__(self, name: str) -> NDArray[np.float64]:
        try:
            return self.arrays[name]
        except KeyError:
            raise DataError(f"no signal {name!r}; the bag was read for {sorted(self.arrays)}") from None


@checked
def read_signals(path: str | Path, signals: Mapping[str, str | list[str]]) -> BagSignals:
    """The ``signals`` of the bag at ``path`` — each name a field ``"/topic:field"`` or a list of
    fields (its columns) — on one uniform time base: :func:`read_bag`, then the run loader's
    handling of a table (:func:`cablekit.diagnose.data.load_run`: jittered stamps put on a
    uniform grid, gaps refused), so that the arrays go straight into an estimator::

        s = read_signals("run_bag", {"q_m": [f"/motors:position[{i}]" for i in range(3)],
                                     "tau_m": [f"/motors:effort[{i}]" for i in range(3)]})
        estimate_joint_states(model, s["q_m"], s["tau_m"], s.dt)

    An empty mapping or list, a value that is not a field, and every defect :func:`read_bag`
    names are :class:`~cablekit.errors.DataError` errors."""
    from cablekit.diagnose.data import load_run

    if not signals:
        raise DataError(f"{path}: name the signals to read (name = field or list of fields)")
    fields: dict[str, list[str]] = {}
    for name, v in signals.items():
        group = [v] if isinstance(v, str) else v
        if not isinstance(group, list) or not group or not all(isinstance(f, str) for f in group):
            raise DataError(
                f'signal {name!r}: a bag field "/topic:field" or a non-empty list of them, got {v!r}'
            )
        for f in group:
            parse_field(f)
        fields[name] = group
    if not is_bag(path):
        raise DataError(
            f"{path}: not a rosbag2 recording (a folder with metadata.yaml and its .mcap or .db3)"
        )
    unique = list(dict.fromkeys(f for group in fields.values() for f in group))
    run = load_run(path, columns=unique)
    arrays = {}
    for name, group in fields.items():
        cols = [run.column(f) for f in group]
        arrays[name] = np.ascontiguousarray(
            cols[0] if isinstance(signals[name], str) else np.column_stack(cols)
        )
    t = np.ascontiguousarray(run.t)
    return BagSignals(t, float(t[1] - t[0]), arrays, tuple(run.notes))
