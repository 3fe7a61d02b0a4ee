"""``cablekit forceps experiments``: seed 000's experiments in the twin, the physics estimator
beside the seed's pipeline, the transfer to other instruments; a report with the tables and
the panels of the seed's Figs 7–9."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from cablekit.forceps.experiments import (
    ESTIMATORS,
    GOAL_RMSE,
    GOAL_TRANSFER,
    SeedReport,
    as_dict,
    seed_experiments,
    seed_table,
    transfer_study,
    transfer_table,
)
from cablekit.forceps.twin import load_twin


def plot_experiment(report: SeedReport, name: str, path: Path) -> Path | None:
    """The seed's panels for one experiment: (a) measured and estimated external and clamping
    forces, (b) errors, (c) joint torque disturbances, (d) measured and free-motion tensions,
    (e) motor displacements and velocities."""
    from cablekit.plotting import pyplot_or_none

    plt = pyplot_or_none()
    if plt is None:
        return None
    inst = report.instrument
    run = inst.runs[name]
    ests = inst.estimates(run)
    t = run.time
    meas = np.column_stack([run.external, 0.5 * np.abs(run.external).sum(axis=1)])
    fig, ax = plt.subplots(5, 1, figsize=(10, 13), sharex=True)
    colours = ("C0", "C1", "C2")
    labels = ("F_ext^A", "F_ext^B", "F_CF")
    for j, (lab, c) in enumerate(zip(labels, colours, strict=True)):
        ax[0].plot(t, meas[:, j], color=c, lw=2, alpha=0.5, label=f"{lab} measured")
    styles = ("--", "-")
    shown = (ESTIMATORS[1], ESTIMATORS[3])
    for style, est_name in zip(styles, shown, strict=True):
        e = ests[est_name]
        val = np.column_stack([e.external, e.clamping])
        for j, c in enumerate(colours):
            ax[0].plot(t, val[:, j], style, color=c, lw=0.8)
            ax[1].plot(t, val[:, j] - meas[:, j], style, color=c, lw=0.8,
                       label=f"{labels[j]}, {est_name}")  # fmt: skip
        ax[2].plot(t, e.torque[:, 0] * 1e3, style, color="C0", lw=0.8, label=f"τ_aD, {est_name}")
        ax[2].plot(t, e.torque[:, 1] * 1e3, style, color="C1", lw=0.8, label=f"τ_bD, {est_name}")
    ax[0].set_ylabel("force (N)")
    ax[0].legend(fontsize=7, ncol=3)
    ax[0].set_title(f"{name}: dashed {shown[0]}, solid {shown[1]}", fontsize=9)
    ax[1].axhline(0.0, color="k", lw=0.5)
    ax[1].set_ylabel("error (N)")
    ax[1].legend(fontsize=6, ncol=2)
    ax[2].set_ylabel("torque disturbance (mN·m)")
    ax[2].legend(fontsize=7)
    free = inst.network.predict(run.motors)
    for j, lab in enumerate(("F_A^1", "F_A^2", "F_B^1", "F_B^2")):
        ax[3].plot(t, run.measured[:, j], color=f"C{j}", lw=0.8, label=f"{lab} measured")
        ax[3].plot(t, free[:, j], "--", color=f"C{j}", lw=0.8, label=f"{lab} PSO-BPNN free motion")
    ax[3].set_ylabel("tension (N)")
    ax[3].legend(fontsize=7, ncol=4)
    ax[4].plot(t, run.motors[:, 0] * 1e3, label="x_a (mm)")
    ax[4].plot(t, run.motors[:, 2] * 1e3, label="x_b (mm)")
    ax[4].plot(t, run.motors[:, 1] * 1e3, "--", label="v_a (mm/s)")
    ax[4].plot(t, run.motors[:, 3] * 1e3, "--", label="v_b (mm/s)")
    ax[4].set_ylabel("motor")
    ax[4].set_xlabel("time (s)")
    ax[4].legend(fontsize=7, ncol=4)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _experiments(args: argparse.Namespace) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    twin = load_twin(args.twin)
    report = seed_experiments(twin, progress=not args.quiet)
    rows = transfer_study(report, progress=not args.quiet)
    figures = []
    if not args.no_plots:
        for k, name in enumerate(report.table):
            p = plot_experiment(report, name, out / f"fig{7 + k}_{name.split(' ')[0]}_{k}.png")
            if p is not None:
                figures.append(p)
    held = {e: report.held_out_rmse(e) for e in ESTIMATORS}
    worst = {e: max(r.ratio[e] for r in rows) for e in ESTIMATORS}

    def met(ok: bool) -> str:
        return "met" if ok else "not met"

    goals = [
        f"- clamp RMSE on the held-out runs ≤ {GOAL_RMSE} N: "
        + "; ".join(f"{e} {held[e]:.3f} N ({met(held[e] <= GOAL_RMSE)})" for e in ESTIMATORS),
        f"- transfer within {GOAL_TRANSFER}× (worst of {len(rows)} instruments): "
        + "; ".join(f"{e} {worst[e]:.2f}× ({met(worst[e] <= GOAL_TRANSFER)})" for e in ESTIMATORS),
    ]
    text = "\n\n".join(
        [
            "# Seed 000's clamping experiments in the forceps twin",
            f"Twin: `{args.twin or 'seed000.toml (shipped)'}`. "
            f"Free-motion data: {report.free_samples} samples; "
            f"the PSO-BPNN 4-10-4 fits them to {report.network_rmse:.3f} N RMS per tension.",
            "## Seed vs cablekit\n\n" + seed_table(report),
            "## Transfer to other instruments (held-out F_CF RMSE, ratio to the first instrument)\n\n"
            + transfer_table(report, rows),
            "## Goals (issue #22)\n\n" + "\n".join(goals),
            "\n".join(f"![{p.stem}]({p.name})" for p in figures),
        ]
    )
    (out / "report.md").write_text(text + "\n", encoding="utf-8")
    (out / "results.json").write_text(json.dumps(as_dict(report, rows), indent=2), encoding="utf-8")
    if not args.quiet:
        print(text)
    print(f"wrote {out / 'report.md'}")
    return 0


def add_parser(sub: Any) -> None:
    """``cablekit forceps experiments``."""
    p = sub.add_parser("forceps", help="cable-driven forceps: clamping-force estimation (seed 000)")
    fs = p.add_subparsers(dest="forceps_command", required=True)
    e = fs.add_parser(
        "experiments",
        help="seed 000's experiments in the twin: seed vs cablekit table, transfer table, Figs 7-9",
        description="Free motion at the seed's five speeds, the PSO-BPNN free-motion model, the JTDO; "
        "continuous and stair clamping; the physics-informed estimator beside it; four other instruments "
        "(±30 %% cable stiffness, pretension, friction). Needs the train extra (torch).",
    )
    e.add_argument("--twin", help="twin TOML file (default: the shipped seed 000 bench)")
    e.add_argument("--out", default="out/forceps", help="output folder")
    e.add_argument("--no-plots", action="store_true", help="no PNGs (no matplotlib needed)")
    e.add_argument("--quiet", action="store_true", help="no progress bars, no table on stdout")
    e.set_defaults(func=_experiments)
