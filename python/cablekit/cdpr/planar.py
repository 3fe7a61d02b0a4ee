"""Seed 003's planar 4-cable robot in closed loop (§2, Figs 1–3): the ``seed003_planar`` robot as
a dynamic plant (:class:`cablekit.cdpr.CdprPlant`: platform, four elastic cables, four of the
seed's winches under their PID) driven through its inverse kinematics, with the tension
distribution of part 1 in the loop.

* :class:`PlanarRobot` — the robot, its winches and the plant together: ``step``, ``circle`` and
  ``follow`` (any trajectory) in closed loop.

* :func:`step_response` — a step of the reference pose: each winch's PID follows the step of its
  drum angle from the inverse kinematics (seed 003 eq. 3, no feed-forward: the seed's position
  control). Rise and settling times, overshoot and the cables' tension range during the step.
* :func:`trajectory_response` — a circle at the platform's centre, with the tension distribution
  in the loop (the current that carries ``f_d`` fed forward, the cable lengths stretched for it:
  seed 003 Fig. 3's tension supervision) and without it (lengths from the kinematics only).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cablekit._args import checked, float_array, instance, real
from cablekit._cablekit import CdprPlant, LoopRun
from cablekit.cdpr import Robot, Winch, shipped
from cablekit.errors import ParameterError

#: the most samples one closed-loop run of this module takes (about 30 min at 1 kHz)
MAX_SAMPLES = 2_000_000

#: the home pose of the shipped planar robot (m, m, rad): the frame's centre
HOME = np.array([0.6, 0.5, 0.0])


@checked
def planar_plant(
    robot: Robot | None = None, home: np.ndarray | None = None, winch: Winch | None = None
) -> CdprPlant:
    """The shipped ``seed003_planar`` robot (or ``robot``) resting at ``home`` under seed 003's
    winches."""
    robot = instance(robot, "robot", Robot, optional=True) or shipped("seed003_planar")
    home = float_array(HOME if home is None else home, "home", 1)
    winch = instance(winch, "winch", Winch, optional=True) or Winch.seed003()
    return CdprPlant(robot, home, winch)


@dataclass(frozen=True)
class StepResponse:
    """A reference step of ``size`` in pose coordinate ``axis``: the run, times (s) and the
    response's figures."""

    axis: int
    size: float
    t: np.ndarray
    run: LoopRun
    #: 10–90 % rise time (s); None: the response did not reach 90 % of the step by the run's end
    rise_time: float | None
    #: 2 % settling time after the step (s); None: still outside the band at the run's end
    settling_time: float | None
    overshoot: float
    final_error: float
    tension_range: tuple[float, float]


def _step_figures(
    t: np.ndarray, y: np.ndarray, t0: float, size: float
) -> tuple[float | None, float | None, float, float]:
    """10–90 % rise time, 2 % settling time (s after the step; None where not reached by the
    end), overshoot (fraction), final error (fraction of the step)."""
    after = t >= t0
    ts, r = t[after] - t0, (y[after] - y[after][0]) / size
    rise = None
    if (r >= 0.9).any() and (r >= 0.1).any():
        rise = float(ts[np.argmax(r >= 0.9)] - ts[np.argmax(r >= 0.1)])
    outside = np.nonzero(np.abs(r - 1.0) > 0.02)[0]
    settle = (
        float(ts[outside[-1] + 1])
        if outside.size and outside[-1] + 1 < ts.size
        else (0.0 if not outside.size else None)
    )
    return rise, settle, float(max(r.max() - 1.0, 0.0)), float(r[-1] - 1.0)


def _samples(t_end: float, dt: float, what: str) -> int:
    dt = real(dt, "dt", lo=0.0, lo_open=True, hi=1.0)
    ratio = real(t_end, what, lo=0.0, lo_open=True) / dt
    k = round(ratio) if ratio <= MAX_SAMPLES else MAX_SAMPLES + 1
    if k < 2 or k > MAX_SAMPLES:
        raise ParameterError(
            f"{what} / dt = {t_end:g} / {dt:g} gives {k} samples; a run takes 2 to {MAX_SAMPLES:,}"
        )
    return k


@checked
def step_response(
    plant: CdprPlant | None = None, *, axis: int = 0, size: float = 0.02, t_end: float = 3.0, dt: float = 1e-3
) -> StepResponse:
    """Step the reference pose by ``size`` along ``axis`` at 0.2 s, PID only (no feed-forward, no
    tension distribution in the reference: the desired tensions are recorded for comparison)."""
    plant = instance(plant, "plant", CdprPlant, optional=True) or planar_plant()
    if isinstance(axis, bool) or not isinstance(axis, int | np.integer) or axis not in (0, 1, 2):
        raise ParameterError(f"axis must be 0 (x), 1 (y) or 2 (θ), got {axis!r}")
    size = real(size, "size")
    if size == 0.0:
        raise ParameterError("size must be a non-zero step")
    k = _samples(t_end, dt, "t_end")
    if k * dt <= 0.2:
        raise ParameterError(f"t_end must be past the step at 0.2 s, got {t_end:g}")
    poses = np.tile(np.asarray(plant.home), (k, 1))
    t = np.arange(k) * dt
    poses[t >= 0.2, axis] += size
    # a step has no finite acceleration: the desired tensions are the static ones at each pose
    run = plant.closed_loop(poses, dt, current_feedforward=False)
    rise, settle, over, final = _step_figures(t, run.pose[:, axis], 0.2, size)
    return StepResponse(
        axis, size, t, run, rise, settle, over, final, (float(run.ee.min()), float(run.ee.max()))
    )


