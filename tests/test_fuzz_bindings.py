"""Property tests over every public binding (issue #20): a valid call with one argument replaced
by a drawn bad value — NaN, ±inf, ±1e308, an empty or huge array, another dtype, rank or
layout, another Python type, an out-of-range count.

The contract asserted for every draw:

* the call raises a :class:`cablekit.CablekitError` subclass, **or** (documented, before
  cablekit runs) PyO3's argument conversion raises ``TypeError`` for a scalar argument of another
  Python type or ``OverflowError`` for an integer outside the argument's range;
* or it returns, and then every number it returns is finite whenever every number it was given
  is finite (no NaN/inf out of finite input without an error);
* each call is bounded in time (the suite's per-test timeout; a hang holding the GIL cannot be
  interrupted in process, so the former hangs are also run in subprocesses in
  ``test_hardening.py``).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import cablekit as ck
from cablekit._cablekit import JointProblem, JointRun

R1 = ck.CableTransmission.raven2(1)
R3 = ck.CableTransmission.raven2(3)
AJ = ck.AntagonisticJoint.forceps_example()


def _finger_doc() -> dict[str, Any]:
    from cablekit.network import shipped_document

    return shipped_document("tendon_finger")


FINGER = ck.CableNetwork.from_json(json.dumps(_finger_doc()))
DAHL = ck.DahlElement(sigma0=1e3, coulomb=0.5)


def _arr(*shape: int, value: float = 0.1) -> np.ndarray:
    return np.full(shape, value)


@dataclass
class Call:
    """A valid call: ``fn(*args, **kwargs)``; the fuzzer replaces one argument at a time."""

    fn: Callable[..., Any]
    args: tuple[Any, ...] = ()
    kwargs: dict[str, Any] | None = None


def _from_functions(x0: Any, p0: Any, q: Any, r: Any, dt: Any = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """A filter over a user's callbacks (a contraction, the first state squared), one step;
    an overflow in the callbacks is an inf they return (NotFiniteError), not a warning."""

    def hx(x: np.ndarray) -> np.ndarray:
        with np.errstate(all="ignore"):
            return x[:1] ** 2

    f = ck.SrUkf.from_functions(lambda x, _dt: 0.9 * x, hx, x0, p0, q, r, dt=dt)
    f.step(np.zeros(0), np.ones(1))
    return f.x, f.P


def _dual_from_functions(x0: Any, theta0: Any, r: Any, dt: Any = 0.01) -> Any:
    """A dual filter over a user's callbacks (a contraction scaled by the parameter), 3 steps."""

    def fx(x: np.ndarray, theta: np.ndarray, _dt: float) -> np.ndarray:
        with np.errstate(all="ignore"):
            return x / (1.0 + theta[0] ** 2)

    f = ck.DualSrUkf.from_functions(
        fx, lambda x: x[:1], x0, np.eye(2), 1e-3 * np.eye(2), theta0, np.eye(1), 1e-3 * np.eye(1), r, dt=dt
    )
    return f.run(np.zeros((3, 0)), np.ones((3, 1)))


def _own(o: Any) -> Any:
    """A fresh copy of an array argument (same dtype, shape and layout); anything else as is."""
    return o.copy(order="K") if isinstance(o, np.ndarray) else o


def _srukf() -> ck.SrUkf:
    return ck.SrUkf(R1, np.zeros(4), np.eye(4), 1e-6 * np.eye(4), np.eye(2), dt=1e-3, states=[0, 2])


def _mlp(n_in: int = 2, hidden: int = 4, n_out: int = 1) -> ck.Mlp:
    """A small random tansig-purelin network, ``n_in``-``hidden``-``n_out``, from bytes."""
    from cablekit.nn import MapMinMax
    from cablekit.nn.export import FORMAT, FORMAT_VERSION, network_arrays, safetensors_bytes

    rng = np.random.default_rng(0)
    arrays = network_arrays(
        [rng.normal(size=(hidden, n_in)), rng.normal(size=(n_out, hidden))],
        [np.zeros(hidden), np.zeros(n_out)],
        MapMinMax(-np.ones(n_in), np.ones(n_in)),
        MapMinMax(np.zeros(n_out), np.ones(n_out)),
    )
    md = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "architecture": f'{{"sizes": [{n_in}, {hidden}, {n_out}], "activations": ["tansig", "purelin"]}}',
        "normalization": "mapminmax",
    }
    return ck.Mlp.from_bytes(safetensors_bytes(arrays, md))


def _problem() -> JointProblem:
    t = np.arange(200) * 1e-3
    run = JointRun(1e-3, 1e-3 * np.sin(6 * t), np.zeros((200, 1)))
    return JointProblem(AJ, [(0, 1.0, True)], [run], ["coulomb_friction"], substeps=8)


