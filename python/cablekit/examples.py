"""Embedded example runs (no data files needed): the main job's default inputs."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cablekit._cablekit import AntagonisticJoint, CableTransmission
from cablekit.errors import ParameterError
from cablekit.simulation import (
    MotorPD,
    SimulationResult,
    propose_step,
    simulate,
    simulate_servo,
    state_indices,
)


def _grid(duration: float, dt: float) -> np.ndarray:
    """Sample times ``k*dt`` covering ``duration`` seconds."""
    if not (dt > 0 and duration > 0):
        raise ParameterError(f"duration and dt must be > 0, got duration={duration}, dt={dt}")
    return np.arange(round(duration / dt), dtype=np.float64) * dt


def raven_link(duration: float = 4.0, dt: float = 1e-3) -> SimulationResult:
    """Raven-II shoulder, elbow and insertion under Raven's 1 kHz motor-space PD servo.

    Each joint follows a 0.5 Hz sinusoid about mid-range (shoulder 45°±15°, elbow 90°±15°,
    insertion 0.40±0.05 m); references are mapped to motor space with the rigid-cable kinematics
    ``q_m = T q_l`` of eq. (2.8), as Raven's controller does. The difference between the true joint
    position and the transmission-kinematics estimate ``T⁻¹ q_m`` is the cable-stretch error that
    motor-encoder-only robots cannot see.
    """
    model = CableTransmission.raven2(3)
    t = _grid(duration, dt)
    w = 2 * np.pi * 0.5
    centre = np.array([np.pi / 4, np.pi / 2, 0.40])
    amp = np.array([np.radians(15), np.radians(15), 0.05])
    q_l = centre + amp * np.sin(w * t)[:, None]
    dq_l = amp * w * np.cos(w * t)[:, None]
    tmat = model.transmission_matrix
    refs = np.ascontiguousarray(np.hstack([q_l @ tmat.T, dq_l @ tmat.T]))
    x0 = np.zeros(model.n_states)
    x0[state_indices(model, "q_m")] = tmat @ centre
    x0[state_indices(model, "q_l")] = centre
    advice = propose_step(model, dt, x0, np.zeros(model.n_inputs))
    result = simulate_servo(model, refs, dt, MotorPD.raven2(3), x0=x0, substeps=advice.substeps)
    result.meta.update(example="raven-link", reference_joint=q_l, advice=advice)
    return result


def forceps(duration: float = 4.0, dt: float = 1e-3) -> SimulationResult:
    """One EndoWrist-like forceps jaw (seed 000) driven by a 0.5 Hz motor sinusoid.

    The jaw swings ±0.5 rad and closes on an object at 0.3 rad; motor-side tensions include the
    capstan losses of the routing pulleys, so they differ from the joint-side tensions with a
    hysteresis that flips with the motor's direction.
    """
    model = AntagonisticJoint.forceps_example()
    r = model.params()["radius"]
    t = _grid(duration, dt)
    w = 2 * np.pi * 0.5
    x_m = r * 0.5 * np.sin(w * t)
    dx_m = r * 0.5 * w * np.cos(w * t)
    u = np.ascontiguousarray(np.column_stack([x_m, dx_m]))
    # linearise in contact, the stiffest configuration
    advice = propose_step(model, dt, np.array([0.35, 0.0]), np.array([0.35 * r, 0.0]))
    result = simulate(model, u, dt, substeps=advice.substeps, hold="foh")
    result.meta.update(example="forceps", advice=advice)
    return result


EXAMPLES: dict[str, Callable[..., SimulationResult]] = {"raven-link": raven_link, "forceps": forceps}


def run_example(name: str, duration: float = 4.0, dt: float = 1e-3) -> SimulationResult:
    """Run the embedded example ``name`` (one of :data:`EXAMPLES`)."""
    try:
        fn = EXAMPLES[name]
    except KeyError:
        raise ParameterError(f"unknown example {name!r}; choose from {sorted(EXAMPLES)}") from None
    return fn(duration=duration, dt=dt)
