"""The kernels of ``benches/peers.py``, each with its peers (see that script and ``core``)."""

from __future__ import annotations

from . import cdpr, diagnosis, estimation, networks, simulation
from .core import Config, Kernel, Pair, Peer, Row, Side, Verdict, check, measure, time_pair

#: in the order the table lists them
KERNELS: tuple[Kernel, ...] = (
    estimation.KERNEL,
    networks.FORWARD,
    cdpr.TENSION,
    simulation.KERNEL,
    networks.TRAINING,
    diagnosis.KERNEL,
    cdpr.WORKSPACE,
    cdpr.KINEMATICS,
)

__all__ = [
    "KERNELS",
    "Config",
    "Kernel",
    "Pair",
    "Peer",
    "Row",
    "Side",
    "Verdict",
    "check",
    "measure",
    "time_pair",
]
