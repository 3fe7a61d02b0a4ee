"""Trajectory simulation with named columns on top of the compiled core."""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cablekit import _cablekit
from cablekit.errors import ParameterError, ShapeError

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from cablekit._cablekit import CableTransmission, Model


@dataclass(frozen=True)
class SimulationResult:
    """A simulated run: time, inputs, states and outputs with their column names.

    Row ``k`` is sample ``t[k] = k*dt``: ``states[0]`` is ``x0`` and ``outputs[k] = h(states[k], inputs[k])``.
    Index by name: ``result["q_l1"]`` returns that column from whichever array has it.
    """

    t: NDArray[np.float64]
    inputs: NDArray[np.float64]
    states: NDArray[np.float64]
    outputs: NDArray[np.float64]
    input_names: list[str]
    state_names: list[str]
    output_names: list[str]
    meta: dict[str, object] = field(default_factory=dict)

    def __getitem__(self, name: str) -> NDArray[np.float64]:
        for names, arr in (
            (self.output_names, self.outputs),
            (self.state_names, self.states),
            (self.input_names, self.inputs),
        ):
            if name in names:
                return arr[:, names.index(name)]
        raise KeyError(f"no column {name!r}; available: {self.columns}")

    @property
    def columns(self) -> list[str]:
        """All column names in CSV order (time, inputs, states, outputs not already listed)."""
        seen: list[str] = ["t"]
        for n in self.input_names + self.state_names + self.output_names:
            if n not in seen:
                seen.append(n)
        return seen

    def to_csv(self, path: str | Path) -> Path:
        """Write every column (SI units) with a header row; returns the path."""
        path = Path(path)
        cols = self.columns
        data = np.column_stack([self.t] + [self[c] for c in cols[1:]])
        with path.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(cols)
            w.writerows(data.tolist())
        return path


def _result(
    model: Model,
    inputs: NDArray[np.float64],
    states: NDArray[np.float64],
    outputs: NDArray[np.float64],
    dt: float,
    **meta: object,
) -> SimulationResult:
    return SimulationResult(
        t=np.arange(states.shape[0], dtype=np.float64) * dt,
        inputs=inputs,
        states=states,
        outputs=outputs,
        input_names=model.input_names,
        state_names=model.state_names,
        output_names=model.output_names,
        meta={"dt": dt, "model": repr(model), **meta},
    )


def state_indices(model: Model, quantity: str) -> list[int]:
    """Indices of ``quantity`` (``"q_m"``, ``"dq_m"``, ``"q_l"``, ``"dq_l"``, …) of every link in
    the model's state vector, link 1 first, read off the core's ``state_names`` (no layout is
    assumed)."""
    names = model.state_names
    out = [i for i, n in enumerate(names) if n.rstrip("0123456789") == quantity]
    if not out:
        raise ParameterError(f"the model has no state {quantity!r}; its states are {names}")
    return out


def simulate(
    model: Model,
    inputs: NDArray[np.float64],
    dt: float,
    x0: NDArray[np.float64] | None = None,
    *,
    substeps: int = 1,
    hold: str = "zoh",
) -> SimulationResult:
    """Simulate ``model`` over sampled ``inputs`` of shape ``(T, model.n_inputs)``.

    Args:
        model: any cablekit model.
        inputs: C-contiguous float64 array, row ``k`` applied at ``t = k*dt``.
        dt: sample interval in seconds (> 0).
        x0: initial state ``(n_states,)``; the model's rest state (zeros) if omitted.
        substeps: RK4 steps per sample interval; see :func:`propose_step`.
        hold: ``"zoh"`` (inputs constant between samples) or ``"foh"`` (linear between samples).

    Raises:
        ShapeError, DTypeError, LayoutError, NotFiniteError, ParameterError,
        SimulationDivergedError (with ``.step`` and ``.time``).
    """
    states, outputs = _cablekit.simulate_arrays(model, inputs, dt, x0, substeps, hold)
    return _result(model, inputs, states, outputs, dt, substeps=substeps, hold=hold)


@dataclass(frozen=True)
class MotorPD:
    """Motor-space PD servo with torque saturation, evaluated once per sample (zero-order hold).

    ``tau = clip(kp*(q_ref - q_m) + kd*(dq_ref - dq_m), -torque_limit, torque_limit)`` per axis;
    gains in N·m/rad and N·m·s/rad, limits in N·m (the model's torque convention).
    """

    kp: tuple[float, ...]
    kd: tuple[float, ...]
    torque_limit: tuple[float, ...]

    @classmethod
    def raven2(cls, links: int = 3) -> MotorPD:
        """Raven-II's servo gains and default current limits (gearbox-output torque)."""
        return cls((0.30, 0.30, 0.15)[:links], (0.008, 0.008, 0.012)[:links], (0.68, 0.68, 0.54)[:links])


def simulate_servo(
    model: CableTransmission,
    references: NDArray[np.float64],
    dt: float,
    controller: MotorPD,
    *,
    external: NDArray[np.float64] | None = None,
    x0: NDArray[np.float64] | None = None,
    substeps: int = 1,
) -> SimulationResult:
    """Simulate a transmission under a discrete motor-space PD servo.

    ``references`` is ``(T, 2n)``: motor-angle references then motor-velocity references (use
    ``model.joint_to_motor`` to map joint trajectories). ``external`` is ``(T, n)`` joint loads.
    The torques the servo applied are returned as ``result.inputs``.
    """
    if len(controller.kp) != model.n_links:
        raise ShapeError(f"controller has {len(controller.kp)} axes, model has {model.n_links} links")
    states, outputs, inputs = _cablekit.simulate_servo_arrays(
        model,
        references,
        dt,
        kp=list(controller.kp),
        kd=list(controller.kd),
        torque_limit=list(controller.torque_limit),
        external=external,
        x0=x0,
        substeps=substeps,
    )
    return _result(model, inputs, states, outputs, dt, substeps=substeps, hold="zoh", controller=controller)


@dataclass(frozen=True)
class StepAdvice:
    """RK4 step advice from the stiffest mode of the linearised model."""

    max_stable_step: float
    """Largest stable RK4 step (s) at the linearisation point."""
    stiffest_eigenvalue: complex
    """The eigenvalue (1/s) that sets it."""
    substeps: int
    """RK4 sub-steps per sample interval ``dt`` (with the safety factor)."""


def propose_step(
    model: Model,
    dt: float,
    x: NDArray[np.float64] | None = None,
    u: NDArray[np.float64] | None = None,
    *,
    safety: float = 0.9,
) -> StepAdvice:
    """Largest stable RK4 step and the sub-steps needed at sample interval ``dt``.

    Linearises ``model`` at ``(x, u)`` (rest state and zero input by default), and for every
    eigenvalue ``λ`` of the Jacobian finds the largest ``h`` with ``|R(hλ)| <= 1`` for RK4's
    stability polynomial ``R``. Slack cables, contact and friction make the stiffness
    state-dependent: linearise at the stiffest state you expect, or keep the safety margin.
    """
    h, (re, im), n = _cablekit.propose_step_raw(model, dt, x, u, safety)
    return StepAdvice(max_stable_step=h, stiffest_eigenvalue=complex(re, im), substeps=n)
