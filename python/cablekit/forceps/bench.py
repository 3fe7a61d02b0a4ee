"""The da Vinci Maryland bench's recording format, read once for every use of it.

O'Neill, Stephens, Kowalewski, RA-L 2018; data ODbL 1.0, contents DbCL 1.0, from
github.com/MRDLab/mis-tool-characterization. The files are **never copied into the project**;
they are read from wherever the user keeps them (``../shared/data/davinci-maryland-bench`` in
our CI). The diagnosis (:mod:`cablekit.diagnose.davinci`: the bench as an antagonistic joint)
and the jaw-torque estimators (:mod:`cablekit.forceps.davinci`) both read through
:func:`read_raw` and take the sensors' constants from here.

A run is a text file (optionally gzipped): ``%`` header lines, then comma-separated rows of time
(s), spindle encoder counts, spindle torque counts, motor current (A), jaw encoder counts, jaw
torque counts, the front- and back-end commands and the back-end motor's encoder counts. Its
name ``FL`` gives the condition: frequency index ``F`` (0.1–0.5 Hz), load index ``L`` (10–40 %
resistive torque).
"""

from __future__ import annotations

import gzip
import re
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from cablekit._args import checked, text
from cablekit._files import check_counts
from cablekit.errors import DataError

__all__ = [
    "BENCH_PATTERN",
    "CITATION",
    "CUI_COUNTS",
    "FREQS",
    "FUTEK_NM",
    "LOADS",
    "MAXON_COUNTS",
    "MOTOR_COUNTS",
    "RawRun",
    "condition",
    "read_raw",
]

F64 = NDArray[np.float64]

CITATION = (
    "J. O'Neill, T. Stephens, T. Kowalewski, 'Evaluation of Torque Measurement Surrogates as Applied to "
    "Grip Torque and Jaw Angle Estimation of Robotic Surgical Tools', IEEE RA-L 3(4):3027-3034, 2018; "
    "data: MRDLab/mis-tool-characterization (ODbL 1.0 / DbCL 1.0)"
)
CUI_COUNTS = 8192.0  # spindle encoder, counts/rev
FUTEK_NM = 3.9811e-5  # both torque sensors, N·m/count
MAXON_COUNTS = 4000.0  # jaw encoder, counts/rev
MOTOR_COUNTS = 4096.0 * 35.0  # back-end motor encoder through its 35:1 gearbox, counts/rev
FREQS = (0.1, 0.2, 0.3, 0.4, 0.5)
LOADS = (10, 20, 30, 40)
#: the columns in order (the bench README's numbering from 1)
COLUMNS = (
    "time",
    "spindle encoder",
    "spindle torque",
    "motor current",
    "jaw encoder",
    "jaw torque",
    "front-end command",
    "back-end command",
    "motor encoder",
)
#: columns holding integer sensor counts (0-based), bounded to ±2^53 before any conversion
COUNT_COLUMNS = (1, 2, 4, 5, 8)
#: what a bench folder holds
BENCH_PATTERN = (
    "files named FL.TXT or FL.TXT.gz (F = frequency index 0-4 for 0.1-0.5 Hz, L = load index 0-3 for "
    "10-40 % resistive torque; any other stem works when named explicitly), each with >= 6 "
    "comma-separated columns: time s, spindle encoder counts, spindle torque counts, motor current A, "
    "jaw encoder counts, jaw torque counts"
)
MIN_ROWS = 10


@dataclass(frozen=True)
class RawRun:
    """One run as recorded: ``data`` ``(T, columns)`` with the time ``t`` (s) from 0 and strictly
    increasing (rows whose time does not increase are dropped, with a note); SI views of the
    sensors below."""

    name: str
    path: Path
    t: F64
    data: F64
    notes: tuple[str, ...]

    @property
    def spindle_angle(self) -> F64:
        """Spindle angle (rad, CUI encoder)."""
        return self.data[:, 1] * (2 * np.pi / CUI_COUNTS)

    @property
    def spindle_torque(self) -> F64:
        """Spindle torque (N·m, Futek)."""
        return self.data[:, 2] * FUTEK_NM

    @property
    def motor_current(self) -> F64:
        """Back-end motor current (A)."""
        return self.data[:, 3].copy()

    @property
    def jaw_angle(self) -> F64:
        """Jaw angle (rad, Maxon encoder; not zeroed by the bench)."""
        return self.data[:, 4] * (2 * np.pi / MAXON_COUNTS)

    @property
    def jaw_torque(self) -> F64:
        """Jaw torque (N·m, Futek)."""
        return self.data[:, 5] * FUTEK_NM

    @property
    def motor_angle(self) -> F64:
        """Back-end motor angle after its gearbox (rad); needs the ninth column."""
        if self.data.shape[1] < 9:
            raise DataError(f"{self.path}: no motor encoder column (9th)")
        return self.data[:, 8] * (2 * np.pi / MOTOR_COUNTS)


