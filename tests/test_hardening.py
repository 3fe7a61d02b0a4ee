"""Regression tests of issue #20's fuzz findings: calls that hung holding the GIL, a panic that
reached Python, unbounded substeps, non-finite results from finite input, and unchecked NaN.

Calls that once hung run in a subprocess with a timeout, so a regression fails the test instead
of freezing the suite; the rest run in process.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import cablekit as ck
from cablekit.nn import MapMinMax
from cablekit.nn.export import write_weights

# ---- calls that hung (or looped for ever) -------------------------------------------------------

_RAVEN = "import numpy as np, cablekit as ck\nR3 = ck.CableTransmission.raven2(3)\n"


def _raven_with(**change) -> ck.CableTransmission:
    p = ck.CableTransmission.raven2(1).params()
    p.update(change)
    return ck.CableTransmission(**{k: v for k, v in p.items() if k != "n_links"})


HANGS = {
    # a NaN Jacobian sent the eigenvalue iteration into an endless loop holding the GIL
    "huge_state": ("ck.propose_step(R3, 1e-3, np.full(12, 1e154))", "NonFiniteResultError"),
    # a parameter that makes the Jacobian overflow at rest
    "tiny_gear_ratio": (
        "p = ck.CableTransmission.raven2(1).params(); p['gear_ratio'] = [1e-300]; "
        "ck.propose_step(ck.CableTransmission(**{k: v for k, v in p.items() if k != 'n_links'}), 1e-3)",
        "NonFiniteResultError",
    ),
    # advice of 2**64 - 1 substeps, then loops that never end
    "advice_for_huge_dt": ("ck.propose_step(R3, 1e300)", "ParameterError"),
    "rk4_substeps": ("R3.rk4_step(np.zeros(12), np.zeros(6), 1e-3, substeps=10**10)", "ParameterError"),
    "simulate_substeps": ("ck.simulate(R3, np.zeros((10, 6)), 1e-3, substeps=10**10)", "ParameterError"),
    "estimate_huge_dt": (
        "ck.estimate_joint_states(R3, np.zeros((10, 3)), np.zeros((10, 3)), 1e300)",
        "ParameterError",
    ),
}


@pytest.mark.parametrize("name", sorted(HANGS))
def test_calls_that_hung_now_end_with_a_typed_error(name):
    call, error = HANGS[name]
    prog = _RAVEN + textwrap.dedent(f"""
        try:
            {call}
        except ck.errors.{error} as e:
            print("typed:", type(e).__name__, e)
        else:
            print("no error")
    """)
    done = subprocess.run([sys.executable, "-c", prog], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith(f"typed: {error}"), done.stdout + done.stderr[-2000:]


def test_step_advice_is_capped_and_names_dt():
    r3 = ck.CableTransmission.raven2(3)
    with pytest.raises(ck.ParameterError, match="MAX_SUBSTEPS") as e:
        ck.propose_step(r3, 1e300)
    assert e.value.parameter == "dt"
    # the cap is the same number the integrator accepts
    adv = ck.propose_step(r3, 1e-3)
    assert 1 <= adv.substeps <= 100_000
    ck.simulate(r3, np.zeros((3, 6)), 1e-3, substeps=100_000)
    with pytest.raises(ck.ParameterError):
        ck.simulate(r3, np.zeros((3, 6)), 1e-3, substeps=100_001)


# ---- a panic that reached Python ---------------------------------------------------------------


def test_degenerate_run_time_base_is_not_a_panic():
    from cablekit._cablekit import JointProblem

    aj = ck.AntagonisticJoint.forceps_example()
    runs = [dict(dt=1e300, input=np.zeros(200), measured=np.zeros((200, 1)))]
    try:
        JointProblem(aj, [(0, 1.0, True)], runs, ["coulomb_friction"])
    except ck.InternalError as e:  # pragma: no cover - the regression
        pytest.fail(f"panic reached Python: {e}")
    except ck.CablekitError:
        pass
    # a time base that overflows is refused, naming the run
    runs = [dict(dt=1e307, input=np.zeros(200), measured=np.zeros((200, 1)))]
    with pytest.raises(ck.ParameterError, match="dt"):
        JointProblem(aj, [(0, 1.0, True)], runs, ["coulomb_friction"])


# ---- non-finite results from finite input ------------------------------------------------------


def test_model_evaluations_refuse_to_return_overflow():
    r3 = ck.CableTransmission.raven2(3)
    x = np.zeros(12)
    x[10] = 50.0  # the exponential cable law overflows
    with pytest.raises(ck.NonFiniteResultError) as e:
        r3.derivative(x, np.zeros(6))
    assert e.value.argument == "derivative"
    with pytest.raises(ck.CablekitError):
        r3.output(x, np.zeros(6))
    with pytest.raises(ck.CablekitError):
        r3.jacobian(x, np.zeros(6))
    with pytest.raises(ck.SimulationDivergedError):
        r3.rk4_step(x, np.zeros(6), 1e-3)


def test_capstan_overflow_and_huge_dt_are_errors():
    with pytest.raises(ck.NonFiniteResultError):
        ck.capstan_ratio(np.array([-1.0]), mu=10.0, wrap=100.0, smoothing=0.1)
    # moving forwards the same wrap attenuates to zero: finite, no error
    assert ck.capstan_ratio(np.array([1.0]), mu=10.0, wrap=100.0, smoothing=0.1)[0] == 0.0
    r1 = ck.CableTransmission.raven2(1)
    with pytest.raises(ck.ParameterError, match="dt"):
        ck.simulate(r1, np.zeros((3, 2)), 1e308)


def _net(tmp_path, w_scale=1.0, in_range=(-1.0, 1.0), name="n.safetensors"):
    rng = np.random.default_rng(0)
    return write_weights(
        tmp_path / name,
        [w_scale * rng.normal(size=(5, 2)), rng.normal(size=(1, 5))],
        [np.zeros(5), np.zeros(1)],
        ["tansig", "purelin"],
        MapMinMax(np.full(2, in_range[0]), np.full(2, in_range[1])),
        MapMinMax(np.zeros(1), np.ones(1)),
    )


def test_network_overflow_is_an_error_at_load_or_predict(tmp_path):
    net = ck.Mlp.load(_net(tmp_path))
    far = np.array([1e308, -1e308])  # the first layer's net input is inf − inf
    with pytest.raises(ck.NonFiniteResultError):
        net.predict(far)
    with pytest.raises(ck.NonFiniteResultError, match=r"flat index 2"):
        net.predict(np.vstack([np.zeros((2, 2)), far]))
    out = np.zeros(1)
    with pytest.raises(ck.NonFiniteResultError):
        net.predict_into(far, out)
    # saturated, not overflowed: a far input on one side is a finite answer
    assert np.isfinite(net.predict(np.full(2, 1e308))).all()
    # finite weights that overflow once folded, or on the training range itself, never load
    with pytest.raises(ck.errors.WeightsValueError):
        ck.Mlp.load(_net(tmp_path, w_scale=1e308, name="big.safetensors"))
    with pytest.raises(ck.errors.WeightsValueError):
        ck.Mlp.load(_net(tmp_path, in_range=(0.0, 1e-308), name="narrow.safetensors"))


# ---- NaN input and parameters ------------------------------------------------------------------

NAN_CALLS = {
    "coulomb_friction": lambda v: ck.coulomb_friction(v, coulomb=1.0, smoothing=0.1),
    "stribeck_friction": lambda v: ck.stribeck_friction(
        v, coulomb=1.0, static_level=1.5, stribeck_velocity=0.1, smoothing=0.01
    ),
    "capstan_ratio": lambda v: ck.capstan_ratio(v, mu=0.1, wrap=1.0, smoothing=0.1),
    "dahl_rate(force)": lambda v: ck.dahl_rate(v, np.ones_like(v), sigma0=1.0, coulomb=1.0),
    "dahl_rate(v)": lambda v: ck.dahl_rate(np.ones_like(v), v, sigma0=1.0, coulomb=1.0),
    "cable_tension(stretch)": lambda v: ck.cable_tension(v, np.zeros_like(v), stiffness=1e3, pretension=10.0),
    "cable_tension(rate)": lambda v: ck.cable_tension(np.zeros_like(v), v, stiffness=1e3, pretension=10.0),
}


@settings(max_examples=40, deadline=None)
@given(
    name=st.sampled_from(sorted(NAN_CALLS)),
    n=st.integers(1, 20),
    at=st.integers(0, 19),
    bad=st.sampled_from([np.nan, np.inf, -np.inf]),
)
def test_curves_refuse_non_finite_input_and_name_the_element(name, n, at, bad):
    v = np.linspace(-1.0, 1.0, n)
    v[at % n] = bad
    with pytest.raises(ck.NotFiniteError) as e:
        NAN_CALLS[name](v)
    assert e.value.index == at % n


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_transmission_maps_refuse_non_finite_input(bad):
    r2 = ck.CableTransmission.raven2(2)
    for call in (
        lambda: r2.energy(np.full(8, bad)),
        lambda: r2.motor_to_joint(np.array([0.0, bad])),
        lambda: r2.joint_to_motor(np.array([bad, 0.0])),
    ):
        with pytest.raises(ck.NotFiniteError):
            call()
    q = np.zeros((40, 2))
    q[37, 1] = bad
    with pytest.raises(ck.NotFiniteError, match="row 37, column 1"):
        ck.kinematic_joint_angles(r2, q)


def test_kinematic_joint_angles_is_the_core_map_row_by_row():
    r3 = ck.CableTransmission.raven2(3)
    q_m = np.random.default_rng(1).normal(size=(25, 3))
    rows = np.array([r3.motor_to_joint(np.ascontiguousarray(r)) for r in q_m])
    np.testing.assert_array_equal(ck.kinematic_joint_angles(r3, q_m), rows)
    # and it inverts T (reference: NumPy's solve), 1e-12 of the angles
    np.testing.assert_allclose(rows, np.linalg.solve(r3.transmission_matrix, q_m.T).T, atol=1e-12)
