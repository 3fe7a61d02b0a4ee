"""A parallel robot as MuJoCo's MJCF (issue #40 §3): the platform a body on a free joint (planar:
two slides and a hinge), a site at every cable's anchor and attachment, each cable a spatial
tendon, each tendon driven by a motor whose control is the cable's tension.

A cable over a swivelling guide pulley (robot file ``pulley = {radius, axis}``) becomes a body
on a hinge about the pulley's swivel axis through the anchor, holding the wheel (a cylinder the
tendon wraps, its side chosen by a site over the wheel) and the tendon runs from an inlet site on
the swivel axis, ``INLET`` m before the anchor, over the wheel to the platform. MuJoCo does not
turn the pulley towards the platform by itself: :func:`swivel_angles` gives the hinge angles of a
pose (cablekit's pulley plane holds the platform point), and :func:`mujoco_state` writes a pose
and those angles into ``qpos``. The tendon's length is then cablekit's cable length plus
``INLET`` (the straight run into the wheel), and its moment arms are cablekit's structure
matrix with the opposite sign (a tendon's moment is ``∂l/∂q``; a cable pulls). See docs/cdpr.md
("MuJoCo") for what MuJoCo then cannot model and how cablekit's cable laws fill it.

Conventions: a pose is ``[x, y, θ]`` (planar) or ``[x, y, z, roll, pitch, yaw]`` (spatial,
``R = R_z(yaw)·R_y(pitch)·R_x(roll)``), as everywhere in :mod:`cablekit.cdpr`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np

from cablekit._args import checked, instance, signal
from cablekit._files import parse_toml, read_text
from cablekit.errors import DataError

__all__ = ["INLET", "export_mjcf", "mujoco_state", "swivel_angles", "to_mjcf"]

#: Straight run of a pulley cable's tendon into the wheel, before the anchor (m).
INLET = 0.05


def _arguments(robot_file: str | Path | dict[str, Any], source: str | None) -> tuple[dict[str, Any], str]:
    from cablekit.cdpr import _robot_arguments

    if isinstance(robot_file, dict):
        where = source or "<robot>"
        return _robot_arguments(robot_file, where), where
    instance(robot_file, "robot_file", (str, Path, dict))
    where = source or str(robot_file)
    return _robot_arguments(parse_toml(read_text(robot_file, "robot file"), where), where), where


def _fmt(v: Any) -> str:
    return " ".join(repr(float(x)) for x in np.ravel(v))


def _reference(axis: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to ``axis``: the wheel's direction at swivel angle 0."""
    trial = np.eye(3)[int(np.argmin(np.abs(axis)))]
    e0 = trial - (trial @ axis) * axis
    return e0 / np.linalg.norm(e0)


