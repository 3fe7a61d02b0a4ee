"""The comparison machinery of ``benches/peers.py``: a kernel, its peers, the agreement check
that must pass before anything is timed, and the interleaved timing.

A :class:`Pair` holds two :class:`Side` s — cablekit's call and the peer's — on the same inputs,
and ``agree`` compares their answers. :func:`check` runs each side's ``answer`` once and returns
a :class:`Verdict`; :func:`time_pair` times each side's ``run`` (median over repeats, the two
sides interleaved so that a burst of load on the shared machine hits both). :func:`measure`
does both in that order and never times a pair whose answers differ: a comparison of wrong
answers is void.
"""

from __future__ import annotations

import contextlib
import importlib
import math
import statistics
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Config:
    """How hard to measure. ``quick``: smaller problems and fewer repeats (a smoke run)."""

    quick: bool = False
    #: repeats per side (the median is reported)
    reps: int = 7
    #: the shortest repeat, s: fast calls are looped until a repeat lasts this long
    target_s: float = 0.05

    @classmethod
    def make(cls, quick: bool) -> Config:
        return cls(quick=True, reps=3, target_s=0.01) if quick else cls()


@dataclass(frozen=True)
class Verdict:
    """The agreement check's outcome: ``detail`` says what was compared and the largest
    difference against its tolerance, or why the answers differ."""

    ok: bool
    detail: str


@dataclass(frozen=True)
class Side:
    """One side of a comparison. ``run()`` is one timed call covering ``count`` units (steps,
    poses, samples); ``answer()`` computes what the check compares (``run`` when omitted)."""

    label: str
    run: Callable[[], Any]
    count: int = 1
    answer: Callable[[], Any] | None = None

    def result(self) -> Any:
        return (self.answer or self.run)()


@dataclass(frozen=True)
class Pair:
    """cablekit's side and the peer's on the same inputs, and how their answers must agree."""

    ours: Side
    theirs: Side
    agree: Callable[[Any, Any], Verdict]
    #: what one unit of ``count`` is ("step", "pose", ...)
    unit: str
    #: at most this many repeats (calls of seconds)
    max_reps: int = 1_000
    #: a caveat shown with the row (what differs beyond the timed call)
    note: str = ""


@dataclass(frozen=True)
class Peer:
    """A peer of a kernel: its name in the table, the modules both sides need, and how to build
    the pair (``build`` is called only once every module imports)."""

    name: str
    needs: tuple[str, ...]
    build: Callable[[Config], Pair]


@dataclass(frozen=True)
class Kernel:
    """A cablekit kernel, what its rows compare (``about``, for the docs) and its peers."""

    name: str
    title: str
    about: str
    peers: tuple[Peer, ...]

    def peer(self, name: str) -> Peer:
        for p in self.peers:
            if p.name == name:
                return p
        raise KeyError(name)


@dataclass
class Row:
    """One line of the table. ``status`` is ``ok``, ``void: <why>`` or ``not installed: <what>``;
    the times (s per unit) and the ratio are set only for ``ok`` rows that were timed."""

    kernel: str
    peer: str
    status: str
    ours: str = ""
    theirs: str = ""
    unit: str = ""
    agreement: str = ""
    note: str = ""
    ours_s: float | None = None
    peer_s: float | None = None
    reps: int = 0

    @property
    def ratio(self) -> float | None:
        """Peer time over cablekit time (> 1: cablekit is faster)."""
        if self.ours_s is None or self.peer_s is None or self.ours_s <= 0:
            return None
        return self.peer_s / self.ours_s


def missing_modules(names: tuple[str, ...]) -> list[str]:
    """The modules of ``names`` that do not import."""
    out = []
    for name in names:
        try:
            # in a scratch working directory: pyswarms writes report.log where it is imported
            with tempfile.TemporaryDirectory() as tmp, contextlib.chdir(tmp):
                importlib.import_module(name)
        except Exception:  # an ImportError, or a package broken in this environment
            out.append(name)
    return out


