"""Joint state–parameter estimation of Raven-II's transmission (issue #4, task 2; seed 001 §3.3
and ch. 4): elbow cable stiffness and damping, the three coupling coefficients and the shoulder
pulley radius, as random-walk states of the sr-UKF, on a twin with known truth.

Usage: python examples/parameters.py [--seconds 40] [--out out/parameters]
"""

from __future__ import annotations

import time

import numpy as np

from cablekit.estimate import estimate_parameters
from cablekit.scripts import finish_table, script_options
from cablekit.twins import raven_parameter_experiment


def main() -> None:
    args, out = script_options(__doc__, "out/parameters", seconds=40.0, seed=0)
    t0 = time.perf_counter()
    run = raven_parameter_experiment(args.seconds, args.seed)
    est = estimate_parameters(
        run.nominal, list(run.truth), run.q_m, run.tau_m, run.dt, q_l=run.q_l, encoder_noise=2e-5
    )
    print(f"{len(run.q_m)} samples in {time.perf_counter() - t0:.1f} s (twin + filter)")
    true = np.array(list(run.truth.values()))
    lines = [
        "| parameter | nominal (start) | truth | estimate | error at 10 s | error at the end | ±1σ |",
        "|---|---|---|---|---|---|---|",
    ]
    k10 = min(len(run.q_m) - 1, round(10.0 / run.dt))
    for j, name in enumerate(est.names):
        e10 = 100 * (est.values[k10, j] - true[j]) / true[j]
        e = 100 * (est.values[-1, j] - true[j]) / true[j]
        lines.append(
            f"| `{name}` | {est.initial[j]:.6g} | {true[j]:.6g} | {est.values[-1, j]:.6g} | {e10:+.2f} % | "
            f"{e:+.2f} % | {100 * est.std[-1, j] / abs(true[j]):.2f} % |"
        )
    text = "\n".join(lines)
    plt = finish_table(out, text)
    if plt is None:
        return
    t = np.arange(len(run.q_m)) * run.dt
    fig, axes = plt.subplots(2, 3, figsize=(13, 6), sharex=True)
    for j, ax in enumerate(axes.flat):
        rel = est.values[:, j] / true[j]
        band = est.std[:, j] / abs(true[j])
        ax.fill_between(t, rel - band, rel + band, color="C0", alpha=0.2, lw=0)
        ax.plot(t, rel, color="C0", lw=1)
        ax.axhline(1.0, color="k", lw=0.8, ls="--")
        ax.set_title(est.names[j], fontsize=9)
        ax.set_ylim(min(0.7, rel.min()), max(1.3, rel.max()))
        ax.set_ylabel("estimate / truth")
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    fig.suptitle("sr-UKF joint state-parameter estimation (±1σ), Raven-II twin")
    fig.tight_layout()
    fig.savefig(out / "parameters.png", dpi=110)
    print(f"wrote {out / 'table.md'} and {out / 'parameters.png'}")


if __name__ == "__main__":
    main()
