"""Seed 002 §3 on the twin: pulley friction between the winch-side sensors (PUL) and the platform
(EE) of the Mini CDPR, and the 14 → 8 network that compensates it.

The twin (the shipped ``seed002_mini`` robot, its platform moving in translation):

* **trajectories** as in the seed's Fig. 5: training — the four diagonals of a cube, there and
  back, and three circles (xy, xz, yz); test 1 — a circle in a tilted plane and a straight line
  in y; test 2 — straight lines through 20 random points of the cube. Both test families are
  unseen in training. Constant speed, corners rounded by a 0.25 s moving average (choices);
* **EE tensions** by the core's tension distribution (``Robot.distribute``, ``auto``) holding
  the weight and the platform's inertia, ``Aᵀf = m·(a − g)`` (seed 002 eq. 6 in translation);
* **PUL tensions** by the core's path friction (``Robot.path_friction``, eqs 7–8: pulley
  friction proportional to the normal force on the guide pulleys and the exit pulley, whose wrap
  moves with the pose; a Dahl state over the hauled cable; viscous) plus the load cell's noise;
* **the network**: inputs ``[x, y, z, ẋ, ẏ, ż, f_PUL1…8]``, outputs ``f_EE1…8``, Bayesian
  regularisation (``cablekit.nn``, ``method="br"``, the seed's MATLAB ``trainbr``), run in Rust
  (:class:`cablekit.Mlp`).

The friction parameters are choices (marked in :data:`TWIN_FRICTION`), set so that the PUL error
is of the seed's size (Tables 1–2: 1.45–1.99 N mean RMSE); they are not tuned on the network's
result.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from cablekit._args import Epochs, Seed, Stride, Width, checked, instance, real, signal, text
from cablekit._cablekit import Mlp
from cablekit.cdpr import Robot, shipped
from cablekit.errors import ParameterError, ShapeError

#: the seed's Tables 1–2: RMSE (N) per cable and mean, EE vs PUL and EE vs NN
SEED_TABLE1 = {
    "PUL": (1.81, 2.11, 2.02, 2.77, 1.89, 1.69, 1.81, 1.82, 1.99),
    "NN": (0.82, 0.46, 0.42, 0.65, 0.34, 0.44, 0.64, 0.30, 0.51),
}
SEED_TABLE2 = {
    "PUL": (1.34, 1.54, 1.30, 1.41, 1.63, 1.57, 1.31, 1.50, 1.45),
    "NN": (0.52, 0.51, 0.65, 0.48, 0.38, 0.67, 0.36, 0.73, 0.54),
}

#: the twin's path friction per cable (choices, see the module docs): pulley coefficient μ,
#: viscous σ_v (N·s/m), guide pulleys' wrap between the sensor and the exit (rad; the seed's
#: sensor sits on the third of five pulleys), Dahl presliding length (m); load-cell noise (N)
TWIN_FRICTION = {
    "coefficient": np.array([0.020, 0.024, 0.018, 0.027, 0.022, 0.020, 0.025, 0.018]),
    "viscous": np.array([6.0, 5.0, 7.0, 5.5, 6.5, 5.0, 6.0, 7.0]),
    "guide_wrap": np.full(8, np.pi),
    "presliding": 2e-3,
    "noise": 0.1,
}


@dataclass(frozen=True)
class Trajectory:
    """Poses ``(T, 6)`` (orientation held at zero), velocity and acceleration ``(T, 3)`` every
    ``dt`` s."""

    name: str
    dt: float
    poses: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray

    @property
    def t(self) -> np.ndarray:
        return np.arange(self.poses.shape[0]) * self.dt


@checked
def path(name: str, points: list[np.ndarray], *, speed: float = 0.1, dt: float = 0.01) -> Trajectory:
    """Through ``points`` at ``speed`` m/s, corners rounded by a 0.25 s moving average."""
    text(name, "name")
    instance(points, "points", list | tuple)
    points = [signal(p, f"points[{k}]", 1) for k, p in enumerate(points)]
    if len(points) < 2 or any(p.shape != (3,) or not np.isfinite(p).all() for p in points):
        raise ParameterError("points must be two or more finite positions (x, y, z)")
    speed = real(speed, "speed", lo=1e-6, hi=1e3)
    dt = real(dt, "dt", lo=1e-6, hi=1.0)
    if sum(float(np.linalg.norm(b - a)) for a, b in itertools.pairwise(points)) / speed / dt > 1e7:
        raise ParameterError("the path is over 1e7 samples at this speed and dt")
    segs = []
    for a, b in itertools.pairwise(points):
        n = max(2, int(np.linalg.norm(b - a) / speed / dt))
        segs.append(a + (b - a) * np.linspace(0.0, 1.0, n, endpoint=False)[:, None])
    segs.append(points[-1][None, :])
    p = np.vstack(segs)
    k = max(1, round(0.25 / dt)) | 1
    kernel = np.ones(k) / k
    p = np.column_stack(
        [np.convolve(np.pad(p[:, i], k // 2, mode="edge"), kernel, "valid") for i in range(3)]
    )
    v = np.gradient(p, dt, axis=0)
    a = np.gradient(v, dt, axis=0)
    poses = np.zeros((p.shape[0], 6))
    poses[:, :3] = p
    return Trajectory(name, dt, poses, v, a)


def _circle(center: np.ndarray, radius: float, u: np.ndarray, w: np.ndarray, n: int = 90) -> list[np.ndarray]:
    return [center + radius * (np.cos(a) * u + np.sin(a) * w) for a in np.linspace(0.0, 2 * np.pi, n)]


@dataclass(frozen=True)
class Cube:
    """The training and test region: ``center`` (m) and ``half`` widths (m)."""

    center: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.475]))
    half: np.ndarray = field(default_factory=lambda: np.array([0.15, 0.10, 0.12]))


@checked
def training_trajectories(cube: Cube | None = None, **kw: float) -> list[Trajectory]:
    """Seed 002 Fig. 5's training paths: four cube diagonals, there and back, and circles in the
    xy, xz and yz planes."""
    c = cube or Cube()
    corners = [c.center + c.half * np.array([sx, sy, 1.0]) for sx in (-1, 1) for sy in (-1, 1)]
    out = [path(f"diagonal {k + 1}", [a, 2 * c.center - a, a], **kw) for k, a in enumerate(corners)]
    e = np.eye(3)
    for name, (i, j) in (("circle xy", (0, 1)), ("circle xz", (0, 2)), ("circle yz", (1, 2))):
        r = 0.9 * min(c.half[i], c.half[j])
        out.append(path(name, _circle(c.center, r, e[i], e[j]), **kw))
    return out


@checked
def first_test_trajectory(cube: Cube | None = None, **kw: float) -> Trajectory:
    """Test 1: a circle in a plane tilted 30° about x (not a training plane), then a line in y."""
    c = cube or Cube()
    tilt = np.radians(30.0)
    u, w = np.array([1.0, 0.0, 0.0]), np.array([0.0, np.cos(tilt), np.sin(tilt)])
    pts = _circle(c.center + np.array([0.0, 0.0, 0.02]), 0.7 * c.half[1], u, w)
    pts += [
        c.center + np.array([0.0, -0.8 * c.half[1], 0.0]),
        c.center + np.array([0.0, 0.8 * c.half[1], 0.0]),
    ]
    return path("test 1: tilted circle and y line", pts, **kw)


@checked
def second_test_trajectory(cube: Cube | None = None, seed: Seed = 2, **kw: float) -> Trajectory:
    """Test 2: straight lines through 20 random points of the cube."""
    c = cube or Cube()
    rng = np.random.default_rng(seed)
    pts = [c.center + c.half * rng.uniform(-0.9, 0.9, 3) for _ in range(20)]
    return path("test 2: lines through 20 random points", pts, **kw)


@dataclass(frozen=True)
class TensionRun:
    """A trajectory's tensions: ``ee`` (platform side) and ``pul`` (the winch-side sensors),
    ``(T, 8)`` N, and the network's inputs ``x`` ``(T, 14)``."""

    trajectory: Trajectory
    ee: np.ndarray
    pul: np.ndarray

    @property
    def x(self) -> np.ndarray:
        tr = self.trajectory
        return np.column_stack([tr.poses[:, :3], tr.velocity, self.pul])