def check(pair: Pair) -> Verdict:
    """Run both sides once and compare; an exception on either side is a void verdict."""
    answers = []
    for who, side in (("cablekit", pair.ours), ("peer", pair.theirs)):
        try:
            answers.append(side.result())
        except Exception as exc:
            return Verdict(False, f"{who} raised {type(exc).__name__}: {str(exc)[:160]}")
    try:
        return pair.agree(*answers)
    except Exception as exc:  # a malformed answer (wrong shape, None) is a disagreement
        return Verdict(False, f"answers not comparable: {type(exc).__name__}: {str(exc)[:160]}")


def time_pair(pair: Pair, cfg: Config) -> tuple[float, float, int]:
    """Median seconds per unit of each side and the repeats taken, the sides interleaved."""
    sides = (pair.ours, pair.theirs)
    loops, samples = [], [[], []]
    for i, side in enumerate(sides):
        t0 = time.perf_counter()
        side.run()
        first = time.perf_counter() - t0
        if first >= cfg.target_s:  # a slow call: the calibration call is the first repeat
            loops.append(1)
            samples[i].append(first / side.count)
        else:
            loops.append(min(100_000, max(1, math.ceil(cfg.target_s / max(first, 1e-9)))))
    reps = min(cfg.reps, pair.max_reps)
    for _ in range(reps):
        for i, side in enumerate(sides):
            if len(samples[i]) >= reps:
                continue
            t0 = time.perf_counter()
            for _ in range(loops[i]):
                side.run()
            samples[i].append((time.perf_counter() - t0) / (loops[i] * side.count))
    return statistics.median(samples[0]), statistics.median(samples[1]), reps


def measure(kernel: Kernel, peer: Peer, cfg: Config, timing: bool = True) -> Row:
    """Check a peer against cablekit and, when they agree and ``timing``, time both."""
    row = Row(kernel.name, peer.name, "ok")
    missing = missing_modules(peer.needs)
    if missing:
        row.status = f"not installed: {', '.join(missing)}"
        return row
    try:
        pair = peer.build(cfg)
    except Exception as exc:
        row.status = f"void: setup raised {type(exc).__name__}: {str(exc)[:160]}"
        return row
    row.ours, row.theirs, row.unit, row.note = pair.ours.label, pair.theirs.label, pair.unit, pair.note
    verdict = check(pair)
    row.agreement = verdict.detail
    if not verdict.ok:
        row.status = f"void: {verdict.detail}"
        return row
    if timing:
        try:
            row.ours_s, row.peer_s, row.reps = time_pair(pair, cfg)
        except Exception as exc:
            row.status = f"void: raised while timed: {type(exc).__name__}: {str(exc)[:160]}"
    return row


# ---- agreement helpers ---------------------------------------------------------------------------


def close(ours: Any, theirs: Any, atol: float, what: str, unit: str = "") -> Verdict:
    """``|ours − theirs| ≤ atol`` elementwise (same shape, both finite)."""
    a, b = np.asarray(ours, dtype=np.float64), np.asarray(theirs, dtype=np.float64)
    if a.shape != b.shape:
        return Verdict(False, f"{what}: shapes differ, {a.shape} and {b.shape}")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return Verdict(False, f"{what}: a non-finite value")
    worst = float(np.max(np.abs(a - b), initial=0.0))
    unit = f" {unit}" if unit else ""
    detail = f"{what}: max |Δ| {worst:.1e}{unit} (tolerance {atol:.0e}{unit}, {a.size:,} values)"
    return Verdict(worst <= atol, detail)


def same_flags(ours: Any, theirs: Any, what: str) -> Verdict:
    """The same boolean verdict everywhere."""
    a, b = np.asarray(ours, dtype=bool), np.asarray(theirs, dtype=bool)
    if a.shape != b.shape:
        return Verdict(False, f"{what}: shapes differ, {a.shape} and {b.shape}")
    differ = int(np.count_nonzero(a != b))
    return Verdict(differ == 0, f"{what}: {a.size - differ} of {a.size} the same ({int(a.sum())} true)")


def both(*verdicts: Verdict) -> Verdict:
    """All checks pass; the details joined (the failing ones first)."""
    ordered = sorted(verdicts, key=lambda v: v.ok)
    return Verdict(all(v.ok for v in verdicts), "; ".join(v.detail for v in ordered))
