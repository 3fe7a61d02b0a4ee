"""Recorded runs: loading, validation and the unit checks the diagnosis relies on.

A run is a table with a header row (columns separated by commas, tabs, semicolons or spaces, as
the header shows; a decimal comma where they are not commas): a time column ``t`` in seconds
and signal columns in SI units (m, rad, N, N·m; others declared in the model file's ``[units]``).
Which columns feed the model and which are measurements is said by the model file (see
:mod:`cablekit.diagnose.spec`), not by the run.

Handling, all of it explicit (never a silent drop):

* missing values (empty cells, NaN, inf) → :class:`~cablekit.errors.DataError` naming the column
  and the first row;
* time not strictly increasing → ``DataError`` with the row; exactly duplicated rows (same time,
  same values, as logging software sometimes writes) are removed **and counted** in
  ``Run.notes``; a repeated time with different values is an error;
* non-uniform sampling (intervals that vary by more than 1 % of the median ``dt``) → a uniform
  grid at ``dt``, **noted** in ``Run.notes`` (printed by the CLI, in the report's metadata). Which
  of two loggers wrote the run is read off the signals (:func:`_only_stamps_jitter`): a loop
  without a real-time clock takes its rows at the stamped times (the rows are resampled by
  linear interpolation), a host stamping a DAQ's uniformly clocked rows on arrival only moves
  the stamps (the rows are kept and ``t`` replaced by the grid). Either way a gap of up to
  ``MAX_FILLED`` dropped samples is filled by linear interpolation; a longer gap in a clocked
  log → ``DataError`` naming its rows (split the run there into two files). Times on no clock at
  all (a variable-step solver's output: steps that shrink and grow with the dynamics) are
  resampled at their stamps, as many samples as rows at their mean step;
* units that are detectably wrong: time in milliseconds (median interval ≥ 0.5 with integer
  steps), angles in degrees (a ``rad`` column beyond ±4π), displacements in millimetres (an ``m``
  column beyond ±0.5 m) → ``DataError`` saying which unit it looks like.
"""

from __future__ import annotations

import csv
import io
import math
import warnings
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from cablekit.errors import DataError

__all__ = ["Run", "check_units", "common_interval", "load_run", "scored_start", "uniform_time"]


@dataclass
class Run:
    """One recorded run: uniform time base and named columns (SI units)."""

    name: str
    t: NDArray[np.float64]
    columns: dict[str, NDArray[np.float64]]
    notes: list[str] = field(default_factory=list)
    #: conditions of the run the model may or may not know, by name (e.g. the wrist posture of a
    #: bench run: ``pitch_deg``, ``roll_deg``, ``yaw_index``); compared with the nominal's
    #: :attr:`~cablekit.diagnose.spec.ModelSpec.conditions`
    attributes: dict[str, float] = field(default_factory=dict)
    #: seconds of history at the run's start: replayed (the initial state is taken at its first
    #: sample) but neither fitted nor scored — the fit run's end before a held-out run that
    #: continues it, so that a state with memory (creep, a pulley's pre-sliding, a sensor's lag)
    #: enters the scored part as it was, not from rest (:meth:`segment`'s ``context``)
    context: float = 0.0

    @property
    def dt(self) -> float:
        return float(np.median(np.diff(self.t)))

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0] + self.dt)

    def __len__(self) -> int:
        return len(self.t)

    def column(self, name: str) -> NDArray[np.float64]:
        try:
            return self.columns[name]
        except KeyError:
            raise DataError(
                f"run {self.name!r} has no column {name!r}; it has {sorted(self.columns)}"
            ) from None

    def at_interval(self, dt: float) -> Run:
        """This run resampled onto a uniform ``dt`` grid (a coarser one, to match other runs) by
        linear interpolation, with a note."""
        grid = dt * np.arange(math.floor(float(self.t[-1] - self.t[0]) / dt + 1e-6) + 1)
        names = list(self.columns)
        values = _interpolate(self.t - self.t[0], np.column_stack([self.columns[n] for n in names]), grid)
        note = f"resampled from {self.dt:g} s to {dt:g} s by linear interpolation, the other runs' interval"
        cols = {n: np.ascontiguousarray(values[:, j]) for j, n in enumerate(names)}
        return Run(self.name, grid, cols, [*self.notes, note], dict(self.attributes), self.context)

    def segment(self, start: float, stop: float, name: str | None = None, *, context: float = 0.0) -> Run:
        """The samples with ``start <= t < stop`` (s), as a new run; with ``context`` (s) the
        samples from ``start − context`` come first as its history (:attr:`context`; as much as the
        run has)."""
        if not (math.isfinite(context) and context >= 0.0):
            raise DataError(f"a segment's context must be a finite number of seconds >= 0, got {context!r}")
        keep = (self.t >= start) & (self.t < stop)
        if keep.sum() < 10:
            raise DataError(f"segment [{start}, {stop}) of run {self.name!r} has fewer than 10 samples")
        first = float(self.t[keep][0])
        take = (self.t >= first - context - 1e-9 * self.dt) & (self.t < stop)
        t = self.t[take]
        return Run(
            name or f"{self.name}[{start:g}:{stop:g}]",
            t - t[0],
            {k: v[take] for k, v in self.columns.items()},
            list(self.notes),
            dict(self.attributes),
            first - float(t[0]),
        )


