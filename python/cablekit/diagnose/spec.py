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

    [units]                             # optional: columns not recorded in SI units
    theta = "deg"                       # converted on load; see UNITS
    x_m = "mm"
    tau_load = {scale = 0.0214, offset = 0.0}   # any column: SI = scale·value + offset

    [diagnosis]                         # optional
    warmup = 0.2                        # s excluded at the start of every run
    substeps = 0                        # RK4 substeps per sample; 0 = from the stiffest mode
    effects = ["coulomb_friction", ...] # candidate subset; default: every applicable one

A **cable network** (any mechanism of a network file, docs/models.md) is diagnosed the same way:

.. code-block:: toml

    model = "cable_network"
    [parameters]
    network = "two_stage_forceps"       # a shipped network, or file = "robot.toml" (relative to
                                        # this file), or an inline [parameters.definition] table
    [inputs]
    drive = "x_motor"                   # one column per motor: a position-driven motor's angle
                                        # (rad), a torque-driven motor's torque (N·m)
    external = {jaw = "tau_jaw"}        # optional: external loads per joint
    [outputs]
    "q:jaw" = "enc_jaw"                 # a network output (q:, q_m:, T:, T_motor:, tau:, load_m:)
    spindle_torque = "torque"           # or a sensor the network file names

Its sites are derived from the network's elements (``joint.<name>``, ``cable.<name>``,
``routing.<cable>``, ``motor.<name>``, the sensor sites); tensions, torques and motor loads are
force channels.

Outputs of the antagonistic joint: ``tension_motor_drive``, ``tension_motor_return``,
``tension_joint_drive``, ``tension_joint_return`` (N, force sensors), ``theta`` (rad, encoder),
``contact_force`` (N, force sensor), ``net_motor_force`` (N, ``T_m,drive − T_m,return``: a
spindle torque sensor's reading divided by the capstan radius). Sensor-side effects (lag,
sampling, gain/bias) act on force sensors only.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from cablekit._args import checked, real
from cablekit._cablekit import AntagonisticJoint, CableNetwork, CableTransmission, Model, effect_catalogue
from cablekit._files import parse_toml, read_text
from cablekit.diagnose.data import Run
from cablekit.errors import CablekitError, DataError

__all__ = [
    "OUTPUTS",
    "ModelSpec",
    "load_model_spec",
    "model_spec_from_dict",
    "output_info",
    "sharpen_dry_friction",
]

#: antagonistic joint: output name → (index in the model outputs, unit, is a force sensor)
OUTPUTS: dict[str, tuple[int, str, bool]] = {
    "tension_motor_drive": (0, "N", True),
    "tension_motor_return": (1, "N", True),
    "tension_joint_drive": (2, "N", True),
    "tension_joint_return": (3, "N", True),
    "theta": (4, "rad", False),
    "contact_force": (5, "N", True),
    "net_motor_force": (6, "N", True),
}

#: cable transmission: per-link output base name → (offset in the link's 5 outputs, unit, sensor)
TRANSMISSION_OUTPUTS: dict[str, tuple[int, str, bool]] = {
    "q_m": (0, "rad", False),
    "q_l": (1, "rad", False),
    "tension_a": (2, "N", True),
    "tension_b": (3, "N", True),
    "joint_torque": (4, "N·m", True),
}

MODELS = ("antagonistic_joint", "cable_transmission", "cable_network")

#: effects a cable network does not offer, and why they are skipped
NOT_IN_NETWORK = {
    "coupling": "a network's routing is its coupling (no separate coupled axis)",
}

#: network output prefix → (unit, is a force channel); angles may be lengths (prismatic joints)
NETWORK_OUTPUTS: dict[str, tuple[str | None, bool]] = {
    "q": (None, False),
    "q_m": ("rad", False),
    "T": ("N", True),
    "T_motor": ("N", True),
    "tau": (None, True),
    "load_m": ("N·m", True),
}

#: effects with no counterpart in the cable transmission
NOT_IN_TRANSMISSION = ("stribeck_friction", "dahl_hysteresis", "capstan_friction", "creep", "backlash")


def network_output_info(network: CableNetwork, name: str) -> tuple[int, str | None, bool]:
    """``(index, unit, is force channel)`` of a network output, by output name (``q:jaw``) or by
    the name of a sensor the network file declares; KeyError if none."""
    names = list(network.output_names)
    if name in names:
        index = names.index(name)
    else:
        index = dict(network.sensors)[name]
    # (a tension between two contacts is ``T@<pulley>:<cable>``)
    unit, force = NETWORK_OUTPUTS[names[index].split(":", 1)[0].split("@", 1)[0]]
    return index, unit, force