def _rotations(motion: str, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions ``(N, 3)`` and rotations ``(N, 3, 3)`` of poses ``q`` ``(N, n)``."""
    if motion == "planar":
        c, s = np.cos(q[:, 2]), np.sin(q[:, 2])
        zero, one = np.zeros_like(c), np.ones_like(c)
        x = np.column_stack([q[:, 0], q[:, 1], zero])
        r = np.stack(
            [np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1), np.stack([zero, zero, one], -1)], 1
        )
        return x, r
    sr, cr = np.sin(q[:, 3]), np.cos(q[:, 3])
    sp, cp = np.sin(q[:, 4]), np.cos(q[:, 4])
    sy, cy = np.sin(q[:, 5]), np.cos(q[:, 5])
    r = np.stack(
        [
            np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
            np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
            np.stack([-sp, cp * sr, cp * cr], -1),
        ],
        1,
    )
    return np.ascontiguousarray(q[:, :3]), r


@checked
def to_mjcf(robot_file: str | Path | dict[str, Any], *, source: str | None = None) -> str:
    """The MJCF text of a robot file (a path, or its parsed table with ``source`` naming it).
    A robot file that is not a valid robot is the loader's :class:`DataError`; a platform without
    mass is one too (MuJoCo moves bodies with mass)."""
    a, where = _arguments(robot_file, source)
    planar = a["motion"] == "planar"
    mass = float(a["mass"])
    if not mass > 0.0:
        raise DataError(f"{where}: MuJoCo needs the platform's mass > 0 (platform.mass = {mass:g})")
    inertia = np.array(a["inertia"], dtype=float)
    if planar:
        # only I_zz acts on a planar platform; MuJoCo wants a physical inertia (a thin plate's)
        izz = inertia[2, 2]
        if not izz > 0.0:
            raise DataError(f"{where}: MuJoCo needs the planar platform's I_zz > 0 (platform.inertia)")
        inertia = np.diag([izz / 2, izz / 2, izz])
    full = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    anchors = np.array(a["anchors"], dtype=float)
    attachments = np.array(a["attachments"], dtype=float)
    if planar:
        anchors[:, 2] = 0.0
        attachments[:, 2] = 0.0
    pulleys = {int(i): (float(r), np.array(ax, dtype=float)) for i, r, ax in a["pulleys"]}
    name = quoteattr(a["name"])
    lines = [
        f"<mujoco model={name}>",
        "  <!-- written by cablekit (cablekit cdpr export-mjcf): cablekit's cable geometry -->",
        '  <compiler angle="radian" autolimits="true"/>',
        f'  <option gravity="{_fmt(a["gravity"])}" timestep="0.001"/>',
        "  <worldbody>",
    ]
    for i, (r, axis) in sorted(pulleys.items()):
        e0 = _reference(axis)
        lines += [
            f'    <body name="pulley{i + 1}" pos="{_fmt(anchors[i])}">',
            f'      <joint name="swivel{i + 1}" type="hinge" axis="{_fmt(axis)}"/>',
            '      <inertial pos="0 0 0" mass="1e-3" diaginertia="1e-7 1e-7 1e-7"/>',
            f'      <geom name="wheel{i + 1}" type="cylinder" pos="{_fmt(r * e0)}" '
            f'zaxis="{_fmt(np.cross(axis, e0))}" size="{r!r} {r / 4!r}" contype="0" conaffinity="0"/>',
            f'      <site name="over{i + 1}" pos="{_fmt(r * e0 + 2.0 * r * axis)}" size="{r / 4!r}"/>',
            "    </body>",
            f'    <site name="inlet{i + 1}" pos="{_fmt(anchors[i] - INLET * axis)}" size="0.005"/>',
        ]
    for i in range(len(anchors)):
        if i not in pulleys:
            lines.append(f'    <site name="anchor{i + 1}" pos="{_fmt(anchors[i])}" size="0.005"/>')
    lines.append('    <body name="platform" pos="0 0 0">')
    if planar:
        lines += [
            '      <joint name="x" type="slide" axis="1 0 0"/>',
            '      <joint name="y" type="slide" axis="0 1 0"/>',
            '      <joint name="theta" type="hinge" axis="0 0 1"/>',
        ]
    else:
        lines.append('      <freejoint name="platform"/>')
    lines.append(f'      <inertial pos="{_fmt(a["com"])}" mass="{mass!r}" fullinertia="{_fmt(full)}"/>')
    for i, b in enumerate(attachments):
        lines.append(f'      <site name="attachment{i + 1}" pos="{_fmt(b)}" size="0.005"/>')
    lines += ["    </body>", "  </worldbody>", "  <tendon>"]
    for i in range(len(anchors)):
        lines.append(f'    <spatial name="cable{i + 1}" width="0.002">')
        if i in pulleys:
            lines += [
                f'      <site site="inlet{i + 1}"/>',
                f'      <geom geom="wheel{i + 1}" sidesite="over{i + 1}"/>',
            ]
        else:
            lines.append(f'      <site site="anchor{i + 1}"/>')
        lines += [f'      <site site="attachment{i + 1}"/>', "    </spatial>"]
    lines += [
        "  </tendon>",
        "  <!-- the control is the cable's tension (N): gear -1 pulls -->",
        "  <actuator>",
    ]
    for i, f_max in enumerate(a["f_max"]):
        rng = f"0 {float(f_max)!r}"
        lines.append(f'    <motor name="tension{i + 1}" tendon="cable{i + 1}" gear="-1" ctrlrange="{rng}"/>')
    lines += ["  </actuator>", "</mujoco>", ""]
    return "\n".join(lines)


@checked
def export_mjcf(robot_file: str | Path, out: str | Path) -> Path:
    """Write :func:`to_mjcf` of ``robot_file`` to ``out`` (its folder created); returns ``out``."""
    instance(out, "out", (str, Path))
    text = to_mjcf(robot_file)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text, encoding="utf-8")
    return out


@checked
def swivel_angles(
    robot_file: str | Path | dict[str, Any], poses: Any, *, source: str | None = None
) -> np.ndarray:
    """``(N, m)`` hinge angles of the exported pulleys at ``poses`` ``(N, n)`` (0 for a cable
    without a pulley): the swivel that turns each wheel's plane onto the platform point, as
    cablekit's inverse kinematics does. A platform point on a swivel axis is a
    :class:`DataError` (the pulley plane is undefined there)."""
    a, _ = _arguments(robot_file, source)
    return _swivels(a, signal(poses, "poses", ndim=2))


def _swivels(a: dict[str, Any], q: np.ndarray) -> np.ndarray:
    """:func:`swivel_angles` of the checked robot arguments ``a`` at poses ``q`` ``(N, n)``
    (vectorised over the poses)."""
    planar = a["motion"] == "planar"
    n = 3 if planar else 6
    if q.shape[1] != n:
        raise DataError(f"poses must have {n} columns for a {a['motion']} robot, got {q.shape[1]}")
    attachments = np.array(a["attachments"], dtype=float)
    anchors = np.array(a["anchors"], dtype=float)
    if planar:
        attachments[:, 2] = 0.0
        anchors[:, 2] = 0.0
    x, r = _rotations(a["motion"], q)
    out = np.zeros((len(q), len(anchors)))
    for i, _radius, ax in a["pulleys"]:
        axis = np.array(ax, dtype=float)
        v = x + r @ attachments[i] - anchors[i]
        perp = v - np.outer(v @ axis, axis)
        dist = np.linalg.norm(perp, axis=1)
        on_axis = ~(dist > 1e-12 * (1.0 + np.linalg.norm(v, axis=1)))
        if on_axis.any():
            k = int(np.flatnonzero(on_axis)[0])
            raise DataError(f"pose {k}: cable {i + 1}'s platform point is on its pulley's swivel axis")
        e = perp / dist[:, None]
        e0 = _reference(axis)
        out[:, i] = np.arctan2(np.cross(e0, e) @ axis, e @ e0)
    return out


@checked
def mujoco_state(
    robot_file: str | Path | dict[str, Any], pose: Any, *, source: str | None = None
) -> np.ndarray:
    """The exported model's ``qpos`` at ``pose`` (one pose, ``(n,)``): the swivel angles of its
    pulleys in cable order, then the platform's coordinates (planar ``x, y, θ``; spatial the
    free joint's position and unit quaternion ``w, x, y, z``)."""
    a, _ = _arguments(robot_file, source)
    q = signal(pose, "pose", ndim=1)
    if q.shape[0] != (3 if a["motion"] == "planar" else 6):
        raise DataError(f"pose must have {3 if a['motion'] == 'planar' else 6} coordinates, got {q.shape[0]}")
    angles = _swivels(a, q[None, :])[0]
    lead = [angles[int(i)] for i, _, _ in sorted(a["pulleys"])]
    if a["motion"] == "planar":
        return np.array([*lead, q[0], q[1], q[2]])
    _, r = _rotations("spatial", q[None, :])
    return np.array([*lead, *q[:3], *_quaternion(r[0])])


def _quaternion(r: np.ndarray) -> np.ndarray:
    """The unit quaternion ``w, x, y, z`` of rotation ``r`` (Shepperd's method)."""
    t = np.trace(r)
    if t > 0:
        s = 2.0 * np.sqrt(1.0 + t)
        q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        q = [0.0] * 4
        q[0] = (r[k, j] - r[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (r[j, i] + r[i, j]) / s
        q[1 + k] = (r[k, i] + r[i, k]) / s
    q = np.array(q)
    return q / np.linalg.norm(q)