def scored_start(warmup: float, run: Run) -> int:
    """The first sample of ``run`` that is fitted or scored: after its history
    (:attr:`Run.context`) and the model's ``warmup`` (s)."""
    return round((warmup + run.context) / run.dt)


def _read_table(path: Path) -> tuple[list[str], NDArray[np.float64]]:
    suffix = "".join(path.suffixes[-2:]).lower()
    if path.suffix.lower() == ".parquet":
        try:
            import pyarrow.parquet as pq
        except ImportError:  # pragma: no cover - depends on the environment
            raise DataError(
                f"{path}: reading Parquet needs pyarrow (pip install 'cablekit[parquet]')"
            ) from None
        table = pq.read_table(path)
        names = list(table.column_names)
        cols = []
        for n in names:
            col = table.column(n).to_numpy(zero_copy_only=False)
            try:
                cols.append(np.asarray(col, dtype=np.float64))
            except (TypeError, ValueError):
                raise DataError(f"{path}: column {n!r} is not numeric") from None
        return names, np.column_stack(cols) if cols else np.empty((0, 0))
    opener = open
    if suffix.endswith(".gz"):
        import gzip

        opener = gzip.open  # type: ignore[assignment]
    # utf-8-sig: a byte-order mark (as spreadsheet programs write) is not part of the first name
    with opener(path, "rt", newline="", encoding="utf-8-sig") as fh:  # type: ignore[operator]
        lines = [ln for ln in fh.read().splitlines() if ln.strip()]
    while lines and lines[0].lstrip().startswith("#"):
        lines.pop(0)
    if not lines:
        raise DataError(f"{path}: no header row")
    sep = _separator(lines[0])
    split = (
        (lambda ls: [ln.split() for ln in ls])
        if sep is None
        else (lambda ls: list(csv.reader(ls, delimiter=sep)))
    )
    header = [h.strip() for h in split(lines[:1])[0]]
    decimal_comma = sep != ","
    if len(set(header)) != len(header):
        dup = sorted({h for h in header if header.count(h) > 1})
        raise DataError(f"{path}: duplicated column names {dup}")
    fast = _fast_numbers(lines[1:], sep, len(header))
    if fast is not None:
        return header, fast
    rows = split(lines[1:])
    data = np.empty((len(rows), len(header)))
    for i, row in enumerate(rows):
        if len(row) != len(header):
            raise DataError(f"{path}: row {i + 2} has {len(row)} fields, the header has {len(header)}")
        for j, cell in enumerate(row):
            cell = cell.strip()
            try:
                data[i, j] = float(cell.replace(",", ".") if decimal_comma else cell) if cell else math.nan
            except ValueError:
                raise DataError(
                    f"{path}: row {i + 2}, column {header[j]!r}: {cell!r} is not a number"
                ) from None
    return header, data