def output_info(kind: str, name: str, links: int = 1) -> tuple[int, str, bool]:
    """``(index, unit, is force sensor)`` of output ``name`` of a model kind; KeyError if none."""
    if kind == "antagonistic_joint":
        return OUTPUTS[name]
    base, _, idx = name.rstrip("0123456789"), None, name[len(name.rstrip("0123456789")) :]
    if base == "tau_m" and idx and 1 <= int(idx) <= links:
        return 5 * links + int(idx) - 1, "N·m", False  # applied motor torque (servo replay)
    if base not in TRANSMISSION_OUTPUTS or not idx or not 1 <= int(idx) <= links:
        raise KeyError(name)
    off, unit, sensor = TRANSMISSION_OUTPUTS[base]
    return 5 * (int(idx) - 1) + off, unit, sensor


#: units a run column may be recorded in: name → (SI unit, factor to it); an encoder's counts
#: are ``"counts/N"`` (N counts per turn → rad)
UNITS: dict[str, tuple[str, float]] = {
    "rad": ("rad", 1.0), "mrad": ("rad", 1e-3), "deg": ("rad", math.pi / 180), "rev": ("rad", 2 * math.pi),
    "m": ("m", 1.0), "cm": ("m", 1e-2), "mm": ("m", 1e-3), "um": ("m", 1e-6), "µm": ("m", 1e-6),
    "in": ("m", 0.0254),
    "N": ("N", 1.0), "mN": ("N", 1e-3), "kN": ("N", 1e3), "kgf": ("N", 9.80665),
    "lbf": ("N", 4.4482216152605),
    "N·m": ("N·m", 1.0), "Nm": ("N·m", 1.0), "N*m": ("N·m", 1.0), "mN·m": ("N·m", 1e-3), "mNm": ("N·m", 1e-3),
    "mN*m": ("N·m", 1e-3), "N·mm": ("N·m", 1e-3), "Nmm": ("N·m", 1e-3), "N*mm": ("N·m", 1e-3),
    "lbf·in": ("N·m", 0.1129848290276167), "ozf·in": ("N·m", 0.00706155181422604),
}  # fmt: skip