def _calls() -> dict[str, Call]:
    v = np.linspace(-1.0, 1.0, 7)
    out: dict[str, Call] = {
        "coulomb_friction": Call(ck.coulomb_friction, (v,), dict(coulomb=1.0, smoothing=0.1)),
        "stribeck_friction": Call(
            ck.stribeck_friction,
            (v,),
            dict(coulomb=1.0, static_level=1.5, stribeck_velocity=0.1, smoothing=0.01),
        ),
        "capstan_ratio": Call(ck.capstan_ratio, (v,), dict(mu=0.2, wrap=1.0, smoothing=0.1)),
        "dahl_rate": Call(ck.dahl_rate, (v, v), dict(sigma0=1.0, coulomb=1.0)),
        "cable_tension": Call(ck.cable_tension, (v, v), dict(stiffness=1e3, pretension=10.0)),
        "CableTransmission.raven2": Call(ck.CableTransmission.raven2, (2,)),
        "AntagonisticJoint": Call(
            ck.AntagonisticJoint, (), dict(radius=0.003, stiffness=3e4, inertia=2e-6, pretension=10.0)
        ),
        "DahlElement": Call(ck.DahlElement, (), dict(sigma0=1e3, coulomb=0.5)),
        "CableTransmission.energy": Call(R3.energy, (_arr(12),)),
        "CableNetwork.from_json": Call(ck.CableNetwork.from_json, (json.dumps(_finger_doc()),)),
        "CableNetwork.length_change": Call(FINGER.length_change, (_arr(3),)),
        "CableNetwork.joint_torques": Call(FINGER.joint_torques, (_arr(4),)),
        "CableNetwork.energy": Call(FINGER.energy, (_arr(FINGER.n_states), _arr(FINGER.n_inputs))),
        "CableTransmission.motor_to_joint": Call(R3.motor_to_joint, (_arr(3),)),
        "CableTransmission.joint_to_motor": Call(R3.joint_to_motor, (_arr(3),)),
        "kinematic_joint_angles": Call(ck.kinematic_joint_angles, (R3, _arr(5, 3))),
        "propose_step": Call(ck.propose_step, (R3, 1e-3)),
        "simulate": Call(ck.simulate, (R1, _arr(20, 2, value=0.0), 1e-3), dict(substeps=2)),
        "simulate_servo": Call(
            ck.simulate_servo, (R1, _arr(20, 2, value=0.0), 1e-3, ck.MotorPD.raven2(1)), dict(substeps=2)
        ),
        "estimate_joint_states": Call(ck.estimate_joint_states, (R1, _arr(30, 1), _arr(30, 1), 1e-3)),
        "Mlp.predict": Call(lambda x: _mlp().predict(x), (_arr(2),)),
        "Mlp.predict_into": Call(lambda x, o: _mlp().predict_into(x, o), (_arr(3, 2), np.zeros((3, 1)))),
        "Mlp.from_bytes": Call(ck.Mlp.from_bytes, (_mlp().to_bytes(),)),
        "SrUkf.step": Call(lambda u, y: _srukf().step(u, y), (_arr(2), _arr(2))),
        "SrUkf.x_into": Call(lambda o: _srukf().x_into(o), (np.zeros(4),)),
        "SrUkf.run": Call(lambda u, y: _srukf().run(u, y), (_arr(10, 2), _arr(10, 2))),
        "SrUkf.reset": Call(lambda x, p: _srukf().reset(x, p), (_arr(4), np.eye(4))),
        "SrUkf.linear": Call(
            ck.SrUkf.linear, (np.eye(2), np.eye(1, 2), _arr(2), np.eye(2), np.eye(2), np.eye(1))
        ),
        "DualSrUkf.from_functions": Call(_dual_from_functions, (_arr(2), _arr(1), np.eye(1)), {"dt": 0.01}),
        "SrUkf.from_functions": Call(
            _from_functions, (_arr(2), np.eye(2), 1e-3 * np.eye(2), np.eye(1)), {"dt": 0.01}
        ),
        "JointProblem.residuals": Call(lambda th: _problem().residuals(th), (_problem().reference(),)),
        "JointProblem.predict": Call(lambda th, r: _problem().predict(th, r), (_problem().reference(), 0)),
    }
    r1 = R1.params()
    r1.pop("n_links", None)
    out["CableTransmission"] = Call(ck.CableTransmission, (), r1)
    out["propose_step(x, u)"] = Call(ck.propose_step, (R1, 1e-3, _arr(4, value=0.0), _arr(2, value=0.0)))
    out["simulate(x0)"] = Call(ck.simulate, (AJ, _arr(20, 2, value=0.0), 1e-4, _arr(2, value=0.0)))
    out["SrUkf.with_parameters"] = Call(
        ck.SrUkf.with_parameters,
        (R1, ["cable_stiffness[0]"], _arr(5), np.eye(5), 1e-6 * np.eye(5), np.eye(1)),
        dict(dt=1e-3, states=[0], bounds=[(1.0, 1e6)]),
    )
    k = r1["cable_stiffness"][0]
    out["DualSrUkf"] = Call(
        ck.DualSrUkf,
        (R1, ["cable_stiffness[0]"], _arr(4, value=0.0), 1e-6 * np.eye(4), 1e-9 * np.eye(4),
         np.array([[(0.1 * k) ** 2]]), np.array([[1.0]]), 1e-8 * np.eye(2)),
        dict(dt=1e-3, states=[0, 2]),
    )  # fmt: skip
    t = np.arange(200) * 1e-3
    out["JointProblem"] = Call(
        lambda inp, meas, dt: JointProblem(
            AJ, [(0, 1.0, True)], [JointRun(dt, inp, meas)], ["coulomb_friction"], substeps=8
        ),
        (1e-3 * np.sin(6 * t), np.zeros((200, 1)), 1e-3),
    )
    from cablekit.cdpr import Robot, shipped

    robot = shipped("seed003_planar")
    pose = np.array([[0.6, 0.5, 0.0]])
    out["Robot.distribute"] = Call(robot.distribute, (pose, np.zeros((1, 3))), dict(method="auto"))
    out["Robot.inverse_kinematics"] = Call(robot.inverse_kinematics, (pose,))
    out["Robot.forward_kinematics"] = Call(
        robot.forward_kinematics, (robot.inverse_kinematics(pose).length[0], pose[0] + 0.01)
    )
    out["Robot.gravity_wrench"] = Call(robot.gravity_wrench, (pose[0],))
    out["Robot.capacity"] = Call(
        robot.capacity, (pose, np.zeros(3), np.full(3, 0.5)), dict(moment_length=0.5)
    )
    ctl = robot.controller()
    out["TensionController.step"] = Call(ctl.step, (pose[0], np.zeros(3), np.zeros(4)))
    anchors, attachments = robot.points()
    out["Robot"] = Call(
        Robot,
        (),
        dict(
            name="r", motion="planar", anchors=anchors, attachments=attachments, f_min=np.ones(4),
            f_max=np.full(4, 50.0), ea=np.full(4, 1e5), mass=1.0, com=np.zeros(3), inertia=np.eye(3),
            gravity=np.array([0.0, -9.8, 0.0]),
        ),
    )  # fmt: skip
    from cablekit.forceps import Jtdo

    jtdo = Jtdo(r2=4e-3, arm_a=12e-3, arm_b=14e-3)
    tensions = np.array([[12.0, 7.0, 14.0, 6.0], [12.5, 6.5, 14.0, 6.0]])
    out["Jtdo"] = Call(Jtdo, (), dict(r2=4e-3, arm_a=12e-3, arm_b=14e-3, threshold=0.11, bias=(0.0, 0.0)))
    out["Jtdo.step"] = Call(jtdo.step, (tensions[1], tensions[0]))
    out["Jtdo.estimate"] = Call(jtdo.estimate, (tensions, tensions[::-1].copy()))
    out["Jtdo.calibrated"] = Call(jtdo.calibrated, (tensions, tensions[::-1].copy(), np.ones((2, 2))))
    from cablekit.forceps import PhysicsObserver, Twin

    seed = Twin.seed()
    bench = dict(tension_noise=0.08, pressure_noise=0.01, seed=3, sample_time=0.01, substeps=100)
    out["Twin"] = Call(Twin, (seed.a, seed.b), bench)
    out["Twin.clamp"] = Call(seed.clamp, (2e-3, 0.5, 2, 0.1))
    out["Twin.run"] = Call(seed.run, (0.0, [("move", 1e-4, 1e-3)], 0.0, [("hold", 0.05)], True))
    physics = PhysicsObserver(r2=4e-3, arm_a=12e-3, arm_b=14e-3)
    motors = np.array([[1e-3, 5e-4, 1e-3, 5e-4], [1.005e-3, 5e-4, 1.005e-3, 5e-4]] * 12)
    out["PhysicsObserver"] = Call(
        PhysicsObserver, (), dict(r2=4e-3, arm_a=12e-3, arm_b=14e-3, losses_a=physics.losses[0].copy())
    )
    out["PhysicsObserver.step"] = Call(physics.step, (motors[0], tensions[0]))
    out["PhysicsObserver.estimate"] = Call(physics.estimate, (motors, np.repeat(tensions, 12, axis=0)))
    from cablekit.forceps import DriveModel

    t = np.arange(400) * 1e-3
    drive_runs = []
    for load in (0.01, 0.03, 0.05):
        th = 0.5 * (1 - np.cos(2 * np.pi * 2.0 * t))
        tj = -load - 0.01 * th
        ts = 0.01 * np.sign(np.sin(4 * np.pi * t)) - tj + 0.02 * th
        drive_runs.append(np.column_stack([th, ts, th, tj, th]))
    drive = DriveModel.fit(drive_runs, [0.01, 0.1], warmup=0.05)
    fit_kw = dict(dt=1e-3, window=20, warmup=0.05)
    out["DriveModel.fit"] = Call(DriveModel.fit, (drive_runs[:2], [0.01, 0.1]), fit_kw)
    weights = [np.ones(len(t)), np.linspace(0.0, 2.0, len(t))]
    out["DriveModel.fit(weights)"] = Call(
        DriveModel.fit, (drive_runs[:2], [0.01, 0.1]), {**fit_kw, "weights": weights}
    )
    out["DriveModel.fit(angle_friction)"] = Call(
        DriveModel.fit, (drive_runs[:2], [0.01, 0.1]), {**fit_kw, "angle_friction": (0.1, 0.9)}
    )
    out["DriveModel.fit(spindle_travels)"] = Call(
        DriveModel.fit, (drive_runs[:2], [0.01, 0.1]), {**fit_kw, "spindle_travels": [0.03]}
    )
    out["DriveModel.estimate"] = Call(drive.estimate, (drive_runs[0][:, :3].copy(),), dict(dt=1e-3))
    from cablekit.cdpr import Winch

    winch = Winch.seed003()
    out["Winch"] = Call(Winch, (winch.values.copy(),))
    out["Winch.zeros_and_poles"] = Call(winch.zeros_and_poles, ("fixed", True))
    out["Winch.root_locus"] = Call(winch.root_locus, ("synchronized", False, [0.5, 6.0]))
    out["Winch.dominant"] = Call(winch.dominant, ("fixed", False, 6.0))
    wd_kw = dict(setup="synchronized", lpf=False, pretension=10.0, current_limit=5.0, friction_smoothing=0.02)
    out["WinchDrive"] = Call(ck.WinchDrive, (winch,), dict(wd_kw, cable_damping=1.0))
    from cablekit.cdpr import Calibration, LoadCellPulley, SignalChain

    loads, reads = np.array([1.0, 2.0, 3.0]), np.array([12.0, 22.0, 32.5])
    out["Calibration.fit"] = Call(Calibration.fit, (loads, reads, loads[::-1].copy(), reads[::-1] + 0.1))
    out["Calibration.tension"] = Call(Calibration(10.0, 2.0).tension, (reads,))
    out["LoadCellPulley.push"] = Call(LoadCellPulley(0.1, 0.2).push, (5.0,))
    out["LoadCellPulley.tension_range"] = Call(LoadCellPulley(0.1, 0.2).tension_range, (50.0,))
    out["LoadCellPulley"] = Call(LoadCellPulley, (0.1, 0.2))
    out["Calibration"] = Call(Calibration, (2.0, 1.0))
    out["SignalChain"] = Call(SignalChain, (0.1, 0.03))
    from cablekit.cdpr import shipped

    mini = shipped("seed002_mini")
    q_mini = np.zeros((4, 6))
    q_mini[:, 2] = 0.475
    q_mini[:, 0] = np.linspace(0.0, 0.01, 4)
    f_mini = np.full((4, 8), 10.0)
    one = np.array([0.05])
    out["Robot.path_friction"] = Call(mini.path_friction, (q_mini, f_mini, 0.01, one, one, one))
    out["Robot.project_tensions"] = Call(mini.project_tensions, (q_mini, f_mini))
    t_chain = np.arange(50) * 0.01
    out["SignalChain.apply"] = Call(SignalChain(0.05, 0.02).apply, (t_chain, np.sin(t_chain)))
    out["JawObserver.step"] = Call(drive.observer().step, (0.1, -0.02, 0.1))
    out["DriveModel.recalibrated"] = Call(drive.recalibrated, (drive_runs[1],), dict(dt=1e-3, friction=True))
    out["DriveModel.recalibrated(list)"] = Call(drive.recalibrated, (drive_runs[1:],), dict(dt=1e-3))
    out["PhysicsObserver.calibrated"] = Call(
        physics.calibrated, (motors, np.repeat(tensions, 12, axis=0), np.zeros((24, 2)))
    )
    out["JointProblem.fit"] = Call(
        lambda th, ftol, max_iter, atol: _problem().fit(th, ftol=ftol, max_iter=max_iter, atol=atol),
        (_problem().reference(), 1e-8, 3, 1e-3),
    )
    out["JointProblem.head"] = Call(_problem().head, (0.05,))
    from cablekit.cdpr import CdprPlant, PulleyFriction

    planar, home = shipped("seed003_planar"), np.array([0.6, 0.5, 0.0])
    side = PulleyFriction(np.array([0.05]), np.array([1.0]), np.array([1.0]), law="coulomb")
    out["PulleyFriction"] = Call(PulleyFriction, (one, one, one), dict(law="dahl", presliding=1e-3))
    out["CdprPlant"] = Call(
        CdprPlant, (planar, home), dict(cable_damping=10.0, platform_side=side, creep=(one, one))
    )
    plant = CdprPlant(planar, home)
    loop_kw = dict(gain=0.5, feedback="sensor", sensor_noise=np.zeros((20, 4)))
    out["CdprPlant.closed_loop"] = Call(plant.closed_loop, (np.tile(home, (20, 1)), 1e-3), loop_kw)
    out.update(_calls_beyond_the_first_campaign(k, drive, jtdo, seed))
    models = (("R3", R3), ("AJ", AJ), ("Dahl", DAHL), ("WD", ck.WinchDrive.seed003()), ("CP", plant))
    for name, model in models:
        x, u = _arr(model.n_states, value=0.0), _arr(model.n_inputs, value=0.0)
        out[f"Model.derivative[{name}]"] = Call(model.derivative, (x, u))
        out[f"Model.output[{name}]"] = Call(model.output, (x, u))
        out[f"Model.jacobian[{name}]"] = Call(model.jacobian, (x, u))
        out[f"Model.rk4_step[{name}]"] = Call(model.rk4_step, (x, u, 1e-4), dict(substeps=2))
        # the controller loop's allocation-free forms (issue #40 §2); each draw writes into its
        # own copy of `out` (a shared one would carry one draw's result into the next)
        out[f"Model.rk4_step.out[{name}]"] = Call(
            lambda x, u, dt, o, m=model: m.rk4_step(x, u, dt, substeps=2, out=_own(o)),
            (x, u, 1e-4, np.zeros(model.n_states)),
        )
        out[f"Model.output.out[{name}]"] = Call(
            lambda x, u, o, m=model: m.output(x, u, out=_own(o)), (x, u, np.zeros(model.n_outputs))
        )
    return out


