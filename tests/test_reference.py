"""Bindings vs the pure-NumPy references in tests/reference (written from the equations).

Tolerances (stated once, used everywhere):
* one evaluation of f, h or one RK4 sample step: |rust − ref| ≤ 1e-12 · scale per component, where
  scale is the magnitude of the terms the component sums (so cancellation cannot hide or fake a
  mismatch; a wrong sign, factor or coupling index is off by O(scale));
* a 1 s trajectory: |rust − ref| ≤ 1e-9 · max_t |ref| per column (+1e-12 of the global scale).
  Stick–slip through a smoothed Coulomb term can make a trajectory ill-conditioned (a 1e-15
  change of x0 moves it by more than 1e-9); such draws are measured with the Rust simulator
  itself and discarded, because no implementation can meet 1e-9 on them.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import cablekit as ck
from tests.reference import antagonistic as ar
from tests.reference import friction as fr
from tests.reference import rk4
from tests.reference import transmission as trf
from tests.strategies import (
    antagonistic_params,
    antagonistic_point,
    transmission_params,
    transmission_point,
)

EVAL_RTOL = 1e-12
TRAJ_RTOL = 1e-9


def conditioning(model, u, dt, x0, substeps, hold):
    """Relative change of the Rust trajectory when x0 and every input sample move by ~1e-15
    relative: rounding enters at every step, and a locally unstable segment (Stribeck friction's
    negative slope is negative damping) amplifies it whatever the initial state."""
    a = ck.simulate(model, u, dt, x0, substeps=substeps, hold=hold).states
    u2 = np.ascontiguousarray(u * (1 + 1e-15 * np.cos(np.arange(u.size)).reshape(u.shape)))
    b = ck.simulate(model, u2, dt, x0 * (1 + 1e-15) + 1e-300, substeps=substeps, hold=hold).states
    return float(np.max(np.max(np.abs(a - b), axis=0) / (np.max(np.abs(a), axis=0) + 1e-300)))


def assert_trajectories_match(res, xs, ys):
    for got, want, name in ((res.states, xs, "states"), (res.outputs, ys, "outputs")):
        col = np.max(np.abs(want), axis=0)
        bound = TRAJ_RTOL * col + 1e-12 * np.max(col)
        err = np.max(np.abs(got - want), axis=0)
        assert np.all(err <= bound), f"{name}: err {err} > bound {bound}"


def rk4_scale(f, scale_fn, x, u0, u1, h, velocity_of=None):
    """|x| + h · (largest term magnitude over the four RK4 stage evaluations).

    `velocity_of` maps a position component to the state that is its derivative: at stages
    2–4 that derivative is a stage velocity `v + c·h·k`, whose rounding is set by the terms of
    `k` (forces that cancel), not by the velocity's own size, so c·h times the velocity's
    term scale of the stage before is added to the position's."""
    k1 = f(x, u0)
    um = 0.5 * (np.asarray(u0) + np.asarray(u1))
    k2 = f(x + h / 2 * k1, um)
    k3 = f(x + h / 2 * k2, um)
    stages = [(x, u0), (x + h / 2 * k1, um), (x + h / 2 * k2, um), (x + h * k3, u1)]
    scales = [np.array(scale_fn(xs, us), dtype=float) for xs, us in stages]
    for j, c in ((1, 0.5), (2, 0.5), (3, 1.0)):
        for pos, vel in (velocity_of or {}).items():
            scales[j][pos] += c * h * scales[j - 1][vel]
    return np.abs(x) + h * np.max(scales, axis=0)


def assert_scaled(actual, expected, scale, rtol, what=""):
    actual, expected, scale = map(np.asarray, (actual, expected, scale))
    err = np.abs(actual - expected)
    bound = rtol * (np.abs(expected) + scale) + 1e-300
    worst = int(np.argmax(err / bound))
    assert np.all(err <= bound), (
        f"{what}: component {worst}: rust={actual.flat[worst]!r} ref={expected.flat[worst]!r} "
        f"err={err.flat[worst]:.3e} bound={bound.flat[worst]:.3e}"
    )


