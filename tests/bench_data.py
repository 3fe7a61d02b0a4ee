"""Where the real da Vinci bench data is: ``$CABLEKIT_DAVINCI_DATA`` or
``../shared/data/davinci-maryland-bench`` (never copied into the repository)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest


def davinci_dir() -> Path:
    env = os.environ.get("CABLEKIT_DAVINCI_DATA")
    here = Path(__file__).resolve().parents[1]
    for cand in ([Path(env)] if env else []) + [here.parent / "shared" / "data" / "davinci-maryland-bench"]:
        if (cand / "tool4_load_sweep").is_dir():
            return cand
    # the data may not be redistributed, so it is not in the repository; CI has it in
    # ../shared/data (where .ci/run also diagnoses it); elsewhere point CABLEKIT_DAVINCI_DATA at it
    pytest.skip("da Vinci bench data not found (set CABLEKIT_DAVINCI_DATA)")