def _dual() -> ck.DualSrUkf:
    k = R1.params()["cable_stiffness"][0]
    return ck.DualSrUkf(
        R1, ["cable_stiffness[0]"], np.zeros(4), 1e-6 * np.eye(4), 1e-9 * np.eye(4),
        np.array([[(0.1 * k) ** 2]]), np.array([[1.0]]), 1e-8 * np.eye(2), dt=1e-3, states=[0, 2],
    )  # fmt: skip


def _with_pulleys(pulleys: Any) -> Any:
    from cablekit.cdpr import Robot, shipped

    anchors, attachments = shipped("seed003_planar").points()
    return Robot(
        name="r", motion="planar", anchors=anchors, attachments=attachments, f_min=np.ones(4),
        f_max=np.full(4, 50.0), ea=np.full(4, 1e5), mass=1.0, com=np.zeros(3), inertia=np.eye(3),
        gravity=np.array([0.0, -9.8, 0.0]), pulleys=pulleys,
    )  # fmt: skip


def _calls_beyond_the_first_campaign(k: float, drive: Any, jtdo: Any, seed: Any) -> dict[str, Call]:
    """Public methods the first table left out (added once every public name was listed)."""
    from cablekit.cdpr import Winch, shipped

    t = np.arange(200) * 1e-3
    run = JointRun(1e-3, 1e-3 * np.sin(6 * t), np.zeros((200, 1)))
    return {
        "DualSrUkf.run": Call(lambda u, y: _dual().run(u, y), (np.zeros((10, 2)), np.zeros((10, 2)))),
        "SrUkf.predict": Call(lambda u: _srukf().predict(u), (_arr(2),)),
        "SrUkf.update": Call(lambda u, y: _srukf().update(u, y), (_arr(2), _arr(2))),
        "SrUkf.with_input_states": Call(
            ck.SrUkf.with_input_states,
            (R1, [0], _arr(5, value=0.0), np.eye(5), 1e-6 * np.eye(5), np.eye(2)),
            dict(dt=1e-3, substeps=2, states=[0, 2]),
        ),
        "CableTransmission.with_parameter_values": Call(
            R1.with_parameter_values, (["cable_stiffness[0]"], np.array([0.5 * k]))
        ),
        "CableTransmission.parameter_values": Call(R1.parameter_values, (["cable_stiffness[0]"],)),
        "JointRun.with_measured": Call(run.with_measured, (np.zeros((200, 1)),)),
        "JointProblem.with_effects": Call(_problem().with_effects, (["viscous_friction"],), dict(substeps=4)),
        "JointProblem.advised_substeps": Call(_problem().advised_substeps, (_problem().reference(),)),
        "JointProblem.describe": Call(_problem().describe, ("coulomb_friction",)),
        "Jtdo.with_bias": Call(jtdo.with_bias, ((0.1, -0.1),)),
        "Twin.free_motion": Call(seed.free_motion, ([4e-3],), dict(pause=0.05)),
        "Winch.open_loop": Call(Winch.seed003().open_loop, ("fixed", True)),
        "DriveModel.observer": Call(drive.observer, (), dict(dt=1e-3)),
        "Robot.controller": Call(shipped("seed003_planar").controller, ("qp",), dict(gravity=True)),
        "propose_step_raw": Call(ck._cablekit.propose_step_raw, (R1, 1e-3), dict(safety=0.9)),
        "simulate_arrays": Call(
            ck._cablekit.simulate_arrays, (R1, np.zeros((20, 2)), 1e-3), dict(substeps=2)
        ),
        "simulate_servo_arrays": Call(
            ck._cablekit.simulate_servo_arrays,
            (R1, np.zeros((20, 2)), 1e-3),
            dict(kp=[1e3], kd=[10.0], torque_limit=[1.0], substeps=2),
        ),
        "JointProblem(channels)": Call(
            lambda ch: JointProblem(AJ, ch, [run], ["coulomb_friction"], substeps=8), ([(0, 1.0, True)],)
        ),
        "Robot(pulleys)": Call(lambda p: _with_pulleys(p), ([(0, 0.02, (0.0, 0.0, 1.0))],)),
    }


