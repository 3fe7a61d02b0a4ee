"""A parallel robot in MuJoCo, its cables' tensions from cablekit (issue #40 §3).

The Mini CDPR of seed 002 exported as MJCF (`cablekit cdpr export-mjcf seed002_mini`), simulated
by MuJoCo at 1 kHz: each step a PD law on the platform's pose asks for a wrench, cablekit's
tension controller distributes it (with the platform's weight) over the eight cables within their
bounds, and the tensions are the tendon motors' controls. MuJoCo integrates the rigid platform;
the swivelling pulleys are turned onto the platform each step (MuJoCo does not turn them). The
platform starts 2 cm and 0.05 rad off its target and settles on it.

    python examples/mujoco_cdpr.py          # needs: pip install 'cablekit[mujoco]'
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np

from cablekit.cdpr import shipped
from cablekit.cdpr.mjcf import mujoco_state, swivel_angles, to_mjcf


@dataclass
class Settled:
    """The run: time (s), pose error (m, rad) at every step, tensions (N) and their bounds."""

    t: np.ndarray
    position_error: np.ndarray
    angle_error: np.ndarray
    tensions: np.ndarray
    bounds: tuple[np.ndarray, np.ndarray]


def _pose(d: mujoco.MjData, start: int) -> tuple[np.ndarray, np.ndarray]:
    """Platform pose ``[x, y, z, roll, pitch, yaw]`` and its world-frame velocity ``[v, ω]``."""
    x, quat = d.qpos[start : start + 3], d.qpos[start + 3 : start + 7]
    r = np.zeros(9)
    mujoco.mju_quat2Mat(r, quat)
    r = r.reshape(3, 3)
    rpy = [np.arctan2(r[2, 1], r[2, 2]), -np.arcsin(np.clip(r[2, 0], -1, 1)), np.arctan2(r[1, 0], r[0, 0])]
    # (each swivel is one coordinate and one speed: the free joint's speeds start where its
    # coordinates do, ``[v (world), ω (body)]``)
    v, w_body = d.qvel[start : start + 3], d.qvel[start + 3 : start + 6]
    return np.array([*x, *rpy]), np.concatenate([v, r @ w_body])


def run(seconds: float = 2.0, name: str = "seed002_mini") -> Settled:
    """Simulate ``seconds`` of the PD-held platform (see the module docs)."""
    path = str(resources.files("cablekit.cdpr") / "robots" / f"{name}.toml")
    doc = tomllib.loads(Path(path).read_text(encoding="utf-8"))  # read once, not every step
    robot = shipped(name)
    m = mujoco.MjModel.from_xml_string(to_mjcf(path))
    d = mujoco.MjData(m)
    n_sw = sum(m.joint(j).name.startswith("swivel") for j in range(m.njnt))
    swivel_cables = [int(m.joint(j).name[6:]) - 1 for j in range(n_sw)]
    target = np.array([0.0, 0.0, 0.45, 0.0, 0.0, 0.0])
    d.qpos[:] = mujoco_state(path, target + np.array([0.02, -0.02, 0.02, 0.05, -0.05, 0.05]))
    controller = robot.controller()
    mass, inertia = robot.mass, 3e-3
    # critically damped at 8 Hz (translation) and 6 Hz (rotation)
    kp = np.array([mass * (2 * np.pi * 8) ** 2] * 3 + [inertia * (2 * np.pi * 6) ** 2] * 3)
    kd = np.array([2 * mass * 2 * np.pi * 8] * 3 + [2 * inertia * 2 * np.pi * 6] * 3)
    steps = round(seconds / m.opt.timestep)
    err_p, err_a, tensions = np.zeros(steps), np.zeros(steps), np.zeros((steps, robot.n_cables))
    f = np.zeros(robot.n_cables)
    for k in range(steps):
        pose, vel = _pose(d, n_sw)
        d.qpos[:n_sw] = swivel_angles(doc, pose[None, :], source=path)[0][swivel_cables]
        wrench = kp * (target - pose) - kd * vel
        # tensions hold an external wrench w when Aᵀf + w = 0: the cables exert −w
        controller.step(pose, wrench=-wrench, out=f)
        d.ctrl[:] = f
        mujoco.mj_step(m, d)
        err_p[k] = np.linalg.norm(pose[:3] - target[:3])
        err_a[k] = np.abs(pose[3:] - target[3:]).max()
        tensions[k] = f
    return Settled(np.arange(steps) * m.opt.timestep, err_p, err_a, tensions, robot.bounds)


def main() -> None:
    s = run()
    lo, hi = s.bounds
    print(
        f"Mini CDPR in MuJoCo, cablekit's tensions on the tendon motors: position error "
        f"{1e3 * s.position_error[0]:.1f} mm -> {1e3 * s.position_error[-1]:.3f} mm, "
        f"angle error {s.angle_error[0]:.3f} rad -> {s.angle_error[-1]:.5f} rad "
        f"after {s.t[-1] + 1e-3:.1f} s; "
        f"tensions {s.tensions.min():.2f}-{s.tensions.max():.2f} N within [{lo.min():g}, {hi.max():g}] N"
    )


if __name__ == "__main__":
    main()
