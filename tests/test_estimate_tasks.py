"""Estimation tasks on the sr-UKF: joint states of Raven-II from motor encoders (seed 001 ch. 3)
on the twin experiments, and the helpers' input checks."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

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


# ---- task 2: joint state–parameter estimation ----------------------------------------------------


@pytest.fixture(scope="module")
def parameter_run():
    from cablekit.twins import raven_parameter_experiment

    return raven_parameter_experiment(seconds=15.0, seed=1)


def test_parameters_converge_to_the_twin_truth(parameter_run):
    """Cable stiffness and damping of the elbow, the three coupling coefficients and the
    shoulder pulley radius, started at the nominal values (20 % off for the stiffness, 50 % for
    the damping, 5–20 % for the others): within 2 % of the truth at the end."""
    from cablekit.estimate import estimate_parameters

    run = parameter_run
    est = estimate_parameters(
        run.nominal, list(run.truth), run.q_m, run.tau_m, run.dt, q_l=run.q_l, encoder_noise=2e-5
    )
    true = np.array(list(run.truth.values()))
    start_err = np.abs(est.initial - true) / np.abs(true)
    end_err = np.abs(est.values[-1] - true) / np.abs(true)
    assert np.all(start_err > 0.04)
    assert np.all(end_err < 0.02), dict(zip(run.truth, end_err, strict=True))
    assert np.all(est.recovered == 0)
    # the filter's own uncertainty covers the remaining error (3σ)
    assert np.all(np.abs(est.values[-1] - true) < 3 * est.std[-1] + 1e-3 * np.abs(true))


def test_dual_estimation_converges_too(parameter_run):
    """Dual estimation (eqs 3.7–3.8: a state filter and a parameter filter) on the same run:
    every parameter within 2 % of the truth at the end."""
    from cablekit.estimate import estimate_parameters

    run = parameter_run
    est = estimate_parameters(
        run.nominal,
        list(run.truth),
        run.q_m,
        run.tau_m,
        run.dt,
        q_l=run.q_l,
        encoder_noise=2e-5,
        method="dual",
    )
    true = np.array(list(run.truth.values()))
    end_err = np.abs(est.values[-1] - true) / np.abs(true)
    assert np.all(end_err < 0.02), dict(zip(run.truth, end_err, strict=True))
    assert np.all(est.std[-1] > 0) and np.all(np.isfinite(est.x))
    with pytest.raises(ck.ParameterError, match="method"):
        estimate_parameters(run.nominal, ["cable_stiffness[1]"], run.q_m, run.tau_m, run.dt, method="triple")


def test_bounds_hold_every_sigma_point_and_the_mean(parameter_run):
    """A stiffness bound below the truth: the estimate stops at the bound and never crosses it."""
    from cablekit.estimate import estimate_parameters

    run = parameter_run
    names = ["cable_stiffness[1]"]
    lo, hi = 0.9 * run.truth[names[0]] / 0.8, 2e5  # lower bound above the true 0.8 × nominal
    est = estimate_parameters(
        run.nominal,
        names,
        run.q_m[:3000],
        run.tau_m[:3000],
        run.dt,
        q_l=run.q_l[:3000],
        encoder_noise=2e-5,
        bounds=[(lo, hi)],
    )
    assert np.all(est.values >= lo) and np.all(est.values <= hi)
    assert est.values[-1, 0] == pytest.approx(lo, rel=5e-3)  # pressed against the bound


def test_unknown_parameter_names_are_refused():
    from cablekit.estimate import TransmissionParameters

    model = ck.CableTransmission.raven2(3)
    for bad in ["mass[0]", "cable_stiffness[5]", "coupling[0][1]", "cable_stiffness"]:
        with pytest.raises(ck.ParameterError, match="parameter"):
            TransmissionParameters(model, [bad])
    with pytest.raises(ck.CablekitError, match="parameter"):
        ck.SrUkf.with_parameters(
            model,
            ["cable_stiffness[7]"],
            np.zeros(13),
            np.eye(13),
            np.eye(13),
            np.eye(3),
            dt=1e-3,
            states=[0, 4, 8],
        )


# ---- task 3: camera fusion with occlusion --------------------------------------------------------


def test_camera_identifies_the_pulley_radius_and_fusion_stays_consistent_under_occlusion():
    """Seed 001 ch. 4 on the twin: the shoulder pulley radius (5 % off design) is identified
    from camera frames; with the updated model the fused estimate stays consistent (≥ 98 % of
    samples within 3σ, NEES ≤ 3) at 10 % and at 80 % occlusion, far better than the design
    kinematics and better than the identified kinematics on the elastic links."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
    from camera_fusion import identify, occlusion_sweep

    est, true_r, updated = identify(15.0, 0)
    assert abs(est.values[-1, 0] - true_r) / true_r < 0.01
    assert abs(est.initial[0] - true_r) / true_r > 0.04
    rows = occlusion_sweep(updated, [0.1, 0.8], 6.0, 1)
    assert rows[1]["occlusion"] > 0.7
    for row in rows:
        assert np.all(row["within_3sigma"] >= 0.98), row
        assert np.all(row["nees"] <= 3.0), row
        assert np.all(row["fused"] < row["kinematics_nominal"]), row
        # elastic elbow and insertion: better than the identified kinematics; the stiff shoulder
        # (720 kN/m) gains nothing from the dynamics (seed 001 §3.5) and stays within 30 %
        assert np.all(row["fused"][1:] < row["kinematics_updated"][1:]), row
        assert row["fused"][0] < 1.3 * row["kinematics_updated"][0], row


