"""Cable networks: any cable-driven mechanism of revolute or prismatic joints, described in a
model file (issue #39 §1; the format is docs/models.md).

A network file lists bodies (with their inertias), joints, pulleys, cables with their routing
(the ordered pulleys each passes, the sense and angle of each wrap), motors and sensors. From the
routing follow the length map ``l(q) = l(0) − J·q`` and the moment-arm (coupling) matrix ``J``;
the dynamics, its outputs and every check of the mechanism are the core's
(``cable_core::dynamics::network``). The file is read here (TOML), its numbers checked for NaN/inf, and the
document handed to the core, which names the element at fault for every defect
(:class:`~cablekit.errors.NetworkError`).

Shipped networks (:func:`shipped`): the antagonistic joint and Raven-II's coupled transmission
(equal to the built-in models), the two-stage forceps of the da Vinci bench, and a tendon-driven
finger with more tendons than joints.
"""

from __future__ import annotations

import json
import math
from importlib import resources
from pathlib import Path
from typing import Any

from cablekit._args import checked
from cablekit._cablekit import CableNetwork
from cablekit._files import parse_toml, read_text
from cablekit.errors import DataError

__all__ = [
    "CableNetwork",
    "files_folder",
    "from_dict",
    "from_toml",
    "load",
    "shipped",
    "shipped_document",
    "shipped_names",
]


def _finite(value: Any, where: str) -> None:
    """A :class:`DataError` naming the first NaN or infinite number of a parsed document."""
    if isinstance(value, float) and not math.isfinite(value):
        raise DataError(f"{where} must be finite, got {value!r}")
    if isinstance(value, dict):
        for k, v in value.items():
            _finite(v, f"{where}.{k}" if where else str(k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _finite(v, f"{where}[{i}]")


@checked
def from_dict(doc: dict[str, Any], source: str = "<network>") -> CableNetwork:
    """The network of a parsed network file (a dict as TOML gives it)."""
    _finite(doc, "")
    try:
        text = json.dumps(doc)
    except (TypeError, ValueError) as exc:
        raise DataError(f"{source}: not a network document ({exc})") from None
    return CableNetwork.from_json(text)


@checked
def from_toml(text: str, source: str = "<network>") -> CableNetwork:
    """The network of a network file's TOML text."""
    return from_dict(parse_toml(text, source), source)


@checked
def load(path: str | Path) -> CableNetwork:
    """The network of the TOML network file ``path``."""
    return from_toml(read_text(path, "network file"), str(path))


@checked
def files_folder() -> Any:
    """The folder of the shipped network files (a resource of the package)."""
    return resources.files("cablekit.network") / "files"


@checked
def shipped_names() -> list[str]:
    """The names of the shipped networks."""
    return sorted(p.name.removesuffix(".toml") for p in files_folder().iterdir() if p.name.endswith(".toml"))


@checked
def shipped(name: str) -> CableNetwork:
    """The shipped network ``name`` (see :func:`shipped_names`)."""
    return from_dict(shipped_document(name), f"{name}.toml")


@checked
def shipped_document(name: str) -> dict[str, Any]:
    """The parsed file of the shipped network ``name`` (its name, description and reference)."""
    names = shipped_names()
    if name not in names:
        raise DataError(f"no shipped network {name!r}; shipped: {names}")
    return parse_toml((files_folder() / f"{name}.toml").read_text(encoding="utf-8"), f"{name}.toml")