def _fast_numbers(lines: list[str], sep: str | None, width: int) -> NDArray[np.float64] | None:
    """The numbers of a clean table (every cell a number, ``width`` per row) by a compiled
    parser — pyarrow's if installed, else NumPy's — instead of the cell-by-cell loop; None for
    anything else (empty cells, decimal commas, ragged rows), which the loop then reads and
    reports cell by cell."""
    if not lines:
        return None
    if sep is not None:
        table = _arrow_numbers(lines, sep, width)
        if table is not None:
            return table
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            data = np.loadtxt(io.StringIO("\n".join(lines)), delimiter=sep, ndmin=2, dtype=np.float64)
    except (ValueError, Warning):
        return None
    if data.shape != (len(lines), width):
        return None
    return np.ascontiguousarray(data)


def _arrow_numbers(lines: list[str], sep: str, width: int) -> NDArray[np.float64] | None:
    """pyarrow's CSV reader (when the ``parquet`` extra is installed: ~5× NumPy's) on a clean
    table; None when pyarrow is missing or any cell is not a number."""
    try:
        import pyarrow as pa
        import pyarrow.csv as pc
    except ImportError:
        return None
    names = [f"c{j}" for j in range(width)]
    try:
        table = pc.read_csv(
            io.BytesIO("\n".join(lines).encode()),
            read_options=pc.ReadOptions(column_names=names),
            parse_options=pc.ParseOptions(delimiter=sep),
            convert_options=pc.ConvertOptions(column_types=dict.fromkeys(names, pa.float64())),
        )
    except Exception:  # any cell that is not a number, a ragged row: the careful reader says which
        return None
    if table.num_rows != len(lines) or any(table.column(n).null_count for n in names):
        return None
    return np.ascontiguousarray(np.column_stack([table.column(n).to_numpy() for n in names]))


def _separator(header: str) -> str | None:
    """The column separator a header line shows: a comma, else a tab, else a semicolon (a
    spreadsheet's export where the comma is the decimal mark), else whitespace (``None``: MATLAB's
    ``save -ascii``, a bench's text log)."""
    return next((c for c in (",", "\t", ";") if c in header), None)


def load_run(path: str | Path, name: str | None = None, *, columns: list[str] | None = None) -> Run:
    """Load a CSV (optionally ``.csv.gz``) or Parquet run with a ``t`` column; see the module.
    A ROS 2 bag (a rosbag2 folder, or its ``.mcap``/``.db3``) is read for ``columns`` — the
    model's columns, each a bag field ``"/topic:field"`` (:mod:`cablekit.bags`) — and then
    handled as a table.

    Every defect of the file is a :class:`DataError` naming it: a missing path or a folder, a
    file that is not UTF-8 text (a UTF-8 byte-order mark is skipped), a corrupt gzip or Parquet
    file, a malformed CSV (an unterminated quote, a field over the CSV module's size limit)."""
    from cablekit.bags import is_bag, read_bag

    path = Path(path)
    if is_bag(path):
        if not columns:
            raise DataError(f"{path}: a ROS 2 bag is read for the model's columns; none were given")
        header, data, notes = read_bag(path, list(columns))
        bag = path if path.is_dir() else path.parent
        run = from_arrays(name or bag.name, header, data, source=str(path))
        run.notes[:0] = notes
        return run
    header, data = read_table(path)
    return from_arrays(name or path.stem, header, data, source=str(path))


