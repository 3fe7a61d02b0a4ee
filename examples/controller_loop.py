"""A 1 kHz controller loop in Python on cablekit's allocation-free calls (issue #40 §2).

The plant is the Mini CDPR of seed 002 (:func:`cablekit.cdpr.force.mini_plant`: the platform,
eight elastic cables, seed 003's winches under their PIDs, the twin's Dahl pulley friction between
the load cells and the platform), simulated alongside at 5 RK4 substeps a period. Each tick the
controller

1. **reads a sample**: the eight load cells (the winch-side tensions with the cell's noise) and a
   tracker's platform pose (0.2 mm, 1 mrad noise), as the plant's outputs after the last period;
2. **steps the square-root UKF**: a constant-velocity model of the platform (12 states: pose and
   its rate) updated with the tracker's pose — the position and velocity the network needs;
3. **runs the network** (seed 002's NN-tension, trained on the plant by
   :func:`cablekit.cdpr.force.plant_network`): the platform-side tensions from the estimated
   position and velocity and the load cells, past the pulley friction the cells cannot see;
4. **distributes tensions**: :meth:`cablekit.cdpr.Robot.controller`'s closed form / QP of the
   weight and the desired motion's inertia at the planned pose, warm between ticks;
5. **writes the commands**: the force loop ``f_d + k_p·(f_d − f̂)`` turned into each winch's drum
   angle (the cable's unstretched length at that tension, eq. 15), its rate, and the motor current
   that carries the tension (the seed's feed-forward) — the loop of
   :meth:`cablekit.cdpr.CdprPlant.closed_loop`, tick by tick in Python.

Every array is allocated before the loop; the calls write into them: ``Model.output(x, u,
out=)``, ``Model.rk4_step(x, u, dt, substeps, out=)``, ``SrUkf.step(u, y)`` + ``SrUkf.x_into(out)``,
``Mlp.predict_into(x, out)``, ``TensionController.step(pose, wrench, out=)`` and NumPy's ``out=``
ufuncs. The loop reports the distribution of the controller's time per tick (the plant's
simulation is timed apart: it stands in for the robot) and the tracking errors.

With ``network_inputs="desired"`` the network sees the planned motion instead of the filter's
estimate: the loop is then :meth:`CdprPlant.closed_loop` exactly (the tests compare them).

    python examples/controller_loop.py                 # 60 s; trains the network (torch: the train extra)
    python examples/controller_loop.py --seconds 5 --weights net.safetensors   # reuse a network
"""

from __future__ import annotations

import argparse
import gc
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import cablekit as ck
from cablekit.cdpr.compensate import TWIN_FRICTION, second_test_trajectory
from cablekit.cdpr.force import mini_plant, plant_robot

#: the force loop's gain (seed 002 Table 3's best on the twin, :func:`cablekit.cdpr.force.force_control`)
GAIN = 0.70
#: the tracker's noise: position (m), orientation (rad)
TRACKER_NOISE = (2e-4, 1e-3)
#: the filter's acceleration noise (m/s², rad/s²): the planned motion's accelerations reach ~1
ACCEL_NOISE = 2.0


@dataclass(frozen=True)
class LoopReport:
    """The run: controller time per tick (ns, ``(T,)``), the plant's simulation time per tick
    (ns), each stage's time per tick (ns, ``(T, 5)``: sample, filter, network, distribution,
    commands), the platform's pose ``(T, 6)``, the planned poses, the platform-side tensions and
    the distributed ones ``(T, 8)`` (N), the network's estimate ``(T, 8)`` and the filter's pose
    ``(T, 6)``."""

    tick_ns: np.ndarray
    plant_ns: np.ndarray
    stage_ns: np.ndarray
    pose: np.ndarray
    desired_pose: np.ndarray
    tension: np.ndarray
    desired_tension: np.ndarray
    estimate: np.ndarray
    filtered_pose: np.ndarray

    def percentiles(self, values: np.ndarray | None = None) -> dict[str, float]:
        """Median, p99, p99.9 and max of ``values`` (default: the controller's tick) in µs."""
        v = (self.tick_ns if values is None else values) / 1e3
        return {
            "median": float(np.median(v)),
            "p99": float(np.percentile(v, 99)),
            "p99.9": float(np.percentile(v, 99.9)),
            "max": float(v.max()),
        }

    def position_error_mm(self) -> tuple[float, float]:
        """RMS and largest distance of the platform from its planned position (mm)."""
        d = np.linalg.norm(self.pose[:, :3] - self.desired_pose[:, :3], axis=1) * 1e3
        return float(np.sqrt(np.mean(d**2))), float(d.max())

    def tension_rmse(self) -> float:
        """The platform-side tensions' RMS error against the distribution, mean over cables (N)."""
        return float(np.sqrt(np.mean((self.tension - self.desired_tension) ** 2, axis=0)).mean())


