"""``cablekit nn``: the trainer comparison on the two twins, and training one network."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from cablekit.nn.datasets import Dataset, cdpr_pulley_friction, forceps_free_motion

DATASETS = {
    "forceps": lambda: forceps_free_motion(),
    # every 3rd sample of the 100 Hz training paths: ~3,500 samples (LM's Jacobian stays small)
    "cdpr": lambda: _every(cdpr_pulley_friction(), 3),
}


def _every(d: Dataset, k: int) -> Dataset:
    from dataclasses import replace

    return replace(d, x=d.x[::k], y=d.y[::k])


def _plot(comparisons: list, path: Path) -> Path | None:  # type: ignore[type-arg]
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    fig, axes = plt.subplots(1, len(comparisons), figsize=(6 * len(comparisons), 4))
    for ax, c in zip(np.atleast_1d(axes), comparisons, strict=True):
        key = "heldout_mse" if c.n_heldout else "test_mse"
        ax.boxplot([getattr(r, key) for r in c.rows], tick_labels=[r.method for r in c.rows])
        ax.set_yscale("log")
        ax.set_title(c.dataset, fontsize=9)
        ax.set_ylabel(("held-out paths" if c.n_heldout else "test") + " MSE, N²")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def compare(args: argparse.Namespace) -> int:
    from cablekit._cablekit import Mlp
    from cablekit.nn.compare import compare_trainers
    from cablekit.nn.export import export
    from cablekit.nn.spec import METHODS, TrainConfig
    from cablekit.nn.train import train_mlp

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    seeds = list(range(args.seeds))
    t0 = time.perf_counter()
    results = []
    for name in args.data:
        data = DATASETS[name]()
        print(
            f"cablekit nn: {data.name}: {data.x.shape[0]} samples, "
            f"methods {', '.join(METHODS)}, seeds {seeds}"
        )
        cfg = TrainConfig(hidden=(10,), progress=not args.quiet)
        results.append(compare_trainers(data, METHODS, seeds, cfg, progress=not args.quiet))
    md = "\n\n".join(c.markdown() + f"\n\nlowest median MSE: **{c.best()}**" for c in results)
    (out / "comparison.md").write_text(md + "\n")
    for c in results:
        c.to_json(out / f"comparison_{c.dataset.split()[0].lower()}.json")
    png = _plot(results, out / "comparison.png")
    print(md)
    # the deployable artefact: the forceps network (PSO-BPNN) through the Rust loader
    data = DATASETS["forceps"]()
    res = train_mlp(data.x, data.y, method="pso-lm", seed=0, progress=False)
    path = export(
        res,
        out / "forceps_pso_lm.safetensors",
        input_names=data.input_names,
        input_units=data.input_units,
        output_names=data.output_names,
        output_units=data.output_units,
    )
    diff = float(np.max(np.abs(Mlp.load(path).predict(data.x) - res.predict(data.x))))
    print(f"\nwrote {path}: Rust vs NumPy forward on {data.x.shape[0]} samples, max |diff| {diff:.2e} N")
    print(
        f"wrote {out / 'comparison.md'}"
        + (f", {png}" if png else "")
        + f" in {time.perf_counter() - t0:.0f} s"
    )
    return 0 if diff <= 1e-10 else 1


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    n = sub.add_parser("nn", help="neural networks: compare the trainers on the forceps and CDPR twins")
    nsub = n.add_subparsers(dest="nn_command", required=True)
    c = nsub.add_parser("compare", help="PSO-BPNN vs Adam vs L-BFGS vs LM vs LM+BR, median over seeds")
    c.add_argument("--data", nargs="+", choices=sorted(DATASETS), default=["forceps", "cdpr"])
    c.add_argument("--seeds", type=int, default=5, help="number of seeds (>= 5 for the table)")
    c.add_argument("--out", default="out/nn")
    c.add_argument("--quiet", action="store_true")
    c.set_defaults(func=compare)