def read_table(path: str | Path) -> tuple[list[str], NDArray[np.float64]]:
    """The header and the numbers (rows = samples; an empty cell is NaN) of a CSV, ``.csv.gz``
    or Parquet table; every defect of the file is a :class:`DataError` naming it (see
    :func:`load_run`)."""
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: no such file")
    if path.is_dir():
        raise DataError(f"{path}: is a folder, not a table file (CSV, .csv.gz or Parquet)")
    try:
        return _read_table(path)
    except DataError:
        raise
    except UnicodeDecodeError as exc:
        raise DataError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except (csv.Error, EOFError, OSError, zlib.error) as exc:
        raise DataError(f"{path}: unreadable or corrupt ({type(exc).__name__}: {exc})") from None
    except Exception as exc:  # pyarrow's own errors on a corrupt Parquet file
        if type(exc).__module__.startswith("pyarrow"):
            raise DataError(f"{path}: unreadable Parquet file ({exc})") from None
        raise


def require_finite_cells(source: str | Path, header: list[str], data: NDArray[np.float64]) -> None:
    """A :class:`DataError` naming the first cell of a table (rows = samples) that is missing or
    not finite (its file row, counting the header as row 1, and its column)."""
    bad = ~np.isfinite(data)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise DataError(f"{source}: row {i + 2}, column {header[j]!r}: missing or not finite")


def from_arrays(name: str, header: list[str], data: NDArray[np.float64], source: str = "") -> Run:
    """Validate a table (rows = samples) into a :class:`Run`; see the module for the rules."""
    where = source or name
    if "t" not in header:
        raise DataError(f"{where}: no time column 't' (columns: {header})")
    if data.ndim != 2 or data.shape[0] < 10:
        raise DataError(f"{where}: needs at least 10 samples, got {data.shape[0] if data.ndim == 2 else 0}")
    bad = ~np.isfinite(data)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise DataError(
            f"{where}: missing or non-finite value in column {header[j]!r} at data row {i + 1} "
            f"({int(bad[:, j].sum())} such rows in that column); fill or drop them explicitly"
        )
    notes = []
    ti = header.index("t")
    t = data[:, ti]
    dt_raw = np.diff(t)
    dup_rows = np.flatnonzero(dt_raw == 0.0)
    if dup_rows.size:
        same = np.all(data[dup_rows] == data[dup_rows + 1], axis=1)
        if not same.all():
            k = int(dup_rows[~same][0])
            raise DataError(
                f"{where}: time {t[k]} s repeats at data rows {k + 1} and {k + 2} with different values"
            )
        data = np.delete(data, dup_rows + 1, axis=0)
        t = data[:, ti]
        notes.append(f"removed {dup_rows.size} exactly duplicated rows")
        if data.shape[0] < 10:  # the minimum counts distinct samples
            raise DataError(
                f"{where}: needs at least 10 samples, got {data.shape[0]} once {dup_rows.size} exactly "
                "duplicated rows are removed"
            )
    dt = np.diff(t)
    if (dt <= 0).any():
        k = int(np.flatnonzero(dt <= 0)[0])
        raise DataError(f"{where}: time goes backwards at data row {k + 2} (t = {t[k]} then {t[k + 1]})")
    med = float(np.median(dt))
    if med >= 0.5 and np.allclose(dt, np.round(dt)):
        raise DataError(
            f"{where}: t looks like milliseconds or samples (median step {med}); t must be in seconds"
        )
    t, data = uniform_time(where, data, ti, notes)
    cols = {h: np.ascontiguousarray(data[:, j]) for j, h in enumerate(header) if h != "t"}
    return Run(name, t - t[0], cols, notes)


#: dropped samples in a row that resampling fills by interpolation; a longer gap is an error
MAX_FILLED = 5
#: the most samples a run resampled on its clock may have
MAX_GRID = 20_000_000


