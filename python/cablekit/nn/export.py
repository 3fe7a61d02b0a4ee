"""Write a network as a safetensors file (never pickle), in the layout the Rust core reads
(``cable_core::nn::format``): ``layers.{l}.weight`` ``(n_out, n_in)``, ``layers.{l}.bias``,
``input.min/max``, ``output.min/max``, all float64, plus ``__metadata__`` with the
architecture, activations, names, units, training-data hash and cablekit version.

The writer is plain Python (no torch, no safetensors package needed): an 8-byte little-endian
header length, the JSON header padded to a multiple of 8 bytes, then the tensor bytes.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from cablekit._cablekit import __version__
from cablekit.errors import ShapeError
from cablekit.nn.mapminmax import MapMinMax

if TYPE_CHECKING:
    from cablekit._cablekit import Mlp
    from cablekit.nn.spec import TrainResult

F64 = NDArray[np.float64]
FORMAT, FORMAT_VERSION = "cablekit-mlp", "1"


def network_arrays(
    weights: Sequence[F64], biases: Sequence[F64], input_map: MapMinMax, output_map: MapMinMax
) -> dict[str, F64]:
    """The tensors of a weight file, by name."""
    out: dict[str, F64] = {}
    for i, (w, b) in enumerate(zip(weights, biases, strict=True)):
        out[f"layers.{i}.weight"] = np.ascontiguousarray(w, dtype="<f8")
        out[f"layers.{i}.bias"] = np.ascontiguousarray(b, dtype="<f8")
    out["input.min"], out["input.max"] = input_map.min.astype("<f8"), input_map.max.astype("<f8")
    out["output.min"], out["output.max"] = output_map.min.astype("<f8"), output_map.max.astype("<f8")
    return out


def data_sha256(*arrays: F64) -> str:
    """Hash of the training data (shapes and float64 bytes), stored for provenance."""
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a, dtype="<f8")
        h.update(repr(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def safetensors_bytes(tensors: Mapping[str, F64], metadata: Mapping[str, str]) -> bytes:
    """Serialise float64 tensors and string metadata in the safetensors format."""
    header: dict[str, object] = {"__metadata__": dict(metadata)}
    offset, blobs = 0, []
    for name in sorted(tensors):
        blob = np.ascontiguousarray(tensors[name], dtype="<f8").tobytes()
        header[name] = {
            "dtype": "F64",
            "shape": list(np.shape(tensors[name])),
            "data_offsets": [offset, offset + len(blob)],
        }
        offset += len(blob)
        blobs.append(blob)
    text = json.dumps(header, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 8)
    return len(text).to_bytes(8, "little") + text + b"".join(blobs)


def write_weights(
    path: str | Path,
    weights: Sequence[F64],
    biases: Sequence[F64],
    activations: Sequence[str],
    input_map: MapMinMax,
    output_map: MapMinMax,
    *,
    input_names: Sequence[str] = (),
    input_units: Sequence[str] = (),
    output_names: Sequence[str] = (),
    output_units: Sequence[str] = (),
    metadata: Mapping[str, str] | None = None,
) -> Path:
    """Write a weight file; returns its path. Load it with ``cablekit.Mlp.load(path)``."""
    sizes = [int(np.shape(weights[0])[1]), *(int(np.shape(w)[0]) for w in weights)]
    if len(activations) != len(weights):
        raise ShapeError(f"{len(activations)} activations for {len(weights)} layers")
    md = {k: str(v) for k, v in (metadata or {}).items()}
    md.update(
        format=FORMAT,
        format_version=FORMAT_VERSION,
        architecture=json.dumps({"sizes": sizes, "activations": list(activations)}),
        normalization="mapminmax",
        cablekit_version=__version__,
    )
    for key, names in (
        ("input_names", input_names),
        ("input_units", input_units),
        ("output_names", output_names),
        ("output_units", output_units),
    ):
        if len(names):
            md[key] = json.dumps([str(n) for n in names])
    path = Path(path)
    path.write_bytes(safetensors_bytes(network_arrays(weights, biases, input_map, output_map), md))
    return path


def export(
    result: TrainResult,
    path: str | Path,
    *,
    input_names: Sequence[str] = (),
    input_units: Sequence[str] = (),
    output_names: Sequence[str] = (),
    output_units: Sequence[str] = (),
    metadata: Mapping[str, str] | None = None,
) -> Path:
    """Write a trained network (:func:`cablekit.nn.train_mlp`) with its provenance."""
    md = {
        "training": json.dumps(result.summary()),
        "training_data_sha256": result.data_sha256,
        **(metadata or {}),
    }
    return write_weights(
        path,
        result.weights,
        result.biases,
        result.activations,
        result.input_map,
        result.output_map,
        input_names=input_names,
        input_units=input_units,
        output_names=output_names,
        output_units=output_units,
        metadata=md,
    )


def to_mlp(result: TrainResult, **names: Sequence[str]) -> Mlp:
    """A trained network as the Rust ``cablekit.Mlp``, through the same weight file
    :func:`export` writes (so inference runs exactly what a user would load); ``names`` are
    :func:`export`'s ``input_names`` … ``output_units``."""
    import tempfile

    from cablekit._cablekit import Mlp

    with tempfile.TemporaryDirectory() as d:
        return Mlp.load(export(result, Path(d) / "network.safetensors", **names))  # type: ignore[arg-type]
