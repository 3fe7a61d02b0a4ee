"""ONNX export of a network for interop (the ``onnx`` extra: ``pip install cablekit[onnx]``).

The graph is the exact computation of the Rust :class:`cablekit.Mlp` — MATLAB ``mapminmax`` on
the input, ``Gemm`` + ``Sigmoid``/``Tanh`` per layer, the reverse map on the output — so any
ONNX runtime reproduces ``Mlp.predict`` (to ~1e-15 in float64; float32 is offered for runtimes
without double kernels). The batch dimension is dynamic. The weight file's metadata (names,
units, training provenance) is carried as ONNX ``metadata_props``.

Only the ``onnx`` package is needed (no torch, no ``torch.onnx``): the graph is written with
``onnx.helper`` and checked with ``onnx.checker`` before it is saved.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cablekit._cablekit import Mlp
from cablekit.errors import OnnxExportError

if TYPE_CHECKING:
    import onnx

__all__ = ["OnnxExportError", "export_onnx", "onnx_model"]

#: The oldest opset whose Gemm, Sigmoid, Tanh and arithmetic ops all accept float64.
MIN_OPSET = 13
ONNX_ACTIVATION = {"logsig": "Sigmoid", "tansig": "Tanh", "purelin": None}
DTYPES = ("float64", "float32")


def _onnx() -> Any:
    try:
        import onnx
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise OnnxExportError("ONNX export needs the 'onnx' package: pip install 'cablekit[onnx]'") from e
    return onnx


def onnx_model(network: Mlp | str | Path, *, dtype: str = "float64", opset: int = 17) -> onnx.ModelProto:
    """Build (and check) the ONNX model of ``network`` — an :class:`~cablekit.Mlp` or the path
    of a weight file. Input ``x`` ``(N, n_in)``, output ``y`` ``(N, n_out)``, physical units."""
    onnx = _onnx()
    from onnx import TensorProto, helper, numpy_helper

    if dtype not in DTYPES:
        raise OnnxExportError(f"dtype must be one of {DTYPES}, got {dtype!r}")
    if not isinstance(opset, int) or opset < MIN_OPSET:
        raise OnnxExportError(f"opset must be an integer >= {MIN_OPSET}, got {opset!r}")
    mlp = network if isinstance(network, Mlp) else Mlp.load(network)
    np_dtype = np.dtype(dtype)
    elem = TensorProto.DOUBLE if dtype == "float64" else TensorProto.FLOAT

    inits: list[Any] = []
    nodes: list[Any] = []

    def const(name: str, value: np.ndarray) -> str:
        inits.append(numpy_helper.from_array(np.ascontiguousarray(value, dtype=np_dtype), name))
        return name

    def node(op: str, inputs: list[str], out: str, **attrs: Any) -> str:
        nodes.append(helper.make_node(op, inputs, [out], name=out, **attrs))
        return out

    def gain(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        # mapminmax: g = 2/(max − min), and 1 for an empty range (as the Rust core and MATLAB)
        rng = hi - lo
        return np.where((rng > 0) & np.isfinite(rng), 2.0 / np.where(rng > 0, rng, 1.0), 1.0)

    in_lo, in_hi = (np.asarray(a) for a in mlp.input_range())
    out_lo, out_hi = (np.asarray(a) for a in mlp.output_range())
    one = const("one", np.array(1.0))
    # a = (x − min)·g − 1
    a = node("Sub", ["x", const("input.min", in_lo)], "input.centred")
    a = node("Mul", [a, const("input.gain", gain(in_lo, in_hi))], "input.scaled")
    a = node("Sub", [a, one], "input.normalised")
    for i, ((w, b), act) in enumerate(zip(mlp.layers(), mlp.activations, strict=True)):
        z = node(
            "Gemm",
            [a, const(f"layers.{i}.weight", w), const(f"layers.{i}.bias", b)],
            f"layers.{i}.net",
            transB=1,
        )
        op = ONNX_ACTIVATION[act]
        a = z if op is None else node(op, [z], f"layers.{i}.{act}")
    # y = (a + 1)/g + min
    a = node("Add", [a, one], "output.shifted")
    a = node("Div", [a, const("output.gain", gain(out_lo, out_hi))], "output.scaled")
    node("Add", [a, const("output.min", out_lo)], "y")

    graph = helper.make_graph(
        nodes,
        "cablekit_mlp",
        [helper.make_tensor_value_info("x", elem, ["N", mlp.n_inputs])],
        [helper.make_tensor_value_info("y", elem, ["N", mlp.n_outputs])],
        initializer=inits,
        doc_string=_describe(mlp),
    )
    model = helper.make_model(
        graph,
        producer_name="cablekit",
        opset_imports=[helper.make_operatorsetid("", opset)],
        doc_string="cablekit MLP (mapminmax → dense layers → reverse mapminmax)",
    )
    # readers built against older ONNX releases need an IR version they know
    model.ir_version = min(model.ir_version, 8)
    md = dict(mlp.metadata)
    md["onnx_dtype"] = dtype
    helper.set_model_props(model, md)
    onnx.checker.check_model(model, full_check=True)
    return model


def export_onnx(
    network: Mlp | str | Path, path: str | Path, *, dtype: str = "float64", opset: int = 17
) -> Path:
    """Write ``network`` as an ONNX file (see :func:`onnx_model`); returns the path."""
    onnx = _onnx()
    model = onnx_model(network, dtype=dtype, opset=opset)
    path = Path(path)
    onnx.save_model(model, str(path))
    return path


def _describe(mlp: Mlp) -> str:
    parts = [f"sizes {mlp.sizes}, activations {mlp.activations}"]
    for side, names, units in (
        ("inputs", mlp.input_names, mlp.input_units),
        ("outputs", mlp.output_names, mlp.output_units),
    ):
        if names:
            units = units or [""] * len(names)
            labels = [f"{n} [{u}]" for n, u in zip(names, units, strict=True)]
            parts.append(f"{side}: " + json.dumps(labels))
    return "; ".join(parts)
