"""The table of ``benches/peers.py``: the machine and versions it was measured with, the
Markdown section of ``docs/benchmarks.md`` (between :data:`START` and :data:`END`, the rest of
the file kept) and ``docs/benchmarks.json`` with the same data."""

from __future__ import annotations

import datetime
import importlib.metadata
import json
import os
import platform
import sys
from dataclasses import asdict
from pathlib import Path
from typing import Any

from .core import Config, Kernel, Row

START, END = "<!-- peers:start -->", "<!-- peers:end -->"
SCHEMA = "cablekit.peers/1"
PACKAGES = ("cablekit", "numpy", "scipy", "filterpy", "torch", "onnx", "onnxruntime", "quadprog", "qpsolvers",
            "highspy", "pyswarms", "mujoco")  # fmt: skip


def machine() -> dict[str, Any]:
    """CPU model and logical CPU count (``/proc/cpuinfo``, else ``platform``), OS, Python."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {
        "cpu": cpu,
        "logical_cpus": os.cpu_count(),
        "usable_cpus": usable,
        "platform": platform.platform(),
        "python": sys.version.split()[0],
        # other tenants' load when the table was written (1, 5, 15 min averages)
        "load_average": [round(x, 2) for x in os.getloadavg()] if hasattr(os, "getloadavg") else None,
    }


def versions() -> dict[str, str | None]:
    out: dict[str, str | None] = {}
    for name in PACKAGES:
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            out[name] = None
    return out


def document(rows: list[Row], cfg: Config, seconds: float) -> dict[str, Any]:
    """The JSON document: when, where, with what, and every row (times in s per unit)."""
    return {
        "schema": SCHEMA,
        "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": machine(),
        "packages": versions(),
        "settings": {
            "quick": cfg.quick,
            "reps": cfg.reps,
            "target_s": cfg.target_s,
            "wall_s": round(seconds, 1),
        },
        "rows": [{**asdict(r), "ratio": r.ratio} for r in rows],
    }


def seconds(s: float | None) -> str:
    """A time with its unit, 3 significant digits."""
    if s is None:
        return "—"
    for scale, unit in ((1.0, "s"), (1e-3, "ms"), (1e-6, "µs")):
        if s >= scale:
            return f"{s / scale:.3g} {unit}"
    return f"{s / 1e-9:.3g} ns"


def ratio(r: Row) -> str:
    if r.status.startswith("void"):
        return "**void**"
    if r.status != "ok":
        return r.status
    if r.ratio is None:
        return "not timed"
    x = r.ratio
    return f"{x:,.0f}×" if x >= 100 else f"{x:.3g}×"


def table(rows: list[Row], kernels: tuple[Kernel, ...]) -> str:
    titles = {k.name: k.title for k in kernels}
    lines = [
        "| kernel | cablekit | peer | per | cablekit | peer | peer / cablekit "
        "| agreement (checked before timing) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        peer = r.theirs or r.peer
        if r.note:
            peer += f" ({r.note})"
        cells = [titles.get(r.kernel, r.kernel), r.ours or "—", peer, r.unit or "—", seconds(r.ours_s),
                 seconds(r.peer_s), ratio(r), r.agreement or "—"]  # fmt: skip
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return "\n".join(lines)


def section(doc: dict[str, Any], rows: list[Row], kernels: tuple[Kernel, ...]) -> str:
    m, s = doc["machine"], doc["settings"]
    pkgs = ", ".join(f"{k} {v}" for k, v in doc["packages"].items() if v)
    about = "\n".join(f"* **{k.title}** — {k.about}." for k in kernels)
    load = " / ".join(f"{x:g}" for x in m["load_average"]) if m.get("load_average") else "unknown"
    return f"""{START}
## Every peer in one command (issue #40 §4)

`python benches/peers.py [--quick] [--only NAME]` runs each cablekit kernel against what a user
would otherwise pick, in one process, with the same inputs. Each row first checks that the two
answers agree, to the tolerance given in its last column; a row whose check fails reads **void**
and gets no ratio (a comparison of wrong answers means nothing), and a peer that is not installed
says so. Only then are both sides timed, their repeats interleaved: the medians per unit are shown
and the ratio peer / cablekit (above 1×: cablekit is faster; below 1×: the peer is). The machine
is shared with other tenants and noisy (absolute times move by 20 % and more from run to run);
the ratios, measured in the same run, are what to compare. The peers' exact settings are in the
docstrings of `benches/peerbench/`. This section and `docs/benchmarks.json` (the same data) are
written by the script.

{about}

Measured {doc["date"]}{" (quick run)" if s["quick"] else ""}: {s["reps"]} repeats per side (fewer for
calls of seconds), {s["wall_s"]:.0f} s in all, load average {load} (1, 5, 15 min) at the end.

* Machine: {m["cpu"]}, {m["logical_cpus"]} logical CPUs ({m["usable_cpus"]} usable), {m["platform"]}.
* Python {m["python"]}; {pkgs}.

{table(rows, kernels)}
{END}"""


def write(md: Path, js: Path, doc: dict[str, Any], rows: list[Row], kernels: tuple[Kernel, ...]) -> None:
    """Replace the section between the markers of ``md`` (append it when absent) and write ``js``."""
    text = md.read_text(encoding="utf-8") if md.exists() else "# Benchmarks\n"
    new = section(doc, rows, kernels)
    if START in text and END in text:
        head, rest = text.split(START, 1)
        text = head + new + rest.split(END, 1)[1]
    else:
        text = text.rstrip("\n") + "\n\n" + new + "\n"
    md.write_text(text, encoding="utf-8")
    js.write_text(json.dumps(doc, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