@dataclass(frozen=True)
class TrajectoryResponse:
    """A circle with and without the tension distribution in the loop: RMSE of the pose (m) and
    of the cable tensions against ``f_d`` (N), and the runs."""

    t: np.ndarray
    poses: np.ndarray
    with_tensions: LoopRun
    without: LoopRun
    pose_rmse: tuple[float, float]
    tension_rmse: tuple[float, float]


@checked
def circle(
    home: np.ndarray, radius: float = 0.1, period: float = 4.0, turns: float = 2.0, dt: float = 1e-3
) -> np.ndarray:
    """A circle of ``radius`` through ``home`` in the robot's plane, the radius eased in over one
    period (smoothstep), at rest at both ends: poses ``(T, 3)``."""
    home = float_array(home, "home", 1)
    if home.shape != (3,) or not np.isfinite(home).all():
        raise ParameterError(f"home must be a finite planar pose [x, y, θ], got {home.tolist()}")
    radius = real(radius, "radius", lo=-1e3, hi=1e3)
    period = real(period, "period", lo=0.0, lo_open=True)
    turns = real(turns, "turns", lo=0.0, lo_open=True)
    n = _samples((turns + 1) * period, dt, "(turns + 1)·period")
    if period < 2 * dt:
        raise ParameterError(f"period must span at least two samples of dt = {dt:g} s, got {period:g}")
    t = np.arange(n) * dt
    s = np.clip(t / period, 0.0, 1.0)
    ease = s * s * (3 - 2 * s)
    fade = np.clip((t[-1] - t) / period, 0.0, 1.0)
    ease = ease * fade * fade * (3 - 2 * fade)
    ph = 2 * np.pi * t / period
    poses = np.tile(np.asarray(home, float), (t.size, 1))
    poses[:, 0] += ease * radius * np.sin(ph)
    poses[:, 1] += ease * radius * (1 - np.cos(ph))
    return poses


@checked
def trajectory_response(
    plant: CdprPlant | None = None, *, radius: float = 0.1, period: float = 4.0, dt: float = 1e-3
) -> TrajectoryResponse:
    """The circle with the tension distribution in the loop (feed-forward) and without it."""
    plant = plant or planar_plant()
    poses = circle(np.asarray(plant.home), radius, period, dt=dt)
    runs = [plant.closed_loop(poses, dt, current_feedforward=ff) for ff in (True, False)]

    def pose_rmse(r: LoopRun) -> float:
        return float(np.sqrt(np.mean(np.sum((r.pose[:, :2] - poses[:, :2]) ** 2, axis=1))))

    def tension_rmse(r: LoopRun) -> float:
        return float(np.sqrt(np.mean((r.ee - r.desired) ** 2)))

    t = np.arange(poses.shape[0]) * dt
    return TrajectoryResponse(
        t,
        poses,
        runs[0],
        runs[1],
        (pose_rmse(runs[0]), pose_rmse(runs[1])),
        (tension_rmse(runs[0]), tension_rmse(runs[1])),
    )


@checked
def markdown(steps: list[StepResponse], tr: TrajectoryResponse) -> str:
    """The step table and the trajectory comparison."""
    names = ("x", "y", "θ")
    lines = [
        "**Pose steps** (PID position control of each winch, seed 003's gains)",
        "",
        "| step | rise 10–90 % (ms) | settling 2 % (s) | overshoot | final error | tension range (N) |",
        "|---|---|---|---|---|---|",
    ]
    for s in steps:
        unit = "rad" if s.axis == 2 else "m"
        late = f"not within {s.t[-1]:.0f} s"
        rise = late if s.rise_time is None else f"{1e3 * s.rise_time:.0f}"
        settle = late if s.settling_time is None else f"{s.settling_time:.2f}"
        lines.append(
            f"| {s.size:g} {unit} in {names[s.axis]} | {rise} | {settle} | "
            f"{100 * s.overshoot:.1f} % | {100 * s.final_error:.2f} % | "
            f"{s.tension_range[0]:.1f} – {s.tension_range[1]:.1f} |"
        )
    lines += [
        "",
        "**Circle** (radius 0.1 m, 4 s per turn, two turns)",
        "",
        "| controller | pose RMSE (mm) | tension RMSE vs f_d (N) |",
        "|---|---|---|",
        "| tension distribution in the loop (current and stretch fed forward) | "
        f"{1e3 * tr.pose_rmse[0]:.2f} | {tr.tension_rmse[0]:.2f} |",
        "| kinematics only (PID on the drum angles) | "
        f"{1e3 * tr.pose_rmse[1]:.2f} | {tr.tension_rmse[1]:.2f} |",
    ]
    return "\n".join(lines)


