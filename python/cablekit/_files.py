"""Reading the text and TOML files cablekit loads, every failure a :class:`DataError` naming the
file: missing, a folder, unreadable, not UTF-8, not TOML, or nested too deeply for the parser."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path
from typing import Any

from cablekit.errors import DataError, DTypeError


def read_text(path: str | Path, what: str) -> str:
    """The UTF-8 text of ``path`` (a byte-order mark dropped); ``what`` names the file kind."""
    p = Path(path)
    try:
        return p.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise DataError(f"{p}: no such {what}") from None
    except IsADirectoryError:
        raise DataError(f"{p}: is a folder, not a {what}") from None
    except UnicodeDecodeError as exc:
        raise DataError(f"{p}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the path
        raise DataError(f"{p}: cannot read the {what} ({exc})") from None


def parse_toml(text: str, source: str) -> dict[str, Any]:
    """The document of TOML ``text``; ``source`` names it in the error."""
    if not isinstance(text, str):
        raise DTypeError(f"{source}: TOML text must be a string, got {type(text).__name__}")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DataError(f"{source}: not valid TOML ({exc})") from None
    except RecursionError:
        raise DataError(f"{source}: not valid TOML (nested too deeply)") from None


def load_toml(path: str | Path, what: str) -> dict[str, Any]:
    """The document of the TOML file ``path``."""
    return parse_toml(read_text(path, what), str(path))


#: a bench recording's file ending (MRDLab format: ``XY.TXT``, gzip-compressed or not, any case)
_TEXT_RUN = re.compile(r"\.txt(\.gz)?$", re.IGNORECASE)


def text_runs(folder: Path) -> dict[str, Path]:
    """Every ``*.TXT`` / ``*.TXT.gz`` file (any case) of ``folder`` by stem; empty for no folder."""
    out: dict[str, Path] = {}
    for f in sorted(folder.iterdir()) if folder.is_dir() else []:
        m = _TEXT_RUN.search(f.name)
        if m and f.is_file():
            out.setdefault(f.name[: m.start()], f)
    return out


def bench_runs(folder: Path) -> dict[str, Path]:
    """The run files of a bench folder by stem: those whose stem is a condition code (digits:
    ``XY``, ``ZXY``) — not the upstream ``README.txt`` or ``SerialLog.txt`` a copied folder keeps
    beside its runs. A run with another stem is read when it is named (:func:`text_runs`)."""
    return {k: v for k, v in text_runs(folder).items() if k.isascii() and k.isdigit()}


#: the largest magnitude an encoder or converter count can have in a bench file: every integer
#: up to 2⁵³ is exact in a double, and no real counter goes beyond it
COUNT_LIMIT = 2.0**53


def check_counts(path: Path, d: Any, columns: tuple[int, ...], rows: Any = None) -> None:
    """A :class:`DataError` naming the first cell of ``d``'s count ``columns`` (0-based) beyond
    :data:`COUNT_LIMIT`; ``rows`` maps row indices to file lines when given."""
    import numpy as np

    block = np.abs(np.asarray(d)[:, list(columns)])
    bad = np.argwhere(block > COUNT_LIMIT)
    if bad.size:
        r, c = bad[0]
        line = rows[r] if rows is not None else r + 1
        raise DataError(
            f"{path}:{line}: column {columns[c] + 1} holds {d[r, columns[c]]:g}, beyond any encoder's or "
            f"converter's count (|count| <= 2^53)"
        )
