"""Physics checks that a wrong model would fail (energy, equilibrium, slack, capstan, coupling)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import cablekit as ck


def _conservative(law="exponential", length_scale=0.05):
    """2-link coupled transmission without friction, damping or slack (high pretension)."""
    return ck.CableTransmission(
        motor_inertia=[2e-4, 3e-4],
        gear_ratio=[10.0, 12.0],
        capstan_radius=[5e-3, 6e-3],
        joint_radius=[0.05, 0.04],
        link_inertia=[0.05, 0.03],
        cable_stiffness=[2e4, 1e4],
        cable_damping=0.0,
        pretension=1e3,
        cable_law=law,
        length_scale=length_scale,
        gravity_amplitude=[1.5, 0.7],
        gravity_offset=[0.2, -0.4],
        coupling=[[0.0, 0.0], [0.15, 0.0]],
    )


@pytest.mark.parametrize("law", ["linear", "exponential"])
def test_rk4_energy_drift_is_bounded_and_shrinks_as_dt4(law):
    """RK4 is fourth order: the energy error over a fixed time shrinks at least as dt⁴ (for a
    nearly linear oscillator the leading amplitude error is O(dt⁵), so the observed order may be
    up to ~5); a second-order or wrong integrator fails the lower bound."""
    model = _conservative(law)
    assert ck.propose_step(model, 8e-4).substeps == 1
    x0 = np.array([10.0, 0.0, 0.0, 0.0, 0.0, 30.0, 0.0, 0.0])  # stretched cables, moving motor
    drifts = []
    for dt in (8e-4, 4e-4, 2e-4):
        steps = round(0.5 / dt)
        res = ck.simulate(model, np.zeros((steps, model.n_inputs)), dt, x0)
        e = np.array([model.energy(x) for x in res.states[:: max(1, steps // 200)]])
        drifts.append(np.max(np.abs(e - e[0])) / abs(e[0]))
        # no side ever slack, otherwise energy conservation is not the claim
        assert np.min(res["tension_b1"]) > 0 and np.min(res["tension_b2"]) > 0
    assert drifts[0] < 1e-3
    order = np.log2(drifts[0] / drifts[1]), np.log2(drifts[1] / drifts[2])
    assert all(3.8 < o < 6.2 for o in order), (drifts, order)


def test_friction_and_damping_dissipate():
    p = _conservative().params()
    p.update(cable_damping=[50.0, 50.0], link_coulomb=[0.05, 0.05], link_viscous=[1e-3, 1e-3])
    model = ck.CableTransmission(**p)
    x0 = np.array([10.0, 0.0, 0.0, 0.0, 0.0, 30.0, 0.0, 0.0])
    res = ck.simulate(model, np.zeros((2000, model.n_inputs)), 1e-4, x0)
    e = np.array([model.energy(x) for x in res.states])
    assert np.all(np.diff(e) <= 1e-9 * abs(e[0]))
    assert e[-1] < e[0] - 1e-3 * abs(e[0])


@settings(max_examples=40)
@given(
    theta=st.floats(-0.8, 0.8),
    stretch=st.floats(-2e-4, 2e-4),
    k=st.floats(1e3, 1e5),
    t0=st.floats(5.0, 40.0),
)
def test_static_equilibrium_tensions_are_pretension_plus_minus_k_stretch(theta, stretch, k, t0):
    joint = ck.AntagonisticJoint(radius=3e-3, stiffness=k, inertia=1e-5, pretension=t0, damping=5.0)
    x_m = 3e-3 * theta + stretch
    y = joint.output(np.array([theta, 0.0]), np.array([x_m, 0.0]))
    expect_drive, expect_return = max(0.0, t0 + k * stretch), max(0.0, t0 - k * stretch)
    np.testing.assert_allclose(y[2:4], [expect_drive, expect_return], rtol=1e-12, atol=1e-9)
    # and the joint settles where both tensions are equal: simulate a held motor position
    damped = ck.AntagonisticJoint(
        radius=3e-3, stiffness=k, inertia=1e-5, pretension=t0, damping=50.0, viscous=1e-4
    )
    u = np.tile([x_m, 0.0], (10000, 1))
    x0 = np.array([x_m / 3e-3 + 0.01, 0.0])
    res = ck.simulate(damped, u, 1e-4, x0, substeps=ck.propose_step(damped, 1e-4).substeps)
    np.testing.assert_allclose(res["theta"][-1], x_m / 3e-3, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(res["tension_joint_drive"][-1], t0, rtol=1e-6)


def test_slack_tension_never_negative_and_slack_happens():
    joint = ck.AntagonisticJoint(
        radius=3e-3, stiffness=2e4, inertia=1e-5, pretension=2.0, damping=2.0, viscous=1e-3
    )
    t = np.arange(4000) * 1e-4
    x_m = 2e-3 * np.sin(2 * np.pi * 5 * t)  # far beyond the 0.1 mm the pretension can take up
    u = np.ascontiguousarray(np.column_stack([x_m, 2e-3 * 2 * np.pi * 5 * np.cos(2 * np.pi * 5 * t)]))
    res = ck.simulate(joint, u, 1e-4, substeps=4, hold="foh")
    for name in (
        "tension_joint_drive",
        "tension_joint_return",
        "tension_motor_drive",
        "tension_motor_return",
    ):
        assert np.min(res[name]) >= 0.0
    assert np.mean(res["tension_joint_return"] == 0.0) > 0.1  # it did go slack
    # transmission: a loop pulling against a 20 N·m load needs γ ≈ 317 N > 2·T₀ = 80 N, so the
    # return side goes slack, and no side ever pushes
    model = ck.CableTransmission.raven2(1)
    res = ck.simulate(model, np.tile([0.68, -20.0], (3000, 1)), 1e-4)
    assert np.min(res["tension_b1"]) == 0.0 and np.min(res["tension_a1"]) >= 0.0


@pytest.mark.parametrize("mu,wrap", [(0.05, 2 * np.pi), (0.2, np.pi / 2), (0.1, 3.0)])
def test_capstan_ratio_at_steady_sliding(mu, wrap):
    joint = ck.AntagonisticJoint(
        radius=3e-3,
        stiffness=2e4,
        inertia=1e-5,
        pretension=20.0,
        damping=2.0,
        viscous=1e-4,
        capstan_mu=mu,
        capstan_wrap=wrap,
        capstan_smoothing=1e-6,
    )
    v = 0.01  # steady hauling speed, 10 mm/s, 10^4 × the smoothing velocity
    t = np.arange(2000) * 1e-4
    u = np.ascontiguousarray(np.column_stack([v * t, np.full_like(t, v)]))
    res = ck.simulate(joint, u, 1e-4, substeps=2, hold="foh")
    ratio_drive = res["tension_motor_drive"][-1] / res["tension_joint_drive"][-1]
    ratio_return = res["tension_joint_return"][-1] / res["tension_motor_return"][-1]
    np.testing.assert_allclose([ratio_drive, ratio_return], np.exp(mu * wrap), rtol=1e-8)
    # reversing the motion flips which side carries the loss
    u[:, 1] *= -1
    y = joint.output(res.states[-1], u[-1])
    np.testing.assert_allclose(y[0] / y[2], np.exp(-mu * wrap), rtol=1e-8)


def test_coupling_matrix_reproduces_eq_2_8():
    model = ck.CableTransmission.raven2(3)
    q_l = np.array([0.7, 1.4, 0.35])
    tr1 = 63.095e-3 * 12.25 / 5.675e-3
    tr2 = 56.297e-3 * 12.25 / 5.675e-3
    tr3 = 12.25 / 5.675e-3
    expected = [
        tr1 * q_l[0],
        tr2 * (q_l[1] + 0.14545 * q_l[0]),
        tr3 * (q_l[2] + 0.0077973826 * q_l[0] + 0.008077387 * q_l[1]),
    ]
    np.testing.assert_allclose(model.joint_to_motor(q_l), expected, rtol=1e-12)
    np.testing.assert_allclose(model.motor_to_joint(np.asarray(expected)), q_l, rtol=1e-12)
    # on the rest-length manifold q_m = T q_l every loop sits at pretension and nothing moves
    x = np.zeros(12)
    x[0::4], x[2::4] = expected, q_l
    y = model.output(x, np.zeros(6))
    np.testing.assert_allclose(y[2::5], [40.0, 40.0, 11.0], rtol=1e-12)
    np.testing.assert_allclose(model.derivative(x, np.zeros(6)), 0.0, atol=1e-9)
    # pulling cable 2 alone loads joint 1 through C01: Γ = Tᵀ (ρ ⊙ γ)
    x[4] += 0.01
    y = model.output(x, np.zeros(6))
    gamma2 = y[7] - y[8]
    rho = 5.675e-3 / 12.25
    np.testing.assert_allclose(y[4::5][:2], [0.14545 * tr2 * rho * gamma2, tr2 * rho * gamma2], rtol=1e-12)


def test_propose_step_is_right_about_stability():
    # a linear, stiff, well-damped cable drive: its fastest mode is a real eigenvalue, so RK4 with
    # steps past the advised limit really diverges (smoothed Coulomb modes only chatter)
    model = ck.CableTransmission(
        motor_inertia=1e-4,
        gear_ratio=10.0,
        capstan_radius=5e-3,
        joint_radius=1.0,
        joint_kind=["prismatic"],
        link_inertia=0.05,
        cable_stiffness=2e4,
        cable_damping=2000.0,
        pretension=1e4,
    )
    adv = ck.propose_step(model, 1e-3)
    assert adv.substeps > 2 and adv.stiffest_eigenvalue.real < 0
    u = np.zeros((400, 2))
    u[:, 0] = 0.05
    res = ck.simulate(model, u, 1e-3, substeps=adv.substeps)
    fine = ck.simulate(model, u, 1e-3, substeps=2 * adv.substeps)
    np.testing.assert_allclose(res.states, fine.states, rtol=1e-6, atol=1e-9 * np.max(np.abs(fine.states)))
    # past the limit the run is wrong: non-finite (reported with its step) or, once slack bounds
    # the unstable mode, visibly off the converged answer
    coarse = ck.simulate(model, u, 1e-3, substeps=adv.substeps // 2)
    assert np.max(np.abs(coarse.states - fine.states)) > 1e-2 * np.max(np.abs(fine.states))
    with pytest.raises(ck.SimulationDivergedError) as info:
        ck.simulate(model, u, 1e-3, substeps=adv.substeps // 4)
    assert info.value.step > 0 and info.value.time == pytest.approx(info.value.step * 1e-3)