CALLS = _calls()

#: public callables outside the table, and why: no arguments to mutate (or only a model object,
#: whose wrong type is PyO3's TypeError as for every model argument), or (Mlp.load/save) a path
#: whose OS errors are Python's own (documented in docs/networks.md, tested in test_nn.py)
NOT_IN_TABLE = {
    "AntagonisticJoint.forceps_example", "AntagonisticJoint.params", "CableTransmission.params",
    "CableNetwork.from_joint", "CableNetwork.from_transmission", "CableNetwork.tension_closure",
    "JawObserver.reset", "JointProblem.candidate_library", "JointProblem.hold_from_updates",
    "JointProblem.param_specs", "JointProblem.reference", "Mlp.input_range", "Mlp.layers",
    "Mlp.output_range", "Mlp.to_bytes", "Mlp.load", "Mlp.save", "Model.rest_state",
    "PhysicsObserver.reset", "Robot.points", "SignalChain.hx711_ble", "TensionController.reset",
    "Twin.seed", "Winch.seed003", "WinchDrive.seed003", "effect_catalogue",
}  # fmt: skip


def test_every_public_binding_is_in_the_table():
    """A new binding or method joins the property table (or ``NOT_IN_TABLE`` with a reason)."""
    import cablekit._cablekit as m

    names = []
    for n in (n for n in dir(m) if not n.startswith("_")):
        obj = getattr(m, n)
        if not isinstance(obj, type):
            names.append(n)
            continue
        names += [f"{n}.{a}" for a in vars(obj) if not a.startswith("_") and callable(getattr(obj, a))]
    covered = {k.split("(")[0].split("[")[0] for k in CALLS}
    missing = sorted(set(names) - covered - NOT_IN_TABLE)
    assert not missing, f"public bindings without property draws: {missing}"


