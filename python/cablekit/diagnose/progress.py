"""Progress of long work on stderr: a thin, thread-safe layer over tqdm (quiet when disabled).

Every long loop of cablekit (candidate fits in parallel threads, self-test cases, benchmark
cases, network training) reports through :class:`Progress`, so the look and the ``--quiet``
switch are the same everywhere; tqdm draws the bar, its rate and remaining time."""

from __future__ import annotations

import sys
import threading

from tqdm import tqdm


class Progress:
    """``with Progress(total, "fitting") as p: ... p.advance(label)``. Thread-safe: parallel fits
    advance it from their threads."""

    def __init__(self, total: int, label: str, enabled: bool = True, width: int = 28):
        self.total = max(1, total)
        self.label = label
        self.enabled = enabled
        self.done = 0
        self._lock = threading.Lock()
        self._bar = tqdm(
            total=self.total,
            desc=f"{label:<14}",
            disable=not enabled,
            file=sys.stderr,
            ncols=width + 80,
            leave=True,
            bar_format="{desc} [{bar}] {n_fmt:>3}/{total_fmt:<3} {elapsed} <{remaining} {postfix}",
            ascii=" #",
        )

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self._bar.close()

    def advance(self, note: str = "") -> None:
        """One more unit done; ``note`` (what it was) is shown beside the bar."""
        with self._lock:
            self.done += 1
            if self.enabled:
                self._bar.set_postfix_str(note[:32], refresh=False)
            self._bar.update(1)