# ---- friction and cable laws --------------------------------------------------------------------

speeds = st.lists(st.floats(-100, 100, allow_nan=False), min_size=1, max_size=50).map(np.array)


@given(v=speeds, fc=st.floats(0, 10), eps=st.floats(1e-4, 1.0))
def test_coulomb_matches_reference(v, fc, eps):
    got = ck.coulomb_friction(v, coulomb=fc, smoothing=eps)
    np.testing.assert_allclose(got, fr.coulomb_viscous(v, fc, 0.0, eps), rtol=1e-14, atol=1e-300)


@given(
    v=speeds,
    fc=st.floats(0, 5),
    fs=st.floats(0, 10),
    vs=st.floats(1e-3, 1.0),
    delta=st.floats(0.5, 3.0),
    b=st.floats(0, 1),
    eps=st.floats(1e-4, 1e-1),
)
def test_stribeck_matches_reference(v, fc, fs, vs, delta, b, eps):
    got = ck.stribeck_friction(
        v, coulomb=fc, static_level=fs, stribeck_velocity=vs, exponent=delta, viscous=b, smoothing=eps
    )
    scale = fs + fc + np.abs(b * v)
    assert_scaled(got, fr.stribeck(v, fc, fs, vs, delta, b, eps), scale, 1e-13, "stribeck")


@given(v=speeds, mu=st.floats(0, 0.5), wrap=st.floats(0, 10), eps=st.floats(1e-5, 1e-1))
def test_capstan_matches_reference(v, mu, wrap, eps):
    got = ck.capstan_ratio(v, mu=mu, wrap=wrap, smoothing=eps)
    np.testing.assert_allclose(got, fr.capstan_ratio(v, mu, wrap, eps), rtol=1e-13)


@given(
    data=st.data(),
    sigma0=st.floats(1.0, 1e5),
    fc=st.floats(0.01, 10),
    n=st.floats(0.5, 3.0),
)
def test_dahl_rate_matches_reference(data, sigma0, fc, n):
    f = data.draw(st.lists(st.floats(-2 * fc, 2 * fc), min_size=1, max_size=30).map(np.array))
    v = data.draw(st.lists(st.floats(-1, 1), min_size=len(f), max_size=len(f)).map(np.array))
    got = ck.dahl_rate(f, v, sigma0=sigma0, coulomb=fc, exponent=n)
    np.testing.assert_allclose(got, fr.dahl_rate(f, v, sigma0, fc, n), rtol=1e-13, atol=1e-300)


@given(
    data=st.data(),
    law=st.sampled_from(["linear", "exponential"]),
    k=st.floats(1e2, 1e6),
    ell=st.floats(1e-2, 1.0),
    c=st.floats(0, 100),
    t0=st.floats(0, 100),
)
def test_cable_tension_matches_reference(data, law, k, ell, c, t0):
    s = data.draw(st.lists(st.floats(-0.01, 0.01), min_size=1, max_size=30).map(np.array))
    sd = data.draw(st.lists(st.floats(-1, 1), min_size=len(s), max_size=len(s)).map(np.array))
    got = ck.cable_tension(s, sd, stiffness=k, damping=c, pretension=t0, law=law, length_scale=ell)
    ref = fr.run_tension(s, sd, law, k, ell, c, t0)
    assert np.all(got >= 0.0)
    scale = t0 + np.abs(fr.elastic(s, law, k, ell)) + np.abs(c * sd)
    assert_scaled(got, ref, scale, 1e-13, "tension")


# ---- transmission -------------------------------------------------------------------------------