def _finite_numbers(obj: Any) -> bool:
    """Whether every number in ``obj`` (arrays, scalars, containers, result objects) is finite."""
    if isinstance(obj, np.ndarray):
        return obj.dtype.kind not in "fc" or bool(np.isfinite(obj).all())
    if isinstance(obj, bool | str | bytes) or obj is None:
        return True
    if isinstance(obj, int | float):
        return math.isfinite(obj)
    if isinstance(obj, dict):
        return all(_finite_numbers(v) for v in obj.values())
    if isinstance(obj, list | tuple):
        return all(_finite_numbers(v) for v in obj)
    if isinstance(obj, ck.StepAdvice):  # documented: h_max is +inf when no mode limits the step
        return obj.max_stable_step > 0 and 1 <= obj.substeps <= 100_000
    if hasattr(obj, "__dataclass_fields__"):
        return all(_finite_numbers(getattr(obj, f)) for f in obj.__dataclass_fields__)
    if type(obj).__name__ in _RESULTS and type(obj).__module__ == "cablekit._cablekit":
        values = [getattr(obj, n) for n in dir(obj) if not n.startswith("_")]
        return all(_finite_numbers(v) for v in values if not callable(v))
    return True


#: typed results whose every number is finite from finite input (FilterRun/FilterHealth are
#: not: their NIS is NaN, as documented, at a step without a measurement)
_RESULTS = {
    "ClampRun",
    "ClampStep",
    "Tensions",
    "Kinematics",
    "Capacity",
    "Step",
    "FitReport",
    "DualRun",
    "TwinRun",
    "PhysicsCalibration",
    "JawEstimate",
    "JawSample",
    "LoopRun",
    "PathRun",
    "CalibrationFit",
}