def plan(seconds: float, dt: float = 1e-3) -> np.ndarray:
    """``seconds`` of planned poses ``(T, 6)``: seed 002's test 2 (lines through 20 random points
    of the workspace), then back along it, and so on (continuous)."""
    p = second_test_trajectory(dt=dt).poses
    steps = round(seconds / dt)
    reps = -(-steps // p.shape[0])
    return np.concatenate([p if i % 2 == 0 else p[::-1] for i in range(reps)])[:steps].copy()


def run(
    network: ck.Mlp,
    poses: np.ndarray,
    *,
    dt: float = 1e-3,
    seed: int = 0,
    network_inputs: str = "estimate",
    gain: float = GAIN,
    sensor_noise: np.ndarray | None = None,
    progress: bool = False,
) -> LoopReport:
    """Run the loop (module docs) along ``poses`` ``(T, 6)`` every ``dt`` s from rest at the first
    pose; ``network_inputs`` ``"estimate"`` (the filter's) or ``"desired"`` (the plan's); ``gain``
    the force loop's (0: open);
    ``sensor_noise`` ``(T, 8)`` N (default: the cell's noise, drawn with ``seed``)."""
    if network_inputs not in ("estimate", "desired"):
        raise ValueError(f"network_inputs must be 'estimate' or 'desired', got {network_inputs!r}")
    robot = plant_robot()
    plant = mini_plant(home=poses[0])
    n, m = robot.dof, robot.n_cables
    t_len = poses.shape[0]
    rng = np.random.default_rng(seed)
    if sensor_noise is None:
        sensor_noise = rng.normal(0.0, float(TWIN_FRICTION["noise"]), (t_len, m))
    tracker_noise = np.concatenate(
        [rng.normal(0.0, TRACKER_NOISE[0], (t_len, 3)), rng.normal(0.0, TRACKER_NOISE[1], (t_len, 3))], axis=1
    )

    # -- the plan (offline): motion by central differences as the core's loop takes it, the
    # inertia's wrench, the geometry at each planned pose
    a, b = np.maximum(np.arange(t_len) - 1, 0), np.minimum(np.arange(t_len) + 1, t_len - 1)
    vel = (poses[b] - poses[a]) / (np.maximum(b - a, 1)[:, None] * dt)
    acc = np.zeros_like(poses)
    acc[1:-1] = (poses[2:] - 2 * poses[1:-1] + poses[:-2]) / dt**2
    wrench = np.zeros_like(poses)
    wrench[:, :3] = -robot.mass * acc[:, :3]  # (the plan keeps the orientation)
    kin = robot.inverse_kinematics(poses)
    length = np.ascontiguousarray(kin.length)
    winch = dict(zip(plant.winch.NAMES, plant.winch.values, strict=True))
    r = winch["drum_radius"]
    # the drum rate that follows the planned motion (l̇ through the structure matrix)
    rate = np.einsum("tim,ti->tm", kin.structure, vel) / r
    rest, ea = plant.rest_length, robot.ea
    gear2 = winch["gear_ratio"] ** 2
    j_load = winch["rotor_inertia"] * gear2 + winch["gearbox_inertia"] + winch["drum_inertia"]
    b_load = winch["rotor_viscous"] * gear2 + winch["drum_viscous"]
    amp = 1.0 / (winch["torque_constant"] * winch["gear_ratio"])

    # -- the filter: constant velocity, the tracker measures the pose
    eye = np.eye(n)
    f_mat = np.block([[eye, dt * eye], [np.zeros((n, n)), eye]])
    h_mat = np.hstack([eye, np.zeros((n, n))])
    q_block = ACCEL_NOISE**2 * np.block([[dt**4 / 4 * eye, dt**3 / 2 * eye], [dt**3 / 2 * eye, dt**2 * eye]])
    r_mat = np.diag([TRACKER_NOISE[0] ** 2] * 3 + [TRACKER_NOISE[1] ** 2] * 3)
    x0 = np.concatenate([poses[0], np.zeros(n)])
    p0 = np.diag([1e-6] * n + [1e-4] * n)
    ukf = ck.SrUkf.linear(f_mat, h_mat, x0, p0, q_block + 1e-12 * np.eye(2 * n), r_mat, alpha=1.0, kappa=0.0)
    controller = robot.controller("auto", gravity=True)

    # -- every array the loop touches, allocated once
    x = plant.rest_state()
    # the feed-forward current carries the tension: the PIDs' integrals start empty
    x[[i for i, s in enumerate(plant.state_names) if s.startswith("error_integral")]] = 0.0
    u = np.zeros(plant.n_inputs)
    y = np.zeros(plant.n_outputs)
    cells = np.array(plant.home_tensions)  # the load cells before the first period
    tracker = poses[0].copy()
    no_input = np.zeros(0)
    xhat = np.zeros(2 * n)
    net_in = np.zeros(network.n_inputs)
    f_hat = np.zeros(m)
    fd = np.zeros(m)
    target = np.zeros(m)
    tmp = np.zeros(m)
    last_rate = np.zeros(m)
    accel = np.zeros(m)
    tick_ns = np.zeros(t_len, dtype=np.int64)
    plant_ns = np.zeros(t_len, dtype=np.int64)
    stage_ns = np.zeros((t_len, 5), dtype=np.int64)
    out_pose = np.zeros((t_len, n))
    out_tension = np.zeros((t_len, m))
    out_desired = np.zeros((t_len, m))
    out_estimate = np.zeros((t_len, m))
    out_filtered = np.zeros((t_len, n))
    pul = slice(n + m, n + 2 * m)  # the winch-side (load cell) tensions among the outputs
    clock = time.perf_counter_ns

    gc.disable()  # a collection is a pause no real-time loop takes; nothing here makes cycles
    try:
        for k in range(t_len):
            t0 = clock()
            # 1. the sample (measured after the last period): load cells and tracker
            np.add(cells, sensor_noise[k], out=cells)
            np.add(tracker, tracker_noise[k], out=tracker)
            t1 = clock()
            # 2. the filter's step
            ukf.step(no_input, tracker)
            ukf.x_into(xhat)
            t2 = clock()
            # 3. the network: platform-side tensions from the motion and the cells
            if network_inputs == "estimate":
                net_in[:3] = xhat[:3]
                net_in[3:6] = xhat[n : n + 3]
            else:
                net_in[:3] = poses[k, :3]
                net_in[3:6] = vel[k, :3]
            net_in[6:] = cells
            network.predict_into(net_in, f_hat)
            t3 = clock()
            # 4. the distribution of the weight and the planned inertia
            controller.step(poses[k], wrench[k], out=fd)
            t4 = clock()
            # 5. commands: f_d + k_p·(f_d − f̂) → drum angle, rate, feed-forward current
            np.subtract(fd, f_hat, out=target)
            np.multiply(target, gain, out=target)
            np.add(target, fd, out=target)
            np.maximum(target, 0.0, out=target)
            np.divide(target, ea, out=tmp)  # unstretched length l/(1 + T/EA), angle (L0 − L)/r
            np.add(tmp, 1.0, out=tmp)
            np.divide(length[k], tmp, out=tmp)
            np.subtract(rest, tmp, out=tmp)
            np.divide(tmp, r, out=u[:m])
            u[m : 2 * m] = rate[k]
            if k > 0:
                np.subtract(rate[k], last_rate, out=accel)
                np.divide(accel, dt, out=accel)
            last_rate[:] = rate[k]
            np.multiply(target, r, out=tmp)  # (r·T + B·α̇ + J·α̈)/(k_t·G)
            tmp += b_load * rate[k]
            tmp += j_load * accel
            np.multiply(tmp, amp, out=u[2 * m : 3 * m])
            t5 = clock()
            tick_ns[k] = t5 - t0
            stage_ns[k] = (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4)

            # the robot: one period of the plant, then its sensors
            plant.rk4_step(x, u, dt, 5, out=x)
            plant.output(x, u, out=y)
            cells[:] = y[pul]
            tracker[:] = y[:n]
            plant_ns[k] = clock() - t5
            out_pose[k] = y[:n]
            out_tension[k] = y[n : n + m]
            out_desired[k] = fd
            out_estimate[k] = f_hat
            out_filtered[k] = xhat[:n]
            if progress and (k + 1) % 10_000 == 0:
                print(f"  {(k + 1) * dt:5.1f} s simulated", flush=True)
    finally:
        gc.enable()
    return LoopReport(
        tick_ns, plant_ns, stage_ns, out_pose, poses, out_tension, out_desired, out_estimate, out_filtered
    )


def network_for_loop(weights: Path | None, epochs: int) -> ck.Mlp:
    """The loop's network: loaded from ``weights`` if the file exists, else trained on the plant
    (torch, the ``train`` extra) and written there when a path is given."""
    if weights is not None and weights.exists():
        return ck.Mlp.load(weights)
    from cablekit.cdpr.force import plant_network

    t = time.perf_counter()
    net = plant_network(epochs=epochs, progress=True).network
    print(f"network trained on the plant in {time.perf_counter() - t:.0f} s")
    if weights is not None:
        net.save(weights)
    return net


def main(argv: list[str] | None = None) -> LoopReport:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--weights", type=Path, help="the network's weight file (trained if missing)")
    ap.add_argument("--epochs", type=int, default=150)
    args = ap.parse_args(argv)
    net = network_for_loop(args.weights, args.epochs)
    poses = plan(args.seconds)
    print(f"1 kHz loop over {args.seconds:g} s ({poses.shape[0]:,} ticks) ...")
    rep = run(net, poses, progress=True)
    pc = rep.percentiles()
    print("\ncontroller per tick (µs): " + ", ".join(f"{k} {v:.1f}" for k, v in pc.items()))
    names = ("sample", "sr-UKF", "network", "distribution", "commands")
    med = np.median(rep.stage_ns, axis=0) / 1e3
    print("  stage medians (µs): " + ", ".join(f"{a} {b:.1f}" for a, b in zip(names, med, strict=True)))
    pp = rep.percentiles(rep.plant_ns)
    print(
        f"plant simulation per tick (µs, not the controller's): median {pp['median']:.1f}, "
        f"p99 {pp['p99']:.1f}"
    )
    rms, worst = rep.position_error_mm()
    print(f"tracking: position error RMS {rms:.2f} mm, max {worst:.2f} mm")
    err = np.linalg.norm(rep.filtered_pose[:, :3] - rep.pose[:, :3], axis=1) * 1e3
    print(f"sr-UKF position against the truth: RMS {np.sqrt(np.mean(err**2)):.3f} mm (tracker noise 0.35 mm)")
    print(
        f"platform-side tensions against the distribution: RMSE {rep.tension_rmse():.3f} N (mean over cables)"
    )
    est = float(np.sqrt(np.mean((rep.estimate - rep.tension) ** 2)))
    print(f"network's estimate of the platform-side tensions: RMSE {est:.3f} N")
    print(f"goal p99 <= 100 µs: {'met' if pc['p99'] <= 100.0 else 'NOT met'}")
    return rep


if __name__ == "__main__":
    main()
