"""Options every report-writing command shares: where it writes, whether it plots, how much it
prints."""

from __future__ import annotations

import argparse


def outputs(p: argparse.ArgumentParser, out: str | None, *, plots: bool = True, quiet: bool = True) -> None:
    """``--out`` (``out`` by default, required when ``None``), ``--no-plots`` and ``--quiet``."""
    if out is None:
        p.add_argument("--out", required=True, help="output folder")
    else:
        p.add_argument("--out", default=out, help="output folder")
    if plots:
        p.add_argument("--no-plots", action="store_true", help="no PNGs (no matplotlib needed)")
    if quiet:
        p.add_argument("--quiet", action="store_true", help="no progress or table on stdout")
