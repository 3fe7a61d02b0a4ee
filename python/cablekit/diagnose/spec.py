"""The nominal-model file of the diagnosis (TOML).

.. code-block:: toml

    model = "antagonistic_joint"        # the cablekit model

    [parameters]                        # keywords of cablekit.AntagonisticJoint, SI units
    radius = 0.0025                     # m, joint pulley
    stiffness = 31800.0                 # N/m, per cable
    inertia = 2e-6                      # kg·m²
    damping = 20.0                      # N·s/m, per cable
    pretension = 10.0                   # N
    viscous = 2e-5                      # N·m·s/rad

    [inputs]
    x_m = "x_m"                         # run column: motor displacement at the capstan (m)
    coupled = "x_c"                     # optional: a coupled axis (any unit)
    external = "tau_load"               # optional: external joint torque (N·m, along θ)

    [outputs]                           # model output = run column
    tension_motor_drive = "T_drive"     # N
    tension_motor_return = "T_return"   # N
    theta = "theta"                     # optional, rad

    [diagnosis]                         # optional
    warmup = 0.2                        # s excluded at the start of every run
    substeps = 0                        # RK4 substeps per sample; 0 = from the stiffest mode
    effects = ["coulomb_friction", ...] # candidate subset; default: every applicable one

Outputs of the antagonistic joint: ``tension_motor_drive``, ``tension_motor_return``,
``tension_joint_drive``, ``tension_joint_return`` (N, force sensors), ``theta`` (rad, encoder),
``contact_force`` (N, force sensor), ``net_motor_force`` (N, ``T_m,drive − T_m,return``: a
spindle torque sensor's reading divided by the capstan radius). Sensor-side effects (lag,
sampling, gain/bias) act on force sensors only.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cablekit._cablekit import AntagonisticJoint, effect_catalogue
from cablekit.errors import CablekitError, DataError

__all__ = ["OUTPUTS", "ModelSpec", "load_model_spec", "model_spec_from_dict"]

#: output name → (index in the model outputs, unit, is a force sensor)
OUTPUTS: dict[str, tuple[int, str, bool]] = {
    "tension_motor_drive": (0, "N", True),
    "tension_motor_return": (1, "N", True),
    "tension_joint_drive": (2, "N", True),
    "tension_joint_return": (3, "N", True),
    "theta": (4, "rad", False),
    "contact_force": (5, "N", True),
    "net_motor_force": (6, "N", True),
}

MODELS = ("antagonistic_joint",)


@dataclass
class ModelSpec:
    """A parsed model file."""

    kind: str
    parameters: dict[str, Any]
    x_m: str
    coupled: str | None
    external: str | None
    outputs: list[tuple[str, str]]
    warmup: float = 0.2
    substeps: int = 0
    effects: list[str] | None = None
    source: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    def model(self) -> AntagonisticJoint:
        """The nominal model (validated by the core)."""
        try:
            return AntagonisticJoint(**self.parameters)
        except TypeError as exc:
            raise DataError(f"{self.source}: [parameters]: {exc}") from None

    def units(self) -> dict[str, str]:
        """Run column → declared unit, for the unit checks."""
        u = {self.x_m: "m"}
        for out, col in self.outputs:
            u[col] = OUTPUTS[out][1]
        return u

    def channels(self) -> list[tuple[int, bool]]:
        """``(output index, is force sensor)`` per measured column, in file order."""
        return [(OUTPUTS[o][0], OUTPUTS[o][2]) for o, _ in self.outputs]

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": self.kind,
            "parameters": dict(self.parameters),
            "inputs": {"x_m": self.x_m}
            | ({"coupled": self.coupled} if self.coupled else {})
            | ({"external": self.external} if self.external else {}),
            "outputs": dict(self.outputs),
            "diagnosis": {"warmup": self.warmup, "substeps": self.substeps}
            | ({"effects": self.effects} if self.effects else {}),
        }


def load_model_spec(path: str | Path) -> ModelSpec:
    """Parse and validate a model file; errors are :class:`DataError` naming the key."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise DataError(f"{path}: no such model file") from None
    except tomllib.TOMLDecodeError as exc:
        raise DataError(f"{path}: not valid TOML: {exc}") from None
    return model_spec_from_dict(doc, source=str(path))


def model_spec_from_dict(doc: dict[str, Any], source: str = "<model>") -> ModelSpec:
    """Validate a parsed model document; see the module for the schema."""
    kind = doc.get("model")
    if kind not in MODELS:
        raise DataError(f"{source}: 'model' must be one of {list(MODELS)}, got {kind!r}")
    for key in ("parameters", "inputs", "outputs"):
        if not isinstance(doc.get(key), dict):
            raise DataError(f"{source}: missing table [{key}]")
    inputs = doc["inputs"]
    if "x_m" not in inputs:
        raise DataError(f"{source}: [inputs] needs x_m = <column of the motor displacement, m>")
    unknown = set(inputs) - {"x_m", "coupled", "external"}
    if unknown:
        raise DataError(
            f"{source}: [inputs] has unknown keys {sorted(unknown)}; allowed: x_m, coupled, external"
        )
    outputs = []
    for out, col in doc["outputs"].items():
        if out not in OUTPUTS:
            raise DataError(f"{source}: [outputs] {out!r} is not an output; choose from {list(OUTPUTS)}")
        if not isinstance(col, str):
            raise DataError(f"{source}: [outputs] {out} must name a run column (a string)")
        outputs.append((out, col))
    if not outputs:
        raise DataError(f"{source}: [outputs] maps no measured column")
    diag = doc.get("diagnosis", {})
    known = {e["name"] for e in effect_catalogue()}
    effects = diag.get("effects")
    if effects is not None:
        bad = [e for e in effects if e not in known]
        if bad:
            raise DataError(f"{source}: [diagnosis] effects {bad} unknown; choose from {sorted(known)}")
    spec = ModelSpec(
        kind=kind,
        parameters=dict(doc["parameters"]),
        x_m=inputs["x_m"],
        coupled=inputs.get("coupled"),
        external=inputs.get("external"),
        outputs=outputs,
        warmup=float(diag.get("warmup", 0.2)),
        substeps=int(diag.get("substeps", 0)),
        effects=list(effects) if effects is not None else None,
        source=source,
    )
    if spec.warmup < 0 or spec.substeps < 0:
        raise DataError(f"{source}: [diagnosis] warmup and substeps must be >= 0")
    try:
        spec.model()
    except CablekitError as exc:  # keep the specific class (ParameterError, ...), add the file
        raise type(exc)(f"{source}: [parameters]: {exc}") from exc
    return spec