def _is_finite_input(obj: Any) -> bool:
    if isinstance(obj, np.ndarray) and obj.dtype.kind in "fc":
        return bool(np.isfinite(obj).all())
    if isinstance(obj, float):
        return math.isfinite(obj)
    return True


def _bad_arrays(a: np.ndarray) -> st.SearchStrategy[Any]:
    shape = a.shape
    specials = st.sampled_from([np.nan, np.inf, -np.inf, 1e308, -1e308, 1e154, 5e-324, 0.0])

    def poke(v: float, at: int) -> np.ndarray:
        b = a.astype(np.float64).copy()
        if b.size:
            b.flat[at % b.size] = v
        return b

    return st.one_of(
        st.builds(poke, specials, st.integers(0, 10**6)),
        st.builds(lambda v: np.full(shape, v), specials),
        st.just(np.zeros((0, *shape[1:]))),
        st.just(np.zeros((*shape, 1))),
        st.just(a.reshape(-1)[:1].copy() if a.size else a),
        st.just(np.zeros((10**6, shape[-1])) if len(shape) == 2 else np.zeros(10**6)),
        st.sampled_from(["float32", "int64", "complex128", "object", "bool"]).map(lambda d: a.astype(d)),
        st.just(np.asfortranarray(np.repeat(a[..., None], 2, axis=-1))[..., 0] if a.ndim else a),
        st.just(a.tolist()),
        st.sampled_from([None, "x", 1, {"a": 1}]),
    )