def test_camera_input_is_checked():
    model = ck.CableTransmission.raven2(2)
    q = np.zeros((20, 2))
    with pytest.raises(ck.ShapeError, match="q_camera"):
        estimate_joint_states(model, q, q, 1e-3, q_camera=np.zeros((20, 3)))
    with pytest.raises(ck.ParameterError, match="NaN"):
        estimate_joint_states(model, q, q, 1e-3, q_camera=np.full((20, 2), np.inf))
    with pytest.raises(ck.ParameterError, match="camera_noise"):
        estimate_joint_states(model, q, q, 1e-3, q_camera=q, camera_noise=0.0)
    with pytest.raises(ck.ParameterError, match="occlusion"):
        from cablekit.twins import raven_camera_experiment

        raven_camera_experiment(1.0)


# ---- task 5: external force ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def force_runs():
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
    from external_force import both_methods, per_weight

    from cablekit.twins import raven_force_experiment

    out = {}
    for kind in ("zero", "basket"):
        run = raven_force_experiment(kind)
        out[kind] = (run, *both_methods(run))
    return out, per_weight


def test_basket_weights_are_read_by_the_ukf_and_the_stretch_method(force_runs):
    """The lifted-basket twin (271/497/704/910 g): the UKF and the cable-stretch method with the
    reference chosen by the direction of motion read every weight within 2 %; the seed's
    stretch-range quadrant rule reads light by about the friction level once the load's
    stretch exceeds the gap between the unloaded modes."""
    from cablekit.twins import BASKET

    runs, per_weight = force_runs
    run, forces, method = runs["basket"]
    for label in ("UKF", "stretch (direction)"):
        means = per_weight(run, forces[label])
        for m in BASKET:
            assert means[m] == pytest.approx(-m * 9.80665, rel=0.02), (label, m, means[m])
    quad = per_weight(run, forces["stretch (quadrants)"])
    gap = method.stiffness * (method.upper - method.lower) / 2
    for m in BASKET:
        assert quad[m] - (-m * 9.80665) == pytest.approx(gap, rel=0.3)


