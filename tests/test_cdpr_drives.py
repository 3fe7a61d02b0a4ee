"""A parallel robot's cable drives as a network (issue #39 §2: the parallel robots in the one
diagnosis engine): the network replays the parallel-robot plant it stands for, the pose's noise
is smoothed and accounted for, and bad input is a typed error."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cablekit import CablekitError
from cablekit._cablekit import CableNetwork, simulate_arrays
from cablekit.cdpr import Winch, drives
from cablekit.cdpr.compensate import TWIN_FRICTION, second_test_trajectory
from cablekit.cdpr.force import excitation, mini_plant, plant_robot
from cablekit.diagnose.prepare import _input_window, _load_window
from cablekit.errors import ParameterError, ShapeError


def _plant_run(samples: int = 1500):
    poses = second_test_trajectory(dt=1e-3).poses[:samples]
    plant = mini_plant(home=poses[0])
    rng = np.random.default_rng(3)
    run = plant.closed_loop(poses, 1e-3, tension_offset=excitation(plant_robot(), poses, rng))
    return plant, run


def test_the_drive_network_replays_the_parallel_robot_plant():
    """Driven by the plant's drum angles and platform poses, the network gives the plant's
    platform-side tensions (the cable's free length and damping), the load cells' tensions of
    cablekit's other implementation of seed 002's path (``Robot.path_friction``: Dahl pulleys
    with the pose's exit wrap) and the drums' loads ``k·N·i − J·α̈``: a wrong wrap, law or
    stiffness is off by newtons."""
    plant, run = _plant_run()
    robot, winch = plant_robot(), Winch.seed003()
    doc = drives.drive_network(robot, winch, plant.rest_length, TWIN_FRICTION, cable_damping=50.0)
    for m in doc["motors"]:
        m["drive"] = "position"  # the diagnosis replays the drums from their measured angles
    net = CableNetwork.from_json(json.dumps(doc))
    t = np.arange(len(run.alpha)) * 1e-3
    args = (robot, winch, plant.rest_length, t, run.alpha, run.current, run.sensor, run.pose)
    cols = drives.drive_columns(*args, smoothing=0.0, decimate=1).columns
    u = []
    for k in range(1, 9):
        for name in (f"alpha{k}", f"stretch{k}"):
            u += [cols[name], np.gradient(cols[name], 1e-3, edge_order=2)]
    u += [cols[f"wrap{k}"] for k in range(1, 9)]
    _, y = simulate_arrays(net, np.column_stack(u), 1e-3, substeps=4, hold="foh")
    names = list(net.output_names)
    path = robot.path_friction(
        np.ascontiguousarray(run.pose),
        np.ascontiguousarray(run.ee),
        1e-3,
        TWIN_FRICTION["coefficient"],
        TWIN_FRICTION["viscous"],
        TWIN_FRICTION["guide_wrap"],
        law="dahl",
        presliding=TWIN_FRICTION["presliding"],
    )
    inner = slice(20, -20)
    w = dict(zip(Winch.NAMES, winch.values, strict=True))
    for k in range(1, 9):
        ee = np.abs(y[:, names.index(f"T:c{k}")] - run.ee[:, k - 1])[inner]
        assert ee.max() < 0.01, (k, ee.max())  # N, of tensions of 5–40 N
        pul = np.abs(y[:, names.index(f"T@drum_side{k}:c{k}")] - path.pul[:, k - 1])[inner]
        assert pul.max() < 0.01, (k, pul.max())
        acc = np.gradient(np.gradient(run.alpha[:, k - 1], 1e-3), 1e-3)
        load = w["torque_constant"] * w["gear_ratio"] * run.current[:, k - 1] - winch.load[0] * acc
        err = np.abs(y[:, names.index(f"load_m:drum{k}")] - load)[inner]
        assert np.median(err) < 3e-3, (k, np.median(err))  # N·m, of loads of 0.1–1 N·m
    # smoothed against a tracker's noise, the lengths keep the tensions within a few 10 mN
    smooth = drives.drive_columns(*args, decimate=1).columns
    for k in range(1, 9):
        for name in (f"stretch{k}", f"wrap{k}"):
            d = (smooth[name] - cols[name])[60:-60]
            scale = 1e-6 if name.startswith("stretch") else 1e-4  # 1 µm: 0.1 N; 0.1 mrad
            assert np.sqrt(np.mean(d**2)) < scale, (name, np.sqrt(np.mean(d**2)))
    # a path without the exit wrap's share is off by much more than that at the top cables
    doc["signals"] = []
    for c in doc["cables"]:
        c["path"]["exit_wrap"] = 0.0
    off = simulate_arrays(
        CableNetwork.from_json(json.dumps(doc)), np.column_stack(u[:32]), 1e-3, substeps=4, hold="foh"
    )[1]
    worst = max(
        np.abs(off[:, names.index(f"T@drum_side{k}:c{k}")] - path.pul[:, k - 1]).max() for k in range(5, 9)
    )
    assert worst > 0.3, worst


@pytest.mark.parametrize("half", [1, 3, 12, 40])
def test_the_pose_smoothing_is_exact_for_a_cubic_and_damps_white_noise(half):
    w = drives.smoothing_kernel(half)
    assert w.shape == (2 * half + 1,) and abs(w.sum() - 1) < 1e-12
    i = np.arange(-half, half + 1, dtype=float)
    for p in ([1.0], [0.3, -2.0], [1.0, 0.5, -0.25], [0.0, 0.0, 0.0, 2.0]):
        poly = np.polyval(p[::-1], i)
        assert abs(w @ poly - poly[half]) < 1e-9 * (1 + np.abs(poly).max())
    if half >= 3:
        assert np.linalg.norm(w) < 1.6 / np.sqrt(2 * half + 1)


@settings(max_examples=40, deadline=None)
@given(
    sigma=st.floats(1e-4, 10.0),
    ratio=st.floats(0.0, 100.0),
    half=st.integers(0, 15),
    dt=st.sampled_from([5e-4, 1e-3, 2e-3, 1e-2]),
)
def test_an_input_windows_noise_is_the_averaged_residuals(sigma, ratio, half, dt):
    """The noise :func:`_input_window` reports is a NumPy simulation's of the measurement's white
    noise and the input's, filtered by its kernel, through the mean (5 %); the window stops
    growing once the input's part is no larger than the measurement's per-sample noise."""
    kernel = tuple(drives.smoothing_kernel(half)) if half else (1.0,)
    noise = (ratio * sigma, kernel)
    k, s = _input_window(sigma, noise, dt)
    assert k % 2 == 1 and 1 <= k <= max(1, round(0.02 / dt))
    rng = np.random.default_rng(1)
    n = 200_000
    meas = rng.normal(0, sigma, n)
    inp = np.convolve(rng.normal(0, ratio * sigma, n + len(kernel) - 1), kernel, mode="valid")
    averaged = np.convolve(meas + inp, np.full(k, 1.0 / k), mode="valid")
    assert abs(np.std(averaged) / s - 1.0) < 0.05
    if ratio == 0.0:
        assert k == 1
    # a derived load channel takes the same input noise into its own window
    k2, s2 = _load_window(sigma, 0.0, dt, noise, held=False)
    assert k2 >= 1 and s2 <= float(np.hypot(sigma, ratio * sigma * np.linalg.norm(kernel))) * 1.0001


def test_bad_drive_runs_and_networks_are_typed_errors():
    robot, winch = plant_robot(), Winch.seed003()
    rest = np.full(8, 0.9)
    t = np.arange(20) * 1e-3
    a = np.zeros((20, 8))
    poses = np.tile([0, 0, 0.45, 0, 0, 0], (20, 1)).astype(float)
    with pytest.raises(ShapeError, match="poses"):
        drives.drive_columns(robot, winch, rest, t, a, a, a, poses[:, :3])
    with pytest.raises(ShapeError):
        drives.drive_columns(robot, winch, rest, t, a[:, :4], a, a, poses)
    bad = a.copy()
    bad[3, 2] = np.nan
    with pytest.raises(ParameterError, match="current"):
        drives.drive_columns(robot, winch, rest, t, a, bad, a, poses)
    with pytest.raises(ParameterError, match="increase"):
        drives.drive_columns(robot, winch, rest, t[::-1].copy(), a, a, a, poses)
    with pytest.raises(ParameterError, match="rest_length"):
        drives.drive_network(robot, winch, -rest)
    with pytest.raises(ShapeError, match="rest_length"):
        drives.drive_network(robot, winch, rest[:3])
    with pytest.raises(ParameterError, match="coefficient"):
        drives.drive_network(
            robot, winch, rest, {**TWIN_FRICTION, "coefficient": -TWIN_FRICTION["coefficient"]}
        )
    with pytest.raises(ParameterError, match="cable_damping"):
        drives.drive_network(robot, winch, rest, cable_damping=-1.0)
    with pytest.raises(ParameterError, match="input_noise"):
        drives.drive_spec(robot, winch, rest, {"T1": (np.nan, (1.0,))})
    with pytest.raises(CablekitError, match="input_noise"):
        drives.drive_spec(robot, winch, rest, {"T1": 0.3})


@settings(max_examples=30, deadline=None)
@given(
    rows=st.integers(0, 30),
    cols=st.integers(0, 10),
    value=st.sampled_from([0.0, 1.0, np.nan, np.inf, -np.inf, 1e308, -1e308]),
    which=st.integers(0, 4),
)
def test_drive_columns_never_returns_non_finite_numbers_from_any_input(rows, cols, value, which):
    """Any shape and any bad value: a typed error, or finite columns and noises."""
    robot, winch = plant_robot(), Winch.seed003()
    n = max(rows, 1)
    t = np.arange(n) * 1e-3
    arrays = [np.full((rows, cols), value), np.zeros((n, 8)), np.zeros((n, 8)), np.zeros((n, 8))]
    poses = np.tile([0, 0, 0.45, 0, 0, 0], (n, 1)).astype(float)
    args = [robot, winch, np.full(8, 0.9), t, arrays[1], arrays[2], arrays[3], poses]
    args[3 + which] = arrays[0] if which else np.full(rows, value)
    try:
        out = drives.drive_columns(*args)
    except CablekitError:
        return
    assert all(np.isfinite(c).all() for c in out.columns.values())
    assert all(np.isfinite(v[0]) for v in out.input_noise.values())


def test_a_wound_cables_creep_of_its_stretch_is_the_twins_creep():
    """The Mini CDPR twin's creeping cable (a Kelvin–Voigt element in series with a crept length
    ``c`` in metres, ratio ``ρ``, time constant ``τ``), replayed through its drive network: the
    network's creep of the stretch (``creep@cable.c5/stretch``) at the twin's values
    (``κ = ρ/(1+ρ)``, ``τ/(1+ρ)``) gives the twin's tensions as closely as the nominal gives a
    twin without creep; the creep of the tension at the same values does not (the cable's free
    length changes by ±12 % along the path, and the crept length stays in the free span)."""
    from cablekit.cdpr.diagnose import Lengths
    from cablekit.cdpr.selftest import TWIN_CABLE_DAMPING
    from cablekit.diagnose.data import Run, common_interval
    from cablekit.diagnose.prepare import prepare

    cable, rho, tau = 4, 0.5, 5.0
    poses = second_test_trajectory(dt=1e-3).poses[:12_000]
    nominal = mini_plant(home=poses[0])
    ratio = np.zeros(8)
    ratio[cable] = rho
    plant = mini_plant(plant_robot(), home=poses[0], creep=(ratio, np.full(8, tau)))
    offset = excitation(plant_robot(), poses, np.random.default_rng(17))
    run = plant.closed_loop(poses, 1e-3, tension_offset=offset)
    t = np.arange(poses.shape[0]) * 1e-3
    lg = Lengths(plant_robot(), nominal.rest_length, run.pose, TWIN_FRICTION)
    sensor = run.sensor + np.random.default_rng(1).normal(0.0, 1e-3, run.sensor.shape)
    rest = lg.rest_length
    cols = drives.drive_columns(lg.robot, plant.winch, rest, t, run.alpha, run.current, sensor, lg.poses)
    spec = drives.drive_spec(
        lg.robot, plant.winch, rest, cols.input_noise, TWIN_FRICTION, cable_damping=TWIN_CABLE_DAMPING
    )
    runs = common_interval([spec.in_si(Run("run", cols.t, cols.columns))])
    prep = prepare(spec, runs, runs)
    channel = prep.channel_names.index(f"tension{cable + 1}")
    truth = np.array([rho / (1 + rho), tau / (1 + rho)])

    def rms(effect: str, theta: np.ndarray) -> float:
        r = prep.fit0.with_effects([effect], prep.substeps).residuals(theta).reshape(-1, prep.q)
        return float(np.sqrt(np.mean((r[:, channel] * prep.sigma[channel]) ** 2)))

    nominal_rms = rms(f"creep@cable.c{cable + 1}", np.array([0.0, 1.0]))
    stretch = rms(f"creep@cable.c{cable + 1}/stretch", truth)
    tension = rms(f"creep@cable.c{cable + 1}", truth)
    assert stretch < 0.08, stretch  # N: the nominal's own match of a twin without creep is 0.04 N
    assert nominal_rms > 5 * stretch and tension > 5 * stretch, (nominal_rms, tension, stretch)
    assert "creep@cable.c5/stretch" in prep.candidates
