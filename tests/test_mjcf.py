"""The MuJoCo export of a parallel robot (issue #40 §3): MuJoCo, an independent implementation of
the same geometry, reads the exported MJCF and its tendon lengths and moment arms equal cablekit's
inverse kinematics and structure matrix over random poses, for the three shipped robots (one
planar, one spatial without pulleys, one spatial with swivelling pulleys); the tendon motors
driven by cablekit's tension distribution hold the platform still; bad robots and poses are
typed errors."""

from __future__ import annotations

import sys
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np
import pytest

import cablekit as ck
from cablekit._files import parse_toml
from cablekit.cdpr import shipped, shipped_names
from cablekit.cdpr.mjcf import INLET, export_mjcf, mujoco_state, swivel_angles, to_mjcf


def _path(name: str) -> Path:
    return Path(str(resources.files("cablekit.cdpr") / "robots" / f"{name}.toml"))


def _poses(robot: ck.cdpr.Robot, rng: np.random.Generator, n: int) -> np.ndarray:
    """Poses with every cable taut inside the frame: positions within the middle half of the
    anchors' box, orientations up to ±0.25 rad."""
    anchors, _ = robot.points()
    lo, hi = anchors.min(axis=0), anchors.max(axis=0)
    mid, half = (lo + hi) / 2, (hi - lo) / 4
    if robot.motion == "planar":
        xy = mid[:2] + half[:2] * rng.uniform(-1, 1, (n, 2))
        return np.hstack([xy, rng.uniform(-0.25, 0.25, (n, 1))])
    xyz = mid + half * rng.uniform(-1, 1, (n, 3))
    return np.hstack([xyz, rng.uniform(-0.25, 0.25, (n, 3))])


def _tendon_jacobian(m: mujoco.MjModel, d: mujoco.MjData) -> np.ndarray:
    """``∂l/∂v`` of every tendon, dense ``(ntendon, nv)`` (MuJoCo 3.3+ keeps it sparse)."""
    if hasattr(d, "ten_moment"):  # MuJoCo before 3.3: dense
        return np.array(d.ten_moment).reshape(m.ntendon, m.nv)
    jac = np.zeros((m.ntendon, m.nv))
    sparse = m if hasattr(m, "ten_J_rownnz") else d
    mujoco.mju_sparse2dense(jac, d.ten_J, sparse.ten_J_rownnz, sparse.ten_J_rowadr, sparse.ten_J_colind)
    return jac


@pytest.mark.parametrize("name", ["seed002_mini", "ipanema_like", "seed003_planar"])
def test_mujoco_reads_cablekits_cable_lengths_and_structure_matrix(name):
    robot = shipped(name)
    m = mujoco.MjModel.from_xml_string(to_mjcf(_path(name)))
    d = mujoco.MjData(m)
    swivels = [int(m.joint(j).name[6:]) - 1 for j in range(m.njnt) if m.joint(j).name.startswith("swivel")]
    inlet = np.zeros(robot.n_cables)
    inlet[swivels] = INLET
    assert (len(swivels) > 0) == (name == "seed002_mini")
    n_sw = len(swivels)
    poses = _poses(robot, np.random.default_rng(0), 100)
    kin = robot.inverse_kinematics(poses)
    for pose, length, structure in zip(poses, kin.length, kin.structure, strict=True):
        d.qpos[:] = mujoco_state(_path(name), pose)
        mujoco.mj_forward(m, d)
        # lengths: cablekit's (arc on the pulley + free length) plus the straight run into the wheel
        np.testing.assert_allclose(d.ten_length - inlet, length, rtol=1e-9, atol=0)
        jac = _tendon_jacobian(m, d)
        platform = jac[:, n_sw:]
        if robot.motion == "spatial":
            # the free joint's angular velocity is in the body frame: to the world frame
            rot = d.xmat[m.body("platform").id].reshape(3, 3)
            platform = np.hstack([platform[:, :3], platform[:, 3:] @ rot.T])
        # a tendon's moment is ∂l/∂q; a cable pulls: the structure matrix Aᵀ is its negative
        scale = np.abs(structure).max()
        np.testing.assert_allclose(-platform.T, structure, rtol=0, atol=1e-9 * scale)
        # each pulley faces the platform: its swivel does not change the length (first order)
        assert np.abs(jac[:, :n_sw]).max(initial=0.0) <= 1e-9 * scale