@settings(max_examples=150)
@given(data=st.data())
def test_transmission_derivative_output_and_step(data):
    p = data.draw(transmission_params())
    model = ck.CableTransmission(**p)
    ref = trf.TransmissionRef(p)
    x, u = data.draw(transmission_point(p))
    assert_scaled(
        model.derivative(x, u), ref.derivative(x, u), trf.derivative_scale(ref, x, u), EVAL_RTOL, "f"
    )
    assert_scaled(model.output(x, u), ref.output(x, u), trf.output_scale(ref, x), EVAL_RTOL, "h")
    dt = data.draw(st.sampled_from([1e-6, 1e-5, 1e-4]))
    got = model.rk4_step(x, u, dt)
    want = rk4.advance(ref.derivative, x, u, u, dt, 1)
    # states per link: motor angle, motor velocity, joint position, joint velocity
    velocity_of = {4 * i + k: 4 * i + k + 1 for i in range(len(x) // 4) for k in (0, 2)}
    scale = rk4_scale(
        ref.derivative,
        lambda xs, us: trf.derivative_scale(ref, xs, us),
        x,
        u,
        u,
        dt,
        velocity_of,
    )
    assert_scaled(got, want, scale, EVAL_RTOL, "rk4 step")


@settings(max_examples=8)
@given(data=st.data())
def test_transmission_one_second_trajectory(data):
    p = data.draw(transmission_params(stiffness=(1e3, 1e5), min_length_scale=0.1))
    model = ck.CableTransmission(**p)
    ref = trf.TransmissionRef(p)
    x0, _ = data.draw(transmission_point(p))
    dt = 1e-3
    advice = ck.propose_step(model, dt, x0, np.zeros(model.n_inputs), safety=0.5)
    assume(advice.substeps <= 12)
    t = np.arange(1000) * dt
    n = model.n_links
    freqs = np.array(data.draw(st.lists(st.floats(0.2, 3.0), min_size=2 * n, max_size=2 * n)))
    amps = np.array(data.draw(st.lists(st.floats(0.0, 0.5), min_size=2 * n, max_size=2 * n)))
    u = np.ascontiguousarray(amps * np.sin(2 * np.pi * freqs * t[:, None]))
    hold = data.draw(st.sampled_from(["zoh", "foh"]))
    assume(conditioning(model, u, dt, x0, advice.substeps, hold) < 1e-11)
    res = ck.simulate(model, u, dt, x0, substeps=advice.substeps, hold=hold)
    xs, ys = rk4.simulate(ref.derivative, ref.output, u, x0, dt, advice.substeps, hold)
    assert_trajectories_match(res, xs, ys)


def test_params_round_trip():
    p = {
        "motor_inertia": [1e-4, 2e-4],
        "gear_ratio": [10.0, 12.0],
        "capstan_radius": [5e-3, 6e-3],
        "joint_radius": [0.05, 1.0],
        "link_inertia": [0.1, 0.5],
        "cable_stiffness": [1e4, 2e4],
        "cable_damping": [10.0, 20.0],
        "pretension": [30.0, 40.0],
        "cable_law": "exponential",
        "length_scale": 0.5,
        "joint_kind": ["revolute", "prismatic"],
        "motor_coulomb": [0.01, 0.02],
        "motor_viscous": [1e-4, 2e-4],
        "motor_smoothing": [0.1, 0.2],
        "link_coulomb": [0.3, 0.4],
        "link_viscous": [1e-3, 2e-3],
        "link_smoothing": [1e-3, 2e-3],
        "gravity_amplitude": [1.0, -2.0],
        "gravity_offset": [0.1, 0.2],
        "coupling": [[0.0, 0.0], [0.1, 0.0]],
    }
    assert ck.CableTransmission(**p).params() == p


# ---- antagonistic joint and Dahl element ---------------------------------------------------------


@settings(max_examples=150)
@given(data=st.data())
def test_antagonistic_derivative_output_and_step(data):
    p = data.draw(antagonistic_params())
    model = ck.AntagonisticJoint(**p)
    ref = ar.AntagonisticRef(p)
    x, u = data.draw(antagonistic_point(p))
    scale = ar.derivative_scale(ref, x, u)
    assert_scaled(model.derivative(x, u), ref.derivative(x, u), scale, EVAL_RTOL, "f")
    y_ref = ref.output(x, u)
    assert_scaled(model.output(x, u), y_ref, np.abs(y_ref), EVAL_RTOL, "h")
    u_next = u + np.array([1e-5, 1e-3])
    got = model.rk4_step(x, u, 1e-5, substeps=2, u_next=u_next)
    want = rk4.advance(ref.derivative, x, u, u_next, 1e-5, 2)
    scale = rk4_scale(ref.derivative, lambda xs, us: ar.derivative_scale(ref, xs, us), x, u, u_next, 1e-5)
    assert_scaled(got, want, scale, EVAL_RTOL, "rk4 foh step")


@settings(max_examples=8)
@given(data=st.data())
def test_antagonistic_one_second_trajectory(data):
    p = data.draw(antagonistic_params())
    model = ck.AntagonisticJoint(**p)
    ref = ar.AntagonisticRef(p)
    dt = 1e-3
    r = p["radius"]
    n = ref.n_states
    # probe at rest and at the fastest the joint can swing (released from 1 rad off its cables'
    # equilibrium): velocity-dependent stiffness (Dahl: σ₀|θ̇|/F_d) is invisible at rest
    omega = math.sqrt((p["stiffness"] + p["stiffness_return"]) * r * r / p["inertia"])
    probe = [np.r_[a, v, np.zeros(n - 2)] for a in (-0.5, 0.0, 0.5) for v in (0.0, omega, -omega)]
    substeps = max(
        ck.propose_step(model, dt, x, np.array([r * x[0], 0.0]), safety=0.5).substeps for x in probe
    )
    assume(substeps <= 20)
    t = np.arange(1000) * dt
    f = data.draw(st.floats(0.2, 2.0))
    amp = data.draw(st.floats(0.0, 0.5))
    u = np.ascontiguousarray(
        np.column_stack(
            [r * amp * np.sin(2 * np.pi * f * t), r * amp * 2 * np.pi * f * np.cos(2 * np.pi * f * t)]
        )
    )
    x0 = np.r_[data.draw(st.floats(-0.5, 0.5)), np.zeros(n - 1)]
    assume(conditioning(model, u, dt, x0, substeps, "foh") < 1e-11)
    res = ck.simulate(model, u, dt, x0, substeps=substeps, hold="foh")
    xs, ys = rk4.simulate(ref.derivative, ref.output, u, x0, dt, substeps, "foh")
    assert_trajectories_match(res, xs, ys)


@given(
    sigma0=st.floats(10.0, 1e4),
    fc=st.floats(0.1, 10.0),
    n=st.floats(0.5, 2.0),
    f0=st.floats(-0.9, 0.9),
    v=st.floats(-1, 1),
)
def test_dahl_element_matches_reference(sigma0, fc, n, f0, v):
    model = ck.DahlElement(sigma0=sigma0, coulomb=fc, exponent=n)
    x, u = np.array([f0 * fc]), np.array([v])
    # the step comparison needs a step RK4 can take: h·|∂Ḟ/∂F| inside its stability interval
    # over the states the step visits (|1 − F/F_c·sgn v| ≤ 2); beyond it both integrators diverge
    assume(1e-4 / 3 * sigma0 * n * 2.0 ** max(n - 1.0, 0.0) * abs(v) / fc < 2.5)
    np.testing.assert_allclose(
        model.derivative(x, u), fr.dahl_rate(x, u, sigma0, fc, n), rtol=1e-13, atol=1e-300
    )
    want = rk4.advance(lambda xx, uu: fr.dahl_rate(xx, uu, sigma0, fc, n), x, u, u, 1e-4, 3)
    np.testing.assert_allclose(model.rk4_step(x, u, 1e-4, substeps=3), want, rtol=1e-12, atol=1e-15)
