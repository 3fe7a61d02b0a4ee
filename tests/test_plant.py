"""``CdprPlant`` (issue #23): a cable-driven parallel robot with winches and pulleys as a model —
f and h against a NumPy reference, rest at home, the closed loop's desired tensions against the
tension distribution, the force loop's physics, seed 002's Tables 3–4 and seed 003's planar robot
in closed loop, and bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cablekit.cdpr import CdprPlant, PulleyFriction, Robot, Winch, shipped
from cablekit.cdpr.planar import HOME, circle, planar_plant
from cablekit.errors import CablekitError, NotFiniteError, ParameterError, ShapeError
from tests.reference.plant import planar_plant as reference

# seed 003's planar robot (the shipped file's values) with its centre of mass off the origin
SPEC = dict(
    anchors=np.array([[0.0, 1.0, 0.0], [1.2, 1.0, 0.0], [0.0, 0.0, 0.0], [1.2, 0.0, 0.0]]),
    attachments=np.array([[-0.05, 0.05, 0.0], [0.05, 0.05, 0.0], [-0.05, -0.05, 0.0], [0.05, -0.05, 0.0]]),
    f_min=np.full(4, 1.0),
    f_max=np.full(4, 98.0),
    ea=np.full(4, 48.9e9 * 1.89e-6),
    mass=1.0,
    com=np.array([0.01, -0.005, 0.0]),
    inertia=np.diag([0.0, 0.0, 1.7e-3]),
    gravity=np.array([0.0, -9.80665, 0.0]),
)
PLANAR = Robot(name="planar", motion="planar", **SPEC)
DRUM_SCALE = np.array([1.0, 1.5, 0.5, 1.2])
WINCH = dict(zip(Winch.NAMES, Winch.seed003().values, strict=True))


def _rough(damping: float = 30.0) -> CdprPlant:
    return CdprPlant(
        PLANAR,
        HOME,
        Winch.seed003(),
        cable_damping=damping,
        platform_side=PulleyFriction(np.array([0.04]), np.array([3.0]), np.array([np.pi / 2]), law="coulomb"),
        drum_side=PulleyFriction(np.array([0.02]), np.array([1.0]), np.array([np.pi]), law="coulomb"),
        creep=(np.array([0.3]), np.array([2.0])),
        drum_friction=DRUM_SCALE,
    )


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_f_and_h_equal_the_numpy_reference(seed):
    """A planar robot with Coulomb pulley friction on both sides: derivative and outputs at
    random states about rest agree with the NumPy reference to 1e-9 (relative)."""
    rng = np.random.default_rng(seed)
    plant = _rough()
    x = np.zeros(plant.n_states)
    x[:3] = HOME + rng.normal(0, [0.02, 0.02, 0.05])
    x[3:6] = rng.normal(0, 0.2, 3)
    x[6:22] = rng.normal(0, [0.01] * 4 + [0.5] * 4 + [0.02] * 4 + [0.01] * 4)
    x[30:34] = rng.normal(0, 1e-4, 4)  # creep stretches (m)
    u = np.concatenate(
        [rng.normal(0, 0.01, 4), rng.normal(0, 0.3, 4), rng.normal(0, 0.5, 4), rng.normal(0, 1, 3)]
    )
    kw = dict(
        anchors=SPEC["anchors"],
        attach=SPEC["attachments"],
        ea=SPEC["ea"],
        mass=SPEC["mass"],
        izz=SPEC["inertia"][2, 2],
        com=SPEC["com"],
        gravity=SPEC["gravity"],
        rest=plant.rest_length,
        winch=WINCH,
        mu_d=0.04,
        wrap_d=np.pi / 2,
        mu_u=0.02,
        wrap_u=np.pi,
        visc_d=3.0,
        visc_u=1.0,
        eps_path=1e-3,
        damping=30.0,
        current_limit=10.0,
        eps_drum=0.01,
        creep_ratio=0.3,
        creep_tau=2.0,
        drum_scale=DRUM_SCALE,
    )
    dx, y = reference(x, u, **kw)
    np.testing.assert_allclose(plant.derivative(x, u), dx, rtol=1e-9, atol=1e-9 * (1 + np.abs(dx).max()))
    np.testing.assert_allclose(plant.output(x, u), y, rtol=1e-9, atol=1e-9)


def test_rest_at_home_holds_the_distributed_tensions():
    plant = planar_plant(PLANAR)
    x, u = plant.rest_state(), np.zeros(plant.n_inputs)
    assert np.abs(plant.derivative(x, u)).max() < 1e-8
    want = PLANAR.distribute(HOME[None, :]).f[0]
    np.testing.assert_allclose(plant.home_tensions, want, rtol=1e-9)
    y = plant.output(x, u)
    np.testing.assert_allclose(y[3:7], want, rtol=1e-9)  # EE
    np.testing.assert_allclose(y[15:19], want, rtol=1e-9)  # motor-current estimate
    assert plant.tension_per_ampere == pytest.approx(
        WINCH["torque_constant"] * WINCH["gear_ratio"] / WINCH["drum_radius"]
    )


def test_closed_loop_desired_tensions_are_the_distribution_of_weight_and_inertia():
    """f_d at each period is Robot.distribute at the desired pose with the inertial wrench of the
    desired motion (central differences); frictionless, the platform follows within 0.5 mm and
    its tensions f_d within 0.2 N (the controller's inertial wrench leaves out the centre of
    mass's offset, which this robot has)."""
    plant = planar_plant(
        PLANAR, winch=Winch(np.where(np.array(Winch.NAMES) == "static_friction", 0.0, Winch.seed003().values))
    )
    dt = 1e-3
    poses = circle(HOME, radius=0.05, period=2.0, turns=1.0, dt=dt)
    run = plant.closed_loop(poses, dt)
    acc = np.zeros_like(poses)
    acc[1:-1] = (poses[2:] - 2 * poses[1:-1] + poses[:-2]) / dt**2
    m, izz = SPEC["mass"], SPEC["inertia"][2, 2]
    wrench = -np.column_stack([m * acc[:, 0], m * acc[:, 1], izz * acc[:, 2]])
    want = PLANAR.distribute(poses, wrench).f
    np.testing.assert_allclose(run.desired, want, rtol=1e-9, atol=1e-9)
    assert np.abs(run.pose - poses).max() < 5e-4
    assert np.sqrt(np.mean((run.ee - run.desired) ** 2)) < 0.2
    # the wrench of f_d is the desired one: M·a − m·g
    np.testing.assert_allclose(run.wrench_desired[:, :2], m * (acc[:, :2] - SPEC["gravity"][:2]), atol=1e-6)


def test_the_force_loop_corrects_platform_side_friction_only_through_a_platform_side_tension():
    """Friction between the sensor and the platform: feeding the platform-side tension back takes
    the tension error down (more with more gain); feeding the winch-side sensor back does not."""
    plant = CdprPlant(
        PLANAR,
        HOME,
        Winch(np.where(np.array(Winch.NAMES) == "static_friction", 0.0, Winch.seed003().values)),
        platform_side=PulleyFriction(np.array([0.05]), np.array([2.0]), np.array([np.pi]), law="coulomb"),
    )
    poses = circle(HOME, radius=0.05, period=2.0, turns=1.0)

    def err(feedback, gain):
        r = plant.closed_loop(poses, 1e-3, feedback=feedback, gain=gain)
        return np.sqrt(np.mean((r.ee - r.desired) ** 2))

    open_ = err("open", 0.0)
    assert err("platform", 0.7) < 0.75 * open_
    assert err("platform", 3.0) < 0.4 * open_
    assert err("sensor", 0.7) > 0.95 * open_

    # the same loop fed a measurement a few periods older rings on the drums' cable mode
    def late(gain, delay):
        r = plant.closed_loop(poses, 1e-3, feedback="platform", gain=gain, sensor_delay=delay)
        return np.sqrt(np.mean((r.ee - r.desired) ** 2))

    assert late(3.0, 2) > 10 * late(3.0, 0)
    assert late(0.7, 5) > 10 * late(0.7, 0)


def test_planar_robot_step_and_circle():
    """Seed 003's robot (``PlanarRobot``): a 20 mm step settles with the PID's integral (no error
    left), the tension distribution in the loop tracks the circle's tensions better than
    kinematics alone, and ``follow`` equals the plant's closed loop."""
    from cablekit.cdpr import PlanarRobot

    robot = PlanarRobot()
    s = robot.step(0, 0.02, t_end=3.0)
    assert abs(s.final_error) < 0.02
    assert 0.0 < s.rise_time < 1.0
    assert s.tension_range[0] >= 0.0
    tr = robot.circle(radius=0.05, period=2.0)
    assert tr.tension_rmse[0] < 0.8 * tr.tension_rmse[1]
    assert tr.pose_rmse[0] < 1e-3
    poses = tr.poses[:500]
    np.testing.assert_array_equal(robot.follow(poses).ee, robot.plant.closed_loop(poses, 1e-3).ee)
    with pytest.raises(ParameterError):
        robot.step(3)
    with pytest.raises(ParameterError):
        PlanarRobot(shipped("seed002_mini"))  # spatial
    with pytest.raises(ParameterError):  # options reach the plant and are checked there
        PlanarRobot(creep=(np.array([-1.0]), np.array([1.0])))


def test_bad_input_is_a_typed_error():
    plant = planar_plant()
    poses = np.tile(HOME, (5, 1))
    with pytest.raises(ShapeError):
        plant.closed_loop(poses[:, :2].copy(), 1e-3)
    with pytest.raises(ParameterError):
        plant.closed_loop(poses, -1e-3)
    with pytest.raises(ParameterError):
        plant.closed_loop(poses, 1e-3, substeps=0)
    with pytest.raises(ParameterError):
        plant.closed_loop(poses, 1e-3, feedback="imu")
    with pytest.raises(ParameterError):
        plant.closed_loop(poses, 1e-3, feedback="network")  # no network
    with pytest.raises(ShapeError):
        plant.closed_loop(poses, 1e-3, sensor_noise=np.zeros((5, 3)))
    bad = poses.copy()
    bad[2, 1] = np.nan
    with pytest.raises(NotFiniteError):
        plant.closed_loop(bad, 1e-3)
    with pytest.raises(ParameterError):
        CdprPlant(PLANAR, np.array([0.6, 3.0, 0.0]))  # the weight cannot be held there
    with pytest.raises(ParameterError):
        CdprPlant(PLANAR, HOME, cable_damping=-1.0)
    with pytest.raises(ShapeError):
        CdprPlant(PLANAR, HOME, platform_side=PulleyFriction(np.zeros(3), np.zeros(3), np.zeros(3)))
    with pytest.raises(ParameterError):
        CdprPlant(PLANAR, HOME, creep=(np.array([-0.1]), np.array([1.0])))
    with pytest.raises(ParameterError):
        CdprPlant(PLANAR, HOME, creep=(np.array([0.1]), np.array([0.0])))
    with pytest.raises(ShapeError):
        CdprPlant(PLANAR, HOME, creep=(np.zeros(3), np.ones(1)))
    with pytest.raises(ParameterError, match="finite"):
        CdprPlant(PLANAR, HOME, creep=(np.array([np.nan]), np.ones(1)))
    with pytest.raises(ShapeError):
        CdprPlant(PLANAR, HOME, drum_friction=np.ones(3))
    with pytest.raises(ParameterError):
        CdprPlant(PLANAR, HOME, drum_friction=np.array([1.0, -0.5, 1.0, 1.0]))
    with pytest.raises(ParameterError):
        PulleyFriction(np.array([-0.1]), np.array([0.0]), np.array([0.0]))
    light = Robot(name="light", motion="planar", **dict(SPEC, mass=0.0))
    with pytest.raises(CablekitError):
        CdprPlant(light, HOME)


def test_the_diagnosis_finds_pulley_friction_and_its_cable_and_raises_no_false_alarm():
    """A Dahl pulley between the drum and the sensor of a drawn cable (the candidate assumes
    Coulomb) is found at that cable from the motor-current vs sensor residual, and the length
    channel finds nothing; with nothing withheld, neither channel reports anything."""
    from cablekit.cdpr.diagnose import twin_run

    for cable in (2, 6):
        d = twin_run("pulley_friction", cable, seed=cable).diagnose()
        f = d.force.found
        assert f is not None and (f.effect, f.cable) == ("pulley_friction", cable), d.summary()
        assert f.closed > 0.6
        assert d.length is not None and d.length.found is None, d.summary()
    d = twin_run(None, 0, seed=11).diagnose()
    assert d.findings == [], d.summary()
    # the length channel is noise; the force channel keeps a gap below the noise that no
    # candidate claims (the drums' static friction at reversals, the current's trapezoidal mean)
    assert d.length is not None and d.length.status == "no gap", d.summary()
    assert d.force.gap_rms.max() < d.force.noise, d.summary()


@pytest.mark.parametrize(("effect", "cable"), [("cable_creep", 5), ("cable_elasticity", 1)])
def test_the_length_channel_finds_a_creeping_or_softer_cable(effect, cable):
    """A creeping cable (Kelvin–Voigt, ρ = 0.5, τ = 5 s) or one 40 % softer than nominal is found
    at its cable from the measured poses (tracker noise 10 µm); the force channel stays quiet; a
    creep's time constant is recovered within a factor 2."""
    from cablekit.cdpr.diagnose import CREEP, twin_run

    d = twin_run(effect, cable, seed=cable).diagnose()
    assert [(f.effect, f.cable) for f in d.findings] == [(effect, cable)], d.summary()
    if effect == "cable_creep":
        assert CREEP[1] / 2 < d.findings[0].coefficients[-1] < 2 * CREEP[1]


def test_the_diagnosis_rejects_bad_runs():
    from cablekit.cdpr.diagnose import Lengths, diagnose
    from cablekit.cdpr.force import plant_robot

    t = np.arange(100) * 1e-3
    a = np.zeros((100, 4))
    with pytest.raises(ShapeError):
        diagnose(Winch.seed003(), t, a, a[:, :3], a)
    bad = a.copy()
    bad[5, 1] = np.inf
    with pytest.raises(ParameterError):
        diagnose(Winch.seed003(), t, a, bad, a)
    with pytest.raises(ParameterError):
        diagnose(Winch.seed003(), t[::-1].copy(), a, a, a)
    with pytest.raises(ParameterError):
        diagnose(Winch.seed003(), t, a, a, a, effects=("creep",))
    # the length channel: an 8-cable robot for a 4-cable run; poses of the wrong length; NaN
    with pytest.raises(ShapeError):
        diagnose(Winch.seed003(), t, a, a, a, lengths=Lengths(plant_robot(), np.ones(8), np.zeros((100, 6))))
    with pytest.raises(ShapeError):
        diagnose(Winch.seed003(), t, a, a, a, lengths=Lengths(PLANAR, np.ones(4), np.zeros((99, 3))))
    poses = np.tile(HOME, (100, 1))
    poses[3, 0] = np.nan
    with pytest.raises(ParameterError):
        diagnose(Winch.seed003(), t, a, a, a, lengths=Lengths(PLANAR, np.ones(4), poses))


def test_a_closed_loop_run_replays_through_simulate_and_the_srukf_recovers_an_unmeasured_tension():
    """The run's inputs and initial state replay it through ``simulate`` (same RK4, same bits to
    1e-9); the sr-UKF with the plant as its model, measuring the four drum angles and three of
    the four winch-side sensors (0.1 N noise), recovers the fourth cable's tension (not
    measured) within 10 % of its swing."""
    import cablekit as ck
    from cablekit.cdpr.force import excitation

    plant = planar_plant(PLANAR)
    poses = circle(HOME, radius=0.03, period=2.0, turns=1.0)
    offset = excitation(PLANAR, poses, np.random.default_rng(1), rms=3.0)
    run = plant.closed_loop(poses, 1e-3, tension_offset=offset)
    sim = ck.simulate(plant, run.inputs, 1e-3, x0=run.initial_state, substeps=5)
    m, n = 4, 3
    np.testing.assert_allclose(sim.outputs[1:, n : n + m], run.ee[:-1], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(sim.states[1:, :n], run.pose[:-1], atol=1e-12)
    rng = np.random.default_rng(2)
    idx = [n + m + 0, n + m + 1, n + m + 2] + [n + 4 * m + j for j in range(m)]
    y = sim.outputs[:, idx] + rng.normal(0, [0.1] * 3 + [1e-6] * 4, (sim.outputs.shape[0], len(idx)))
    ns = plant.n_states
    q = np.eye(ns) * 1e-14
    for j in range(2 * n, 2 * n + 2 * m):  # drum angles and rates take the process noise
        q[j, j] = 1e-8
    f = ck.SrUkf(
        plant,
        run.initial_state,
        np.eye(ns) * 1e-12,
        q,
        np.diag([0.01] * 3 + [1e-12] * 4),
        dt=1e-3,
        substeps=5,
        outputs=idx,
    )
    est = f.run(run.inputs, y)
    h = np.array([plant.output(x, u) for x, u in zip(est.x, run.inputs, strict=True)])
    truth = sim.outputs[:, n + m + 3]
    swing = float(truth.std())
    assert swing > 1.0
    err = float(np.sqrt(np.mean((h[500:, n + m + 3] - truth[500:]) ** 2)))
    assert err < 0.1 * swing, (err, swing)