@dataclass
class ModelSpec:
    """A parsed model file."""

    kind: str
    parameters: dict[str, Any]
    inputs: list[str]
    coupled: str | None
    external: list[str]
    outputs: list[tuple[str, str]]
    warmup: float = 0.2
    substeps: int = 0
    effects: list[str] | None = None
    source: str = ""
    extra: dict[str, Any] = field(default_factory=dict)
    #: ``[units]``: run column → ``(scale, offset, as declared)``, SI = scale·value + offset
    column_units: dict[str, tuple[float, float, Any]] = field(default_factory=dict)
    #: run attributes at which the nominal was built (e.g. the wrist posture of the calibration
    #: runs), name → values; a run with another value, or without one, gets a warning
    conditions: dict[str, tuple[float, ...]] = field(default_factory=dict)

    @property
    def x_m(self) -> str:
        """The joint's motor-displacement column (the first input column)."""
        return self.inputs[0]

    @property
    def links(self) -> int:
        return len(self.inputs) if self.kind == "cable_transmission" else 1

    def model(self) -> Model:
        """The nominal model (validated by the core)."""
        try:
            if self.kind == "antagonistic_joint":
                return AntagonisticJoint(**self.parameters)
            if self.kind == "cable_network":
                return self.network()
            return _transmission(self.parameters, self.links)
        except TypeError as exc:
            raise DataError(f"{self.source}: [parameters]: {exc}") from None

    def __getstate__(self) -> dict[str, Any]:
        # the built network (a core object) is a cache: a pickled spec (a Ray task's) rebuilds it
        state = dict(self.__dict__)
        state["extra"] = {k: v for k, v in self.extra.items() if k != "_network"}
        return state

    def network(self) -> CableNetwork:
        """The nominal network (built once per spec)."""
        net = self.extra.get("_network")
        if net is None:
            net = self.extra["_network"] = _network(
                self.parameters, self.source, self.extra.get("sharp_dry_friction")
            )
        return net

    def output(self, name: str) -> tuple[int, str, bool]:
        if self.kind == "cable_network":
            index, unit, force = network_output_info(self.network(), name)
            return index, unit or "rad|m", force
        return output_info(self.kind, name, self.links)

    def units(self) -> dict[str, str]:
        """Run column → declared unit, for the unit checks (angles of prismatic links are m)."""
        u = {self.x_m: "m"} if self.kind == "antagonistic_joint" else {}
        for out, col in self.outputs:
            unit = self.output(out)[1]
            if (self.kind == "cable_transmission" and unit == "rad") or unit == "rad|m":
                continue  # revolute (rad) or prismatic (m): not checkable by name
            if self.kind == "cable_network" and unit == "rad" and self._base_output(out).startswith("q_m:"):
                continue  # a motor turns many times: its angle's size says nothing of the unit
            u[col] = unit
        return u

    def in_si(self, run: Run) -> Run:
        """``run`` with the ``[units]`` columns converted to SI units (a note says which)."""
        if not self.column_units:
            return run
        cols = dict(run.columns)
        done = []
        for col, (scale, offset, declared) in self.column_units.items():
            with np.errstate(over="ignore", invalid="ignore"):
                cols[col] = scale * run.column(col) + offset
            if not np.isfinite(cols[col]).all():
                raise DataError(f"run {run.name!r}: column {col!r} overflows when converted from {declared}")
            how = f"from {declared}" if isinstance(declared, str) else f"×{scale:g} + {offset:g}"
            done.append(f"{col} {how}")
        return replace(run, columns=cols, notes=[*run.notes, "converted to SI units: " + ", ".join(done)])

    def columns(self) -> dict[str, str | None]:
        """Every run column the model reads → the SI unit it must be in (``None``: any, or an
        angle that is a length on a prismatic link: ``"rad|m"``)."""
        cols: dict[str, str | None] = {}
        if self.kind == "antagonistic_joint":
            cols[self.x_m] = "m"
            if self.coupled:
                cols[self.coupled] = None
        elif self.kind == "cable_network":
            net = self.network()
            for name, c in zip([*net.motor_names, *net.signal_names], self.inputs, strict=True):
                if name in net.signal_names:
                    cols[c] = None  # a measured signal: its unit is the network file's
                else:
                    cols[c] = "N·m" if f"tau_m:{name}" in net.input_names else "rad|m"
        else:
            for c in self.inputs:
                cols[c] = "rad|m" if self.servo() else "N·m"
            for c in self.extra.get("dq_m_ref") or []:
                cols[c] = None
        for c in self.external:
            cols[c] = "N·m"
        for out, col in self.outputs:
            unit = self.output(out)[1]
            cols[col] = "rad|m" if self.kind == "cable_transmission" and unit == "rad" else unit
            if cols[col] == "rad|m" and self.kind == "cable_network" and not out.startswith(("q:", "q_m:")):
                cols[col] = None  # a joint torque: N·m, or N on a prismatic joint
        return cols

    def _base_output(self, name: str) -> str:
        """A network output's own name (``q_m:m1``) for a name or a sensor's name."""
        net = self.network()
        return list(net.output_names)[network_output_info(net, name)[0]]

    def channels(self) -> list[tuple[int, bool]]:
        """``(output index, is force sensor)`` per measured column, in file order."""
        return [(self.output(o)[0], self.output(o)[2]) for o, _ in self.outputs]

    def primary(self) -> tuple[str, str]:
        """``(column, kind)`` of the signal that localisation bins by position and speed: the
        joint's motor displacement, or the transmission's first measured angle (else its first
        torque)."""
        if self.kind == "antagonistic_joint":
            return self.x_m, "input"
        for out, col in self.outputs:
            if out.startswith(("q_l", "q_m", "q:")):
                return col, "measured"
        return self.inputs[0], "input"

    def servo(self) -> tuple[list[float], list[float], list[float]] | None:
        """Servo gains ``(kp, kd, torque_limit)`` of a closed-loop replay, else None."""
        return self.extra.get("servo")

    def to_dict(self) -> dict[str, Any]:
        """The model file's tables (:func:`write_model_toml` writes them, :func:`load_model_spec`
        reads them back into the same spec)."""
        servo = self.servo()
        if self.kind == "cable_network":
            net = self.network()
            inputs: dict[str, Any] = dict(
                zip([*net.motor_names, *net.signal_names], self.inputs, strict=True)
            )
            if self.external:
                inputs["external"] = dict(self.extra["external_joints"])
        elif self.kind == "antagonistic_joint":
            inputs = {"x_m": self.x_m}
            if self.coupled:
                inputs["coupled"] = self.coupled
            if self.external:
                inputs["external"] = self.external[0]
        elif self.servo():
            inputs = {"q_m_ref": list(self.inputs)}
            if self.extra.get("dq_m_ref"):
                inputs["dq_m_ref"] = list(self.extra["dq_m_ref"])
        else:
            inputs = {"tau_m": list(self.inputs)}
            if self.external:
                inputs["external"] = list(self.external)
        parameters = dict(self.parameters)
        if self.kind == "cable_network" and isinstance(parameters.get("file"), str):
            parameters["file"] = str(_network_file(parameters["file"], self.source).resolve())
        return (
            {
                "model": self.kind,
                "parameters": parameters,
                "inputs": inputs,
                "outputs": dict(self.outputs),
                "diagnosis": {"warmup": self.warmup, "substeps": self.substeps}
                | ({"effects": self.effects} if self.effects else {})
                | ({"replay": self.extra["replay"]} if "replay" in self.extra else {})
                | ({"torque": self.extra["torque"]} if "torque" in self.extra else {}),
            }
            | ({"servo": dict(zip(SERVO_GAINS, map(list, servo), strict=True))} if servo else {})
            | ({"units": {c: d for c, (_, _, d) in self.column_units.items()}} if self.column_units else {})
            | ({"conditions": {k: list(v) for k, v in self.conditions.items()}} if self.conditions else {})
        )


