"""The forceps twin (seed 000's bench) and the physics-informed clamping-force estimator: the
binding against a NumPy reference, the twin's physics, the TOML loader's errors, and issue
#22's goals on the twin (clamp RMSE ≤ 0.07 N, transfer within 1.5×)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cablekit.errors import DataError, NotFiniteError, ParameterError, ShapeError
from cablekit.forceps import PhysicsObserver, Twin, load_twin, twin_from_toml
from cablekit.forceps.twin import SEED_FILE
from tests.reference import forceps as ref

NAMES = list(Twin.JAW_NAMES)
LOWER = np.array([0.0, 1e-7, 0.0, 0.0, 1e-7, 0.0, -1.0, -1.0, 0.0])
UPPER = np.array([3.0, 1e-2, 1e5, 1.0, 1e-2, 10.0, 1.0, 1.0, 1e-3])


def _geometry(twin: Twin) -> dict[str, float]:
    arm = NAMES.index("arm")
    return dict(r2=twin.a[NAMES.index("r2")], arm_a=twin.a[arm], arm_b=twin.b[arm])


@settings(max_examples=40, deadline=None)
@given(t=st.integers(2, 60), seed=st.integers(0, 2**32 - 1), threshold=st.floats(0.0, 1.0))
def test_physics_estimator_equals_the_numpy_reference(t, seed, threshold):
    rng = np.random.default_rng(seed)
    losses = LOWER + (UPPER - LOWER) * rng.uniform(0.0, 1.0, (2, 9))
    losses[:, [1, 4]] = 10 ** rng.uniform(-6, -3, (2, 2))  # travels on a log scale
    losses[:, 0] *= 0.3
    x = np.cumsum(rng.normal(0, 2e-5, (t, 2)), axis=0)
    x[1::4] = x[0:-1:4][: x[1::4].shape[0]]  # repeated positions: steps of zero
    v = rng.normal(0, 1e-3, (t, 2))
    motors = np.column_stack([x[:, 0], v[:, 0], x[:, 1], v[:, 1]])
    measured = rng.uniform(1.0, 30.0, (t, 4))
    g = dict(r2=4e-3, arm_a=12e-3, arm_b=14e-3)
    obs = PhysicsObserver(**g, losses_a=losses[0], losses_b=losses[1], threshold=threshold)
    run = obs.estimate(motors, measured)
    f_f, tau, f_ext, f_cf, contact = ref.physics(motors, measured, losses, threshold=threshold, **g)
    scale = np.abs(measured).max() * math.exp(losses[:, 0].max()) + losses[:, 2].max() * 1e-3 * 4
    np.testing.assert_allclose(run.disturbance, f_f, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(run.torque, tau, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(run.external, f_ext, rtol=0, atol=1e-12 * scale / 12e-3)
    np.testing.assert_allclose(run.clamping, f_cf, rtol=0, atol=1e-12 * scale / 12e-3)
    near = np.abs(np.abs(f_ext) - threshold) < 1e-9 * scale / 12e-3
    assert np.array_equal(run.contact[~near], contact[~near])
    # step by step from reset equals the log; reset forgets the direction states
    for _ in range(2):
        obs.reset()
        for k in range(t):
            s = obs.step(motors[k], measured[k])
            assert s.external == tuple(run.external[k])


def test_physics_estimator_rejects_bad_input_by_name():
    g = dict(r2=4e-3, arm_a=12e-3, arm_b=14e-3)
    good = np.array([0.1, 5e-5, 0.0, 1e-3, 5e-5, 0.0, 0.0, 0.0, 3e-5])
    with pytest.raises(ParameterError, match=r"losses_a\.capstan"):
        PhysicsObserver(**g, losses_a=np.r_[-0.1, good[1:]])
    with pytest.raises(ShapeError):
        PhysicsObserver(**g, losses_b=good[:7])
    with pytest.raises(ParameterError, match="r2"):
        PhysicsObserver(r2=-1.0, arm_a=0.01, arm_b=0.01)
    obs = PhysicsObserver(**g)
    m = np.zeros((20, 4))
    with pytest.raises(ShapeError):
        obs.estimate(m, np.zeros((19, 4)))
    bad = m.copy()
    bad[3, 2] = np.nan
    with pytest.raises(NotFiniteError, match="row 3"):
        obs.estimate(bad, m)
    with pytest.raises(ShapeError):
        obs.calibrated(m[:5], m[:5], np.zeros((5, 2)))
    with pytest.raises(ShapeError):
        obs.calibrated(m, m, np.zeros((20, 3)))


def test_the_shipped_twin_file_is_the_cores_seed_bench():
    a, b = load_twin(), Twin.seed()
    assert np.array_equal(a.a, b.a) and np.array_equal(a.b, b.b) and a.bench == b.bench


@pytest.mark.parametrize(
    ("text", "error", "match"),
    [
        ("[c]\nx = 1", DataError, "unknown section"),
        ("[a]\nstiffnes = 1.0", DataError, "unknown key"),
        ("[a]\nr2 = 'four'", DataError, "r2 must be a number"),
        ("[a]\nr2 = true", DataError, "r2 must be a number"),
        ("[a]\nr2 = nan", DataError, "finite"),
        ("[bench]\nsubsteps = 1.5", DataError, "whole number"),
        ("[bench]\nsubsteps = 0", DataError, "substeps"),
        ("[a]\ncable_stiffness = -1.0", ParameterError, "a.cable_stiffness"),
        ("[b]\narm = 0.0", ParameterError, "b.contact.lever_arm"),
        ("a = 1", DataError, r"\[a\] must be a table"),
        ("[a", DataError, "not valid TOML"),
    ],
)
def test_twin_file_errors_name_the_field(text, error, match):
    with pytest.raises(error, match=match):
        twin_from_toml(text)


def test_a_key_left_out_keeps_the_seed_value_and_a_given_one_changes_it():
    t = twin_from_toml("[b]\npretension = 12.5\n")
    assert t.b[NAMES.index("pretension")] == 12.5
    assert np.array_equal(t.a, Twin.seed().a)
    assert SEED_FILE.exists()


def test_free_motion_has_no_contact_and_the_sensors_have_their_noise():
    twin = load_twin()
    run = twin.free_motion([1.0e-3])
    assert np.all(run.external_true == 0.0)
    tn, pn, *_ = twin.bench
    noise = run.measured - run.tensions
    assert abs(noise.std() / tn - 1.0) < 0.05
    assert abs(noise.mean()) < 3 * tn / math.sqrt(noise.size)
    assert abs((run.external - run.external_true).std() / pn - 1.0) < 0.1
    # the jaw covers the whole range, 0-65°, in each direction
    assert run.angles.max() > math.radians(64.0) and run.angles.min() < math.radians(1.0)
    # positions are whole pulses of 0.00127 mm
    steps = run.motors[:, [0, 2]] / 1.27e-6
    assert np.abs(steps - np.round(steps)).max() < 1e-6


def test_a_stair_clamp_loads_in_equal_increments_and_programs_are_checked():
    twin = load_twin()
    run = twin.clamp(0.5e-3, 2.0, 5, 1.0)
    still = (run.motors[:, 1] == 0) & (run.external_true[:, 0] > 0.05)
    levels = np.unique(np.round(run.external_true[still, 0], 1))
    assert len(levels) == 5
    # each increment is a fifth of the peak, within the joint friction's share (τ_c / l_e)
    slack = twin.a[NAMES.index("joint_friction")] / twin.a[NAMES.index("arm")]
    np.testing.assert_allclose(np.diff(levels), 0.4, atol=slack / 2 + 0.05)
    custom = twin.run(0.0, [("move", 1e-3, 1e-3), ("hold", 0.5)], 0.0, [("hold", 0.2)], False)
    assert custom.time[-1] == pytest.approx(1.0 + 0.02 + 0.5, abs=0.011)
    assert np.all(custom.motors[:, 2] == 0.0)
    with pytest.raises(ParameterError, match="program segment"):
        twin.run(0.0, [("jump", 1e-3, 1e-3)], 0.0, [], False)
    with pytest.raises(ParameterError, match="speed"):
        twin.run(0.0, [("move", 1e-3, 0.0)], 0.0, [], False)
    with pytest.raises(ParameterError, match="samples"):
        twin.run(0.0, [("hold", 1e9)], 0.0, [], False)


def test_physics_calibrated_on_free_motion_estimates_a_clamp_without_a_network():
    """Issue #22 §2 on the twin, without torch: one free-motion sweep calibrates it, a stair
    clamp it never saw is estimated within the goal of 0.07 N RMS."""
    twin = load_twin()
    sweep = twin.free_motion([0.8e-3])
    obs, (ca, cb) = PhysicsObserver(**_geometry(twin)).calibrated(
        sweep.motors, sweep.measured, np.zeros((sweep.time.size, 2))
    )
    assert ca.rmse < 0.5 * ca.rmse_start and cb.rmse < 0.5 * cb.rmse_start
    run = twin.clamp(0.8e-3, 1.6, 5, 2.0)
    est = obs.estimate(run.motors, run.measured)
    cf = 0.5 * np.abs(run.external).sum(axis=1)
    assert np.sqrt(((est.clamping - cf) ** 2).mean()) < 0.07
    # the neutral start is far off: the fit, not the start, does the work
    raw = PhysicsObserver(**_geometry(twin)).estimate(run.motors, run.measured)
    assert np.sqrt(((raw.clamping - cf) ** 2).mean()) > 0.2
