"""Square-root UKF: the Rust filter against the NumPy reference written from seed 001's
equations, against the exact Kalman filter on linear systems, against filterpy's UKF (the peer),
forced downdate failures, masks and bad input."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter
from hypothesis import given, settings
from hypothesis import strategies as st

import cablekit as ck
from tests.reference import rk4
from tests.reference.srukf import SrUkfRef
from tests.reference.transmission import TransmissionRef

# ---- a damped two-mass linear system (4 states, 2 measured) ------------------------------------

DT = 0.01


def linear_system():
    f = np.array(
        [
            [1.0, DT, 0.0, 0.0],
            [-40 * DT, 1 - 0.5 * DT, 10 * DT, 0.0],
            [0.0, 0.0, 1.0, DT],
            [10 * DT, 0.0, -30 * DT, 1 - 0.2 * DT],
        ]
    )
    b = np.array([[0.0], [DT], [0.0], [0.0]])
    h = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
    q = np.diag([1e-6, 1e-5, 1e-6, 1e-5])
    r = np.array([[1e-4, 2e-5], [2e-5, 4e-4]])
    p0 = 0.01 * np.ones((4, 4)) + 0.09 * np.eye(4)
    x0 = np.array([0.1, 0.0, -0.2, 0.0])
    return f, b, h, q, r, p0, x0


def linear_log(steps, seed=0):
    f, b, h, q, r, _, _ = linear_system()
    rng = np.random.default_rng(seed)
    x = np.array([0.05, 0.0, -0.1, 0.0])
    us, ys = [], []
    for k in range(steps):
        u = np.array([np.sin(0.05 * k)])
        x = f @ x + b @ u + rng.multivariate_normal(np.zeros(4), q)
        us.append(u)
        ys.append(h @ x + rng.multivariate_normal(np.zeros(2), r))
    return np.array(us), np.array(ys)


#: agreement of means, relative to the state's scale, by α. At the seed's α = 1e-3 the sigma
#: points x ± γ·s sit γ = α·√n ≈ 2e-3 standard deviations apart, so storing them loses
#: log10(1/γ²) ≈ 5.4 digits: any implementation's predicted mean carries ~eps·|x|/γ² ≈ 3e-12
#: per step (both this one and the reference are 3.5e-12 off the exact Kalman filter after one
#: step), and 500 steps of a weakly damped system accumulate it to a few 1e-10.
MEAN_TOL = {1e-3: 2e-9, 0.5: 1e-10}


@pytest.mark.parametrize("alpha", sorted(MEAN_TOL))
def test_rust_matches_the_numpy_reference_on_a_linear_system_for_500_steps(alpha):
    """Means (tolerance above) and S·Sᵀ (1e-10 of its scale) at every step, with a negative W0
    at α = 1e-3 and a camera-like mask dropping one channel on every third step."""
    f, b, h, q, r, p0, x0 = linear_system()
    us, ys = linear_log(500)
    rust = ck.SrUkf.linear(f, h, x0, p0, q, r, B=b, alpha=alpha)
    ref = SrUkfRef(lambda x, u: f @ x + b @ u, lambda x, u: h @ x, x0, p0, q, r, alpha=alpha)
    assert rust.weights[2][0] < 0  # W0 < 0 (−1e6 at α = 1e-3, −0.25 at α = 0.5): the downdate path
    for k in range(500):
        mask = [True, k % 3 != 0]
        rust.step(us[k], ys[k], mask)
        ref.step(us[k], ys[k], mask)
        np.testing.assert_allclose(rust.x, ref.x, rtol=0, atol=MEAN_TOL[alpha] * (1 + np.abs(ref.x).max()))
        np.testing.assert_allclose(rust.P, ref.p, rtol=0, atol=1e-10 * np.abs(ref.p).max())


def test_linear_system_equals_the_exact_kalman_filter():
    f, b, h, q, r, p0, x0 = linear_system()
    us, ys = linear_log(300, seed=1)
    rust = ck.SrUkf.linear(f, h, x0, p0, q, r, B=b)
    x, p = x0.copy(), p0.copy()
    for k in range(300):
        rust.step(us[k], ys[k])
        x, p = f @ x + b @ us[k], f @ p @ f.T + q
        s = h @ p @ h.T + r
        k_gain = p @ h.T @ np.linalg.inv(s)
        x, p = x + k_gain @ (ys[k] - h @ x), p - k_gain @ s @ k_gain.T
        np.testing.assert_allclose(rust.x, x, atol=1e-9)
        np.testing.assert_allclose(rust.P, p, atol=1e-9 * np.abs(p).max())


def test_batch_run_equals_stepping_and_reports_health():
    f, b, h, q, r, p0, x0 = linear_system()
    us, ys = linear_log(200, seed=2)
    a = ck.SrUkf.linear(f, h, x0, p0, q, r, B=b)
    res = a.run(us, ys)
    s = ck.SrUkf.linear(f, h, x0, p0, q, r, B=b)
    for k in range(200):
        s.step(us[k], ys[k])
    np.testing.assert_array_equal(res.x[-1], s.x)
    np.testing.assert_allclose(res.S[-1] @ res.S[-1].T, s.P, rtol=0, atol=1e-15)
    assert res.x.shape == (200, 4) and res.S.shape == (200, 4, 4)
    # a consistent filter: the NIS averages the number of measured channels (chi-square, 2 dof)
    assert 1.5 < np.mean(res.nis[20:]) < 2.5
    assert np.all(res.recovered == 0) and np.all(res.measured == 2)
    assert np.all(np.triu(res.S[-1], 1) == 0) and np.all(np.diag(res.S[-1]) > 0)


@settings(max_examples=25, deadline=None)
@given(
    n=st.integers(1, 5),
    p=st.integers(1, 3),
    seed=st.integers(0, 2**16),
    alpha=st.sampled_from([1e-3, 0.1, 1.0]),
)
def test_random_linear_systems_match_the_reference(n, p, seed, alpha):
    """Property: any stable linear system, any sizes, any α: Rust = reference (1e-9)."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n))
    f = 0.95 * a / max(1.0, np.abs(np.linalg.eigvals(a)).max())
    h = rng.normal(size=(p, n))
    m = rng.normal(size=(n, n))
    p0 = m @ m.T + 0.1 * np.eye(n)
    q = 0.01 * np.eye(n)
    mr = rng.normal(size=(p, p))
    r = 0.1 * (mr @ mr.T) + 0.05 * np.eye(p)
    x0 = rng.normal(size=n)
    rust = ck.SrUkf.linear(f, h, x0, p0, q, r, alpha=alpha)
    ref = SrUkfRef(lambda x, u: f @ x, lambda x, u: h @ x, x0, p0, q, r, alpha=alpha)
    for _ in range(30):
        y = rng.normal(size=p)
        rust.step(np.zeros(0), y)
        ref.step(np.zeros(0), y)
    scale = 1 + np.abs(ref.x).max()
    np.testing.assert_allclose(rust.x, ref.x, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(rust.P, ref.p, rtol=0, atol=1e-9 * np.abs(ref.p).max())


# ---- nonlinear: Raven-II's 2-link cable transmission, motor encoders only ------------------------

SUB = 2


def raven_setup():
    model = ck.CableTransmission.raven2(2)
    ref = TransmissionRef(model.params())
    n = model.n_states
    q = np.diag(np.tile([1e-10, 1e-6, 1e-10, 1e-6], 2))
    r = 1e-8 * np.eye(2)
    p0 = np.diag(np.tile([1e-8, 1e-4, 1e-6, 1e-4], 2))
    x0 = np.zeros(n)
    return model, ref, q, r, p0, x0


def raven_log(model, steps, seed=3):
    rng = np.random.default_rng(seed)
    t = np.arange(steps) * 1e-3
    tau = np.column_stack([0.05 * np.sin(2 * np.pi * 1.3 * t), 0.03 * np.sin(2 * np.pi * 2.1 * t + 0.5)])
    u = np.ascontiguousarray(np.column_stack([tau, np.zeros_like(tau)]))
    sim = ck.simulate(model, u, 1e-3, np.zeros(model.n_states), substeps=SUB, hold="zoh")
    y = np.column_stack([sim["q_m1"], sim["q_m2"]]) + rng.normal(0, 1e-4, (steps, 2))
    return u, y


def raven_fx(tref):
    """The reference process: the NumPy transmission through RK4, SUB steps per 1 ms."""

    def fx(x, uk):
        return rk4.advance(tref.derivative, x.copy(), uk, uk, 1e-3, SUB)

    return fx


def step_both_and_compare(rust, ref, u, y, tol):
    """Step the Rust filter and the reference on the same log; at every step the means agree
    within `tol` of |x| + σ and the covariances within `tol` of σᵢσⱼ; no recovery needed."""
    for k in range(len(y)):
        rust.step(u[k], y[k])
        ref.step(u[k], y[k])
        xs = np.abs(ref.x) + np.sqrt(np.diag(ref.p))
        assert np.all(np.abs(rust.x - ref.x) <= tol * xs), k
        ps = np.sqrt(np.outer(np.diag(ref.p), np.diag(ref.p)))
        assert np.all(np.abs(rust.P - ref.p) <= tol * ps), k
    assert rust.health.recoveries_total == 0


#: (α, steps, tolerance) for the nonlinear comparisons. At α = 0.5 (W0 = −0.25, n = 8) the two
#: implementations agree to 2e-13 over 500 steps. At the seed's α = 1e-3 the weights are ±1e5 and
#: the stiff cables (720 kN/m) make the transform amplify rounding ~10× every few steps: two
#: correct implementations drift apart (1e-9 after 8 steps, 1e-5 after 36), so only the first
#: steps are compared. Measured accuracy against the simulated truth over 3 s: joint-angle MAE
#: 1.7e-5 / 9.1e-5 rad at α = 1e-3, 1.3e-5 / 3.8e-5 rad at α = 0.5 (docs/estimation.md).
NONLINEAR = [(0.5, 500, 1e-10), (1e-3, 10, 1e-8)]


@pytest.mark.parametrize(("alpha", "steps", "tol"), NONLINEAR)
def test_rust_matches_the_reference_on_the_raven_transmission(alpha, steps, tol):
    """Nonlinear process (RK4, 2 substeps of a frictional, coupled cable transmission), only
    the motor angles measured, negative W0: means and S·Sᵀ within `tol` of their scale."""
    model, tref, q, r, p0, x0 = raven_setup()
    u, y = raven_log(model, steps)
    rust = ck.SrUkf(model, x0, p0, q, r, dt=1e-3, substeps=SUB, states=[0, 4], alpha=alpha)
    assert rust.weights[2][0] < 0

    ref = SrUkfRef(raven_fx(tref), lambda x, uk: x[[0, 4]], x0, p0, q, r, alpha=alpha)
    step_both_and_compare(rust, ref, u, y, tol)


@pytest.mark.parametrize(("alpha", "steps", "tol"), [(0.5, 500, 1e-10), (1e-3, 2, 5e-8)])
def test_rust_matches_the_reference_with_a_nonlinear_measurement(alpha, steps, tol):
    """A measured cable tension (a nonlinear output) next to a motor angle: the sigma-point
    measurement update (eqs 3.16–3.21), which a linear `H` replaces by its closed form. At
    α = 0.5 the two agree to 4e-13 over 500 steps. At α = 1e-3 the ±6e4 weights multiply the
    rounding of 40 N tensions (~1e-14 N) that differ by mN between points: ŷ carries ~2e-9 N in
    any implementation. The two sit 8e-9 apart after one step and 2e-8 after two (five noise
    draws), and the stiff transmission then amplifies the gap as for the process alone."""
    model, tref, q, _, p0, x0 = raven_setup()
    u, _ = raven_log(model, steps)
    names = model.output_names
    idx = [names.index("q_m1"), names.index("tension_a2")]
    sim = ck.simulate(model, u, 1e-3, x0, substeps=SUB, hold="zoh")
    rng = np.random.default_rng(7)
    noise = rng.normal(0, [1e-4, 0.1], (steps, 2))
    y = np.column_stack([sim["q_m1"], sim["tension_a2"]]) + noise
    r = np.diag([1e-8, 1e-2])
    rust = ck.SrUkf(model, x0, p0, q, r, dt=1e-3, substeps=SUB, outputs=idx, alpha=alpha)
    assert rust.weights[2][0] < 0

    ref = SrUkfRef(raven_fx(tref), lambda x, uk: tref.output(x, uk)[idx], x0, p0, q, r, alpha=alpha)
    step_both_and_compare(rust, ref, u, y, tol)


def filterpy_ukf(fx, hx, n, p, x0, p0, q, r, alpha=1e-3):
    pts = MerweScaledSigmaPoints(n, alpha=alpha, beta=2.0, kappa=0.0)
    ukf = UnscentedKalmanFilter(dim_x=n, dim_z=p, dt=1e-3, fx=fx, hx=hx, points=pts)
    ukf.x, ukf.P, ukf.Q, ukf.R = x0.copy(), p0.copy(), q.copy(), r.copy()
    return ukf


@pytest.mark.parametrize("alpha", [1e-3, 0.5])
def test_peer_filterpy_on_a_linear_system(alpha):
    f, b, h, q, r, p0, x0 = linear_system()
    us, ys = linear_log(300, seed=4)
    rust = ck.SrUkf.linear(f, h, x0, p0, q, r, B=b, alpha=alpha)
    peer = filterpy_ukf(lambda x, dt, u: f @ x + b @ u, lambda x: h @ x, 4, 2, x0, p0, q, r, alpha=alpha)
    for k in range(300):
        rust.step(us[k], ys[k])
        peer.predict(u=us[k])
        peer.update(ys[k])
        np.testing.assert_allclose(rust.x, peer.x, rtol=0, atol=1e-8)
        np.testing.assert_allclose(rust.P, peer.P, rtol=0, atol=1e-8 * np.abs(peer.P).max())


@pytest.mark.parametrize(("alpha", "steps", "tol"), [(0.5, 300, 1e-8)])
def test_peer_filterpy_on_the_raven_transmission_with_negative_w0(alpha, steps, tol):
    """filterpy's UKF with Merwe's points on the same nonlinear transmission (W0 = −0.25), only
    the motor angles measured: per-step agreement. At α = 1e-3 (W0 = −1.3e5) filterpy's literal
    weighted sums leave the exact transform by ~1e-8 within 3 steps on this stiff model, so the
    seed's α is compared with filterpy on the linear system instead."""
    model, _, q, r, p0, x0 = raven_setup()
    u, y = raven_log(model, steps, seed=5)
    rust = ck.SrUkf(model, x0, p0, q, r, dt=1e-3, substeps=SUB, states=[0, 4], alpha=alpha)
    assert rust.weights[2][0] < 0

    def fx(x, dt, u):
        two = np.ascontiguousarray(np.vstack([u, u]))
        return ck.simulate(model, two, dt, x, substeps=SUB, hold="zoh").states[1]

    peer = filterpy_ukf(fx, lambda x: x[[0, 4]], 8, 2, x0, p0, q, r, alpha=alpha)
    for k in range(steps):
        rust.step(u[k], y[k])
        peer.predict(u=u[k])
        peer.update(y[k])
        xs = np.abs(peer.x) + np.sqrt(np.abs(np.diag(peer.P)))
        assert np.all(np.abs(rust.x - peer.x) <= tol * xs), k
        ps = np.sqrt(np.abs(np.outer(np.diag(peer.P), np.diag(peer.P))))
        assert np.all(np.abs(rust.P - peer.P) <= tol * ps), k


# ---- failures, masks, bad input ------------------------------------------------------------------


def test_forced_downdate_failure_is_recovered_and_counted():
    """A near-perfect measurement (R = 1e-30 against a prior variance of 1): the rank-one
    downdate loses positive definiteness in floating point; the filter rebuilds the covariance,
    projects it onto the positive definite cone and counts the recovery."""
    ukf = ck.SrUkf.linear(
        np.eye(2), np.array([[1.0, 0.0]]), np.zeros(2), np.eye(2), np.zeros((2, 2)), np.array([[1e-30]])
    )
    ukf.step(np.zeros(0), np.array([0.5]))
    h = ukf.health
    assert h.recovered >= 1 and h.recoveries_total >= 1
    assert np.all(np.isfinite(ukf.P)) and 0 <= ukf.P[0, 0] < 1e-6 and abs(ukf.P[1, 1] - 1) < 1e-9
    assert abs(ukf.x[0] - 0.5) < 1e-9
    for _ in range(5):  # keeps going
        ukf.step(np.zeros(0), np.array([0.5]))
    assert np.all(np.isfinite(ukf.x)) and np.all(np.isfinite(ukf.P)) and abs(ukf.x[0] - 0.5) < 1e-9


def test_nan_measurement_is_an_error_unless_masked():
    f, b, h, q, r, p0, x0 = linear_system()
    ukf = ck.SrUkf.linear(f, h, x0, p0, q, r, B=b)
    ukf.step(np.ones(1), np.array([0.1, 0.2]))
    x_before, p_before = ukf.x.copy(), ukf.P.copy()
    with pytest.raises(ck.NotFiniteError, match="mask"):
        ukf.step(np.ones(1), np.array([0.1, np.nan]))
    # refused before the prediction: the filter is where it was
    np.testing.assert_array_equal(ukf.x, x_before)
    np.testing.assert_array_equal(ukf.P, p_before)
    ukf = ck.SrUkf.linear(f, h, x0, p0, q, r, B=b)
    ukf.step(np.zeros(1), np.array([0.1, np.nan]), [True, False])
    assert ukf.health.measured == 1 and np.all(np.isfinite(ukf.x))
    _, ys = linear_log(10)
    ys[4, 1] = np.nan
    with pytest.raises(ck.NotFiniteError, match=r"row 4, column 1"):
        ck.SrUkf.linear(f, h, x0, p0, q, r, B=b).run(np.zeros((10, 1)), ys)
    mask = ~np.isnan(ys)
    res = ck.SrUkf.linear(f, h, x0, p0, q, r, B=b).run(np.zeros((10, 1)), ys, mask)
    assert res.measured[4] == 1 and np.all(np.isfinite(res.x))


@pytest.mark.parametrize(
    ("change", "error", "match"),
    [
        ({"p0": np.array([[1.0, 2.0], [2.0, 1.0]])}, ck.ParameterError, "P0"),
        ({"p0": np.array([[1.0, 0.5], [0.0, 1.0]])}, ck.ParameterError, "symmetric"),
        ({"r": np.array([[0.0]])}, ck.ParameterError, "R"),
        ({"q": -np.eye(2)}, ck.ParameterError, "Q"),
        ({"x0": np.zeros(3)}, ck.ShapeError, "x0"),
        ({"p0": np.eye(3)}, ck.ShapeError, "P0"),
        ({"x0": np.array([0.0, np.inf])}, ck.NotFiniteError, "x0"),
        ({"alpha": 0.0}, ck.ParameterError, "alpha"),
    ],
)
def test_bad_filter_input_raises_typed_errors(change, error, match):
    args = {"x0": np.zeros(2), "p0": np.eye(2), "q": np.zeros((2, 2)), "r": np.eye(1), "alpha": 1e-3}
    args |= change
    with pytest.raises(error, match=match):
        ck.SrUkf.linear(
            np.eye(2),
            np.array([[1.0, 0.0]]),
            args["x0"],
            args["p0"],
            args["q"],
            args["r"],
            alpha=args["alpha"],
        )


def test_step_shape_errors_and_measurement_choice():
    model = ck.CableTransmission.raven2(2)
    n = model.n_states
    ukf = ck.SrUkf(
        model, np.zeros(n), np.eye(n) * 1e-4, np.eye(n) * 1e-8, np.eye(2) * 1e-8, dt=1e-3, states=[0, 4]
    )
    with pytest.raises(ck.ShapeError, match="u"):
        ukf.step(np.zeros(3), np.zeros(2))
    with pytest.raises(ck.ShapeError, match="mask"):
        ukf.step(np.zeros(4), np.zeros(2), [True])
    with pytest.raises(ck.ParameterError, match="exactly one measurement"):
        ck.SrUkf(model, np.zeros(n), np.eye(n), np.eye(n), np.eye(2), dt=1e-3)
    with pytest.raises(ck.ParameterError, match="index"):
        ck.SrUkf(model, np.zeros(n), np.eye(n), np.eye(n), np.eye(2), dt=1e-3, states=[0, 99])
    # tension outputs as a nonlinear measurement
    names = model.output_names
    idx = [names.index("tension_a1"), names.index("tension_b1")]
    ukf = ck.SrUkf(model, np.zeros(n), np.eye(n) * 1e-6, np.eye(n) * 1e-10, np.eye(2), dt=1e-3, outputs=idx)
    ukf.step(np.zeros(4), np.array([40.0, 40.0]))
    assert np.all(np.isfinite(ukf.x))


# ---- square-root URTS smoother -------------------------------------------------------------------


@pytest.mark.parametrize("alpha", [1e-3, 0.5])
def test_smoother_equals_the_linear_rts_smoother(alpha):
    """On a linear system the unscented RTS smoother is the Rauch–Tung–Striebel smoother:
    means and covariances at every sample (the last equals the filter)."""
    f, b, h, q, r, p0, x0 = linear_system()
    us, ys = linear_log(200, seed=6)
    res = ck.SrUkf.linear(f, h, x0, p0, q, r, B=b, alpha=alpha).run(us, ys, smooth=True)
    # exact KF forward, RTS backward
    xf, pf, xp, pp = [], [], [], []
    x, p = x0.copy(), p0.copy()
    for k in range(200):
        x, p = f @ x + b @ us[k], f @ p @ f.T + q
        xp.append(x), pp.append(p)
        s = h @ p @ h.T + r
        kg = p @ h.T @ np.linalg.inv(s)
        x, p = x + kg @ (ys[k] - h @ x), p - kg @ s @ kg.T
        xf.append(x), pf.append(p)
    xs, ps = [xf[-1]], [pf[-1]]
    for k in range(198, -1, -1):
        # the prediction from k to k+1 uses the input of sample k+1
        g = pf[k] @ f.T @ np.linalg.inv(pp[k + 1])
        xs.insert(0, xf[k] + g @ (xs[0] - xp[k + 1]))
        ps.insert(0, pf[k] + g @ (ps[0] - pp[k + 1]) @ g.T)
    xs, ps = np.array(xs), np.array(ps)
    tol = 1e-9 if alpha == 0.5 else 2e-9
    np.testing.assert_allclose(res.x_smooth, xs, rtol=0, atol=tol * (1 + np.abs(xs).max()))
    p_sm = np.einsum("tij,tkj->tik", res.S_smooth, res.S_smooth)
    np.testing.assert_allclose(p_sm, ps, rtol=0, atol=1e-9 * np.abs(ps).max())
    np.testing.assert_array_equal(res.x_smooth[-1], res.x[-1])
    # smoothing never increases the variance
    assert np.all(np.einsum("tii->ti", p_sm) <= np.einsum("tij,tij->ti", res.S, res.S) * (1 + 1e-9))


def test_smoother_reduces_the_joint_angle_error_on_the_raven_twin():
    """Offline: the smoothed joint angles of a Raven-II twin run scatter less around the truth
    than the filtered ones on every joint, and the mean error does not grow. (Joint 2's error
    is mostly a bias from the nominal model's mismatch, -2.9e-4 m against a 1.6e-4 m spread;
    a smoother cannot remove a bias, so its mean absolute error stays within rounding of the
    filter's and is not compared strictly.)"""
    from cablekit.twins import raven_joint_state_experiment

    run = raven_joint_state_experiment("A", seconds=4.0, seed=2)
    model = run.nominal
    n = model.n_states
    u = np.concatenate([run.tau_m, np.zeros_like(run.tau_m)], axis=1)
    u = np.ascontiguousarray(np.vstack([u[:1], u[:-1]]))
    x0 = np.zeros(n)
    x0[0::4] = run.q_m[0]
    x0[2::4] = ck.kinematic_joint_angles(model, run.q_m[:1])[0]
    q = np.diag(np.tile([0.0, 1e-3, 0.0, 1e-3], 3))
    p0 = np.diag(np.tile([1e-9, 1e-2, 1e-6, 1e-2], 3))
    ukf = ck.SrUkf(model, x0, p0, q, 1.8e-9 * np.eye(3), dt=run.dt, substeps=6, states=[0, 4, 8])
    res = ukf.run(u, run.q_m, smooth=True)
    s = slice(1000, -10)
    dev_f = res.x[s][:, 2::4] - run.q_l_true[s]
    dev_s = res.x_smooth[s][:, 2::4] - run.q_l_true[s]
    spread_f, spread_s = dev_f.std(axis=0), dev_s.std(axis=0)
    assert np.all(spread_s < 0.98 * spread_f), (spread_s, spread_f)
    err_f, err_s = np.abs(dev_f).mean(axis=0), np.abs(dev_s).mean(axis=0)
    assert np.all(err_s < 1.01 * err_f), (err_s, err_f)
    assert err_s[0] < 0.5 * err_f[0], (err_s, err_f)
