"""Neural networks for cable drives: training in torch (the ``train`` extra), inference in Rust.

* :class:`Mlp` (Rust): load a safetensors weight file, ``predict`` / ``predict_into``.
* :func:`train_mlp` (torch): PSO-BPNN (seed 000, Table 1), Levenberg–Marquardt, Bayesian
  regularisation (MacKay; MATLAB ``trainbr``, seed 002), Adam, L-BFGS, with MATLAB
  ``mapminmax`` normalisation, a seeded 90/10 split and validation early stopping.
* :func:`export` writes the trained network as safetensors with its metadata (no pickle);
  :func:`export_onnx` writes any network as ONNX for other runtimes (the ``onnx`` extra).
* :mod:`cablekit.nn.datasets`: the forceps free-motion and CDPR pulley-friction twins.
* :func:`compare_trainers`: the comparison table of the trainers over seeds.

Importing this package does not import torch; the training functions do, on first use.
"""

from __future__ import annotations

from cablekit._cablekit import Mlp
from cablekit.nn.export import export, network_arrays, to_mlp
from cablekit.nn.mapminmax import MapMinMax
from cablekit.nn.onnx_export import export_onnx, onnx_model
from cablekit.nn.spec import METHODS, PsoConfig, TrainConfig, TrainResult

__all__ = [
    "METHODS",
    "MapMinMax",
    "Mlp",
    "PsoConfig",
    "TrainConfig",
    "TrainResult",
    "compare_trainers",
    "export",
    "export_onnx",
    "network_arrays",
    "onnx_model",
    "to_mlp",
    "train_mlp",
]


def __getattr__(name: str) -> object:
    # torch-backed entry points load lazily so `import cablekit.nn` stays light.
    if name == "train_mlp":
        from cablekit.nn.train import train_mlp

        return train_mlp
    if name == "compare_trainers":
        from cablekit.nn.compare import compare_trainers

        return compare_trainers
    raise AttributeError(f"module 'cablekit.nn' has no attribute {name!r}")