@checked
def condition(name: str) -> tuple[int | None, int | None]:
    """The frequency and load indices of a run named ``FL`` (or ``ZFL`` with a wrist stop ``Z``);
    ``None`` for what the name does not give."""
    text(name, "name")
    m = re.fullmatch(r"\d?(\d)(\d)", name)
    if m is None:
        return None, None
    f, load = int(m.group(1)), int(m.group(2))
    return (f if f < len(FREQS) else None), (load if load < len(LOADS) else None)


def _text(path: Path) -> str:
    opener: Callable[..., object] = gzip.open if path.suffix == ".gz" else open
    try:
        with opener(path, "rt", encoding="utf-8") as fh:  # type: ignore[operator]
            return fh.read()  # type: ignore[attr-defined, no-any-return]
    except (OSError, EOFError, UnicodeDecodeError) as exc:
        raise DataError(f"{path}: cannot read a bench file ({exc}); expected {BENCH_PATTERN}") from exc


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _parse_lines(path: Path, text: str, columns: int) -> F64:
    """Row by row, naming the line and column of the first bad cell."""
    rows, numbers = [], []
    for i, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("%"):
            continue
        cells = stripped.split(",")
        if len(cells) < columns:
            raise DataError(
                f"{path}:{i}: {len(cells)} columns, need at least {columns} "
                f"({', '.join(COLUMNS[:columns])}); expected {BENCH_PATTERN}"
            )
        try:
            numbers.append([float(c) for c in cells[:columns]])
        except ValueError:
            j = next(k for k, c in enumerate(cells[:columns]) if not _is_float(c))
            raise DataError(
                f"{path}:{i}: column {j + 1} is not a number: {cells[j]!r}; not a bench file"
            ) from None
        rows.append(i)
    d = np.asarray(numbers, dtype=np.float64).reshape(len(numbers), columns)
    return _checked(path, d, rows)


def _checked(path: Path, d: F64, rows: list[int] | None) -> F64:
    if d.shape[0] < MIN_ROWS:
        raise DataError(f"{path}: {d.shape[0]} data rows; a bench run needs at least {MIN_ROWS}")
    bad = np.argwhere(~np.isfinite(d))
    if bad.size:
        r, c = bad[0]
        where = f":{rows[r]}:" if rows is not None else f": data row {r + 1},"
        raise DataError(f"{path}{where} column {c + 1} is not finite ({d[r, c]})")
    check_counts(path, d, tuple(c for c in COUNT_COLUMNS if c < d.shape[1]), rows)
    return d


@checked
def read_raw(path: str | Path, columns: int = 6) -> RawRun:
    """One bench file with at least ``columns`` numeric columns (6 for the diagnosis, 9 for the
    motor encoder): a :class:`RawRun`, or a ``DataError`` naming the file and, for a malformed
    row, its line and column. NumPy reads a well-formed file at once; anything it refuses is
    read again row by row for the message."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: no such bench file")
    text = _text(path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # an empty file: reported below
            d = np.loadtxt(text.splitlines(), comments="%", delimiter=",", ndmin=2, usecols=range(columns))
        d = _checked(path, d, None) if np.isfinite(d).all() else _parse_lines(path, text, columns)
    except ValueError:
        d = _parse_lines(path, text, columns)
    t = d[:, 0] - d[0, 0]
    keep = np.concatenate([[True], np.diff(t) > 0])
    notes = () if keep.all() else (f"dropped {int((~keep).sum())} rows whose time does not increase",)
    return RawRun(path.name.split(".")[0], path, t[keep], d[keep], notes)
