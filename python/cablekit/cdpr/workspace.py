"""Wrench-feasible and static workspace on a grid of positions at a fixed orientation.

The capacity margin of every grid pose comes from the Rust core (``Robot.capacity``: hyperplane
shifting over the available wrench set, exact membership, in parallel); this module builds the
grid, keeps the result with its axes, summarises it and plots slices and a 3-D view.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cablekit._args import checked, count, float_array
from cablekit._cablekit import Robot
from cablekit.errors import DTypeError, ParameterError, ShapeError

__all__ = ["Requirement", "Workspace", "plot_workspace", "workspace"]

#: grid points per axis by default (50³ = 125,000 poses for a spatial robot)
DEFAULT_COUNTS = 50
#: the most grid points one call evaluates (a 1000³ grid would need 1e9 poses and ~50 GB):
#: 1e6 poses take a few seconds and ~100 MB; finer grids are several calls over sub-boxes
MAX_POSES = 1_000_000


@dataclass(frozen=True)
class Requirement:
    """The wrench set every workspace pose must hold: the platform's weight (``gravity``) plus
    the box ``wrench ± half_width`` (``(n,)`` each, N and N·m); moments count in the margin
    divided by ``moment_length`` (m). The default is the static workspace. ``margins="inside"``
    keeps membership and the margins inside exact but stops an outside pose's scan at the first
    facet the wrench set crosses (its margin is then an upper bound): faster where only the
    workspace, not the depth outside it, matters."""

    gravity: bool = True
    wrench: np.ndarray | None = None
    half_width: np.ndarray | None = None
    moment_length: float = 1.0
    margins: str = "everywhere"

    @property
    def kind(self) -> str:
        """``"static"`` (the weight only) or ``"wrench-feasible"``."""
        boxed = self.half_width is not None and bool(np.any(np.asarray(self.half_width) > 0))
        moved = self.wrench is not None and bool(np.any(np.asarray(self.wrench) != 0))
        return "wrench-feasible" if boxed or moved else "static"


@dataclass(frozen=True)
class Workspace:
    """Capacity margins on a grid: ``axes`` (one 1-D array per position coordinate: x, y for a
    planar robot, x, y, z for a spatial one), the fixed ``orientation`` coordinates, and per
    grid point (``indexing="ij"``) the ``margin``, ``feasible`` and ``degenerate`` arrays."""

    robot: str
    motion: str
    axes: tuple[np.ndarray, ...]
    orientation: np.ndarray
    requirement: Requirement
    margin: np.ndarray
    feasible: np.ndarray
    degenerate: np.ndarray
    seconds: float = field(default=0.0, compare=False)

    @property
    def cell(self) -> float:
        """Area (planar, m²) or volume (spatial, m³) of one grid cell."""
        return float(np.prod([a[1] - a[0] if len(a) > 1 else 1.0 for a in self.axes]))

    @property
    def fraction(self) -> float:
        """Share of the grid inside the workspace."""
        return float(self.feasible.mean())

    @property
    def size(self) -> float:
        """Workspace area (planar, m²) or volume (spatial, m³): feasible cells × cell size."""
        return float(self.feasible.sum()) * self.cell

    @checked
    def table(self) -> str:
        """A Markdown summary."""
        inside = self.margin[self.feasible]
        unit = "m²" if self.motion == "planar" else "m³"
        rows = [
            ("robot", self.robot),
            ("workspace", self.requirement.kind),
            ("grid", " × ".join(str(len(a)) for a in self.axes) + f" = {self.margin.size:,} poses"),
            ("orientation", np.array2string(self.orientation, precision=3)),
            ("inside", f"{self.feasible.sum():,} poses ({100 * self.fraction:.1f} %)"),
            (f"size ({unit})", f"{self.size:.4g}"),
            ("degenerate poses", f"{int(self.degenerate.sum())}"),
            ("largest margin (N)", f"{inside.max():.3g}" if inside.size else "—"),
            ("median margin inside (N)", f"{np.median(inside):.3g}" if inside.size else "—"),
            ("moment length (m)", f"{self.requirement.moment_length:g}"),
            ("margins exact", self.requirement.margins),
            ("time (s)", f"{self.seconds:.3f}"),
        ]
        return "| quantity | value |\n|---|---|\n" + "\n".join(f"| {k} | {v} |" for k, v in rows) + "\n"

    @checked
    def save(self, out: str | Path) -> Path:
        """``workspace.npz`` (axes, margin, feasible, degenerate) and ``workspace.md`` in ``out``."""
        d = Path(out)
        d.mkdir(parents=True, exist_ok=True)
        names = ("x", "y", "z")[: len(self.axes)]
        arrays: dict[str, np.ndarray] = {
            "margin": self.margin,
            "feasible": self.feasible,
            "degenerate": self.degenerate,
            "orientation": self.orientation,
            **dict(zip(names, self.axes, strict=True)),
        }
        np.savez_compressed(d / "workspace.npz", **arrays)  # type: ignore[arg-type]
        (d / "workspace.md").write_text(self.table(), encoding="utf-8")
        return d


def _axis(lo: float, hi: float, count: int) -> np.ndarray:
    return np.linspace(lo, hi, count) if count > 1 else np.array([(lo + hi) / 2])


@checked
def workspace(
    robot: Robot,
    *,
    counts: int | tuple[int, ...] = DEFAULT_COUNTS,
    lower: Any = None,
    upper: Any = None,
    orientation: Any = None,
    requirement: Requirement | None = None,
) -> Workspace:
    """The workspace of ``robot`` on a grid of ``counts`` points per position axis between
    ``lower`` and ``upper`` (default: the box of the frame anchors), at the fixed ``orientation``
    (``[θ]`` planar, ``[roll, pitch, yaw]`` spatial; default 0), for the ``requirement`` (default:
    static). At most :data:`MAX_POSES` grid points per call (a :class:`ParameterError` says so)."""
    if not isinstance(robot, Robot):
        raise DTypeError(f"robot must be a cablekit.cdpr.Robot, got {type(robot).__name__}")
    if requirement is not None and not isinstance(requirement, Requirement):
        raise DTypeError(f"requirement must be a Requirement, got {type(requirement).__name__}")
    req = requirement or Requirement()
    planar = robot.motion == "planar"
    k = 2 if planar else 3
    anchors, _ = robot.points()
    lo = anchors.min(axis=0)[:k] if lower is None else float_array(lower, "lower", 1)
    hi = anchors.max(axis=0)[:k] if upper is None else float_array(upper, "upper", 1)
    rot = np.zeros(robot.dof - k) if orientation is None else float_array(orientation, "orientation", 1)
    if isinstance(counts, list | tuple):
        cnt = tuple(count(c, "counts", lo=1, hi=MAX_POSES) for c in counts)
    else:
        cnt = (count(counts, "counts", lo=1, hi=MAX_POSES),) * k
    if lo.shape != (k,) or hi.shape != (k,) or rot.shape != (robot.dof - k,) or len(cnt) != k:
        raise ShapeError(
            f"a {robot.motion} grid needs lower/upper of {k} values, counts of {k} and an orientation "
            f"of {robot.dof - k}; got {lo.shape}, {hi.shape}, {len(cnt)} and {rot.shape}"
        )
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo <= hi)):
        raise ParameterError(f"the grid needs finite lower <= upper, got {lo} and {hi}")
    if not np.all(np.isfinite(rot)):
        raise ParameterError(f"the orientation must be finite, got {rot}")
    if math.prod(cnt) > MAX_POSES:
        raise ParameterError(
            f"counts {cnt} ask for {math.prod(cnt):,} poses; one call evaluates at most {MAX_POSES:,} "
            "(split the box into sub-boxes for a finer grid)"
        )
    axes = tuple(_axis(a, b, c) for a, b, c in zip(lo, hi, cnt, strict=True))
    mesh = np.meshgrid(*axes, indexing="ij")
    poses = np.empty((mesh[0].size, robot.dof))
    for j, m in enumerate(mesh):
        poses[:, j] = m.ravel()
    poses[:, k:] = rot
    start = time.perf_counter()
    cap = robot.capacity(
        poses,
        req.wrench,
        req.half_width,
        gravity=req.gravity,
        moment_length=req.moment_length,
        margins=req.margins,
    )
    seconds = time.perf_counter() - start
    shape = mesh[0].shape
    return Workspace(
        robot=robot.name,
        motion=robot.motion,
        axes=axes,
        orientation=rot,
        requirement=req,
        margin=cap.margin.reshape(shape),
        feasible=cap.feasible.reshape(shape),
        degenerate=cap.degenerate.reshape(shape),
        seconds=seconds,
    )


@checked
def plot_workspace(ws: Workspace, out: str | Path, robot: Robot | None = None) -> list[Path]:
    """Slices of the margin (planar: the plane; spatial: three heights and the x–z plane
    through the middle) with the workspace's edge, and a 3-D view of the feasible poses;
    PNGs in ``out``. Needs matplotlib (the ``report`` extra)."""
    from cablekit.plotting import _pyplot

    plt = _pyplot()
    d = Path(out)
    d.mkdir(parents=True, exist_ok=True)
    anchors = robot.points()[0] if robot is not None else None
    inside = ws.margin[ws.feasible]
    top = float(np.max(np.abs(ws.margin))) if inside.size == 0 else float(inside.max())
    top = top if top > 0 else 1.0
    kw = {"cmap": "RdYlGn", "vmin": -top, "vmax": top, "shading": "auto"}
    title = f"{ws.robot}: {ws.requirement.kind} workspace, capacity margin (N)"
    paths = []

    def panel(ax: Any, u: np.ndarray, v: np.ndarray, m: np.ndarray, lab: tuple[str, str]) -> Any:
        im = ax.pcolormesh(u, v, m.T, **kw)
        if np.any(m > 0) and np.any(m < 0):
            ax.contour(u, v, m.T, levels=[0.0], colors="k", linewidths=1.2)
        ax.set_xlabel(f"{lab[0]} (m)")
        ax.set_ylabel(f"{lab[1]} (m)")
        ax.set_aspect("equal")
        return im

    if ws.motion == "planar":
        fig, ax = plt.subplots(figsize=(7, 6))
        im = panel(ax, ws.axes[0], ws.axes[1], ws.margin, ("x", "y"))
        if anchors is not None:
            ax.plot(anchors[:, 0], anchors[:, 1], "ks", ms=6, label="anchors")
            ax.legend(loc="upper right")
        ax.set_title(f"{title}\nθ = {ws.orientation[0]:.3g} rad; black: edge (margin 0)", fontsize=10)
        fig.colorbar(im, ax=ax)
        fig.tight_layout()
        paths.append(d / "workspace.png")
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)
        return paths
    x, y, z = ws.axes
    levels = [len(z) // 4, len(z) // 2, (3 * len(z)) // 4]
    fig, axes = plt.subplots(1, 4, figsize=(20, 5))
    for ax, iz in zip(axes[:3], levels, strict=True):
        im = panel(ax, x, y, ws.margin[:, :, iz], ("x", "y"))
        ax.set_title(f"z = {z[iz]:.3f} m")
        if anchors is not None:
            ax.plot(anchors[:, 0], anchors[:, 1], "ks", ms=5)
    iy = len(y) // 2
    im = panel(axes[3], x, z, ws.margin[:, iy, :], ("x", "z"))
    axes[3].set_title(f"y = {y[iy]:.3f} m")
    if anchors is not None:
        axes[3].plot(anchors[:, 0], anchors[:, 2], "ks", ms=5)
    fig.colorbar(im, ax=axes.tolist(), shrink=0.9)
    fig.suptitle(f"{title}; orientation (rpy) {np.round(ws.orientation, 3)}; black: edge (margin 0)")
    paths.append(d / "workspace_slices.png")
    fig.savefig(paths[-1], dpi=100)
    plt.close(fig)
    # 3-D: the feasible poses on the workspace's surface (a feasible pose with an infeasible
    # neighbour), coloured by height
    f = ws.feasible
    pad = np.pad(f, 1, constant_values=False)
    interior = (
        pad[2:, 1:-1, 1:-1]
        & pad[:-2, 1:-1, 1:-1]
        & pad[1:-1, 2:, 1:-1]
        & pad[1:-1, :-2, 1:-1]
        & pad[1:-1, 1:-1, 2:]
        & pad[1:-1, 1:-1, :-2]
    )
    surface = f & ~interior
    ii = np.argwhere(surface)
    fig = plt.figure(figsize=(8, 7))
    ax = fig.add_subplot(projection="3d")
    if len(ii):
        pts = np.column_stack([x[ii[:, 0]], y[ii[:, 1]], z[ii[:, 2]]])
        step = max(1, len(pts) // 20000)
        ax.scatter(*pts[::step].T, c=pts[::step, 2], cmap="viridis", s=2, alpha=0.5)
    if anchors is not None:
        ax.scatter(*anchors.T, c="k", marker="s", s=30, label="anchors")
        ax.legend(loc="upper left")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.set_title(
        f"{ws.robot}: {ws.requirement.kind} workspace "
        f"({100 * ws.fraction:.1f} % of the grid, {ws.size:.3g} m³)"
    )
    paths.append(d / "workspace_3d.png")
    fig.savefig(paths[-1], dpi=100)
    plt.close(fig)
    return paths
