"""A dependency-free progress bar on stderr (quiet when disabled or not a terminal-like run)."""

from __future__ import annotations

import sys
import threading
import time


class Progress:
    """``with Progress(total, "fitting") as p: ... p.advance(label)``. Thread-safe."""

    def __init__(self, total: int, label: str, enabled: bool = True, width: int = 28):
        self.total = max(1, total)
        self.label = label
        self.enabled = enabled
        self.width = width
        self.done = 0
        self.t0 = time.perf_counter()
        self._lock = threading.Lock()

    def __enter__(self) -> Progress:
        self._draw("")
        return self

    def __exit__(self, *exc: object) -> None:
        if self.enabled:
            sys.stderr.write("\n")
            sys.stderr.flush()

    def advance(self, note: str = "") -> None:
        with self._lock:
            self.done += 1
            self._draw(note)

    def _draw(self, note: str) -> None:
        if not self.enabled:
            return
        frac = self.done / self.total
        filled = round(frac * self.width)
        elapsed = time.perf_counter() - self.t0
        bar = "#" * filled + "-" * (self.width - filled)
        sys.stderr.write(
            f"\r{self.label:<14} [{bar}] {self.done:>3}/{self.total:<3} {elapsed:6.1f}s {note[:32]:<32}"
        )
        sys.stderr.flush()