@pytest.mark.parametrize("kind", ["pull", "push"])
def test_spring_contact_in_all_four_quadrants(kind):
    """Seed 001 §5.3 experiments 3–4 on the twin: an extension spring (always pulling) and a
    compression spring (always pushing). The UKF and the direction-rule stretch method are
    unbiased (mean error < 0.05 N) and the direction rule stays within ±0.5 N (1–99 %); the
    quadrant rule is biased by the friction gap, with the sign of the force."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
    from external_force import both_methods

    from cablekit.twins import raven_force_experiment

    run = raven_force_experiment(kind)
    forces, method = both_methods(run)
    s = slice(round(6.2 / run.dt), None)
    assert np.all(np.sign(run.force[s]) == (-1 if kind == "pull" else 1))
    for label in ("UKF", "stretch (direction)"):
        assert abs(np.mean((forces[label] - run.force)[s])) < 0.05, label
    e = (forces["stretch (direction)"] - run.force)[s]
    assert np.all(np.abs(np.quantile(e, [0.01, 0.99])) < 0.5)
    gap = method.stiffness * (method.upper - method.lower) / 2
    bias = np.mean((forces["stretch (quadrants)"] - run.force)[s])
    assert bias == pytest.approx(gap if kind == "pull" else -gap, rel=0.3)


def test_zero_force_error_ranges(force_runs):
    runs, _ = force_runs
    run, forces, _ = runs["zero"]
    s = slice(1000, None)
    spread = {k: np.quantile(np.abs(f - run.force)[s], 0.99) for k, f in forces.items()}
    assert spread["UKF"] < 1.0 and spread["stretch (direction)"] < 0.5, spread
    assert spread["stretch (direction)"] < min(spread["stretch (quadrants)"], spread["UKF"]), spread


@settings(max_examples=20, deadline=None)
@given(
    ratio=st.floats(4.0, 30.0),
    sigma=st.floats(0.5, 2.0),
    share=st.floats(0.3, 0.7),
    seed=st.integers(0, 2**16),
)
def test_two_gaussian_fit_recovers_the_modes(ratio, sigma, share, seed):
    """Property: a bimodal stretch (modes at least 4σ apart, as the friction-held modes of
    seed 001 Fig. 5.6; any mix) gives back its two means within 0.2σ and its spread within
    20 %. Modes closer than that overlap and their means are not recoverable to 0.2σ."""
    from cablekit.estimate import CableStretchForce

    gap = ratio * sigma
    rng = np.random.default_rng(seed)
    n = 4000
    k = int(share * n)
    s = np.r_[rng.normal(-gap / 2, sigma, k), rng.normal(gap / 2, sigma, n - k)] * 1e-6
    m = CableStretchForce(1.0, 0.0).fit(s)
    assert m.lower == pytest.approx(-gap / 2 * 1e-6, abs=0.2 * sigma * 1e-6)
    assert m.upper == pytest.approx(gap / 2 * 1e-6, abs=0.2 * sigma * 1e-6)
    assert m.sigma == pytest.approx(sigma * 1e-6, rel=0.2)


def test_force_helpers_reject_bad_input():
    from cablekit.estimate import CableStretchForce, estimate_external_force

    model = ck.CableTransmission.raven2(3)
    q = np.zeros((50, 3))
    with pytest.raises(ck.ParameterError, match="links"):
        estimate_external_force(model, q, q, 1e-3, links=[3])
    with pytest.raises(ck.ParameterError, match="links"):
        estimate_external_force(model, q, q, 1e-3, links=[1, 1])
    m = CableStretchForce(1e4, 10.0)
    with pytest.raises(ck.ParameterError, match="fit"):
        m.force(np.zeros(5), np.zeros(5))
    with pytest.raises(ck.ParameterError, match="20 samples"):
        m.fit(np.zeros(5))
    with pytest.raises(ck.ParameterError, match="both ways"):
        m.fit(np.linspace(0, 1, 100), np.ones(100))


# ---- task 4: pretension ---------------------------------------------------------------------------


def test_pretension_from_estimated_stiffness_on_held_out_runs():
    """Seed 001 §5.2 on the twin: the filter's stiffness rises with the tension set by hand; the
    taut-string calibration recovers 4L²μ; a degree-two map fitted on 4 runs puts both held-out
    runs in their right Low/Mid/High category."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
    from pretension import study

    from cablekit.estimate import PretensionMap

    tensions = [4.0, 6.0, 10.0, 12.0, 16.0, 18.0]
    r = study(tensions, seconds=4.0, gauge=3, held_out_every=3)
    assert np.all(np.diff(r["k_hat"]) > 0), r["k_hat"]
    assert r["calibration"].a == pytest.approx(4 * 0.25**2 * 1.2e-3, rel=0.02)
    held = r["held"]
    assert held.sum() == 2
    cat = PretensionMap.category
    np.testing.assert_array_equal(cat(r["t_hat"][held]), cat(r["tension"][held]))
    assert np.all(np.abs(r["t_hat"][held] - r["tension"][held]) < 2.0)
    # the one-run helper gives the same answer for a new run
    from cablekit.estimate import estimate_pretension
    from cablekit.twins import LINEAR_ENCODER_LSB, raven_pretension_run

    run = raven_pretension_run(5.0, seconds=4.0)
    q_l = np.full_like(run.q_m, np.nan)
    q_l[:, 2] = run.q_l3
    one = estimate_pretension(
        run.nominal,
        2,
        r["map"],
        run.q_m,
        run.tau_m,
        run.dt,
        q_l=q_l,
        encoder_noise=SIGMA,
        joint_noise=LINEAR_ENCODER_LSB / np.sqrt(12),
    )
    assert one.category == "low" and abs(one.tension - 5.0) < 2.0