@checked
def plot(path: str | Path, steps: list[StepResponse], tr: TrajectoryResponse) -> Path | None:
    """Step responses and the circle's tensions."""
    from cablekit.plotting import pyplot_or_none, save_figure

    plt = pyplot_or_none()
    if plt is None:
        return None
    fig, (a, b) = plt.subplots(2, 1, figsize=(10, 7))
    for s in steps:
        a.plot(
            s.t,
            (s.run.pose[:, s.axis] - s.run.pose[0, s.axis]) / s.size,
            lw=1,
            label=f"step in {'xyθ'[s.axis]}",
        )
    a.axhline(1.0, color="k", lw=0.5)
    a.set_xlabel("t (s)")
    a.set_ylabel("response / step")
    a.legend(fontsize=8)
    for j in range(tr.with_tensions.ee.shape[1]):
        b.plot(tr.t, tr.with_tensions.desired[:, j], "k", lw=0.6)
        b.plot(tr.t, tr.with_tensions.ee[:, j], lw=0.8, label=f"cable {j + 1}")
    b.set_xlabel("t (s)")
    b.set_ylabel("tension (N); black: f_d")
    b.legend(fontsize=8)
    a.set_title("Seed 003's planar robot in closed loop")
    return save_figure(fig, path)


@checked
def report(out: str | Path, plots: bool = True) -> str:
    """Steps in x, y and θ and the circle on the shipped robot; writes ``planar.md``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    plant = planar_plant()
    steps = [step_response(plant, axis=a, size=s, t_end=6.0) for a, s in ((0, 0.02), (1, 0.02), (2, 0.05))]
    tr = trajectory_response(plant)
    text = "# Seed 003's planar robot in closed loop\n\n" + markdown(steps, tr) + "\n"
    if plots and (fig := plot(out / "planar.png", steps, tr)):
        text += f"\n![steps and the circle's tensions]({fig.name})\n"
    (out / "planar.md").write_text(text, encoding="utf-8")
    return text


class PlanarRobot:
    """Seed 003's planar 4-cable robot in closed loop: ``robot`` (default the shipped
    ``seed003_planar``; any planar robot), one ``winch`` per cable (default
    :meth:`Winch.seed003`), resting at ``home`` (default :data:`HOME`), with any further
    :class:`CdprPlant` options (``cable_damping``, ``drum_side``, ``platform_side``, ``creep``,
    ...). The plant is built once; every response runs on it."""

    def __init__(
        self,
        robot: Robot | None = None,
        *,
        home: np.ndarray | None = None,
        winch: Winch | None = None,
        **plant_options: Any,
    ) -> None:
        robot = robot or shipped("seed003_planar")
        if robot.motion != "planar":
            raise ParameterError(f"PlanarRobot needs a planar robot, got {robot.name!r} ({robot.motion})")
        self.robot = robot
        self.winch = winch or Winch.seed003()
        self.plant = CdprPlant(
            robot, np.asarray(HOME if home is None else home, float), self.winch, **plant_options
        )

    @property
    def home(self) -> np.ndarray:
        """The home pose ``[x, y, θ]``."""
        return np.asarray(self.plant.home)

    @checked
    def step(
        self, axis: int = 0, size: float = 0.02, *, t_end: float = 3.0, dt: float = 1e-3
    ) -> StepResponse:
        """A reference step of ``size`` along ``axis`` (0: x, 1: y, 2: θ) at 0.2 s, PID only; see
        :func:`step_response`."""
        if isinstance(axis, bool) or not isinstance(axis, int | np.integer) or axis not in (0, 1, 2):
            raise ParameterError(f"axis must be 0 (x), 1 (y) or 2 (θ), got {axis!r}")
        return step_response(self.plant, axis=axis, size=size, t_end=t_end, dt=dt)

    @checked
    def circle(self, radius: float = 0.1, period: float = 4.0, *, dt: float = 1e-3) -> TrajectoryResponse:
        """Two turns of a circle through home with and without the tension distribution in the
        loop; see :func:`trajectory_response`."""
        return trajectory_response(self.plant, radius=radius, period=period, dt=dt)

    @checked
    def follow(self, poses: np.ndarray, dt: float = 1e-3, **loop_options: Any) -> LoopRun:
        """Desired ``poses`` ``(T, 3)`` every ``dt`` s through the trajectory controller with the
        tension distribution in the loop (:meth:`CdprPlant.closed_loop` and its options)."""
        dt = real(dt, "dt", lo=0.0, lo_open=True, hi=1.0)
        return self.plant.closed_loop(float_array(poses, "poses", 2), dt, **loop_options)

    def __repr__(self) -> str:
        return f"PlanarRobot(robot={self.robot.name!r}, home={self.home.tolist()})"