#: the tables and keys a model file may hold (anything else is a DataError: a misspelt key
#: must not be silently ignored)
TOP_LEVEL = {"model", "parameters", "inputs", "outputs", "diagnosis", "servo", "units", "conditions"}
DIAGNOSIS_KEYS = {"warmup", "substeps", "effects", "replay", "torque"}
#: what a torque-driven motor's torque column is: a command a digital drive holds over each
#: sample ("held", the default), or a sampled measurement of a continuous torque or current
#: ("sampled") — the measured-motor replay's load channel weighs it accordingly
TORQUES = ("held", "sampled")
#: how a network with torque-driven motors is replayed (prepare._measured_motor_replay)
REPLAYS = ("auto", "measured_motors", "open_loop")
SERVO_GAINS = ("kp", "kd", "torque_limit")
SERVO_KEYS = {"preset", *SERVO_GAINS}
#: the most RK4 substeps per sample the core accepts (cable_core::integrate::MAX_SUBSTEPS)
MAX_SUBSTEPS = 100_000


def _unknown(table: dict[str, Any], allowed: set[str], where: str, source: str) -> None:
    unknown = set(table) - allowed
    if unknown:
        raise DataError(f"{source}: {where} has unknown keys {sorted(unknown)}; allowed: {sorted(allowed)}")


