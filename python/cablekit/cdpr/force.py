"""Seed 002 §4–5 in simulation: the P force loop on the network's tension estimate, on the Mini
CDPR twin as a dynamic plant (:class:`cablekit.cdpr.CdprPlant`).

The plant: the ``seed002_mini`` robot's platform (Newton–Euler), its elastic cables, one of seed
003's winches per cable under its PID (the seed's Beckhoff servos are not described; their gains
``k_mp``, ``k_mv`` have no units in the seed), and the twin's pulley friction between the
winch-side sensors and the platform (:data:`cablekit.cdpr.compensate.TWIN_FRICTION`, the Dahl
law the network was trained on), with the load cell's noise on the sensor.

The controller (:meth:`CdprPlant.closed_loop`, seed 002 Fig. 7 and eqs 10–15): along test
trajectory 1 at 1 kHz, ``f_d`` is the tension distribution of the weight and the inertia; the
force loop ``f_u = k_p·(f_d − f̂)`` with ``f̂`` the network's estimate (NN-tension) from the
desired position and velocity and the noisy sensor; the winches take the cable lengths (eq. 15)
and the current of ``f_d + f_u``.

The loop's network is trained on the plant (:func:`plant_network`): the training trajectories
run through it at 1 kHz with a slow random excitation of the internal forces (in the null space
of ``Aᵀ``), so that the platform-side tensions vary at a given pose and only the sensor can tell
them. The network of Tables 1–2 is trained on the quasi-static twin, whose platform-side
tensions are always the distribution's: it learns the distribution, not the friction, and in the
loop its estimate is ``f_d`` whatever the tensions are (reported beside, as a finding).

Table 3 is the RMSE between the platform-side tension and ``f_d`` (mean over the cables) per
gain; Table 4 the RMSE of the cable wrench against the desired one, from the platform-side
tensions (the seed's IMU), the network and the sensor, at ``k_p = 0.70``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cablekit import _log
from cablekit._args import Epochs, Seed, Stride, Width, checked, instance, real, signal
from cablekit._cablekit import CdprPlant, LoopRun, Mlp, PulleyFriction
from cablekit.cdpr import Robot, Winch, shipped
from cablekit.cdpr.compensate import TWIN_FRICTION, first_test_trajectory, training_trajectories
from cablekit.errors import ShapeError

#: seed 002 Table 3: force RMSE (N) per gain k_p
SEED_TABLE3 = {0.55: 0.489, 0.60: 0.466, 0.65: 0.465, 0.70: 0.437, 0.75: 0.451, 0.85: 0.479, 0.90: 0.527}
#: seed 002 Table 4: wrench RMSE [F_x, F_y, F_z (N), M_x, M_y, M_z (N·m)]
SEED_TABLE4 = {
    "measured": (0.42, 0.61, 0.37, 0.01, 0.01, 0.01),
    "NN": (0.44, 0.56, 0.80, 0.03, 0.02, 0.02),
    "PUL": (1.36, 1.90, 1.87, 0.09, 0.05, 0.03),
}


@checked
def mini_plant(
    robot: Robot | None = None,
    home: np.ndarray | None = None,
    friction: dict | None = None,
    drum_side: PulleyFriction | None = None,
    creep: tuple[np.ndarray, np.ndarray] | None = None,
    drum_friction: np.ndarray | None = None,
) -> CdprPlant:
    """The Mini CDPR as a plant resting at ``home`` (default: test 1's first pose) with the
    twin's platform-side pulley friction (Dahl), seed 003's winch and any ``drum_side``
    friction, cable ``creep`` and winch static friction (``drum_friction``, per cable, a multiple
    of the winch's)."""
    robot = robot or shipped("seed002_mini")
    fr = TWIN_FRICTION if friction is None else friction
    if home is None:
        home = first_test_trajectory(dt=1e-3).poses[0]
    side = PulleyFriction(
        np.asarray(fr["coefficient"], float),
        np.asarray(fr["viscous"], float),
        np.asarray(fr["guide_wrap"], float),
        law="dahl",
        presliding=float(fr["presliding"]),
    )
    return CdprPlant(
        robot,
        np.asarray(home, float),
        Winch.seed003(),
        platform_side=side,
        drum_side=drum_side,
        creep=creep,
        drum_friction=drum_friction,
    )


@checked
def excitation(
    robot: Robot,
    poses: np.ndarray,
    rng: np.random.Generator,
    *,
    rms: float = 2.0,
    dt: float = 1e-3,
    correlation: float = 0.5,
) -> np.ndarray:
    """Tension offsets ``(T, m)`` in the null space of ``Aᵀ`` at each pose (internal forces only:
    the wrench stays): white noise low-passed twice over ``correlation`` s (smooth), projected,
    scaled to ``rms`` N."""
    instance(robot, "robot", Robot)
    instance(rng, "rng", np.random.Generator)
    poses = signal(poses, "poses", 2)
    if poses.shape[1] != robot.dof or poses.shape[0] < 2:
        raise ShapeError(f"poses must be finite (T, {robot.dof}), got shape {poses.shape}")
    rms = real(rms, "rms", lo=0.0, hi=1e6)
    dt = real(dt, "dt", lo=1e-9, hi=1.0)
    correlation = real(correlation, "correlation", lo=1e-9, hi=1e6)
    t_len, m = poses.shape[0], robot.n_cables
    a = np.exp(-dt / correlation)
    white = rng.normal(size=(t_len, m)) * np.sqrt(1 - a * a)
    r = np.empty_like(white)
    r[0] = rng.normal(size=m)
    for k in range(1, t_len):
        r[k] = a * r[k - 1] + white[k]
    smooth = np.empty_like(r)
    smooth[0] = r[0]
    for k in range(1, t_len):
        smooth[k] = a * smooth[k - 1] + (1 - a) * r[k]
    r = smooth
    at = robot.inverse_kinematics(poses).structure  # (T, n, m)
    _, _, vh = np.linalg.svd(at)
    null = vh[:, at.shape[1] :, :]  # (T, m − n, m)
    off = np.einsum("tkm,tk->tm", null, np.einsum("tkm,tm->tk", null, r))
    return off * (rms / max(float(np.sqrt(np.mean(off**2))), 1e-12))


@dataclass(frozen=True)
class PlantNetwork:
    """The loop's network and what it was trained on."""

    network: Mlp
    samples: int
    train_time_s: float


@checked
def plant_network(
    *, hidden: Width = 20, epochs: Epochs = 150, seed: Seed = 0, every: Stride = 10, progress: bool = False
) -> PlantNetwork:
    """Train the 14 → ``hidden`` → 8 network (Bayesian regularisation) on the plant: the training
    trajectories at 1 kHz without a force loop, the internal forces excited (:func:`excitation`),
    the sensor with the load cell's noise; inputs ``[x, y, z, ẋ_d, ẏ_d, ż_d, f_PUL]`` (the desired
    motion, as in the loop), outputs the platform-side tensions; every ``every``-th sample."""
    from cablekit.nn import to_mlp, train_mlp

    rng = np.random.default_rng(seed)
    xs, ys = [], []
    for tr in training_trajectories(dt=1e-3):
        plant = mini_plant(home=tr.poses[0])
        noise = rng.normal(0.0, float(TWIN_FRICTION["noise"]), (tr.poses.shape[0], 8))
        run = plant.closed_loop(
            tr.poses, tr.dt, sensor_noise=noise, tension_offset=excitation(plant_robot(), tr.poses, rng)
        )
        xs.append(np.column_stack([tr.poses[:, :3], tr.velocity, run.sensor])[::every])
        ys.append(run.ee[::every])
        if progress:
            _log.info(f"plant run for the loop's network: {tr.name}, {tr.poses.shape[0]:,} periods")
    x, y = np.vstack(xs), np.vstack(ys)
    result = train_mlp(
        x, y, method="br", hidden=(hidden,), epochs=epochs, seed=seed, test_fraction=0.0, progress=progress
    )
    return PlantNetwork(to_mlp(result), x.shape[0], result.train_time_s)


@checked
def plant_robot() -> Robot:
    """The robot of :func:`mini_plant`."""
    return shipped("seed002_mini")


@dataclass(frozen=True)
class ForceControl:
    """Per gain the tension RMSE (platform side vs ``f_d``, mean over cables, N); the reference
    rows (no force loop; the loop on the raw sensor; the loop on the true platform tension, all
    at ``gain``); per wrench source the RMSE ``(6,)``; and the runs at ``gain``."""

    gains: tuple[float, ...]
    rmse: np.ndarray
    rmse_delayed: dict[int, np.ndarray]
    gain: float
    network: PlantNetwork
    references: dict[str, float]
    wrench: dict[str, np.ndarray]
    runs: dict[str, LoopRun]
    t: np.ndarray


def _tension_rmse(run: LoopRun) -> float:
    return float(np.sqrt(np.mean((run.ee - run.desired) ** 2, axis=0)).mean())


def _wrench_rmse(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean((a - b) ** 2, axis=0))


@checked
def force_control(
    quasi_static: Mlp | None = None,
    *,
    gains: tuple[float, ...] = (*SEED_TABLE3, 1.0, 1.5, 2.0, 3.0),
    gain: float = 0.70,
    delays: tuple[int, ...] = (2, 3),
    seed: Seed = 0,
    epochs: Epochs = 150,
    progress: bool = False,
) -> ForceControl:
    """Tables 3–4 in simulation: the network trained on the plant (:func:`plant_network`)
    closing the force loop along test 1, as sampled (the measurement one period old) and with
    the measurement older still by each of ``delays`` periods; with ``quasi_static`` (the network of
    Tables 1–2) its loop as a reference row."""
    pn = plant_network(seed=seed, epochs=epochs, progress=progress)
    network = pn.network
    tr = first_test_trajectory(dt=1e-3)
    plant = mini_plant(home=tr.poses[0])
    noise = np.random.default_rng(seed).normal(0.0, float(TWIN_FRICTION["noise"]), (tr.poses.shape[0], 8))

    def loop(feedback: str, k: float, late: int = 0) -> LoopRun:
        return plant.closed_loop(
            tr.poses, tr.dt, gain=k, feedback=feedback, sensor_noise=noise, network=network, sensor_delay=late
        )

    def loop_with(net: Mlp, k: float) -> LoopRun:
        return plant.closed_loop(tr.poses, tr.dt, gain=k, feedback="network", sensor_noise=noise, network=net)

    rmse, runs = [], {}
    for k in gains:
        run = loop("network", k)
        rmse.append(_tension_rmse(run))
        if progress:
            _log.info(f"force loop on NN-tension, k_p = {k:.2f}: RMSE {rmse[-1]:.3f} N")
        if abs(k - gain) < 1e-12:
            runs["NN"] = run
    delayed = {}
    for late in delays:
        delayed[late] = np.array([_tension_rmse(loop("network", k, late)) for k in gains])
        if progress:
            _log.info(f"force loop fed back {late} ms later: RMSE {np.round(delayed[late], 3)} N")
    if "NN" not in runs:
        runs["NN"] = loop("network", gain)
    runs["open"] = loop("open", 0.0)
    runs["PUL"] = loop("sensor", gain)
    runs["platform"] = loop("platform", gain)
    references = {}
    if quasi_static is not None:
        references[f"loop on the network of Tables 1–2 (quasi-static training), k_p = {gain:.2f}"] = (
            _tension_rmse(loop_with(quasi_static, gain))
        )
    references |= {
        "no force loop": _tension_rmse(runs["open"]),
        f"loop on PUL-tension, k_p = {gain:.2f}": _tension_rmse(runs["PUL"]),
        f"loop on the true EE-tension, k_p = {gain:.2f}": _tension_rmse(runs["platform"]),
    }
    nn = runs["NN"]
    wrench = {
        "measured-wrench": _wrench_rmse(nn.wrench_ee, nn.wrench_desired),
        "NN-wrench": _wrench_rmse(nn.wrench_feedback, nn.wrench_desired),
        "PUL-wrench": _wrench_rmse(nn.wrench_sensor, nn.wrench_desired),
        "measured-wrench, loop on PUL": _wrench_rmse(runs["PUL"].wrench_ee, runs["PUL"].wrench_desired),
        "measured-wrench, no force loop": _wrench_rmse(runs["open"].wrench_ee, runs["open"].wrench_desired),
    }
    return ForceControl(tuple(gains), np.array(rmse), delayed, gain, pn, references, wrench, runs, tr.t)


@checked
def markdown(fc: ForceControl) -> str:
    """Tables 3 and 4, ours beside the seed's."""
    head = "| k_p | " + " | ".join(f"{k:.2f}" for k in fc.gains) + " |"
    lines = [
        f"The loop's network: 14 → 20 → 8, Bayesian regularisation on {fc.network.samples:,} samples of the "
        "training trajectories run through the plant with excited internal forces "
        f"({fc.network.train_time_s:.0f} s).",
        "",
        "**Table 3** (force loop on the NN-tension along test 1: RMSE between the platform-side "
        "tension and f_d, mean over the cables, N)",
        "",
        head,
        "|---" * (len(fc.gains) + 1) + "|",
        "| twin | " + " | ".join(f"{v:.3f}" for v in fc.rmse) + " |",
        *(
            f"| twin, fed back {late} ms later | " + " | ".join(f"{v:.3f}" for v in row) + " |"
            for late, row in fc.rmse_delayed.items()
        ),
        "| seed | "
        + " | ".join(f"{SEED_TABLE3[k]:.3f}" if k in SEED_TABLE3 else "—" for k in fc.gains)
        + " |",
        "",
        "| reference run | RMSE (N) |",
        "|---|---|",
        *(f"| {name} | {v:.3f} |" for name, v in fc.references.items()),
        "",
        f"**Table 4** (wrench RMSE against the desired wrench, k_p = {fc.gain:.2f})",
        "",
        "| desired vs | F_x (N) | F_y (N) | F_z (N) | M_x (N·m) | M_y (N·m) | M_z (N·m) |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, v in fc.wrench.items():
        lines.append(f"| {name}, twin | " + " | ".join(f"{a:.3f}" for a in v) + " |")
    for name, v in SEED_TABLE4.items():
        lines.append(f"| {name}-wrench, seed | " + " | ".join(f"{a:.2f}" for a in v) + " |")
    return "\n".join(lines)


@checked
def plot(path: str | Path, fc: ForceControl, cable: int = 3) -> Path | None:
    """One cable's tension with and without the force loop (seed 002 Fig. 10) and the force
    wrench errors (Fig. 8)."""
    from cablekit.plotting import pyplot_or_none, save_figure

    plt = pyplot_or_none()
    if plt is None:
        return None
    fig, (a, b) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    nn, op = fc.runs["NN"], fc.runs["open"]
    a.plot(fc.t, nn.desired[:, cable], "k", lw=1, label="f_d")
    a.plot(fc.t, op.ee[:, cable], "C1", lw=0.8, label="EE, no force loop")
    a.plot(fc.t, nn.ee[:, cable], "C0", lw=0.8, label=f"EE, loop on NN (k_p {fc.gain:.2f})")
    a.set_ylabel(f"cable {cable + 1} tension (N)")
    a.legend(fontsize=8)
    for i, axis in enumerate("xyz"):
        b.plot(fc.t, nn.wrench_ee[:, i] - nn.wrench_desired[:, i], lw=0.8, label=f"F_{axis} error")
    b.set_ylabel("measured − desired force (N)")
    b.set_xlabel("t (s)")
    b.legend(fontsize=8)
    a.set_title("Seed 002 Figs 8 and 10 on the twin: the force loop on the NN-tension, test 1")
    return save_figure(fig, path)