def test_pretension_helpers_check_their_input():
    from cablekit.estimate import PretensionMap, StringCalibration

    with pytest.raises(ck.ParameterError, match="fit"):
        PretensionMap().tension(1e4)
    with pytest.raises(ck.ParameterError, match="3 finite"):
        PretensionMap().fit([1e4, 2e4], [5.0, 10.0])
    with pytest.raises(ck.ParameterError, match="fit"):
        StringCalibration().tension(100.0)
    np.testing.assert_array_equal(
        PretensionMap.category([7.9, 8.0, 14.0, 14.1]), ["low", "mid", "mid", "high"]
    )
    from cablekit.twins import raven_pretension_run

    with pytest.raises(ck.ParameterError, match="tension"):
        raven_pretension_run(0.1)


def test_named_parameters_are_read_and_set_by_the_core():
    """TransmissionParameters reads and writes through the core's parser; the result equals
    the constructor with the edited keywords (the reference), and the edit is validated."""
    from cablekit.estimate import TransmissionParameters

    model = ck.CableTransmission.raven2(3)
    names = ["cable_stiffness[1]", "coupling[2][0]", "link_viscous[0]", "joint_radius[2]"]
    tp = TransmissionParameters(model, names)
    p = model.params()
    want = [p["cable_stiffness"][1], p["coupling"][2][0], p["link_viscous"][0], p["joint_radius"][2]]
    np.testing.assert_array_equal(tp.values(), want)
    new = [2.0 * want[0], 0.05, 3.0 * want[2] + 1e-3, 0.9 * want[3]]
    got = tp.model(new).params()
    ref = {k: ([list(r) for r in v] if k == "coupling" else v) for k, v in p.items()}
    ref["cable_stiffness"][1], ref["coupling"][2][0] = new[0], new[1]
    ref["link_viscous"][0], ref["joint_radius"][2] = new[2], new[3]
    assert got == ck.CableTransmission(**ref).params()
    with pytest.raises(ck.ParameterError):
        tp.model([-1.0, 0.0, 0.0, 0.01])  # a negative stiffness
    with pytest.raises(ck.ShapeError):
        tp.model([1.0])
