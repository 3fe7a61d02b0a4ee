"""``cablekit nn``: the trainer comparison on the two twins, and training one network."""

from __future__ import annotations

import argparse
import textwrap
import time
from pathlib import Path

import numpy as np

from cablekit.cli._options import outputs
from cablekit.nn.datasets import Dataset, cdpr_pulley_friction, davinci_jaw_torque, forceps_free_motion

#: where CI keeps the real bench data (never copied into the project)
DAVINCI_DIR = "../shared/data/davinci-maryland-bench"

DATASETS = {
    "forceps": lambda args: forceps_free_motion(),
    # every 3rd sample of the 100 Hz training paths: ~3,500 samples (LM's Jacobian stays small)
    "cdpr": lambda args: _every(cdpr_pulley_friction(), 3),
    # real data: 12 training runs at 25 Hz (5,700 samples), 8 held-out runs (3,800)
    "davinci": lambda args: davinci_jaw_torque(args.davinci_dir),
}


def _every(d: Dataset, k: int) -> Dataset:
    from dataclasses import replace

    return replace(d, x=np.ascontiguousarray(d.x[::k]), y=np.ascontiguousarray(d.y[::k]))


def _plot(comparisons: list, path: Path) -> Path | None:  # type: ignore[type-arg]
    from cablekit.plotting import pyplot_or_none

    plt = pyplot_or_none()
    if plt is None:
        return None
    fig, axes = plt.subplots(1, len(comparisons), figsize=(6 * len(comparisons), 4))
    for ax, c in zip(np.atleast_1d(axes), comparisons, strict=True):
        key = "heldout_mse" if c.n_heldout else "test_mse"
        ax.boxplot([getattr(r, key) for r in c.rows], tick_labels=[r.method for r in c.rows])
        ax.set_yscale("log")
        ax.set_title(textwrap.fill(c.dataset, 60), fontsize=9)
        ax.set_ylabel(("held-out" if c.n_heldout else "test") + f" MSE, {c.squared_units()}")
        if c.baseline_mse is not None:
            ax.axhline(c.baseline_mse, color="0.4", ls="--", lw=1, label="without a network")
            ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def _plot_heldout(data: Dataset, predict: object, method: str, path: Path, n: int = 950) -> Path | None:
    """The first output over the first ``n`` held-out samples: measured, network, baseline."""
    if data.x_test is None or data.y_test is None:
        return None
    from cablekit.plotting import pyplot_or_none

    plt = pyplot_or_none()
    if plt is None:
        return None
    k = np.arange(min(n, data.x_test.shape[0]))
    fig, ax = plt.subplots(figsize=(9, 3.5))
    ax.plot(k, data.y_test[k, 0], "k", lw=1.2, label="measured")
    ax.plot(k, predict(data.x_test[k])[:, 0], "C1", lw=1, label=f"network ({method})")  # type: ignore[operator]
    if data.baseline_test is not None:
        ax.plot(k, data.baseline_test[k, 0], "C0--", lw=1, label="without a network")
    ax.set_xlabel("held-out sample")
    ax.set_ylabel(f"{data.output_names[0]} [{data.output_units[0]}]")
    ax.set_title(textwrap.fill(data.name, 90), fontsize=9)
    ax.legend(fontsize=8)
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
    sets = {}
    for name in args.data:
        data = sets[name] = DATASETS[name](args)
        print(
            f"cablekit nn: {data.name}: {data.x.shape[0]} samples, "
            f"methods {', '.join(METHODS)}, seeds {seeds}"
        )
        cfg = TrainConfig(hidden=(10,), progress=not args.quiet)
        results.append(compare_trainers(data, METHODS, seeds, cfg, progress=not args.quiet))
    md = "\n\n".join(c.markdown() + f"\n\nlowest median MSE: **{c.best()}**" for c in results)
    (out / "comparison.md").write_text(md + "\n")
    for name, c in zip(args.data, results, strict=True):
        c.to_json(out / f"comparison_{name}.json")
    png = _plot(results, out / "comparison.png")
    print(md)
    # the deployable artefacts: per data set, the best method's seed-0 network, checked through
    # the Rust loader (and through onnxruntime when the onnx extra is installed)
    worst = 0.0
    for name, c in zip(args.data, results, strict=True):
        data, method = sets[name], c.best()
        res = train_mlp(data.x, data.y, TrainConfig(hidden=(10,)), method=method, seed=0, progress=False)
        path = export(
            res,
            out / f"{name}_{method}.safetensors",
            input_names=data.input_names,
            input_units=data.input_units,
            output_names=data.output_names,
            output_units=data.output_units,
        )
        mlp = Mlp.load(path)
        diff = float(np.max(np.abs(mlp.predict(data.x) - res.predict(data.x))))
        worst = max(worst, diff)
        fig = _plot_heldout(data, mlp.predict, method, out / f"heldout_{name}.png")
        if fig:
            print(f"wrote {fig}")
        print(f"\nwrote {path}: Rust vs NumPy forward on {data.x.shape[0]} samples, max |diff| {diff:.2e}")
        onnx_diff = _onnx_check(path, data.x)
        if onnx_diff is not None:
            worst = max(worst, onnx_diff)
            print(f"wrote {path.with_suffix('.onnx')}: onnxruntime vs Rust, max |diff| {onnx_diff:.2e}")
    print(
        f"wrote {out / 'comparison.md'}"
        + (f", {png}" if png else "")
        + f" in {time.perf_counter() - t0:.0f} s"
    )
    return 0 if worst <= 1e-10 else 1


def _onnx_check(path: Path, x: np.ndarray) -> float | None:
    """Export ``path`` next to it as ONNX and compare onnxruntime with Rust; None without onnx."""
    try:
        import onnxruntime as ort  # type: ignore[import-untyped]

        from cablekit._cablekit import Mlp
        from cablekit.nn.onnx_export import export_onnx

        onnx_path = export_onnx(path, path.with_suffix(".onnx"))
    except ImportError:
        return None
    sess = ort.InferenceSession(str(onnx_path), providers=["CPUExecutionProvider"])
    (y,) = sess.run(None, {"x": x})
    return float(np.max(np.abs(y - Mlp.load(path).predict(x))))


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    n = sub.add_parser("nn", help="neural networks: compare the trainers on the forceps and CDPR twins")
    nsub = n.add_subparsers(dest="nn_command", required=True)
    c = nsub.add_parser("compare", help="PSO-BPNN vs Adam vs L-BFGS vs LM vs LM+BR, median over seeds")
    c.add_argument(
        "--data",
        nargs="+",
        choices=sorted(DATASETS),
        default=["forceps", "cdpr"],
        help="data sets; 'davinci' is the real bench (needs --davinci-dir)",
    )
    c.add_argument("--davinci-dir", default=DAVINCI_DIR, help="folder of the da Vinci bench data")
    c.add_argument("--seeds", type=int, default=5, help="number of seeds (>= 5 for the table)")
    outputs(c, "out/nn", plots=False)
    c.set_defaults(func=compare)