def _number(value: Any, what: str, source: str) -> float:
    """A finite real number (an int or float; not a bool or a string)."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise DataError(f"{source}: {what} must be a finite number, got {value!r}")
    return float(value)


def _conditions(table: Any, source: str) -> dict[str, tuple[float, ...]]:
    """``[conditions]``: run attribute → the value (or list of values) the nominal was built at."""
    if not isinstance(table, dict):
        raise DataError(f"{source}: conditions must be a table [conditions] of attribute = value(s)")
    out: dict[str, tuple[float, ...]] = {}
    for name, value in table.items():
        values = value if isinstance(value, list) else [value]
        if not values:
            raise DataError(f"{source}: [conditions] {name} lists no value")
        out[name] = tuple(_number(v, f"[conditions] {name}", source) for v in values)
    return out


def _column(value: Any, what: str, source: str) -> str:
    if not isinstance(value, str) or not value:
        raise DataError(f"{source}: {what} must name a run column (a non-empty string), got {value!r}")
    return value


def _columns(value: Any, what: str, source: str) -> list[str]:
    if not isinstance(value, list):
        raise DataError(f"{source}: {what} must be a list of run columns, got {value!r}")
    return [_column(v, f"{what}[{i}]", source) for i, v in enumerate(value)]


def _servo_gains(
    table: dict[str, Any], links: int, source: str
) -> tuple[list[float], list[float], list[float]]:
    """``(kp, kd, torque_limit)`` of a ``[servo]`` table: ``preset = "raven2"`` or the three lists."""
    from cablekit.simulation import MotorPD

    _unknown(table, SERVO_KEYS, "[servo]", source)
    if table.get("preset") == "raven2":
        pd = MotorPD.raven2(links)
        return list(pd.kp), list(pd.kd), list(pd.torque_limit)
    if not all(isinstance(table.get(k), list) for k in ("kp", "kd", "torque_limit")):
        raise DataError(
            f'{source}: [servo] needs preset = "raven2" or kp, kd, torque_limit lists (one value per link)'
        )
    kp, kd, lim = (
        [_number(v, f"[servo] {k}[{i}]", source) for i, v in enumerate(table[k])]
        for k in ("kp", "kd", "torque_limit")
    )
    if not len(kp) == len(kd) == len(lim) == links:
        raise DataError(f"{source}: [servo] gains need one value per link ({links})")
    return kp, kd, lim


def _transmission(params: dict[str, Any], links: int) -> CableTransmission:
    """``preset = "raven2"`` (the first ``links`` axes) overridden by any keyword of
    ``cablekit.CableTransmission``, or the keywords alone."""
    p = dict(params)
    preset = p.pop("preset", None)
    p.pop("links", None)
    if preset is None:
        return CableTransmission(**p)
    if preset != "raven2":
        raise DataError(f'[parameters] preset must be "raven2", got {preset!r}')
    base = CableTransmission.raven2(links).params()
    base.update(p)
    return CableTransmission(**base)


#: keys of a network model's [parameters]: exactly one of them
NETWORK_SOURCES = ("network", "file", "definition")


def _network_document(params: dict[str, Any], source: str) -> tuple[dict[str, Any], str]:
    """The network document a model file's ``[parameters]`` name, and a label for its errors: a
    shipped network (``network``), a network file (``file``, relative to the model file) or an
    inline ``definition`` table."""
    from cablekit import network as nw

    given = [k for k in NETWORK_SOURCES if k in params]
    unknown = sorted(set(params) - set(NETWORK_SOURCES))
    if unknown or len(given) != 1:
        raise DataError(
            f"{source}: [parameters] of a cable_network holds exactly one of network = <shipped name>, "
            f"file = <network file>, or a [parameters.definition] table"
            + (f"; unknown keys {unknown}" if unknown else f"; got {given or 'none'}")
        )
    value = params[given[0]]
    if given[0] == "definition":
        if not isinstance(value, dict):
            raise DataError(f"{source}: [parameters] definition must be a table (a network document)")
        return value, f"{source}: [parameters.definition]"
    if not isinstance(value, str):
        raise DataError(f"{source}: [parameters] {given[0]} must be a string, got {type(value).__name__}")
    if given[0] == "network":
        return nw.shipped_document(value), f"{value}.toml"
    path = _network_file(value, source)
    return parse_toml(read_text(path, "network file"), str(path)), str(path)


#: sign smoothing (rad/s or m/s) of a network's dry friction when the diagnosis resolves it
#: sharply (:func:`sharpen_dry_friction`): a stick to 1 µrad/s; the diagnosis's replay integrates
#: stiff friction implicitly (``cable_core::identify::netplant``)
SHARP_DRY_FRICTION = 1e-6


@checked
def sharpen_dry_friction(
    doc: dict[str, Any], smoothing: float = SHARP_DRY_FRICTION
) -> tuple[dict[str, Any], list[str]]:
    """``doc`` (a network document; not changed) with the Coulomb friction of every joint and
    torque-driven motor resolved to ``smoothing`` (> 0, rad/s or m/s), and the elements changed
    (``joint.<name>``, ``motor.<name>``: those with dry friction smoothed more widely).

    A network file's ``smoothing`` regularises the sign of dry friction; at rest under a load
    below its level a smoothed law creeps at ``ε·τ/F_c`` where real dry friction sticks. Tables
    whose numbers are not numbers are left as they are: the network's reader names them.
    """
    eps = real(smoothing, "smoothing", lo=0.0, lo_open=True)
    changed: list[str] = []

    def number(v: Any) -> float | None:
        ok = isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(float(v))
        return float(v) if ok else None

    def sharp(table: Any, default: float, what: str) -> Any:
        if not isinstance(table, dict):
            return table
        coulomb, width = number(table.get("coulomb", 0.0)), number(table.get("smoothing", default))
        if coulomb is None or width is None or coulomb <= 0.0 or width <= eps:
            return table
        changed.append(f"{what}.{table.get('name', '?')}")
        return dict(table, smoothing=eps)

    out = dict(doc)
    for key, default, what in (
        ("joints", JOINT_SMOOTHING_DEFAULT, "joint"),
        ("motors", MOTOR_SMOOTHING_DEFAULT, "motor"),
    ):
        tables = doc.get(key)
        if isinstance(tables, list):
            out[key] = [
                sharp(t, default, what)
                if what == "joint" or (isinstance(t, dict) and t.get("drive") == "torque")
                else t
                for t in tables
            ]
    return out, changed


#: the network format's defaults for a joint's and a motor's ``smoothing`` (docs/models.md)
JOINT_SMOOTHING_DEFAULT = 1e-3
MOTOR_SMOOTHING_DEFAULT = 0.1


def _network(params: dict[str, Any], source: str, sharp: float | None = None) -> CableNetwork:
    """The network a model file's ``[parameters]`` name (:func:`_network_document`), its dry
    friction resolved to ``sharp`` if given."""
    from cablekit import network as nw

    doc, label = _network_document(params, source)
    if sharp is not None:
        doc = sharpen_dry_friction(doc, sharp)[0]
    return nw.from_dict(doc, label)


def _network_file(value: str, source: str) -> Path:
    """A network file named in a model file: relative to the model file's folder."""
    path = Path(value)
    if not path.is_absolute() and source and not source.startswith("<"):
        path = Path(source).parent / path
    return path


