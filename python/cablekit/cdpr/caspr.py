"""Import of CASPR's XML robot files (``*_bodies.xml`` and ``*_cables.xml``).

CASPR (Lau et al., the MATLAB platform many CDPR groups describe their robots in) keeps a robot
in two files: the bodies (``<links>`` of ``<link_rigid>`` with a joint type, mass, centre of mass
and inertia) and the cables (``<cables>`` of named ``<cable_set>``s of cables, each with force
bounds and one attachment on the base, link 0, and one on the platform, link 1). cablekit models
one rigid platform, so the import takes single-link robots with a ``PLANAR_XY`` joint (planar,
3 DOF) or a ``SPATIAL*`` joint (6 DOF) and ideal cables. What it maps:

* ``attachment_reference="joint"``: the platform location is in the platform frame, as in a
  cablekit robot file; ``"com"``: it is relative to the centre of mass and gets ``com_location``
  added (the base's locations are world coordinates either way).
* ``force_min``/``force_max`` → ``f_min``/``f_max``; mass, ``com_location`` and the inertia about
  the centre of mass → the platform.
* Ideal cables are rigid: their axial stiffness is the import's ``ea`` argument.
* The layouts CASPR's own example files use: ``<links>`` as the root or inside a
  ``<bodies_system>``, the joint type as ``<joint type="...">`` or ``<joint_type>``, display
  settings (``<display_range>``) beside the link.
* Gravity is CASPR's: its files hold none, and its model applies ``SystemModel.GRAVITY_CONSTANT``
  = 9.81 m/s² along the base frame's −z to every body (``G_b = R_0kᵀ·[0, 0, −m·g]``). A
  ``PLANAR_XY`` robot therefore moves in a horizontal plane, with no weight in it — unlike a
  cablekit planar robot file, whose default gravity is along −y. The imported robot states it
  (``gravity = [0, 0, −9.81]``); give a cablekit robot file to put a planar robot upright.

Orientation coordinates stay cablekit's (``R = R_z(yaw) R_y(pitch) R_x(roll)``), whatever Euler
convention the CASPR joint names; the geometry does not depend on it. Anything else (several
links, another joint, cable models other than ideal, pulleys) is a ``DataError`` naming it.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from cablekit._args import checked
from cablekit.errors import DataError

__all__ = ["caspr_document"]

#: CASPR's gravity (``SystemModel.GRAVITY_CONSTANT``, m/s²), along the base frame's −z
CASPR_GRAVITY = 9.81


def _parse(path: str | Path, root_tag: str) -> ET.Element:
    p = Path(path)
    try:
        root = ET.parse(p).getroot()
    except (OSError, ET.ParseError) as e:
        raise DataError(f"{p}: cannot read the CASPR file ({e})") from e
    if root.tag != root_tag:
        raise DataError(f"{p}: a CASPR {root_tag} file has a <{root_tag}> root, got <{root.tag}>")
    return root


#: children of <links> that describe the display, not a body
_LINKS_METADATA = {"display_range", "view_angle"}


def _links(path: str | Path) -> ET.Element:
    """The <links> of a bodies file: the root, or the child of a <bodies_system> root (CASPR's
    layout that also holds operational spaces beside the links)."""
    p = Path(path)
    try:
        root = ET.parse(p).getroot()
    except (OSError, ET.ParseError) as e:
        raise DataError(f"{p}: cannot read the CASPR file ({e})") from e
    if root.tag == "links":
        return root
    if root.tag == "bodies_system":
        found = root.find("links")
        if found is None:
            raise DataError(f"{p}: a CASPR <bodies_system> holds no <links>")
        return found
    raise DataError(f"{p}: a CASPR bodies file has a <links> root (or <bodies_system>), got <{root.tag}>")


def _text(node: ET.Element, tag: str, where: str) -> str:
    child = node.find(tag)
    if child is None or child.text is None or not child.text.strip():
        raise DataError(f"{where}: <{tag}> is missing")
    return child.text.strip()


def _float(node: ET.Element, tag: str, where: str) -> float:
    text = _text(node, tag, where)
    try:
        v = float(text)
    except ValueError:
        raise DataError(f"{where}: <{tag}> must be a number, got {text!r}") from None
    if not np.isfinite(v):
        raise DataError(f"{where}: <{tag}> must be finite, got {text!r}")
    return v


def _xyz(node: ET.Element, tag: str, where: str) -> list[float]:
    text = _text(node, tag, where)
    try:
        v = [float(s) for s in text.split()]
    except ValueError:
        raise DataError(f"{where}: <{tag}> must be three numbers, got {text!r}") from None
    if len(v) != 3 or not np.all(np.isfinite(v)):
        raise DataError(f"{where}: <{tag}> must be three finite numbers, got {text!r}")
    return v


@checked
def caspr_document(
    bodies: str | Path, cables: str | Path, cable_set: str | None = None, ea: float = 1e9
) -> dict[str, Any]:
    """The cablekit robot document (as a robot TOML file parses) of a CASPR robot: its bodies
    and cables files, the ``cable_set`` (default: the file's ``default_cable_set``) and the axial
    stiffness ``ea`` (N) given to its ideal cables."""
    links = _links(bodies)
    rigid = links.findall("link_rigid")
    bodies_found = [c.tag for c in links if c.tag not in _LINKS_METADATA]
    if len(rigid) != 1 or len(bodies_found) != 1:
        raise DataError(
            f"{bodies}: cablekit imports single-platform robots (one <link_rigid>), got {bodies_found}"
        )
    link = rigid[0]
    where = f"{bodies}: link {link.get('num', '?')}"
    # the joint type as an attribute (<joint type="...">) or, in CASPR's newer files, an element
    joint = link.find("joint")
    kind = (joint.get("type") if joint is not None else None) or (link.findtext("joint_type") or "").strip()
    if kind == "PLANAR_XY":
        motion = "planar"
    elif kind.startswith("SPATIAL"):
        motion = "spatial"
    else:
        raise DataError(f"{where}: joint type {kind!r} is not imported (PLANAR_XY or SPATIAL*)")
    physical = link.find("physical")
    if physical is None:
        raise DataError(f"{where}: <physical> is missing")
    com = _xyz(physical, "com_location", where)
    inertia_node = physical.find("inertia")
    if inertia_node is None:
        raise DataError(f"{where}: <inertia> is missing")
    if inertia_node.get("ref", "com") != "com":
        raise DataError(f'{where}: the inertia must be about the centre of mass (ref="com")')
    i = {k: _float(inertia_node, k, where) for k in ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")}
    inertia = [[i["Ixx"], i["Ixy"], i["Ixz"]], [i["Ixy"], i["Iyy"], i["Iyz"]], [i["Ixz"], i["Iyz"], i["Izz"]]]
    root = _parse(cables, "cables")
    wanted = cable_set or root.get("default_cable_set")
    sets = {s.get("id"): s for s in root.findall("cable_set")}
    if wanted not in sets:
        raise DataError(f"{cables}: no cable set {wanted!r}; sets: {sorted(k for k in sets if k)}")
    out = []
    for node in sets[wanted]:
        name = node.get("name", "?")
        cw = f"{cables}: cable set {wanted!r}, {name!r}"
        if node.tag != "cable_ideal":
            raise DataError(f"{cw}: cable model <{node.tag}> is not imported (cable_ideal)")
        ref = node.get("attachment_reference", "joint")
        if ref not in ("joint", "com"):
            raise DataError(f"{cw}: attachment_reference {ref!r} (joint or com)")
        props = node.find("properties")
        if props is None:
            raise DataError(f"{cw}: <properties> is missing")
        points: dict[int, list[float]] = {}
        for a in node.findall("attachments/attachment"):
            num_text = a.findtext("link") or a.findtext("link_num") or ""
            try:
                num = int(num_text)
            except ValueError:
                raise DataError(f"{cw}: attachment link {num_text!r} is not 0 or 1") from None
            if num not in (0, 1) or num in points:
                raise DataError(f"{cw}: a cable needs one attachment on link 0 and one on link 1")
            points[num] = _xyz(a, "location", cw)
        if set(points) != {0, 1}:
            raise DataError(f"{cw}: a cable needs one attachment on link 0 and one on link 1")
        attach = points[1]
        if ref == "com":
            attach = [a + c for a, c in zip(attach, com, strict=True)]
        out.append(
            {
                "anchor": points[0],
                "attachment": attach,
                "f_min": _float(props, "force_min", cw),
                "f_max": _float(props, "force_max", cw),
                "ea": float(ea),
            }
        )
    if not out:
        raise DataError(f"{cables}: cable set {wanted!r} has no cables")
    return {
        "name": link.get("name") or Path(bodies).stem,
        "motion": motion,
        "gravity": [0.0, 0.0, -CASPR_GRAVITY],
        "platform": {"mass": _float(physical, "mass", where), "com": com, "inertia": inertia},
        "cables": out,
    }