@pytest.mark.parametrize("name", ["seed002_mini", "seed003_planar"])
def test_cablekits_tensions_on_the_tendon_motors_hold_the_platform(name):
    """The platform's weight held by cablekit's tension distribution, applied as the exported
    motors' controls (tension in N): MuJoCo's platform does not accelerate. Without them it falls
    at g."""
    robot = shipped(name)
    m = mujoco.MjModel.from_xml_string(to_mjcf(_path(name)))
    d = mujoco.MjData(m)
    n_sw = sum(m.joint(j).name.startswith("swivel") for j in range(m.njnt))
    poses = _poses(robot, np.random.default_rng(1), 40)
    tensions = robot.distribute(poses)
    held = np.flatnonzero(tensions.feasible)
    assert len(held) >= 10, len(held)
    for k in held:
        pose = poses[k]
        d.qpos[:] = mujoco_state(_path(name), pose)
        d.qvel[:] = 0.0
        d.ctrl[:] = tensions.f[k]
        mujoco.mj_forward(m, d)
        assert np.abs(d.qacc[n_sw:]).max() <= 1e-6, d.qacc
        d.ctrl[:] = 0.0
        mujoco.mj_forward(m, d)
        g = np.abs(np.asarray(m.opt.gravity)).max()
        assert np.abs(d.qacc[n_sw : n_sw + 3]).max() == pytest.approx(g, rel=1e-9)


def test_the_command_writes_every_shipped_robot(tmp_path):
    from cablekit.cli import main

    for name in shipped_names():
        out = tmp_path / f"{name}.xml"
        assert main(["cdpr", "export-mjcf", name, "--out", str(out)]) == 0
        m = mujoco.MjModel.from_xml_path(str(out))
        assert m.ntendon == m.nu == shipped(name).n_cables
        assert out.read_text() == to_mjcf(_path(name))
    assert export_mjcf(_path("seed003_planar"), tmp_path / "sub" / "p.xml").exists()
    assert main(["cdpr", "export-mjcf", "no_such_robot"]) != 0


def _doc(**platform) -> dict:
    doc = parse_toml(_path("seed003_planar").read_text(), "planar")
    doc["platform"].update(platform)
    return doc


def test_bad_robots_and_poses_are_typed_errors():
    with pytest.raises(ck.DataError, match="mass > 0"):
        to_mjcf(_doc(mass=0.0), source="planar")
    with pytest.raises(ck.DataError, match="I_zz > 0"):
        to_mjcf(_doc(inertia=[0.0, 0.0, 0.0]), source="planar")
    bad = _doc()
    bad["cables"][0]["colour"] = "red"
    with pytest.raises(ck.DataError, match="colour"):
        to_mjcf(bad, source="planar")
    with pytest.raises(ck.DataError, match="3 columns"):
        swivel_angles(_path("seed003_planar"), np.zeros((2, 6)))
    with pytest.raises(ck.ParameterError, match="NaN"):
        mujoco_state(_path("seed002_mini"), np.array([0.0, 0.0, np.nan, 0.0, 0.0, 0.0]))
    # a platform point on a pulley's swivel axis: the pulley plane is undefined
    mini = parse_toml(_path("seed002_mini").read_text(), "mini")
    a, b = mini["cables"][4]["anchor"], mini["cables"][4]["attachment"]
    on_axis = np.array([a[0] - b[0], a[1] - b[1], 0.5, 0.0, 0.0, 0.0])
    with pytest.raises(ck.DataError, match="swivel axis"):
        swivel_angles(mini, on_axis[None, :], source="mini")
    with pytest.raises(ck.DTypeError):
        to_mjcf(3.0)  # type: ignore[arg-type]


def test_the_example_holds_the_platform_with_cablekits_tensions_in_mujoco():
    """examples/mujoco_cdpr.py: MuJoCo integrates the platform, cablekit's tension controller
    drives the tendon motors from a PD wrench; the platform, started 2 cm and 0.05 rad off,
    settles on its target with every tension within its bounds."""
    import importlib.util

    file = Path(__file__).resolve().parents[1] / "examples" / "mujoco_cdpr.py"
    spec = importlib.util.spec_from_file_location("mujoco_cdpr", file)
    assert spec is not None and spec.loader is not None
    example = importlib.util.module_from_spec(spec)
    sys.modules["mujoco_cdpr"] = example  # (its dataclass looks its module up)
    spec.loader.exec_module(example)
    s = example.run(seconds=1.5)
    assert s.position_error[0] > 0.03 and s.angle_error[0] == pytest.approx(0.05)
    assert s.position_error[-1] < 1e-4 and s.angle_error[-1] < 1e-3
    lo, hi = s.bounds
    assert (s.tensions >= lo - 1e-9).all() and (s.tensions <= hi + 1e-9).all()
