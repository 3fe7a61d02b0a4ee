"""Estimation tasks on the sr-UKF: joint states of Raven-II from motor encoders (seed 001 ch. 3)
on the twin experiments, and the helpers' input checks."""

from __future__ import annotations

import numpy as np
import pytest

import cablekit as ck
from cablekit.estimate import estimate_joint_states, kinematic_joint_angles
from cablekit.twins import ENCODER_LSB, raven_joint_state_experiment

SIGMA = float(np.hypot(2e-5, ENCODER_LSB / np.sqrt(12)))


@pytest.fixture(scope="module", params=["A", "B", "C"])
def experiment(request):
    run = raven_joint_state_experiment(request.param, seconds=6.0, seed=3)
    est = estimate_joint_states(run.nominal, run.q_m, run.tau_m, run.dt, encoder_noise=SIGMA)
    return run, est


def test_ukf_beats_the_transmission_kinematics_on_every_link(experiment):
    """Seed 001 Table 3.3's claim on the twin: from motor encoders only, the filter's joint
    angles have a lower MAE than the rigid-transmission kinematics on every link (elastic
    elbow and insertion included), in every experiment, model mismatch and payload included."""
    run, est = experiment
    s = slice(1000, None)  # the first second is the filter's start-up
    mae_ukf = np.mean(np.abs(est.q_l[s] - run.q_l_true[s]), axis=0)
    mae_kin = np.mean(np.abs(est.q_l_kinematics[s] - run.q_l_true[s]), axis=0)
    assert np.all(mae_ukf < mae_kin), (run.experiment, mae_ukf, mae_kin)
    # the elbow's cable (88 kN/m) stretches most: the gain there is large
    assert mae_ukf[1] < 0.7 * mae_kin[1]
    assert np.all(est.recovered == 0)
    # a consistent filter: NIS averages the number of encoders or less (R includes quantisation)
    assert 0.5 < np.nanmean(est.nis[s]) < 4.0


def test_joint_state_result_has_named_fields_and_kinematics_is_the_inverse_map():
    run = raven_joint_state_experiment("A", seconds=1.5, seed=0)
    est = estimate_joint_states(run.nominal, run.q_m, run.tau_m, run.dt, encoder_noise=SIGMA)
    t = len(run.q_m)
    assert est.q_l.shape == est.dq_l.shape == est.q_l_std.shape == (t, 3)
    assert est.x.shape == (t, 12) and est.nis.shape == (t,)
    assert np.all(est.q_l_std > 0)
    q_l = kinematic_joint_angles(run.nominal, run.q_m)
    np.testing.assert_allclose(q_l @ run.nominal.transmission_matrix.T, run.q_m, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(est.q_l_kinematics, q_l)


def test_joint_state_helper_rejects_bad_input():
    model = ck.CableTransmission.raven2(2)
    q = np.zeros((10, 2))
    with pytest.raises(ck.ShapeError, match="q_m"):
        estimate_joint_states(model, np.zeros((10, 3)), q, 1e-3)
    with pytest.raises(ck.ShapeError, match="tau_m"):
        estimate_joint_states(model, q, np.zeros((9, 2)), 1e-3)
    with pytest.raises(ck.ParameterError, match="encoder_noise"):
        estimate_joint_states(model, q, q, 1e-3, encoder_noise=-1.0)
    bad = q.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ck.NotFiniteError, match="row 3"):
        estimate_joint_states(model, bad, q, 1e-3)
    with pytest.raises(ck.NotFiniteError, match="U"):  # the torques, shifted by one sample
        estimate_joint_states(model, q, bad, 1e-3)
    with pytest.raises(ck.ParameterError, match="experiment"):
        raven_joint_state_experiment("D")
