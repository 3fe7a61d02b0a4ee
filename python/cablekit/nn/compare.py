"""The trainers side by side on the same data and seeds (issue #5's comparison table).

For each method and seed: train with :func:`train_mlp` (same split per seed for every
method), record the held-out MSE (the random 10 % test part; for data sets with held-out
trajectories, also the MSE on those) and the training time. The table reports medians over
seeds with the interquartile range, so one lucky or unlucky seed does not decide it.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from cablekit import _log
from cablekit.nn.datasets import Dataset
from cablekit.nn.spec import METHODS, TrainConfig
from cablekit.nn.train import train_mlp


@dataclass
class MethodRow:
    method: str
    test_mse: list[float] = field(default_factory=list)
    heldout_mse: list[float] = field(default_factory=list)
    time_s: list[float] = field(default_factory=list)
    epochs: list[int] = field(default_factory=list)

    def stats(self, values: Sequence[float]) -> tuple[float, float, float]:
        a = np.asarray(values, dtype=float)
        if a.size == 0 or not np.any(np.isfinite(a)):
            return (float("nan"),) * 3  # type: ignore[return-value]
        q1, med, q3 = np.nanpercentile(a, [25, 50, 75])
        return float(med), float(q1), float(q3)


@dataclass
class Comparison:
    dataset: str
    sizes: list[int]
    seeds: list[int]
    rows: list[MethodRow]
    n_train: int
    n_test: int
    n_heldout: int
    #: what a user would use without a network, and its held-out (or test) MSE
    baseline: str = ""
    baseline_mse: float | None = None
    output_units: str = "N"

    def squared_units(self) -> str:
        """``N²``, ``(mN·m)²``: the unit of the MSE columns."""
        u = self.output_units
        return f"{u}²" if u.isalpha() else f"({u})²"

    def best(self, metric: str = "auto") -> str:
        key = "heldout_mse" if (metric == "auto" and self.n_heldout) or metric == "heldout" else "test_mse"
        return min(self.rows, key=lambda r: r.stats(getattr(r, key))[0]).method

    def markdown(self) -> str:
        lines = [
            f"**{self.dataset}** — network {'-'.join(map(str, self.sizes))}, seeds {self.seeds}, "
            f"{self.n_train} training / {self.n_test} test samples"
            + (f", {self.n_heldout} held out (paths or runs the fit never saw)" if self.n_heldout else ""),
            "",
            "| method | test MSE, median [IQR] | "
            + ("held-out MSE, median [IQR] | " if self.n_heldout else "")
            + "time s, median | epochs, median |",
            "|---|---|" + ("---|" if self.n_heldout else "") + "---|---|",
        ]
        for r in self.rows:
            t, t1, t3 = r.stats(r.test_mse)
            cells = [r.method, f"{t:.4g} [{t1:.4g}, {t3:.4g}]"]
            if self.n_heldout:
                h, h1, h3 = r.stats(r.heldout_mse)
                cells.append(f"{h:.4g} [{h1:.4g}, {h3:.4g}]")
            cells += [f"{r.stats(r.time_s)[0]:.2f}", f"{int(np.median(r.epochs))}"]
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
        lines.append(f"MSE in {self.squared_units()}.")
        if self.baseline_mse is not None:
            lines.append(f"Without a network — {self.baseline}: MSE {self.baseline_mse:.4g}.")
        return "\n".join(lines)

    def to_json(self, path: str | Path) -> Path:
        path = Path(path)
        path.write_text(json.dumps(asdict(self), indent=1))
        return path


def compare_trainers(
    data: Dataset,
    methods: Sequence[str] = METHODS,
    seeds: Sequence[int] = (0, 1, 2, 3, 4),
    config: TrainConfig | None = None,
    progress: bool = True,
) -> Comparison:
    """Train every method on ``data`` for every seed; see the module docs."""
    cfg = config or TrainConfig()
    rows = []
    n_train = n_test = 0
    for method in methods:
        row = MethodRow(method)
        for seed in seeds:
            r = train_mlp(data.x, data.y, cfg, method=method, seed=seed, progress=progress)
            row.test_mse.append(r.test_mse)
            row.time_s.append(r.train_time_s)
            row.epochs.append(len(r.history))
            if data.x_test is not None and data.y_test is not None:
                row.heldout_mse.append(float(np.mean((r.predict(data.x_test) - data.y_test) ** 2)))
            n_train, n_test = int(r.split["train"].size + r.split["val"].size), int(r.split["test"].size)
            if progress:
                _log.info(f"  {method:8s} seed {seed}: test MSE {r.test_mse:.4g}, {r.train_time_s:.2f} s")
        rows.append(row)
    sizes = [data.x.shape[1], *cfg.hidden, data.y.shape[1]]
    n_held = 0 if data.x_test is None else int(data.x_test.shape[0])
    base = None
    if data.baseline_test is not None and data.y_test is not None:
        base = float(np.mean((data.baseline_test - data.y_test) ** 2))
    units = sorted(set(data.output_units))
    return Comparison(
        data.name, sizes, list(seeds), rows, n_train, n_test, n_held, data.baseline, base, ", ".join(units)
    )
