"""Bad input gets a specific, typed error that says what and where."""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import cablekit as ck


@pytest.fixture(scope="module")
def raven():
    return ck.CableTransmission.raven2(3)


def test_hierarchy_is_catchable_as_builtins():
    assert issubclass(ck.ShapeError, ValueError) and issubclass(ck.ShapeError, ck.CablekitError)
    assert issubclass(ck.DTypeError, TypeError)
    assert issubclass(ck.SimulationDivergedError, ArithmeticError)


@given(rows=st.integers(1, 5), cols=st.integers(0, 12).filter(lambda c: c != 6))
def test_wrong_input_columns(rows, cols):
    model = ck.CableTransmission.raven2(3)
    with pytest.raises(ck.ShapeError, match=r"\(T, 6\)"):
        ck.simulate(model, np.zeros((rows, cols)), 1e-3)


def test_wrong_ndim_dtype_layout_and_type(raven):
    with pytest.raises(ck.ShapeError, match="2-D"):
        ck.simulate(raven, np.zeros(6), 1e-3)
    with pytest.raises(ck.ShapeError, match="at least one row"):
        ck.simulate(raven, np.zeros((0, 6)), 1e-3)
    with pytest.raises(ck.DTypeError, match="float32"):
        ck.simulate(raven, np.zeros((3, 6), dtype=np.float32), 1e-3)
    with pytest.raises(ck.DTypeError, match="list"):
        ck.simulate(raven, [[0.0] * 6], 1e-3)
    with pytest.raises(ck.LayoutError, match="C-contiguous"):
        ck.simulate(raven, np.zeros((3, 12))[:, ::2], 1e-3)
    with pytest.raises(ck.LayoutError):
        ck.simulate(raven, np.asfortranarray(np.zeros((3, 6))), 1e-3)
    with pytest.raises(ck.ShapeError, match="x0"):
        ck.simulate(raven, np.zeros((3, 6)), 1e-3, np.zeros(11))
    with pytest.raises(ck.ShapeError, match=r"x must have shape \(12,\)"):
        raven.derivative(np.zeros(4), np.zeros(6))


@given(row=st.integers(0, 9), col=st.integers(0, 5), bad=st.sampled_from([np.nan, np.inf, -np.inf]))
def test_non_finite_inputs_name_the_element(row, col, bad):
    model = ck.CableTransmission.raven2(3)
    u = np.zeros((10, 6))
    u[row, col] = bad
    with pytest.raises(ck.NotFiniteError, match=f"row {row}, column {col}") as info:
        ck.simulate(model, u, 1e-3)
    assert info.value.argument == "inputs" and info.value.index == row * 6 + col


def test_non_finite_state(raven):
    x = np.zeros(12)
    x[5] = np.nan
    with pytest.raises(ck.NotFiniteError, match="x0"):
        ck.simulate(raven, np.zeros((3, 6)), 1e-3, x)
    with pytest.raises(ck.NotFiniteError, match="x contains"):
        raven.derivative(x, np.zeros(6))


@pytest.mark.parametrize("dt", [0.0, -1e-3, np.nan, np.inf])
def test_bad_dt(raven, dt):
    with pytest.raises(ck.ParameterError, match="dt"):
        ck.simulate(raven, np.zeros((3, 6)), dt)


def test_bad_substeps_and_hold(raven):
    with pytest.raises(ck.ParameterError, match="substeps"):
        ck.simulate(raven, np.zeros((3, 6)), 1e-3, substeps=0)
    with pytest.raises(ck.ParameterError, match="hold"):
        ck.simulate(raven, np.zeros((3, 6)), 1e-3, hold="cubic")
    with pytest.raises(OverflowError):
        ck.simulate(raven, np.zeros((3, 6)), 1e-3, substeps=-1)


BASE = dict(
    motor_inertia=1e-4,
    gear_ratio=10.0,
    capstan_radius=5e-3,
    joint_radius=0.05,
    link_inertia=0.1,
    cable_stiffness=1e4,
)


@pytest.mark.parametrize(
    "key,value,where",
    [
        ("cable_stiffness", -1.0, "links[0].cable_stiffness"),
        ("cable_stiffness", 0.0, "links[0].cable_stiffness"),
        ("motor_inertia", 0.0, "links[0].motor_inertia"),
        ("link_inertia", -0.1, "links[0].link_inertia"),
        ("gear_ratio", np.nan, "links[0].gear_ratio"),
        ("capstan_radius", np.inf, "links[0].capstan_radius"),
        ("cable_damping", -1.0, "links[0].cable_damping"),
        ("pretension", -5.0, "links[0].pretension"),
        ("motor_coulomb", -0.1, "links[0].motor.coulomb"),
        ("link_smoothing", 0.0, "links[0].link.smoothing"),
    ],
)
def test_bad_transmission_parameters(key, value, where):
    with pytest.raises(ck.ParameterError) as info:
        ck.CableTransmission(**{**BASE, key: value})
    assert info.value.parameter == where
    assert where in str(info.value)


def test_bad_transmission_structure():
    with pytest.raises(ck.ShapeError, match=r"link_inertia: expected 1 or 3 values .*got 2") as e:
        ck.CableTransmission(**{**BASE, "gear_ratio": [1.0, 2.0, 3.0], "link_inertia": [1.0, 2.0]})
    assert e.value.argument == "link_inertia"
    with pytest.raises(ck.ShapeError, match="1 to 3"):
        ck.CableTransmission(**{**BASE, "gear_ratio": [1.0, 2.0, 3.0, 4.0]})
    with pytest.raises(ck.ParameterError, match="lower-triangular"):
        ck.CableTransmission(**{**BASE, "gear_ratio": [10.0, 10.0], "coupling": [[0.0, 0.1], [0.0, 0.0]]})
    with pytest.raises(ck.ParameterError, match="cable_law"):
        ck.CableTransmission(**{**BASE, "cable_law": "quadratic"})
    with pytest.raises(ck.ParameterError, match="joint_kind"):
        ck.CableTransmission(**{**BASE, "joint_kind": ["helical"]})
    with pytest.raises(ck.ShapeError, match="1 to 3"):
        ck.CableTransmission.raven2(4)


