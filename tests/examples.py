"""Running an example script of ``examples/`` as a user does, for the tests that check what it
prints against the docs."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run_example(name: str, out: Path, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    """``python examples/<name> --out <out>`` in ``out``, its output captured (not checked)."""
    return subprocess.run(
        [sys.executable, str(ROOT / "examples" / name), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=out,
        check=False,
    )
