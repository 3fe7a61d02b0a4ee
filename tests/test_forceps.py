"""The forceps' joint torque disturbance observer (seed 000 eqs 8, 15–17): the binding against
the NumPy reference, the physics a wrong implementation breaks, and bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cablekit.errors import DTypeError, NonFiniteResultError, NotFiniteError, ParameterError, ShapeError
from cablekit.forceps import Jtdo, free_motion_tensions
from tests.reference import forceps as ref

GEOMETRY = dict(r2=4e-3, arm_a=12e-3, arm_b=14e-3)


def _finite(lo, hi):
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


@settings(max_examples=60, deadline=None)
@given(
    t=st.integers(1, 40),
    seed=st.integers(0, 2**32 - 1),
    r2=_finite(1e-4, 1e-1),
    arms=st.tuples(_finite(1e-3, 0.2), _finite(1e-3, 0.2)),
    threshold=_finite(0.0, 2.0),
    bias=st.tuples(_finite(-1.0, 1.0), _finite(-1.0, 1.0)),
)
def test_binding_equals_the_numpy_reference(t, seed, r2, arms, threshold, bias):
    rng = np.random.default_rng(seed)
    measured = rng.uniform(0.0, 50.0, (t, 4))
    free = measured + rng.normal(0.0, 0.5, (t, 4))
    j = Jtdo(r2=r2, arm_a=arms[0], arm_b=arms[1], threshold=threshold, bias=bias)
    run = j.estimate(measured, free)
    f_d, tau_d, f_ext, f_cf, contact = ref.jtdo(measured, free, r2, *arms, threshold, bias)
    # ≤ 1e-12 of the terms' magnitudes (the reference multiplies by 1/l where the core divides)
    scale = r2 * np.abs(measured - free).max() / min(arms) + np.abs(bias).max() + 1e-300
    np.testing.assert_allclose(run.disturbance, f_d, rtol=0, atol=1e-12 * np.abs(measured).max())
    np.testing.assert_allclose(run.torque, tau_d, rtol=0, atol=1e-12 * scale * max(arms))
    np.testing.assert_allclose(run.external, f_ext, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(run.clamping, f_cf, rtol=0, atol=1e-12 * scale)
    near = np.abs(np.abs(f_ext) - threshold) < 1e-9 * scale
    assert np.array_equal(run.contact[~near], contact[~near])
    # one sample at a time gives the log's rows
    for k in range(min(t, 5)):
        s = j.step(measured[k], free[k])
        assert s.external == tuple(run.external[k])
        assert s.clamping == run.clamping[k]
        assert s.contact == tuple(bool(c) for c in run.contact[k])


def test_a_known_jaw_force_is_recovered_and_a_free_motion_is_no_contact():
    """A force F at arm l needs F·l/r₂ more drive than return tension; a sign error, a wrong
    arm or a missing ½ in eq. 17 would each miss these numbers by ≥ 20 %."""
    rng = np.random.default_rng(3)
    t = 400
    free = np.column_stack(
        [12 + rng.normal(0, 1, t), 7 + rng.normal(0, 1, t), 14 + rng.normal(0, 1, t), 6 + rng.normal(0, 1, t)]
    )
    f_a = np.clip(np.linspace(-0.2, 1.6, t), 0, None)  # contact from the first quarter on
    f_b = 1.2 * f_a
    split_a = 0.5 * f_a * GEOMETRY["arm_a"] / GEOMETRY["r2"]
    split_b = 0.5 * f_b * GEOMETRY["arm_b"] / GEOMETRY["r2"]
    noise = rng.normal(0.0, 0.01, (t, 4))  # N, a 0–50 N sensor's noise
    measured = free + np.column_stack([split_a, -split_a, split_b, -split_b]) + noise
    run = Jtdo(**GEOMETRY).estimate(measured, free)
    assert np.sqrt(np.mean((run.external[:, 0] - f_a) ** 2)) < 0.02
    assert np.sqrt(np.mean((run.external[:, 1] - f_b) ** 2)) < 0.02
    assert np.sqrt(np.mean((run.clamping - 0.5 * (f_a + f_b)) ** 2)) < 0.02
    # contact: not before the force, always once it is well above the 0.11 N threshold
    assert not run.contact[f_a == 0].any()
    assert run.contact[f_a > 0.2].all()
    # free motion (the free-motion model is exact up to sensor noise): no false collision
    quiet = Jtdo(**GEOMETRY).estimate(free + noise, free)
    assert not quiet.contact.any()
    assert quiet.clamping.max() < 0.11


def test_calibration_removes_a_group_mean_error():
    """The seed compensates the external forces by a first group's mean errors (§3.3): an
    observer with a 10 % wrong arm calibrated on one run is unbiased on the next."""
    rng = np.random.default_rng(5)
    t = 300
    free = rng.uniform(5.0, 15.0, (t, 4))
    force = np.column_stack([np.full(t, 0.9), np.full(t, 1.1)])
    split = 0.5 * force * np.array([GEOMETRY["arm_a"], GEOMETRY["arm_b"]]) / GEOMETRY["r2"]
    measured = free + np.column_stack([split[:, 0], -split[:, 0], split[:, 1], -split[:, 1]])
    wrong = Jtdo(r2=GEOMETRY["r2"], arm_a=1.1 * GEOMETRY["arm_a"], arm_b=GEOMETRY["arm_b"])
    before = wrong.estimate(measured, free).external - force
    cal = wrong.calibrated(measured, free, force)
    np.testing.assert_allclose(cal.bias, before.mean(axis=0), atol=1e-12)
    after = cal.estimate(measured, free).external - force
    assert np.abs(after.mean(axis=0)).max() < 1e-12 < np.abs(before.mean(axis=0)).max()


def test_free_motion_tensions_come_from_a_four_by_four_network():
    from tests.test_fuzz_bindings import _mlp

    with pytest.raises(ShapeError, match="4 motor signals"):
        free_motion_tensions(_mlp(), np.zeros((3, 4)))


def test_bad_input_is_a_typed_error():
    j = Jtdo(**GEOMETRY)
    ok = np.ones((5, 4))
    with pytest.raises(ShapeError):
        j.estimate(np.ones((5, 3)), ok)
    with pytest.raises(ShapeError):
        j.estimate(ok, np.ones((4, 4)))
    with pytest.raises(DTypeError):
        j.estimate(ok.astype(np.float32), ok)
    bad = ok.copy()
    bad[3, 2] = np.nan
    with pytest.raises(NotFiniteError, match="row 3, column 2"):
        j.estimate(bad, ok)
    with pytest.raises(NonFiniteResultError):
        j.step(np.array([1e308, -1e308, 0.0, 0.0]), np.zeros(4))
    for kw in (
        dict(r2=0.0),
        dict(arm_a=-1.0),
        dict(arm_b=np.inf),
        dict(threshold=-0.1),
        dict(bias=(np.nan, 0.0)),
    ):
        with pytest.raises(ParameterError):
            Jtdo(**{**GEOMETRY, **kw})
    with pytest.raises(ShapeError):
        j.calibrated(ok, ok, np.ones((4, 2)))


def test_the_observer_agrees_with_the_antagonistic_joint_physics():
    """A simulated jaw (cablekit's antagonistic joint, seed 000 §2.3.1: pretensioned cables,
    capstan losses at the motor, a pad of 2000 N/m at the contact angle) closes on an object and
    holds; the free-motion tensions are the same joint's without the object. The observer's
    external force is the joint's contact force: to 0.1 % at hold, 2 % while moving (the
    capstan factor), exactly zero before contact. Conventions (which cable pulls, the arm, the
    ½ of eq. 17) agree between the model and the observer."""
    import cablekit as ck

    joint = ck.AntagonisticJoint.forceps_example()
    p = joint.params()
    free_joint = ck.AntagonisticJoint(**{**p, "contact_angle": 10.0})  # never touches
    dt = 1e-3
    t = np.arange(2500) * dt
    s = np.clip(t / 1.5, 0.0, 1.0)
    x = p["radius"] * 0.42 * (10 * s**3 - 15 * s**4 + 6 * s**5)  # past the contact at 0.3 rad
    u = np.column_stack([x, np.gradient(x, dt)])
    sub = max(ck.propose_step(joint, dt).substeps, 4)
    run, free = ck.simulate(joint, u, dt, substeps=sub), ck.simulate(free_joint, u, dt, substeps=sub)
    cols = ["tension_motor_drive", "tension_motor_return"]
    measured = np.column_stack([run[c] for c in cols] * 2)  # forceps B: the same jaw
    predicted = np.column_stack([free[c] for c in cols] * 2)
    arm = p["contact_lever_arm"]
    est = Jtdo(r2=p["radius"], arm_a=arm, arm_b=arm).estimate(measured, predicted)
    force = run["contact_force"]
    hold, moving = t > 2.0, (t > 0.8) & (t < 1.4) & (force > 0.2)
    assert force[hold].mean() > 1.0
    assert np.abs(est.external[hold, 0] - force[hold]).max() < 1e-3 * force[hold].mean()
    assert np.abs(est.clamping[hold] - force[hold]).max() < 1e-3 * force[hold].mean()
    assert np.abs(est.external[moving, 0] / force[moving] - 1.0).max() < 0.02
    assert np.all(est.external[force == 0] == 0.0) and not est.contact[force == 0].any()