def _network_inputs(
    inputs: dict[str, Any], network: CableNetwork, source: str
) -> tuple[list[str], list[str], list[tuple[str, str]]]:
    """Motor columns in the network's motor order, and the external-load columns with their
    joints."""
    motors = list(network.motor_names)
    signals = list(network.signal_names)
    missing = [m for m in motors + signals if m not in inputs]
    if missing:
        raise DataError(
            f"{source}: [inputs] needs a column for every motor of the network ({motors}): a "
            f"position-driven motor's angle (rad) or a torque-driven motor's torque (N·m)"
            + (f", and for every signal it reads ({signals})" if signals else "")
            + f"; missing {missing}"
        )
    cols = [_column(inputs[m], f"[inputs] {m}", source) for m in motors + signals]
    ext = inputs.get("external", {})
    if not isinstance(ext, dict):
        raise DataError(f"{source}: [inputs] external must be a table joint = <column>")
    joints = list(network.joint_names)
    bad = sorted(set(ext) - set(joints))
    if bad:
        raise DataError(f"{source}: [inputs] external names unknown joints {bad}; joints: {joints}")
    pairs = [(j, _column(ext[j], f"[inputs] external.{j}", source)) for j in joints if j in ext]
    return cols, [c for _, c in pairs], pairs


def load_model_spec(path: str | Path) -> ModelSpec:
    """Parse and validate a model file; errors are :class:`DataError` naming the key."""
    from cablekit._files import load_toml

    return model_spec_from_dict(load_toml(path, "model file"), source=str(path))


