"""Estimation tasks on the square-root UKF (seed 001, chapters 3–5).

``SrUkf`` (the filter itself) is compiled; this module holds the task-level helpers that set it
up for a cable transmission and return results with named fields:

* :func:`estimate_joint_states` — joint angles and velocities of a cable transmission from its
  motor encoders and the applied motor torques (seed 001 ch. 3), with the transmission
  kinematics estimate alongside for comparison;
* :func:`kinematic_joint_angles` — the rigid-cable estimate ``q_l = T⁻¹·q_m``;
* :func:`estimate_parameters` — joint state–parameter estimation of transmission parameters
  (cable stiffness and damping, coupling coefficients, pulley radius, …) as random-walk states
  with bounds (seed 001 §3.3, ch. 4);
* :func:`estimate_external_force` — external joint forces as random-walk states (the UKF
  method of seed 001 §5.3), and :class:`CableStretchForce` — the cable-stretch method with its
  two-Gaussian, four-quadrant classification;
* :func:`estimate_stiffness`, :class:`PretensionMap`, :class:`StringCalibration` — pretension
  from the filter's cable stiffness through a fitted quadratic map, its Low/Mid/High category,
  and the taut-string frequency → tension calibration (seed 001 §5.2).
"""

from __future__ import annotations

from cablekit.estimate.common import kinematic_joint_angles
from cablekit.estimate.force import (
    CableStretchForce,
    ForceEstimate,
    estimate_external_force,
    stretch_and_rate,
)
from cablekit.estimate.joint_states import JointStateEstimate, estimate_joint_states
from cablekit.estimate.parameters import ParameterEstimate, TransmissionParameters, estimate_parameters
from cablekit.estimate.pretension import (
    PretensionEstimate,
    PretensionMap,
    StringCalibration,
    estimate_pretension,
    estimate_stiffness,
)

__all__ = [
    "CableStretchForce",
    "ForceEstimate",
    "JointStateEstimate",
    "ParameterEstimate",
    "PretensionEstimate",
    "PretensionMap",
    "StringCalibration",
    "TransmissionParameters",
    "estimate_external_force",
    "estimate_joint_states",
    "estimate_parameters",
    "estimate_pretension",
    "estimate_stiffness",
    "kinematic_joint_angles",
    "stretch_and_rate",
]
