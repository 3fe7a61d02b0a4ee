"""Pretension of Raven-II's insertion cable from the sr-UKF's stiffness estimate (issue #4, task 4;
seed 001 §5.2): 18 runs with the tension set by hand between 4 and 20 N; the taut-string
frequency of a free span, calibrated against a tension gauge on a few runs, gives every run's
reference tension; a degree-two map from the estimated stiffness to tension is fitted on 12 runs
and judged on the other 6: tension error and the Low (< 8 N) / Mid / High (> 14 N) category.

Usage: python examples/pretension.py [--seconds 10] [--out out/pretension]
"""

from __future__ import annotations

import time

import numpy as np

from cablekit.estimate import PretensionMap, StringCalibration, estimate_stiffness
from cablekit.scripts import finish_table, script_options
from cablekit.twins import ENCODER_LSB, LINEAR_ENCODER_LSB, raven_pretension_run

SIGMA = float(np.hypot(2e-5, ENCODER_LSB / np.sqrt(12)))


def study(tensions, seconds: float, seed: int = 0, gauge: int = 5, held_out_every: int = 3):
    """Stiffness per run, string calibration on ``gauge`` runs, map fitted on the runs not held
    out (every ``held_out_every``-th is held out). Returns a dict of arrays."""
    k_hat, k_std, freq = [], [], []
    for tension in tensions:
        run = raven_pretension_run(float(tension), seconds, seed)
        q_l = np.full_like(run.q_m, np.nan)
        q_l[:, 2] = run.q_l3
        k, s = estimate_stiffness(
            run.nominal,
            2,
            run.q_m,
            run.tau_m,
            run.dt,
            q_l=q_l,
            encoder_noise=SIGMA,
            joint_noise=LINEAR_ENCODER_LSB / np.sqrt(12),
        )
        k_hat.append(k)
        k_std.append(s)
        freq.append(run.frequency)
    tensions = np.asarray(tensions, dtype=np.float64)
    k_hat, k_std, freq = map(np.array, (k_hat, k_std, freq))
    # a gauge on a few spans (1 % error) calibrates the string; the string gives every reference
    rng = np.random.default_rng(seed)
    gauge_idx = np.linspace(0, len(tensions) - 1, gauge).round().astype(int)
    calib = StringCalibration().fit(
        freq[gauge_idx], tensions[gauge_idx] * (1 + 0.01 * rng.normal(size=gauge))
    )
    t_ref = calib.tension(freq)
    held = np.zeros(len(tensions), bool)
    held[held_out_every - 1 :: held_out_every] = True
    tmap = PretensionMap().fit(k_hat[~held], t_ref[~held])
    t_hat = tmap.tension(k_hat)
    return {
        "tension": tensions,
        "k_hat": k_hat,
        "k_std": k_std,
        "frequency": freq,
        "t_string": t_ref,
        "t_hat": t_hat,
        "held": held,
        "map": tmap,
        "calibration": calib,
    }


def main() -> None:
    args, out = script_options(__doc__, "out/pretension", seconds=10.0)
    t0 = time.perf_counter()
    tensions = np.geomspace(4.0, 20.0, 18)
    r = study(tensions, args.seconds)
    cat = PretensionMap.category
    lines = [
        f"string calibration: T = {r['calibration'].a:.3e}·f² (true 4L²μ = {4 * 0.25**2 * 1.2e-3:.3e}); "
        f"string-reference error RMS {np.sqrt(np.mean((r['t_string'] - r['tension']) ** 2)):.2f} N",
        "",
        "| run | true T (N) | string T (N) | k̂ (N/m) | ±σ | T from k̂ (N) | true category | estimated | set |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for i, t in enumerate(r["tension"]):
        lines.append(
            f"| {i + 1} | {t:.2f} | {r['t_string'][i]:.2f} | {r['k_hat'][i]:.0f} | {r['k_std'][i]:.0f} | "
            f"{r['t_hat'][i]:.2f} | {cat(t)} | {cat(r['t_hat'][i])} | "
            f"{'held out' if r['held'][i] else 'fit'} |"
        )
    h = r["held"]
    err = r["t_hat"][h] - r["tension"][h]
    right = cat(r["t_hat"][h]) == cat(r["tension"][h])
    acc = float(np.mean(right))
    lines += [
        "",
        f"held-out runs: tension error RMS {np.sqrt(np.mean(err**2)):.2f} N (max {np.abs(err).max():.2f} N), "
        f"category correct {100 * acc:.0f} % ({int(right.sum())}/{h.sum()})",
    ]
    text = "\n".join(lines)
    plt = finish_table(out, text, t0)
    if plt is None:
        return
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    ax = axes[0]
    ax.errorbar(
        r["k_hat"][~h] / 1e3,
        r["t_string"][~h],
        xerr=r["k_std"][~h] / 1e3,
        fmt="o",
        color="C0",
        label="fit runs",
    )
    ax.errorbar(
        r["k_hat"][h] / 1e3,
        r["tension"][h],
        xerr=r["k_std"][h] / 1e3,
        fmt="s",
        color="C3",
        label="held out (truth)",
    )
    kk = np.linspace(r["k_hat"].min(), r["k_hat"].max(), 100)
    ax.plot(kk / 1e3, r["map"].tension(kk), color="k", lw=1, label="degree-2 map")
    for b in (8.0, 14.0):
        ax.axhline(b, color="0.6", ls="--", lw=0.8)
    ax.set_xlabel("estimated stiffness k̂ (kN/m)")
    ax.set_ylabel("tension (N)")
    ax.legend(fontsize=8)
    bx = axes[1]
    bx.plot(r["frequency"], r["tension"], "o", label="true")
    ff = np.linspace(r["frequency"].min(), r["frequency"].max(), 100)
    bx.plot(ff, r["calibration"].tension(ff), color="k", lw=1, label="T = a·f²")
    bx.set_xlabel("free-span frequency (Hz)")
    bx.set_ylabel("tension (N)")
    bx.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "pretension.png", dpi=110)
    print(f"wrote {out / 'table.md'} and {out / 'pretension.png'}")


if __name__ == "__main__":
    main()
