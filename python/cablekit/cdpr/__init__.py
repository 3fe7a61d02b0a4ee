"""Cable-driven parallel robots (seeds 002 and 003): robot files, kinematics, tension distribution.

* :class:`Robot` — a robot from a TOML file (:meth:`Robot.load`, :meth:`Robot.from_toml`,
  :meth:`Robot.from_dict`) or a shipped one by name (:func:`shipped`); inverse and forward
  kinematics, the structure matrix, tension distribution (:meth:`Robot.distribute`, and
  :meth:`Robot.controller` for one pose per call) and capacity margins (:meth:`Robot.capacity`)
  are the Rust core's (see docs/cdpr.md).
* :func:`workspace` — the static or wrench-feasible workspace on a grid, :func:`plot_workspace`
  its slices and 3-D view.
* :class:`Winch` — seed 003's winch linearised (eq. 26: zeros, poles, root locus);
  :class:`WinchDrive` — the same winch as a nonlinear model (static friction, current limit,
  PID with the derivative's filter) for :func:`cablekit.simulate`, the sr-UKF and the
  diagnosis; :mod:`cablekit.cdpr.winch` the seed's Table 5 and step responses; :func:`linearise` (eqs
  26–27) and :func:`root_locus`.
* :class:`CdprPlant` — a robot with its winches and pulleys as a dynamic model, and its closed
  loop; :class:`PlanarRobot` — seed 003's planar robot in closed loop (steps, a circle, any
  trajectory).

Conventions: a pose is ``[x, y, θ]`` (planar) or ``[x, y, z, roll, pitch, yaw]`` (spatial,
``R = R_z(yaw) R_y(pitch) R_x(roll)``); tensions ``f`` hold an external wrench ``w`` when
``Aᵀ f + w = 0`` (seed 002 eq. 5).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from cablekit._args import checked
from cablekit._cablekit import (
    Calibration,
    CalibrationFit,
    Capacity,
    CdprPlant,
    Kinematics,
    LoadCellPulley,
    LoopRun,
    PulleyFriction,
    SignalChain,
    Step,
    TensionController,
    Tensions,
    Winch,
    WinchDrive,
)
from cablekit._cablekit import Robot as _Robot
from cablekit._files import parse_toml, read_text
from cablekit.cdpr.workspace import Requirement, Workspace, plot_workspace, workspace
from cablekit.errors import DataError

__all__ = [
    "Calibration",
    "CalibrationFit",
    "Capacity",
    "CdprPlant",
    "Kinematics",
    "Linearised",
    "LoadCellPulley",
    "LoopRun",
    "PlanarRobot",
    "PulleyFriction",
    "Requirement",
    "Robot",
    "SignalChain",
    "Step",
    "TensionController",
    "Tensions",
    "Winch",
    "WinchDrive",
    "Workspace",
    "linearise",
    "path_friction_of",
    "plot_workspace",
    "root_locus",
    "shipped",
    "shipped_names",
    "topics_of",
    "workspace",
]

_TOP = {"name", "motion", "gravity", "platform", "cable", "cables", "description", "path_friction", "topics"}
_PATH_FRICTION = {"coefficient", "viscous", "guide_wrap", "presliding"}


@checked
def topics_of(doc: dict[str, Any], source: str = "<robot>") -> dict[str, Any] | None:
    """The robot file's optional ``[topics]`` table: where a ROS 2 bag carries each column of
    a run (:func:`cablekit.cdpr.formats.bag_topics`, checked when a bag is read); ``None``
    without one, a :class:`~cablekit.errors.DataError` when it is not a table."""
    if "topics" not in doc:
        return None
    if not isinstance(doc["topics"], dict):
        raise DataError(f'{source}: [topics] must be a table of column = "/topic:field"')
    return doc["topics"]


@checked
def path_friction_of(doc: dict[str, Any], source: str = "<robot>") -> dict[str, Any] | None:
    """The robot file's optional ``[path_friction]`` table: the nominal friction of the pulleys
    between each winch-side load cell and the platform (seed 002 eq. 8, Dahl): ``coefficient``
    μ, ``viscous`` σ_v (N·s/m) and ``guide_wrap`` θ_g (rad), each one number or one per cable,
    and the pre-sliding length ``presliding`` (m). ``None`` without one. The diagnosis of a
    robot's drives (:mod:`cablekit.cdpr.drives`) takes it as the platform side's nominal."""
    if "path_friction" not in doc:
        return None
    where = f"{source}: [path_friction]"
    table = _keys(doc["path_friction"], _PATH_FRICTION, where)
    cables = doc.get("cables")
    m = len(cables) if isinstance(cables, list) else 0
    out: dict[str, Any] = {}
    for key in ("coefficient", "viscous", "guide_wrap"):
        v = table.get(key, 0.0)
        name = f"{where}.{key}"
        values = _vector(v, m, name) if isinstance(v, list) else [_number(v, name)] * m
        if not all(np.isfinite(x) and x >= 0 for x in values):
            raise DataError(f"{where}.{key} must be finite and >= 0, got {v!r}")
        if key == "guide_wrap" and any(x > 2 * np.pi for x in values):
            raise DataError(f"{where}.guide_wrap must lie in [0, 2π] rad, got {v!r}")
        out[key] = np.array(values)
    presliding = _number(table.get("presliding", 1e-3), f"{where}.presliding")
    if not (np.isfinite(presliding) and presliding > 0):
        raise DataError(f"{where}.presliding must be finite and > 0, got {presliding!r}")
    out["presliding"] = presliding
    return out


_PLATFORM = {"mass", "com", "inertia"}
_CABLE = {
    "anchor",
    "attachment",
    "f_min",
    "f_max",
    "ea",
    "youngs_modulus",
    "area",
    "stiffness",
    "length",
    "pulley",
}
_PULLEY = {"radius", "axis"}
_GRAVITY = {"planar": [0.0, -9.80665, 0.0], "spatial": [0.0, 0.0, -9.80665]}


def _keys(table: Any, allowed: set[str], where: str) -> dict[str, Any]:
    if not isinstance(table, dict):
        raise DataError(f"{where} must be a table, got {type(table).__name__}")
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise DataError(f"{where}: unknown key(s) {unknown}; known: {sorted(allowed)}")
    return table


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise DataError(f"{where} must be a number, got {value!r}")
    return float(value)


def _vector(value: Any, n: int, where: str) -> list[float]:
    if not isinstance(value, list) or len(value) != n:
        raise DataError(f"{where} must be a list of {n} numbers, got {value!r}")
    return [_number(v, f"{where}[{i}]") for i, v in enumerate(value)]


def _inertia(value: Any, where: str) -> np.ndarray:
    if isinstance(value, list) and len(value) == 3 and all(isinstance(r, list) for r in value):
        return np.array([_vector(r, 3, f"{where}[{i}]") for i, r in enumerate(value)])
    return np.diag(_vector(value, 3, where))


def _ea(c: dict[str, Any], where: str) -> float:
    """Axial stiffness E·A from ``ea``, ``youngs_modulus`` and ``area``, or ``stiffness``
    (k = EA/L) and the unstrained ``length``."""
    given = [k for k in ("ea", "youngs_modulus", "stiffness") if k in c]
    if given == ["ea"]:
        return _number(c["ea"], f"{where}.ea")
    if given == ["youngs_modulus"] and "area" in c:
        return _number(c["youngs_modulus"], f"{where}.youngs_modulus") * _number(c["area"], f"{where}.area")
    if given == ["stiffness"] and "length" in c:
        return _number(c["stiffness"], f"{where}.stiffness") * _number(c["length"], f"{where}.length")
    got = sorted(k for k in c if k in {"ea", "youngs_modulus", "area", "stiffness", "length"})
    raise DataError(
        f"{where}: give the cable's elasticity once, as ea, as youngs_modulus and area, or as stiffness "
        f"(k = EA/L) and length; got {got}"
    )


def _robot_arguments(doc: dict[str, Any], source: str = "<robot>") -> dict[str, Any]:
    """The keyword arguments of :class:`Robot` from a parsed robot file, checked (a typed
    :class:`DataError` naming the key for anything wrong): name, motion, anchors, attachments,
    f_min, f_max, ea, mass, com, inertia (3 × 3), gravity and pulleys (``(cable, radius, unit
    axis)``). The MJCF export reads the same arguments."""
    doc = _keys(doc, _TOP, source)
    path_friction_of(doc, source)  # (checked here; the drives' diagnosis reads it)
    motion = doc.get("motion")
    if not isinstance(motion, str) or motion not in _GRAVITY:
        raise DataError(f"{source}: motion must be 'planar' or 'spatial', got {motion!r}")
    name = doc.get("name", Path(source).stem)
    if not isinstance(name, str):
        raise DataError(f"{source}: name must be a string, got {name!r}")
    platform = _keys(doc.get("platform", {}), _PLATFORM, f"{source}: [platform]")
    defaults = _keys(doc.get("cable", {}), _CABLE - {"anchor", "attachment"}, f"{source}: [cable]")
    cables = doc.get("cables")
    if not isinstance(cables, list) or not cables:
        raise DataError(f"{source}: [[cables]] must list the cables, got {cables!r}")
    columns: dict[str, list[Any]] = {k: [] for k in ("anchors", "attachments", "f_min", "f_max", "ea")}
    pulleys = []
    for i, raw in enumerate(cables):
        where = f"{source}: cables[{i}]"
        c = {**defaults, **_keys(raw, _CABLE, where)}
        for key in ("anchor", "attachment", "f_min", "f_max"):
            if key not in c:
                raise DataError(f"{where}.{key} is missing (give it per cable or in [cable])")
        columns["anchors"].append(_vector(c["anchor"], 3, f"{where}.anchor"))
        columns["attachments"].append(_vector(c["attachment"], 3, f"{where}.attachment"))
        columns["f_min"].append(_number(c["f_min"], f"{where}.f_min"))
        columns["f_max"].append(_number(c["f_max"], f"{where}.f_max"))
        columns["ea"].append(_ea(c, where))
        if "pulley" in c:
            pl = _keys(c["pulley"], _PULLEY, f"{where}.pulley")
            if set(pl) != _PULLEY:
                raise DataError(f"{where}.pulley needs radius and axis, got {sorted(pl)}")
            axis = np.array(_vector(pl["axis"], 3, f"{where}.pulley.axis"))
            norm = float(np.linalg.norm(axis))
            if not np.isfinite(norm) or norm == 0.0:
                raise DataError(f"{where}.pulley.axis must be a non-zero direction, got {pl['axis']!r}")
            pulleys.append((i, _number(pl["radius"], f"{where}.pulley.radius"), tuple(axis / norm)))
    arrays = {k: np.ascontiguousarray(v, dtype=np.float64) for k, v in columns.items()}
    return dict(
        name=name,
        motion=motion,
        mass=_number(platform.get("mass", 0.0), f"{source}: platform.mass"),
        com=np.asarray(_vector(platform.get("com", [0.0, 0.0, 0.0]), 3, f"{source}: platform.com")),
        inertia=np.ascontiguousarray(
            _inertia(platform.get("inertia", [0.0, 0.0, 0.0]), f"{source}: platform.inertia")
        ),
        gravity=np.asarray(_vector(doc.get("gravity", _GRAVITY[motion]), 3, f"{source}: gravity")),
        pulleys=pulleys,
        **arrays,
    )


class Robot(_Robot):
    """A cable-driven parallel robot. Build one from a robot file (:meth:`load`) or a shipped
    robot (:func:`shipped`); the keyword constructor takes the arrays the file describes."""

    @classmethod
    @checked
    def load(cls, path: str | Path) -> Robot:
        """A robot from a TOML robot file (format: docs/cdpr.md)."""
        return cls.from_toml(read_text(path, "robot file"), source=str(path))

    @classmethod
    @checked
    def from_toml(cls, text: str, source: str = "<robot>") -> Robot:
        """A robot from the text of a TOML robot file."""
        return cls.from_dict(parse_toml(text, source), source)

    @classmethod
    @checked
    def from_dict(cls, doc: dict[str, Any], source: str = "<robot>") -> Robot:
        """A robot from the parsed robot file."""
        return cls(**_robot_arguments(doc, source))

    @classmethod
    @checked
    def from_caspr(
        cls,
        bodies: str | Path,
        cables: str | Path,
        cable_set: str | None = None,
        *,
        ea: float = 1e9,
    ) -> Robot:
        """A robot from CASPR's XML files (``*_bodies.xml``, ``*_cables.xml``): a single
        rigid platform, ideal cables (rigid: their E·A is ``ea``); see
        :mod:`cablekit.cdpr.caspr` for what is mapped and what is refused."""
        from cablekit._args import real
        from cablekit.cdpr.caspr import caspr_document

        ea = real(ea, "ea", lo=0.0, lo_open=True)
        return cls.from_dict(caspr_document(bodies, cables, cable_set, ea), str(cables))

    @checked
    def workspace(
        self,
        *,
        counts: int | tuple[int, ...] = 50,
        lower: Any = None,
        upper: Any = None,
        orientation: Any = None,
        requirement: Requirement | None = None,
    ) -> Workspace:
        """The static (default) or wrench-feasible workspace on a grid: see :func:`workspace`."""
        return workspace(
            self, counts=counts, lower=lower, upper=upper, orientation=orientation, requirement=requirement
        )


@checked
def shipped_names() -> list[str]:
    """The names of the shipped robots."""
    folder = resources.files("cablekit.cdpr") / "robots"
    return sorted(p.name.removesuffix(".toml") for p in folder.iterdir() if p.name.endswith(".toml"))


@checked
def shipped(name: str | None = None) -> Robot | list[str]:
    """The shipped robot ``name`` (``"seed002_mini"``, ``"seed003_planar"``, ``"ipanema_like"``),
    or the list of names without an argument."""
    folder = resources.files("cablekit.cdpr") / "robots"
    names = shipped_names()
    if name is None:
        return names
    if name not in names:
        raise DataError(f"no shipped robot {name!r}; shipped: {names}")
    return Robot.from_toml((folder / f"{name}.toml").read_text(encoding="utf-8"), source=f"{name}.toml")


# after Robot and shipped: the planar module builds on them
from cablekit.cdpr.planar import PlanarRobot  # noqa: E402
from cablekit.cdpr.winch import Linearised, linearise, root_locus  # noqa: E402