def test_bad_antagonistic_parameters():
    ok = dict(radius=3e-3, stiffness=1e4, inertia=1e-5)
    with pytest.raises(ck.ParameterError, match=re.escape("drive.cable_stiffness")):
        ck.AntagonisticJoint(**{**ok, "stiffness": -1.0})
    with pytest.raises(ck.ParameterError, match=re.escape("return.cable_stiffness")):
        ck.AntagonisticJoint(**ok, stiffness_return=0.0)
    with pytest.raises(ck.ParameterError, match="radius"):
        ck.AntagonisticJoint(**{**ok, "radius": 0.0})
    with pytest.raises(ck.ParameterError, match="contact"):
        ck.AntagonisticJoint(**ok, contact_angle=0.3)
    with pytest.raises(ck.ParameterError, match=re.escape("contact.stiffness")):
        ck.AntagonisticJoint(**ok, contact_angle=0.3, contact_stiffness=-1.0, contact_lever_arm=0.01)
    with pytest.raises(ck.ParameterError, match="capstan_mu"):
        ck.AntagonisticJoint(**ok, capstan_mu=-0.1)
    with pytest.raises(ck.ParameterError, match=re.escape("dahl.sigma0")):
        ck.DahlElement(sigma0=0.0, coulomb=1.0)


def test_divergence_reports_step_not_nan(raven):
    u = np.zeros((3000, 6))
    u[:, 2] = 0.5
    with pytest.raises(ck.SimulationDivergedError, match="step") as info:
        ck.simulate(raven, u, 5e-3)
    assert 0 < info.value.step < 3000


def test_servo_errors(raven):
    refs = np.zeros((10, 6))
    with pytest.raises(ck.ShapeError, match="controller"):
        ck.simulate_servo(raven, refs, 1e-3, ck.MotorPD.raven2(2))
    with pytest.raises(ck.ShapeError, match="external"):
        ck.simulate_servo(raven, refs, 1e-3, ck.MotorPD.raven2(3), external=np.zeros((9, 3)))
    with pytest.raises(ck.ParameterError, match="torque_limit"):
        ck.simulate_servo(raven, refs, 1e-3, ck.MotorPD((0.3,) * 3, (0.01,) * 3, (0.5, 0.0, 0.5)))


def test_constructor_keywords_are_checked_by_the_core_and_named():
    """The model constructors take their keywords to the core's specs: a misspelt keyword is a
    ParameterError listing the known ones, a value of the wrong kind a DTypeError naming it (both
    used to be bare TypeErrors from the binding)."""
    with pytest.raises(ck.ParameterError, match="gear_ration") as e:
        ck.CableTransmission(**{**BASE, "gear_ration": 2.0})
    assert "gear_ratio" in str(e.value)
    wrong = (("cable_law", 3.0), ("length_scale", [1.0, 2.0]), ("coupling", "none"), ("joint_kind", 1.0))
    for key, value in wrong:
        with pytest.raises(ck.DTypeError) as e:
            ck.CableTransmission(**{**BASE, key: value})
        assert e.value.argument == key
    with pytest.raises(ck.DTypeError) as e:
        ck.CableTransmission(**{**BASE, "gear_ratio": {"a": 1}})
    assert e.value.argument == "gear_ratio"
    joint = ck.AntagonisticJoint.forceps_example().params()
    with pytest.raises(ck.DTypeError) as e:
        ck.AntagonisticJoint(**{**joint, "stiffness": [1.0, 2.0]})
    assert e.value.argument == "stiffness"
    with pytest.raises(ck.ParameterError, match="radiuss"):
        ck.AntagonisticJoint(**{**joint, "radiuss": 1.0})
    # None means "left out": the core's default applies, as before
    a = ck.CableTransmission(**{**BASE, "cable_damping": None})
    assert a.params()["cable_damping"] == [0.0] * len(a.params()["gear_ratio"])


def _filter(model, *, x0=None, P0=None, R=None, dt=1e-3, states=(0,)):
    x0 = np.zeros(12) if x0 is None else x0
    P0 = np.eye(12) if P0 is None else P0
    R = np.eye(len(states)) if R is None else R
    return ck.SrUkf(model, x0, P0, np.eye(12), R, dt=dt, states=list(states))


@pytest.mark.parametrize(
    ("call", "argument"),
    [
        (lambda m: m.derivative(np.zeros(3), np.zeros(6)), "x"),
        (lambda m: m.derivative(np.zeros(12), np.zeros(6, dtype=np.float32)), "u"),
        (lambda m: m.derivative(np.zeros(12), np.zeros((6, 2))[:, 0]), "u"),
        (lambda m: _filter(m, R=np.eye(2), states=[0, 1, 2]), "R"),
        (lambda m: _filter(m, P0=np.eye(12)[:, :5]), "P0"),
        (lambda m: _filter(m, x0=np.zeros(11)), "x0"),
        (lambda m: _filter(m, dt=-1.0), "dt"),
    ],
)
def test_argument_errors_name_their_argument(call, argument):
    """Every shape, dtype, layout and parameter error carries ``.argument``."""
    with pytest.raises(ck.CablekitError) as e:
        call(ck.CableTransmission.raven2(3))
    assert e.value.argument == argument, str(e.value)