def _bad_scalars(v: Any) -> st.SearchStrategy[Any]:
    if isinstance(v, bool):
        return st.sampled_from([None, "yes", 2])
    if isinstance(v, int):
        return st.sampled_from([0, -1, 2**31, 2**64, 10**30, 1.5, "1", None])
    if isinstance(v, float):
        return st.sampled_from([0.0, -1.0, math.nan, math.inf, -math.inf, 1e308, -1e308, 5e-324, "1", None])
    if isinstance(v, list | tuple) and v and all(isinstance(x, float) for x in v):
        specials = [math.nan, math.inf, -math.inf, 1e308, -1e308, 0.0, -1.0]
        return st.one_of(
            st.sampled_from(specials).map(lambda x: type(v)([x, *v[1:]])),
            st.just(type(v)()),
            st.just(type(v)([*v, *v])),
            st.sampled_from([None, "x", 1.0, [v]]),
        )
    if isinstance(v, list) and v and isinstance(v[0], tuple):  # a list of tuples: one of the wrong length
        first = v[0]
        return st.sampled_from([[first[:-1], *v[1:]], [(*first, first[0]), *v[1:]], [()], [None], ["ab"]])
    if isinstance(v, tuple) and v:  # a tuple of arrays: the wrong length
        return st.sampled_from([v[:-1], (*v, v[0]), (), None, "x"])
    if isinstance(v, bytes):
        return st.one_of(
            st.binary(max_size=300),
            st.integers(0, len(v)).map(lambda k: v[:k]),
            st.integers(0, max(len(v) - 1, 0)).map(lambda k: v[:k] + bytes([v[k] ^ 0xFF]) + v[k + 1 :]),
        )
    return st.sampled_from([None, "x", 1.0])


@st.composite
def mutated(draw: st.DrawFn, call: Call) -> tuple[tuple[Any, ...], dict[str, Any], bool, bool]:
    args, kwargs = list(call.args), dict(call.kwargs or {})
    slots = [("a", i) for i, a in enumerate(args) if not isinstance(a, ck.Model | ck.MotorPD)]
    slots += [("k", k) for k in kwargs]
    kind, key = draw(st.sampled_from(slots))
    old = args[key] if kind == "a" else kwargs[key]  # type: ignore[index]
    new = draw(_bad_arrays(old) if isinstance(old, np.ndarray) else _bad_scalars(old))
    if kind == "a":
        args[key] = new  # type: ignore[index]
    else:
        kwargs[key] = new  # type: ignore[index]
    finite = all(_is_finite_input(a) for a in [*args, *kwargs.values()])
    return tuple(args), kwargs, finite, isinstance(old, np.ndarray | bytes)


@pytest.mark.parametrize("name", sorted(CALLS))
def test_the_valid_call_works_and_is_finite(name):
    call = CALLS[name]
    assert _finite_numbers(call.fn(*call.args, **(call.kwargs or {})))


@pytest.mark.parametrize("name", sorted(CALLS))
@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large]
)
@given(data=st.data())
def test_a_bad_argument_is_a_typed_error_or_a_finite_result(name, data):
    call = CALLS[name]
    args, kwargs, finite, was_array = data.draw(mutated(call))
    try:
        result = call.fn(*args, **kwargs)
    except ck.CablekitError:
        return
    except (TypeError, OverflowError):
        # PyO3's conversion of a scalar of another Python type or an out-of-range integer
        # (documented); an array argument of the wrong kind must be cablekit's own error
        assert not was_array, f"{name}: a bad array argument raised a non-cablekit error"
        return
    if finite:
        assert _finite_numbers(result), f"{name}{args, kwargs} returned non-finite numbers"