def model_spec_from_dict(doc: dict[str, Any], source: str = "<model>") -> ModelSpec:
    """Validate a parsed model document; see the module for the schema."""
    if not isinstance(doc, dict):
        raise DataError(f"{source}: a model document is a table, got {type(doc).__name__}")
    kind = doc.get("model")
    if not isinstance(kind, str) or kind not in MODELS:
        raise DataError(f"{source}: 'model' must be one of {list(MODELS)}, got {kind!r}")
    _unknown(doc, TOP_LEVEL, "the file", source)
    for key in ("parameters", "inputs", "outputs"):
        if not isinstance(doc.get(key), dict):
            raise DataError(f"{source}: missing table [{key}]")
    for key in ("diagnosis", "servo"):
        if key in doc and not isinstance(doc[key], dict):
            raise DataError(f"{source}: {key} must be a table [{key}]")
    inputs = doc["inputs"]
    extra: dict[str, Any] = {}
    if kind == "cable_network":
        try:
            network = _network(dict(doc["parameters"]), source)
        except CablekitError as exc:
            raise _located(exc, f"{source}: [parameters]") from exc
        extra["_network"] = network
        in_cols, external, pairs = _network_inputs(inputs, network, source)
        extra["external_joints"] = pairs
        allowed = {*network.motor_names, *network.signal_names, "external"}
    elif kind == "antagonistic_joint":
        if "x_m" not in inputs:
            raise DataError(f"{source}: [inputs] needs x_m = <column of the motor displacement, m>")
        allowed = {"x_m", "coupled", "external"}
        in_cols = [_column(inputs["x_m"], "[inputs] x_m", source)]
        if "coupled" in inputs:
            _column(inputs["coupled"], "[inputs] coupled", source)
        external = [_column(inputs["external"], "[inputs] external", source)] if "external" in inputs else []
    else:
        servo = "q_m_ref" in inputs
        tau = inputs.get("q_m_ref" if servo else "tau_m")
        if not isinstance(tau, list) or not tau or not all(isinstance(c, str) for c in tau) or len(tau) > 3:
            raise DataError(
                f"{source}: [inputs] needs tau_m = [<motor torque column per link>], or q_m_ref = "
                "[<motor-angle reference column per link>] for a servo replay (1 to 3 links)"
            )
        allowed = {"q_m_ref", "dq_m_ref", "external"} if servo else {"tau_m", "external"}
        in_cols = list(tau)
        if servo:
            dref = inputs.get("dq_m_ref")
            if dref is not None and (not isinstance(dref, list) or len(dref) != len(tau)):
                raise DataError(f"{source}: [inputs] dq_m_ref must name one column per link ({len(tau)})")
            if dref is not None:
                _columns(dref, "[inputs] dq_m_ref", source)
            if not isinstance(doc.get("servo"), dict):
                raise DataError(f"{source}: a servo replay (q_m_ref) needs a [servo] table")
            extra["servo"] = _servo_gains(doc["servo"], len(tau), source)
            extra["dq_m_ref"] = list(dref) if dref else None
        external = _columns(inputs["external"], "[inputs] external", source) if "external" in inputs else []
        if external and len(external) != len(tau):
            raise DataError(f"{source}: [inputs] external must name one column per link ({len(tau)})")
    unknown = set(inputs) - allowed
    if unknown:
        raise DataError(
            f"{source}: [inputs] has unknown keys {sorted(unknown)}; allowed: {', '.join(sorted(allowed))}"
        )
    links = len(in_cols) if kind == "cable_transmission" else 1
    outputs = []
    if kind == "cable_network":
        net = extra["_network"]
        names = list(net.output_names) + [n for n, _ in net.sensors]
    elif kind == "antagonistic_joint":
        names = list(OUTPUTS)
    else:
        names = [f"{b}{i}" for i in range(1, links + 1) for b in TRANSMISSION_OUTPUTS] + (
            [f"tau_m{i}" for i in range(1, links + 1)] if "servo" in extra else []
        )
    for out, col in doc["outputs"].items():
        if out not in names:
            raise DataError(f"{source}: [outputs] {out!r} is not an output; choose from {names}")
        if not isinstance(col, str):
            raise DataError(f"{source}: [outputs] {out} must name a run column (a string)")
        outputs.append((out, col))
    if not outputs:
        raise DataError(f"{source}: [outputs] maps no measured column")
    diag = doc.get("diagnosis", {})
    _unknown(diag, DIAGNOSIS_KEYS, "[diagnosis]", source)
    known = {e["name"] for e in effect_catalogue()}
    effects = diag.get("effects")
    if effects is not None:
        if not isinstance(effects, list):
            raise DataError(f"{source}: [diagnosis] effects must be a list of effect names")
        bad = [e for e in effects if not isinstance(e, str) or e.split("@")[0] not in known]
        if bad:
            raise DataError(
                f"{source}: [diagnosis] effects {bad} unknown; choose from {sorted(known)} "
                "(an effect, or effect@site, effect@site/form: see docs/diagnosis.md)"
            )
    for key, choices, default, what in (
        ("replay", REPLAYS, "auto", "how a cable_network's torque-driven motors are replayed"),
        ("torque", TORQUES, "held", "a cable_network's torque columns: held commands or sampled readings"),
    ):
        value = diag.get(key, default)
        if value not in choices or (value != default and kind != "cable_network"):
            raise DataError(
                f"{source}: [diagnosis] {key} must be one of {list(choices)} ({what}), got {value!r}"
            )
        if kind == "cable_network" and value != default:
            extra[key] = value
    spec = ModelSpec(
        kind=kind,
        parameters=dict(doc["parameters"]),
        inputs=in_cols,
        coupled=inputs.get("coupled") if kind == "antagonistic_joint" else None,
        external=external,
        outputs=outputs,
        warmup=_number(diag.get("warmup", 0.2), "[diagnosis] warmup", source),
        substeps=_substeps(diag.get("substeps", 0), source),
        effects=list(effects) if effects is not None else None,
        source=source,
        extra=extra,
    )
    if spec.warmup < 0 or spec.substeps < 0:
        raise DataError(f"{source}: [diagnosis] warmup and substeps must be >= 0")
    spec.column_units = _column_units(doc.get("units", {}), spec.columns(), source)
    spec.conditions = _conditions(doc.get("conditions", {}), source)
    for key, value in spec.parameters.items():
        if kind != "cable_network":  # a network's numbers are checked by its own reader
            _parameter(value, f"[parameters] {key}", source)
    try:
        spec.model()
    except CablekitError as exc:  # keep the specific class (ParameterError, ...), add the file
        raise _located(exc, f"{source}: [parameters]") from exc
    except (TypeError, ValueError, OverflowError) as exc:  # a value of the wrong kind
        raise DataError(f"{source}: [parameters]: {exc}") from None
    return spec


