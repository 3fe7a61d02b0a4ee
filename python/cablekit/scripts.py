"""Shared start and finish of the example scripts: options, output folder, result table."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from cablekit.plotting import pyplot_or_none

__all__ = ["finish_table", "script_options"]


def script_options(doc: str | None, out: str, **defaults: float | int) -> tuple[argparse.Namespace, Path]:
    """Parse ``--out`` (default ``out``) and one ``--name`` option per keyword default (typed
    like it); the description is the first line of ``doc``. Creates the output folder."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0] if doc else None)
    ap.add_argument("--out", default=out)
    for name, default in defaults.items():
        ap.add_argument(f"--{name}", type=type(default), default=default)
    args = ap.parse_args()
    path = Path(args.out)
    path.mkdir(parents=True, exist_ok=True)
    return args, path


def finish_table(out: Path, text: str, t0: float | None = None) -> Any:
    """Print a result table (and the seconds since ``t0``), write it to ``out/table.md`` and
    return ``matplotlib.pyplot`` for the figures, or None without the report extra."""
    print(text)
    if t0 is not None:
        print(f"({time.perf_counter() - t0:.1f} s)")
    (out / "table.md").write_text(text + "\n")
    return pyplot_or_none()