def _clamped_mean(x: np.ndarray, w: int) -> np.ndarray:
    """NumPy reference of ``Channel.window``: a centred mean of ``w`` samples whose window stays
    inside the series (the whole series when it is shorter)."""
    n = len(x)
    w = min(w, n)
    lo = np.clip(np.arange(n) - w // 2, 0, n - w)
    return np.array([x[a : a + w].mean() for a in lo])


@settings(max_examples=80, deadline=None)
@given(
    window=st.one_of(
        st.integers(-3, 400),
        st.sampled_from([2**40, 2**64, -(2**63)]),
        st.floats(allow_nan=True),
        st.text(max_size=3),
        st.none(),
    )
)
def test_a_channels_window_averages_its_residual_or_is_a_typed_error(window):
    """``JointProblem`` channels ``(output, weight, sensor, window)``: an odd window scores the
    centred mean of the plain channel's residual (NumPy reference, clamped at the ends; a window
    longer than the run is the run's mean), the other channels untouched; anything else is a
    typed error."""
    t = np.arange(120) * 1e-3
    rng = np.random.default_rng(1)
    run = JointRun(1e-3, 1e-3 * np.sin(6 * t), rng.normal(0, 0.1, (120, 2)))
    plain = JointProblem(AJ, [(0, 2.0, True), (4, 50.0, False)], [run], [], substeps=4)
    try:
        windowed = JointProblem(AJ, [(0, 2.0, True, window), (4, 50.0, False)], [run], [], substeps=4)
    except ck.CablekitError:
        assert not (isinstance(window, int) and window >= 1 and window % 2 == 1 and window < 2**63)
        return
    assert isinstance(window, int) and window % 2 == 1
    r0 = plain.residuals(np.zeros(0)).reshape(-1, 2)
    r1 = windowed.residuals(np.zeros(0)).reshape(-1, 2)
    assert np.array_equal(r0[:, 1], r1[:, 1])
    np.testing.assert_allclose(r1[:, 0], _clamped_mean(r0[:, 0], window), rtol=1e-12, atol=1e-14)


def _shifted(x: np.ndarray, m: int) -> np.ndarray:
    """NumPy reference of a delay by ``m`` whole samples, the record's first sample held."""
    return x[np.clip(np.arange(len(x)) - m, 0, None)]


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    commands=st.one_of(
        st.integers(1, 3).map(lambda k: np.sin(np.arange(120 * k) * 0.05).reshape(120, k) * 0.01),
        st.sampled_from(["nan", "inf", "huge", "short", "text", "none", "1d"]),
    ),
    command=st.one_of(st.integers(-2, 3), st.sampled_from([2**64, 1.5, "0"]), st.none()),
    shift=st.integers(0, 12),
)
def test_a_channels_command_is_delayed_by_the_input_delay_or_is_a_typed_error(commands, command, shift):
    """``JointRun(commands=...)`` and channels ``(output, weight, sensor, window, command)``: under
    ``time_delay@input`` at ``d`` the channel holding command column ``j`` gains ``τ_j(t) −
    τ_j(t − d)`` (NumPy reference, ``d`` a whole number of samples), every other channel is
    unchanged; without a delay nothing changes. Bad commands (NaN/inf, a wrong length, a column
    no run has, wrong types) are typed errors."""
    t = np.arange(120) * 1e-3
    rng = np.random.default_rng(2)
    meas = rng.normal(0, 0.1, (120, 2))
    if isinstance(commands, str):
        commands = {
            "nan": np.full((120, 1), np.nan),
            "inf": np.full((120, 1), np.inf),
            "huge": np.full((120, 1), 1e300),
            "short": np.zeros((60, 1)),
            "text": "abc",
            "none": None,
            "1d": np.cos(t),
        }[commands]
    x = 1e-3 * np.sin(6 * t)
    chans = [(0, 2.0, True), (4, 50.0, False)]
    plain = JointProblem(AJ, chans, [JointRun(1e-3, x, meas)], ["time_delay"], substeps=4)
    try:
        run = JointRun(1e-3, x, meas, commands=commands)
        held = JointProblem(AJ, [(0, 2.0, True, 1, command), chans[1]], [run], ["time_delay"], substeps=4)
    except (ck.CablekitError, TypeError, OverflowError):
        width = commands.shape[1] if isinstance(commands, np.ndarray) and commands.ndim == 2 else 1
        in_range = command is None or (type(command) is int and 0 <= command < width)
        finite = isinstance(commands, np.ndarray) and bool(np.all(np.isfinite(commands)))
        assert not (finite and len(commands) == 120 and in_range)
        return
    assert commands is None or (isinstance(commands, np.ndarray) and np.all(np.isfinite(commands)))
    assert command is None or commands is not None
    d = shift * 1e-3
    r0 = plain.residuals(np.array([d])).reshape(-1, 2)
    r1 = held.residuals(np.array([d])).reshape(-1, 2)
    assert np.array_equal(r0[:, 1], r1[:, 1])
    if command is None or shift == 0:
        np.testing.assert_allclose(r1[:, 0], r0[:, 0], rtol=1e-12, atol=1e-14)
        return
    cmd = np.asarray(commands, dtype=float).reshape(120, -1)[:, command]
    want = r0[:, 0] + 2.0 * (cmd - _shifted(cmd, shift))
    np.testing.assert_allclose(r1[:, 0], want, rtol=1e-9, atol=1e-12)