def _located(exc: CablekitError, where: str) -> CablekitError:
    """The same error (its class and attributes, e.g. a NetworkError's ``element``) with
    ``where`` in front of its message."""
    new = type(exc)(f"{where}: {exc}")
    new.__dict__.update(exc.__dict__)
    return new


def _column_units(
    table: Any, columns: dict[str, str | None], source: str
) -> dict[str, tuple[float, float, Any]]:
    """The ``[units]`` table checked against the columns the model reads and their SI units."""
    if not isinstance(table, dict):
        raise DataError(f"{source}: units must be a table [units]")
    out = {}
    for col, declared in table.items():
        if col not in columns:
            raise DataError(f"{source}: [units] {col!r} is not a column the model reads ({sorted(columns)})")
        want = columns[col]
        if isinstance(declared, dict):
            _unknown(declared, {"scale", "offset"}, f"[units] {col}", source)
            scale = _number(declared.get("scale", 1.0), f"[units] {col} scale", source)
            offset = _number(declared.get("offset", 0.0), f"[units] {col} offset", source)
            if scale == 0.0:
                raise DataError(f"{source}: [units] {col} scale must not be 0")
            out[col] = (scale, offset, dict(declared))
            continue
        name, _, per = declared.partition("/") if isinstance(declared, str) else ("", "", "")
        if name == "counts" and per:
            counts = _number(_float_or_none(per), f"[units] {col} counts per turn", source)
            if counts <= 0:
                raise DataError(f"{source}: [units] {col}: counts per turn must be > 0, got {per}")
            si, factor = "rad", 2 * math.pi / counts
        elif isinstance(declared, str) and declared in UNITS:
            si, factor = UNITS[declared]
        else:
            raise DataError(
                f"{source}: [units] {col} = {declared!r} is not a unit; use one of {sorted(UNITS)}, "
                '"counts/N" (encoder counts per turn) or {scale = k, offset = c}'
            )
        if want is None or si not in want.split("|"):
            need = "a scale table" if want is None else want.replace("|", " or ")
            raise DataError(f"{source}: [units] {col} = {declared!r} is in {si}, but {col} needs {need}")
        out[col] = (factor, 0.0, declared)
    return out


def _float_or_none(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


def _substeps(value: Any, source: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_SUBSTEPS:
        raise DataError(
            f"{source}: [diagnosis] substeps must be a whole number in 0 ..= {MAX_SUBSTEPS} "
            f"(0: from the stiffest mode), got {value!r}"
        )
    return value


def _parameter(value: Any, what: str, source: str) -> None:
    """A parameter: a finite number, a string (a preset or a law's name), or a list of finite
    numbers or names (per link), or a list of lists of numbers (a coupling matrix)."""
    if isinstance(value, str):
        return
    if isinstance(value, list):
        if len(value) > 64:
            raise DataError(f"{source}: {what} has {len(value)} entries; at most 64 are meaningful")
        for i, v in enumerate(value):
            if isinstance(v, list):
                for j, w in enumerate(v):
                    _number(w, f"{what}[{i}][{j}]", source)
            elif not isinstance(v, str):  # per-link names, e.g. joint_kind = ["revolute", ...]
                _number(v, f"{what}[{i}]", source)
        return
    _number(value, what, source)


def write_model_toml(spec: ModelSpec, path: str | Path, comment: str = "") -> Path:
    """Write a model file that :func:`load_model_spec` reads back into the same spec."""
    import tomli_w

    path = Path(path)
    text = tomli_w.dumps(spec.to_dict())
    # a TOML comment holds no control character: they become spaces
    printable = "".join(c if c.isprintable() or c in "\t\n" else " " for c in comment)
    head = "".join(f"# {line}\n" for line in printable.split("\n")) if comment else ""
    path.write_text(head + ("\n" if head else "") + text, encoding="utf-8")
    return path