@checked
def tensions(
    robot: Robot, tr: Trajectory, *, rng: np.random.Generator, friction: dict | None = None
) -> TensionRun:
    """EE tensions holding weight and inertia, PUL tensions through the path friction plus the
    load cell's noise."""
    fr = TWIN_FRICTION if friction is None else friction
    wrench = np.zeros((tr.poses.shape[0], 6))
    wrench[:, :3] = -robot.mass * tr.acceleration
    dist = robot.distribute(tr.poses, wrench)
    if not dist.feasible.all():
        bad = int(np.argmin(dist.feasible))
        raise ParameterError(
            f"{tr.name}: no tensions within the bounds hold the platform at sample {bad} "
            f"({tr.poses[bad, :3]} m): the trajectory leaves the wrench-feasible workspace"
        )
    run = robot.path_friction(
        tr.poses,
        dist.f,
        tr.dt,
        fr["coefficient"],
        fr["viscous"],
        fr["guide_wrap"],
        law="dahl",
        presliding=float(fr["presliding"]),
    )
    pul = run.pul + rng.normal(0.0, float(fr["noise"]), run.pul.shape)
    return TensionRun(tr, dist.f.copy(), pul)


@checked
def rmse(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    a, b = signal(a, "a"), signal(b, "b")
    if a.shape != b.shape or a.size == 0:
        raise ShapeError(f"a and b must be non-empty and of one shape, got {a.shape} and {b.shape}")
    """Per-column RMSE."""
    return np.sqrt(np.mean((a - b) ** 2, axis=0))


@checked
def statics(robot: Robot, run: TensionRun) -> np.ndarray:
    """The PUL tensions moved to the nearest ones that hold the platform's weight and inertia
    (``Robot.project_tensions``, seed 002 eq. 10 with the measurement as reference): what
    statics alone takes out of the friction, without learning."""
    tr = run.trajectory
    wrench = np.zeros((tr.poses.shape[0], 6))
    wrench[:, :3] = -robot.mass * tr.acceleration
    return robot.project_tensions(tr.poses, np.ascontiguousarray(run.pul), wrench)


@dataclass(frozen=True)
class Compensation:
    """The trained network's result: per test case the RMSE per cable against EE of PUL, of the
    network's estimate (NN) and of PUL projected onto equilibrium (statics, no learning)."""

    hidden: int
    train_samples: int
    train_time_s: float
    tables: dict[str, tuple[np.ndarray, np.ndarray]]
    runs: dict[str, tuple[TensionRun, np.ndarray]]
    statics: dict[str, np.ndarray]
    network: Mlp


@checked
def compensate(
    robot: Robot | None = None,
    *,
    hidden: Width = 20,
    epochs: Epochs = 150,
    seed: Seed = 0,
    every: Stride = 3,
    progress: bool = False,
) -> Compensation:
    """Simulate the training and test trajectories, train the 14 → ``hidden`` → 8 network by
    Bayesian regularisation on every ``every``-th training sample, and score it from Rust on
    the two test families (seed 002 Tables 1–2) and two transfer checks: test 2 half as fast
    again as any training motion, and test 2 with the pulleys' friction 50 % higher than the
    network was trained on."""
    from cablekit.nn import to_mlp, train_mlp

    robot = robot or shipped("seed002_mini")
    rng = np.random.default_rng(seed)
    train = [tensions(robot, tr, rng=rng) for tr in training_trajectories()]
    x = np.vstack([r.x for r in train])[::every]
    y = np.vstack([r.ee for r in train])[::every]
    result = train_mlp(
        x,
        y,
        method="br",
        hidden=(hidden,),
        epochs=epochs,
        seed=seed,
        test_fraction=0.0,
        progress=progress,
    )
    net = to_mlp(result)
    tables, runs, projected = {}, {}, {}
    # the same random lines half as fast again as anything in training: a transfer check
    faster = replace(second_test_trajectory(speed=0.15), name="test 2 at 0.15 m/s (training: 0.1 m/s)")
    worn = dict(TWIN_FRICTION, coefficient=1.5 * TWIN_FRICTION["coefficient"])
    cases = [
        (first_test_trajectory(), None),
        (second_test_trajectory(), None),
        (faster, None),
        (replace(second_test_trajectory(), name="test 2, pulleys with 50 % more friction"), worn),
    ]
    for tr, friction in cases:
        run = tensions(robot, tr, rng=rng, friction=friction)
        nn = net.predict(np.ascontiguousarray(run.x))
        tables[tr.name] = (rmse(run.pul, run.ee), rmse(nn, run.ee))
        runs[tr.name] = (run, nn)
        projected[tr.name] = rmse(statics(robot, run), run.ee)
    return Compensation(hidden, x.shape[0], result.train_time_s, tables, runs, projected, net)


@checked
def table_markdown(
    name: str, pul: np.ndarray, nn: np.ndarray, seed: dict[str, tuple[float, ...]], statics: np.ndarray
) -> str:
    """One of seed 002's Tables 1–2, ours (with the statics baseline) beside the seed's."""
    head = "| RMSE (N) | " + " | ".join(f"f{i + 1}" for i in range(8)) + " | mean |"
    lines = [f"**{name}**", "", head, "|---" * 10 + "|"]
    rows = (("EE vs PUL, twin", pul), ("EE vs PUL on equilibrium, twin", statics), ("EE vs NN, twin", nn))
    for label, v in rows:
        lines.append(f"| {label} | " + " | ".join(f"{a:.2f}" for a in v) + f" | **{v.mean():.2f}** |")
    for label, key in (("EE vs PUL, seed", "PUL"), ("EE vs NN, seed", "NN")):
        lines.append(f"| {label} | " + " | ".join(f"{a:.2f}" for a in seed[key]) + " |")
    return "\n".join(lines)


@checked
def report(out: str | Path, comp: Compensation, plots: bool = True) -> str:
    """Tables 1–2 and a cable's tensions along test 1; returns the markdown."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    names = list(comp.tables)
    parts = [
        "# Seed 002's pulley-friction compensation on the twin",
        f"14 → {comp.hidden} → 8 network, Bayesian regularisation, {comp.train_samples:,} training "
        f"samples (training trajectories only), {comp.train_time_s:.1f} s; scored from Rust on the two "
        "test families the training never saw.",
        table_markdown(f"Table 1 ({names[0]})", *comp.tables[names[0]], SEED_TABLE1, comp.statics[names[0]]),
        table_markdown(f"Table 2 ({names[1]})", *comp.tables[names[1]], SEED_TABLE2, comp.statics[names[1]]),
        "**Transfer checks** (mean RMSE over the cables, N)\n\n"
        "| case | EE vs PUL | PUL on equilibrium | EE vs NN |\n|---|---|---|---|\n"
        + "\n".join(
            f"| {n} | {comp.tables[n][0].mean():.2f} | {comp.statics[n].mean():.2f} | "
            f"{comp.tables[n][1].mean():.2f} |"
            for n in names[2:]
        ),
    ]
    if plots:
        fig = plot_cable(out / "compensate_test1.png", comp, cable=1)
        if fig:
            parts.append(f"![cable 2 along test 1]({fig.name})")
    text = "\n\n".join(parts) + "\n"
    (out / "compensate.md").write_text(text, encoding="utf-8")
    return text


@checked
def plot_cable(path: str | Path, comp: Compensation, cable: int = 1) -> Path | None:
    """EE, PUL and NN tension of one cable along test 1, and the errors (seed 002 Fig. 6)."""
    from cablekit.plotting import pyplot_or_none, save_figure

    plt = pyplot_or_none()
    if plt is None:
        return None
    run, nn = next(iter(comp.runs.values()))
    t = run.trajectory.t
    fig, (a, b) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    a.plot(t, run.ee[:, cable], "k", lw=1, label="EE")
    a.plot(t, run.pul[:, cable], "C1", lw=0.8, label="PUL")
    a.plot(t, nn[:, cable], "C0", lw=0.8, label="NN")
    a.set_ylabel(f"cable {cable + 1} tension (N)")
    a.legend(fontsize=8)
    b.plot(t, run.pul[:, cable] - run.ee[:, cable], "C1", lw=0.8, label="PUL − EE")
    b.plot(t, nn[:, cable] - run.ee[:, cable], "C0", lw=0.8, label="NN − EE")
    b.set_ylabel("error (N)")
    b.set_xlabel("t (s)")
    b.legend(fontsize=8)
    a.set_title(f"Seed 002 Fig. 6 on the twin: {run.trajectory.name}")
    return save_figure(fig, path)