def uniform_time(
    where: str, data: NDArray[np.float64], ti: int, notes: list[str]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The times and rows of a table whose column ``ti`` (time, strictly increasing) is sampled
    uniformly: as given if every interval is within 1 % of the median ``dt``, else on a uniform
    grid — the rows kept on their clock's fitted grid when only their stamps jitter, else
    resampled at their stamps by linear interpolation — with a note appended to ``notes`` (see
    the module; more than :data:`MAX_FILLED` samples missing in a row is a ``DataError``)."""
    t = data[:, ti]
    steps = np.diff(t)
    dt = float(np.median(steps))
    if float(np.max(np.abs(steps - dt))) <= 0.01 * dt:
        return t, data
    with np.errstate(over="ignore"):
        ratio = steps / dt
        span = (t[-1] - t[0]) / dt
    if not np.isfinite(span) or not np.isfinite(t[-1] - t[0]):
        raise DataError(f"{where}: the time column spans {t[0]:g} to {t[-1]:g} s, beyond float range")
    # a clock of more ticks than MAX_GRID is not looked for (the run is resampled at its rows)
    ticks = _clock_ticks(t, dt) if span < MAX_GRID else None
    k = int(np.argmax(ratio))
    if ticks is not None and not ratio[k] < MAX_FILLED + 1.5:  # a clocked logger lost samples
        raise DataError(
            f"{where}: {ratio[k] - 1:.0f} samples missing between t = {t[k]:g} and {t[k + 1]:g} s (data rows "
            f"{k + 1} and {k + 2}; the interval is {dt:g} s); more than {MAX_FILLED} in a row are not "
            "filled: split the run there into two run files"
        )
    stamped = False
    if ticks is not None:
        period, start = _line(ticks, t)
        stamped = _only_stamps_jitter(data, ti, steps, np.diff(ticks) * period)
        if stamped:  # the rows sit on a uniform clock, whose period and start the stamps fit best
            dt, t = period, start + period * ticks
    else:  # no uniform clock (a variable-step solver): as many samples as rows, at their mean step
        dt = float(t[-1] - t[0]) / (len(t) - 1)
    grid = t[0] + dt * np.arange(math.floor((t[-1] - t[0]) / dt + 1e-6) + 1)
    if len(grid) > MAX_GRID:  # a clock fitted to a few rows of a long run
        raise DataError(f"{where}: {len(grid):,} samples on a uniform {dt:g} s grid; at most {MAX_GRID:,}")
    if len(grid) < 10:
        raise DataError(f"{where}: needs at least 10 samples, got {len(grid)} on a uniform {dt:g} s grid")
    out = _interpolate(t, data, grid)
    out[:, ti] = grid
    if not np.isfinite(out).all():
        j = int(np.argmax(~np.isfinite(out).all(axis=0)))
        raise DataError(f"{where}: column {j + 1} overflows when resampled onto a uniform grid")
    filled = len(grid) - len(t)
    gaps = f"; about {filled} dropped samples filled" if filled > 0 else ""
    steps_seen = f"intervals from {steps.min():g} to {steps.max():g} s"
    if stamped:
        how = f"{gaps} by linear interpolation" if gaps else ""
        notes.append(
            f"time stamps jitter ({steps_seen}) on rows taken on a uniform clock (the signals are "
            f"smoother row by row than in the stamped time): t replaced by a uniform {dt:g} s grid{how}"
        )
    elif ticks is None:
        notes.append(
            f"times on no uniform clock ({steps_seen}: a variable-step solver's output?): resampled "
            f"at their mean interval, {dt:g} s, by linear interpolation between rows; for another "
            f"rate resample the run yourself: {len(t)} samples -> {len(grid)}"
        )
    else:
        notes.append(
            f"resampled onto a uniform {dt:g} s grid by linear interpolation ({steps_seen}{gaps}): "
            f"{len(t)} samples -> {len(grid)}"
        )
    return grid, out


def _interpolate(
    t: NDArray[np.float64], data: NDArray[np.float64], grid: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The rows of ``data`` (sampled at ``t``) linearly interpolated at ``grid``: a weighted mean
    of the two neighbours (np.interp's slopes overflow for values near ±1e308 that it keeps)."""
    i = np.clip(np.searchsorted(t, grid, side="right") - 1, 0, len(t) - 2)
    w = np.clip((grid - t[i]) / (t[i + 1] - t[i]), 0.0, 1.0)[:, None]
    with np.errstate(over="ignore", invalid="ignore"):
        return (1.0 - w) * data[i] + w * data[i + 1]


def common_interval(runs: list[Run]) -> list[Run]:
    """``runs`` at one sample interval: runs sampled finer than the coarsest are resampled onto it
    (never the other way: interpolated samples would count as measurements they are not)."""
    coarse = max(r.dt for r in runs)
    return [r.at_interval(coarse) if r.dt < 0.99 * coarse else r for r in runs]


def _line(x: NDArray[np.float64], y: NDArray[np.float64]) -> tuple[float, float]:
    """Slope and intercept of the least-squares line through ``(x, y)`` (``x`` not constant)."""
    xm, ym = float(np.mean(x)), float(np.mean(y))
    slope = float(np.dot(x - xm, y - ym) / np.dot(x - xm, x - xm))
    return slope, ym - slope * xm


def _clock_ticks(t: NDArray[np.float64], dt: float) -> NDArray[np.float64] | None:
    """Each stamp's tick of a uniform clock, were the rows taken on one: the ticks are read off
    a line fitted to the stamps, over blocks that double (a period from the first rows alone
    drifts by whole ticks over a long run), refitted until they settle. ``None`` if two stamps
    fall on one tick (no uniform clock explains them)."""
    k = np.rint((t - t[0]) / dt)
    m = min(len(t), 64)
    while True:
        for _ in range(8):
            if not np.ptp(k[:m]) > 0:
                return None
            period, start = _line(k[:m], t[:m])
            new = np.rint((t[:m] - start) / period)
            if np.array_equal(new, k[:m]):
                break
            k[:m] = new
        if m == len(t):
            break
        m2 = min(len(t), 2 * m)
        k[m:m2] = np.rint((t[m:m2] - start) / period)
        m = m2
    k -= k[0]
    return k if bool(np.all(np.diff(k) >= 1)) else None


def _only_stamps_jitter(
    data: NDArray[np.float64], ti: int, steps: NDArray[np.float64], clock: NDArray[np.float64]
) -> bool:
    """Whether the rows were taken on a uniform clock and only their time stamps jitter (a host
    stamping a DAQ's samples on arrival), rather than taken at the stamped times (a loop without a
    real-time clock). The signals tell: the rates between rows, each column's differences over
    the ``clock`` intervals or over the stamped ``steps``, are smooth only under the right one.
    Each column weighs the same (its roughness relative to its own rates); white noise adds about
    the same to both, so the smooth columns (commands, encoders) decide."""
    rough = np.zeros(2)
    for j in range(data.shape[1]):
        with np.errstate(all="ignore"):  # a column near ±1e308 overflows: it does not vote
            d = np.diff(data[:, j])
            if j == ti or not np.any(d):
                continue
            rates = [d / intervals for intervals in (clock, steps)]
            r = np.array([np.sum(np.diff(v) ** 2) / np.sum(v * v) for v in rates])
        if np.isfinite(r).all():
            rough += r
    return bool(rough[0] < rough[1])


_UNIT_LIMITS = {
    "rad": (4 * math.pi, "degrees"),
    "m": (0.5, "millimetres"),
}


def check_units(run: Run, units: dict[str, str]) -> None:
    """Raise :class:`DataError` when a column's values are implausible for its declared unit."""
    for col, unit in units.items():
        if unit not in _UNIT_LIMITS:
            continue
        limit, other = _UNIT_LIMITS[unit]
        peak = float(np.max(np.abs(run.column(col))))
        if peak > limit:
            raise DataError(
                f"run {run.name!r}: column {col!r} is declared in {unit} but reaches {peak:g}; it looks like "
                f"{other}. Convert it to SI units"
            )


def write_csv(run: Run, path: str | Path) -> Path:
    """Write a run as CSV with a ``t`` column (the format :func:`load_run` reads)."""
    path = Path(path)
    cols = ["t", *run.columns]
    data = np.column_stack([run.t, *run.columns.values()])
    np.savetxt(path, data, delimiter=",", header=",".join(cols), comments="", fmt="%.9g")
    return path
