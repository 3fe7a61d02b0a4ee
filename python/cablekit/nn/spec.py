"""Training configuration and result types (no torch here)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cablekit.errors import ParameterError
from cablekit.nn.mapminmax import MapMinMax

F64 = NDArray[np.float64]

#: Trainers: PSO then LM (the seed's PSO-BPNN as MATLAB runs it), PSO then Adam, plain LM
#: (MATLAB ``trainlm``), LM with Bayesian regularisation (``trainbr``), Adam, L-BFGS.
METHODS = ("pso-lm", "pso-adam", "lm", "br", "adam", "lbfgs")
ACTIVATIONS = {"tansig": "tansig", "tanh": "tansig", "logsig": "logsig", "logistic": "logsig"}


@dataclass(frozen=True)
class PsoConfig:
    """Particle swarm of seed 000, Table 1, with the velocity/position clamping of the PSO-BP
    literature (the seed omits it; with ``w = 1`` an unclamped swarm diverges).

    ``u_range="unit"`` draws ``u₁, u₂ ∼ U[0, 1]`` (Kennedy–Eberhart); ``"symmetric"`` draws
    ``U[−1, 1]`` as the seed's text says, which makes the attraction terms zero-mean.
    """

    swarm: int = 10
    iterations: int = 30
    c1: float = 1.49445
    c2: float = 1.49445
    w: float = 1.0
    x_max: float = 5.0
    v_max: float = 1.0
    u_range: str = "unit"

    def check(self) -> None:
        for name in ("swarm", "iterations"):
            if int(getattr(self, name)) < 1:
                raise ParameterError(f"pso.{name} must be >= 1, got {getattr(self, name)}")
        for name in ("c1", "c2", "w"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise ParameterError(f"pso.{name} must be finite and >= 0, got {v}")
        for name in ("x_max", "v_max"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise ParameterError(f"pso.{name} must be finite and > 0, got {v}")
        if self.u_range not in ("unit", "symmetric"):
            raise ParameterError(f"pso.u_range must be 'unit' or 'symmetric', got {self.u_range!r}")


@dataclass(frozen=True)
class TrainConfig:
    """What to train and how. Defaults follow seed 000, Table 1 (4-10-4, tansig, 90/10 split,
    100 training epochs) and MATLAB's LM (``mu`` 1e-3, ×0.1 on success, ×10 on failure,
    stop after 6 validation failures)."""

    hidden: tuple[int, ...] = (10,)
    activation: str = "tansig"
    #: plain LM by default: on both twins PSO-BPNN is no better (docs/networks.md)
    method: str = "lm"
    epochs: int = 100
    seed: int = 0
    test_fraction: float = 0.10
    #: share of the training part held out for early stopping (not used by ``br``, which, like
    #: MATLAB's ``trainbr``, regularises instead of stopping early)
    val_fraction: float = 0.15
    max_fail: int = 6
    lr: float = 0.005
    batch_size: int = 128
    mu: float = 1e-3
    mu_dec: float = 0.1
    mu_inc: float = 10.0
    mu_max: float = 1e10
    min_grad: float = 1e-7
    pso: PsoConfig = field(default_factory=PsoConfig)
    progress: bool = True
    #: torch threads; None: CABLEKIT_THREADS, else chosen from the problem's size and the free
    #: cores (one thread for Table-1 sizes; see cablekit._threads)
    threads: int | None = None

    def check(self) -> None:
        if self.method not in METHODS:
            raise ParameterError(f"method must be one of {METHODS}, got {self.method!r}")
        if self.activation not in ACTIVATIONS:
            raise ParameterError(f"activation must be one of {sorted(ACTIVATIONS)}, got {self.activation!r}")
        if not self.hidden or any(int(h) < 1 for h in self.hidden):
            raise ParameterError(f"hidden must list layer sizes >= 1, got {self.hidden}")
        if int(self.epochs) < 0:
            raise ParameterError(f"epochs must be >= 0, got {self.epochs}")
        for name in ("test_fraction", "val_fraction"):
            v = getattr(self, name)
            if not 0.0 <= v < 0.9:
                raise ParameterError(f"{name} must be in [0, 0.9), got {v}")
        for name in ("lr", "mu", "mu_dec", "mu_inc", "mu_max"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise ParameterError(f"{name} must be finite and > 0, got {v}")
        self.pso.check()
        if self.threads is not None and (
            isinstance(self.threads, bool) or not isinstance(self.threads, int) or self.threads < 1
        ):
            raise ParameterError(f"threads must be a whole number >= 1 or None, got {self.threads!r}")


@dataclass
class TrainResult:
    """A trained network in NumPy form plus what happened.

    ``weights[l]`` is ``(n_out, n_in)`` (torch's ``Linear.weight`` layout), ``biases[l]``
    ``(n_out,)``; ``history`` has one dict per epoch (``mse`` on the training part in normalised
    units, ``val``; for ``br`` also ``alpha``, ``beta``, ``gamma``; for LM ``mu``).
    """

    weights: list[F64]
    biases: list[F64]
    activations: list[str]
    input_map: MapMinMax
    output_map: MapMinMax
    config: TrainConfig
    train_mse: float
    test_mse: float
    test_mse_per_output: F64
    train_time_s: float
    split: dict[str, NDArray[np.int64]]
    history: list[dict[str, float]] = field(default_factory=list)
    pso_history: list[float] = field(default_factory=list)
    stop_reason: str = ""
    data_sha256: str = ""
    #: torch threads the training ran on (``config.threads``, or cablekit's choice)
    threads: int = 1

    @property
    def sizes(self) -> list[int]:
        return [self.weights[0].shape[1], *(w.shape[0] for w in self.weights)]

    def predict(self, x: F64) -> F64:
        """NumPy forward (physical units), the same equations as the Rust core."""
        a = self.input_map.apply(np.atleast_2d(np.asarray(x, dtype=np.float64)))
        for w, b, act in zip(self.weights, self.biases, self.activations, strict=True):
            z = a @ w.T + b
            a = np.tanh(z) if act == "tansig" else 1.0 / (1.0 + np.exp(-z)) if act == "logsig" else z
        y = self.output_map.reverse(a)
        return y[0] if np.ndim(x) == 1 else y

    def summary(self) -> dict[str, Any]:
        return {
            "sizes": self.sizes,
            "activations": self.activations,
            "method": self.config.method,
            "seed": self.config.seed,
            "epochs_run": len(self.history),
            "stop_reason": self.stop_reason,
            "train_mse": self.train_mse,
            "test_mse": self.test_mse,
            "train_time_s": self.train_time_s,
        }
