"""cablekit: simulate, estimate and diagnose cable-driven robots.

The numerical core is Rust (``cablekit._cablekit``); this package re-exports it with named,
documented Python entry points. SI units everywhere.
"""

from __future__ import annotations

from cablekit._cablekit import (
    AntagonisticJoint,
    CableNetwork,
    CableTransmission,
    DahlElement,
    DualSrUkf,
    Mlp,
    Model,
    SrUkf,
    WinchDrive,
    __version__,
    cable_tension,
    capstan_ratio,
    coulomb_friction,
    dahl_rate,
    stribeck_friction,
)
from cablekit._threads import export_to_rayon
from cablekit.errors import (
    CablekitError,
    ConcurrentUseError,
    ConvergenceError,
    DataError,
    DTypeError,
    FilterDivergedError,
    InternalError,
    LayoutError,
    NonFiniteResultError,
    NotFiniteError,
    ParameterError,
    ShapeError,
    SimulationDivergedError,
    WeightsFormatError,
)
from cablekit.estimate import JointStateEstimate, estimate_joint_states, kinematic_joint_angles
from cablekit.simulation import (
    MotorPD,
    SimulationResult,
    StepAdvice,
    propose_step,
    simulate,
    simulate_servo,
)

export_to_rayon()  # CABLEKIT_THREADS reaches the core's rayon pool (started lazily, on first use)

__all__ = [
    "AntagonisticJoint",
    "CableNetwork",
    "CableTransmission",
    "CablekitError",
    "ConcurrentUseError",
    "ConvergenceError",
    "DTypeError",
    "DahlElement",
    "DataError",
    "DualSrUkf",
    "FilterDivergedError",
    "InternalError",
    "JointStateEstimate",
    "LayoutError",
    "Mlp",
    "Model",
    "MotorPD",
    "NonFiniteResultError",
    "NotFiniteError",
    "ParameterError",
    "ShapeError",
    "SimulationDivergedError",
    "SimulationResult",
    "SrUkf",
    "StepAdvice",
    "WeightsFormatError",
    "WinchDrive",
    "__version__",
    "cable_tension",
    "capstan_ratio",
    "coulomb_friction",
    "dahl_rate",
    "estimate_joint_states",
    "kinematic_joint_angles",
    "propose_step",
    "simulate",
    "simulate_servo",
    "stribeck_friction",
]
