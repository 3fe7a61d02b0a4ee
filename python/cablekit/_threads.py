"""Thread counts that do not oversubscribe a shared machine.

Small problems lose when they are spread over threads that must wait for a core another process
holds: torch's intra-op pool spins at each barrier while one of its threads waits (measured on
this 2-core machine with one core busy: Table-1 PSO-BPNN training 30.4 s with torch's default 2
threads, 3.5 s with 1). cablekit therefore picks the count from the problem's size and the cores
actually free, and lets the user decide:

* ``threads=`` on the call (e.g. ``TrainConfig(threads=1)``) wins;
* else the environment variable ``CABLEKIT_THREADS``;
* else automatic: one thread below :data:`PARALLEL_WORK` floating-point operations per step,
  otherwise the free cores — those in this process's affinity mask
  (``os.sched_getaffinity``) that are idle right now (the idle share of ``/proc/stat`` over
  50 ms; the 1-minute load average where there is no ``/proc/stat``).

``CABLEKIT_THREADS`` is also handed to the Rust core's rayon pool (``RAYON_NUM_THREADS``, when
that is not set) at import, before the pool starts.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Iterator
from contextlib import contextmanager

from cablekit.errors import ParameterError

__all__ = ["PARALLEL_WORK", "available_cores", "choose_threads", "torch_threads"]

#: below this many floating-point operations per step, one thread is faster than a pool
PARALLEL_WORK = 1e7


def _env_threads() -> int | None:
    raw = os.environ.get("CABLEKIT_THREADS")
    if raw is None or raw.strip() == "":
        return None
    try:
        n = int(raw)
    except ValueError:
        raise ParameterError(f"CABLEKIT_THREADS must be a whole number >= 1, got {raw!r}") from None
    if n < 1:
        raise ParameterError(f"CABLEKIT_THREADS must be a whole number >= 1, got {raw!r}")
    return n


def _cpu_times() -> tuple[float, float] | None:
    """``(idle, total)`` jiffies of all CPUs from ``/proc/stat`` (Linux), else None."""
    try:
        with open("/proc/stat") as fh:
            fields = [float(v) for v in fh.readline().split()[1:]]
    except (OSError, ValueError):  # pragma: no cover - not Linux
        return None
    if len(fields) < 5:  # pragma: no cover - unexpected format
        return None
    return fields[3] + fields[4], sum(fields[:8])


def available_cores(window_s: float = 0.05) -> int:
    """Cores this process may run on (affinity mask) that other work is not using right now:
    the idle share of all CPUs over ``window_s`` (``/proc/stat``), or the 1-minute load average
    where that is not available; at least 1."""
    try:
        allowed = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        allowed = os.cpu_count() or 1
    total_cpus = os.cpu_count() or allowed
    a = _cpu_times()
    if a is not None:
        time.sleep(window_s)
        b = _cpu_times()
        if b is not None and b[1] > a[1]:
            idle = total_cpus * (b[0] - a[0]) / (b[1] - a[1])
            return max(1, min(allowed, math.floor(idle + 0.5)))
    try:  # pragma: no cover - no /proc/stat
        busy = math.floor(os.getloadavg()[0] + 0.5)
    except (AttributeError, OSError):  # pragma: no cover - no load average
        busy = 0
    return max(1, min(allowed, allowed - busy))  # pragma: no cover


def choose_threads(flops_per_step: float, threads: int | None = None) -> int:
    """The thread count for a problem of ``flops_per_step``: the caller's ``threads``, else
    ``CABLEKIT_THREADS``, else automatic (see the module)."""
    if threads is not None:
        if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
            raise ParameterError(f"threads must be a whole number >= 1, got {threads!r}")
        return threads
    env = _env_threads()
    if env is not None:
        return env
    if not flops_per_step >= PARALLEL_WORK:  # also NaN
        return 1
    return available_cores()


@contextmanager
def torch_threads(n: int) -> Iterator[None]:
    """Run torch's intra-op work on ``n`` threads inside the block, restoring the count after."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def export_to_rayon() -> None:
    """Hand ``CABLEKIT_THREADS`` to the core's rayon pool (called once at import)."""
    env = os.environ.get("CABLEKIT_THREADS")
    if env and "RAYON_NUM_THREADS" not in os.environ:
        os.environ["RAYON_NUM_THREADS"] = env
