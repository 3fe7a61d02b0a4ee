"""Plots of simulated runs (needs the ``report`` extra: matplotlib)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from cablekit import _log
from cablekit.errors import CablekitError
from cablekit.simulation import SimulationResult


class Figures:
    """The part of ``matplotlib.pyplot`` cablekit draws with — ``subplots``, ``figure``,
    ``close`` — on bare :class:`matplotlib.figure.Figure` objects: they are never registered
    with pyplot, so drawing a report neither switches the user's backend (a notebook's inline
    or a GUI backend stays as it was) nor opens a window, and saving needs no display."""

    @staticmethod
    def figure(figsize: tuple[float, float] | None = None, **kwargs: Any) -> Any:
        from matplotlib.figure import Figure

        return Figure(figsize=figsize, **kwargs)

    @classmethod
    def subplots(
        cls, nrows: int = 1, ncols: int = 1, *, figsize: tuple[float, float] | None = None, **kwargs: Any
    ) -> tuple[Any, Any]:
        fig = cls.figure(figsize=figsize)
        return fig, fig.subplots(nrows, ncols, **kwargs)

    @staticmethod
    def close(fig: Any = None) -> None:
        """Nothing to release: the figure is not in pyplot's registry (kept so that code
        written against pyplot reads the same)."""


def _pyplot() -> Figures:
    try:
        import matplotlib.figure  # noqa: F401  (the report extra)
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise CablekitError("plots need matplotlib: pip install 'cablekit[report]'") from exc
    return Figures()


def pyplot_or_none() -> Figures | None:
    """A :class:`Figures` namespace (pyplot's ``subplots``/``figure``/``close`` on bare
    figures, the user's backend untouched), or None (with a note) without the report extra: for
    scripts whose plots are optional."""
    try:
        return _pyplot()
    except CablekitError:
        _log.warning("matplotlib not installed (pip install 'cablekit[report]'): no plot")
        return None


def save_figure(fig: Any, path: str | Path) -> Path:
    """Lay out ``fig``, write it to ``path`` (90 dpi) and close it; returns the path."""
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=90)
    _pyplot().close(fig)
    return path


def plot_run(result: SimulationResult, path: str | Path, title: str = "") -> Path:
    """Plot a run's positions, tensions and inputs to a PNG; returns the path."""
    plt = _pyplot()
    example = result.meta.get("example")
    fig, axes = plt.subplots(3, 1, figsize=(10, 9), sharex=True)
    t = result.t
    if example == "raven-link":
        _raven_panels(result, axes)
    else:
        _generic_panels(result, axes)
    axes[-1].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8, ncol=3)
    fig.suptitle(title or f"cablekit simulation ({example or 'run'}), {len(t)} samples")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _raven_panels(result: SimulationResult, axes: Any) -> None:
    t = result.t
    n = sum(1 for name in result.state_names if name.startswith("q_l"))
    ref = result.meta.get("reference_joint")
    for i in range(1, n + 1):
        # revolute joints in degrees, the prismatic insertion axis in centimetres
        scale, unit = (1e2, "cm") if i == 3 else (float(np.degrees(1.0)), "deg")
        axes[0].plot(t, result[f"q_l{i}"] * scale, label=f"joint {i} [{unit}]")
        if isinstance(ref, np.ndarray):
            axes[0].plot(t, ref[:, i - 1] * scale, "k:", lw=0.8)
        axes[1].plot(t, result[f"tension_a{i}"] - result[f"tension_b{i}"], label=f"net tension {i} [N]")
        axes[2].plot(t, result[f"tau_m{i}"], label=f"motor torque {i} [N·m]")
    axes[0].set_ylabel("joint position")
    axes[1].set_ylabel("cable tension")
    axes[2].set_ylabel("servo torque")


def _generic_panels(result: SimulationResult, axes: Any) -> None:
    t = result.t
    tension_cols = [c for c in result.output_names if "tension" in c]
    other = [c for c in result.output_names if c not in tension_cols]
    for c in other:
        axes[0].plot(t, result[c], label=c)
    for c in tension_cols:
        axes[1].plot(t, result[c], label=f"{c} [N]")
    for c in result.input_names:
        col = result[c]
        scale = 1.0 / max(float(np.max(np.abs(col))), 1e-300)
        axes[2].plot(t, col * scale, label=f"{c} (normalised)")
    axes[0].set_ylabel("outputs")
    axes[1].set_ylabel("tension [N]")
    axes[2].set_ylabel("inputs")
