"""External force on Raven-II's insertion axis (issue #4, task 5; seed 001 §5.3): the UKF method
(the force as a random-walk state) against the cable-stretch method (F = K_s·S + b·Ṡ with the
two-Gaussian, four-quadrant classification, the UKF where the quadrant is unknown), on a twin
lifting a basket of 271/497/704/910 g and in free motion.

Also the pulling- and pushing-spring experiments (quadrants I/IV and II/III).

Usage: python examples/external_force.py [--out out/external_force]
"""

from __future__ import annotations

import time

import numpy as np

from cablekit.estimate import CableStretchForce, estimate_external_force, stretch_and_rate
from cablekit.scripts import finish_table, script_options
from cablekit.twins import BASKET, ENCODER_LSB, LINEAR_ENCODER_LSB, raven_force_experiment

SIGMA = float(np.hypot(2e-5, ENCODER_LSB / np.sqrt(12)))
SETTLE = 0.2  # s after a load change not scored in the per-weight means


def both_methods(run):
    q_l = np.full_like(run.q_m, np.nan)
    q_l[:, 2] = run.q_l3
    ukf = estimate_external_force(
        run.nominal,
        run.q_m,
        run.tau_m,
        run.dt,
        links=[2],
        q_l=q_l,
        encoder_noise=SIGMA,
        joint_noise=LINEAR_ENCODER_LSB / np.sqrt(12),
    ).force[:, 0]
    p = run.nominal.params()
    s, rate = stretch_and_rate(run.nominal, run.q_m, run.q_l3, 2, run.dt)
    k = 10  # joint velocity from the linear encoder, central difference over ±10 ms
    v = np.zeros_like(run.q_l3)
    v[k:-k] = (run.q_l3[2 * k :] - run.q_l3[: -2 * k]) / (2 * k * run.dt)
    method = CableStretchForce(2 * p["cable_stiffness"][2], 2 * p["cable_damping"][2]).fit(
        s[run.training], v[run.training]
    )
    return {
        "UKF": ukf,
        "stretch (quadrants)": method.force(s, rate, ukf),
        "stretch (direction)": method.force(s, rate, ukf, velocity=v),
    }, method


def per_weight(run, force):
    steps = np.flatnonzero(np.diff(run.mass) != 0) + 1
    settled = np.ones(len(run.mass), bool)
    for k in steps:
        settled[k : k + round(SETTLE / run.dt)] = False
    return {m: float(np.mean(force[(run.mass == m) & settled])) for m in BASKET}


def main() -> None:
    _, out = script_options(__doc__, "out/external_force")
    t0 = time.perf_counter()
    runs = {
        "zero force": raven_force_experiment("zero"),
        "basket": raven_force_experiment("basket"),
        "pulling spring": raven_force_experiment("pull"),
        "pushing spring": raven_force_experiment("push"),
    }
    results = {}
    lines = ["| run | method | error min … max | 1–99 % of the errors | MAE |", "|---|---|---|---|---|"]
    for name, run in runs.items():
        forces, method = both_methods(run)
        # scored: after the first second; on the springs, once attached (after the training)
        start = 1.0 if name in ("zero force", "basket") else 6.2
        s = slice(round(start / run.dt), None)
        results[name] = (run, forces, method)
        for label, f in forces.items():
            e = (f - run.force)[s]
            lines.append(
                f"| {name} | {label} | {e.min():+.2f} … {e.max():+.2f} N | "
                f"{np.quantile(e, 0.01):+.2f} … {np.quantile(e, 0.99):+.2f} N | {np.mean(np.abs(e)):.3f} N |"
            )
    run, forces, method = results["basket"]
    lines += [
        "",
        "| load | true force | " + " | ".join(f"{k} mean" for k in forces) + " |",
        "|---|---|---|---|---|",
    ]
    means = {k: per_weight(run, f) for k, f in forces.items()}
    for m in BASKET:
        cells = " | ".join(f"{means[k][m]:.3f} N" for k in forces)
        lines.append(f"| {1000 * m:.0f} g | {-m * 9.80665:.3f} N | {cells} |")
    lines.append("")
    lines.append(
        f"two-Gaussian fit of the unloaded stretch: lower {method.lower * 1e6:.1f} µm, "
        f"upper {method.upper * 1e6:.1f} µm, σ {method.sigma * 1e6:.1f} µm"
    )
    text = "\n".join(lines)
    plt = finish_table(out, text, t0)
    if plt is None:
        return
    fig, axes = plt.subplots(3, 2, figsize=(13, 10), gridspec_kw={"width_ratios": [3, 1]})
    colors = {"UKF": "C0", "stretch (quadrants)": "C1", "stretch (direction)": "C2"}
    for row, name in enumerate(("basket", "zero force", "pushing spring")):
        run, forces, _ = results[name]
        t = np.arange(len(run.force)) * run.dt
        ax = axes[row, 0]
        s = slice(round(1.0 / run.dt), None)
        bx = axes[row, 1]
        bins = np.linspace(-1.5, 1.5, 61)
        for label, f in forces.items():
            ax.plot(t, f, lw=0.5, color=colors[label], label=label)
            bx.hist((f - run.force)[s], bins, alpha=0.5, color=colors[label], label=label)
        ax.plot(t, run.force, lw=1.2, color="k", label="truth")
        ax.set_ylabel(f"{name}: force (N)")
        bx.set_xlabel("error (N)")
    axes[0, 0].legend(loc="lower left", fontsize=8)
    axes[0, 1].legend(fontsize=8)
    axes[-1, 0].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(out / "external_force.png", dpi=110)
    print(f"wrote {out / 'table.md'} and {out / 'external_force.png'}")


if __name__ == "__main__":
    main()
