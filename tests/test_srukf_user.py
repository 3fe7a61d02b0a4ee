"""Your own model in the square-root UKF (issue #39 §3): ``SrUkf.from_functions(fx, hx, ...)``
in filterpy's convention, per sigma point or vectorised, against filterpy's
``UnscentedKalmanFilter`` (the peer), against the NumPy reference filter of ``test_srukf.py``
and against the built-in linear model; callback failures, recovery and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import cablekit as ck
from tests.test_srukf import SrUkfRef, linear_log, linear_system

DT = 0.01


def pendulum_fx(x: np.ndarray, dt: float, u: np.ndarray | None = None) -> np.ndarray:
    """A damped pendulum driven by a torque ``u``: ``[angle, speed]`` one explicit-midpoint
    step later (nonlinear: ``sin``)."""
    tau = 0.0 if u is None else float(u[0])

    def f(s: np.ndarray) -> np.ndarray:
        return np.array([s[1], -9.81 * math.sin(s[0]) - 0.4 * s[1] + tau])

    mid = x + 0.5 * dt * f(x)
    return x + dt * f(mid)


def pendulum_fx_many(xs: np.ndarray, dt: float, u: np.ndarray | None = None) -> np.ndarray:
    tau = 0.0 if u is None else float(u[0])

    def f(s: np.ndarray) -> np.ndarray:
        return np.column_stack([s[:, 1], -9.81 * np.sin(s[:, 0]) - 0.4 * s[:, 1] + tau])

    mid = xs + 0.5 * dt * f(xs)
    return xs + dt * f(mid)


def tip_hx(x: np.ndarray) -> np.ndarray:
    """The tip of a 0.5 m pendulum, seen by a camera: ``(x, y)`` (nonlinear)."""
    return np.array([0.5 * math.sin(x[0]), -0.5 * math.cos(x[0])])


def tip_hx_many(xs: np.ndarray) -> np.ndarray:
    return np.column_stack([0.5 * np.sin(xs[:, 0]), -0.5 * np.cos(xs[:, 0])])


X0 = np.array([0.3, 0.0])
P0 = np.diag([0.05, 0.2])
Q = np.diag([1e-6, 1e-4])
R = np.diag([1e-4, 1e-4])


def pendulum_log(steps: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    x, us, ys = np.array([0.8, 0.0]), [], []
    for k in range(steps):
        u = np.array([0.5 * math.sin(0.05 * k)])
        x = pendulum_fx(x, DT, u) + rng.normal(0, np.sqrt(np.diag(Q)))
        us.append(u)
        ys.append(tip_hx(x) + rng.normal(0, 1e-2, 2))
    return np.array(us), np.array(ys)


def filterpy_pendulum(alpha: float, beta: float = 2.0, kappa: float = 0.0) -> UnscentedKalmanFilter:
    pts = MerweScaledSigmaPoints(2, alpha=alpha, beta=beta, kappa=kappa)
    ukf = UnscentedKalmanFilter(dim_x=2, dim_z=2, dt=DT, fx=pendulum_fx, hx=tip_hx, points=pts)
    ukf.x, ukf.P, ukf.Q, ukf.R = X0.copy(), P0.copy(), Q.copy(), R.copy()
    return ukf


@pytest.mark.parametrize(("alpha", "kappa"), [(0.5, 0.0), (1.0, 1.0), (0.1, 0.0)])
@pytest.mark.parametrize("vectorized", [False, True])
def test_agrees_with_filterpy_to_1e9_on_a_nonlinear_model(alpha, kappa, vectorized):
    """The same model, the same Merwe points and weights: cablekit's square-root filter and
    filterpy's covariance filter agree to 1e-9 at every step (nonlinear process and
    measurement, 400 steps, inputs)."""
    us, ys = pendulum_log(400, seed=1)
    fx, hx = (pendulum_fx_many, tip_hx_many) if vectorized else (pendulum_fx, tip_hx)
    mine = ck.SrUkf.from_functions(
        fx, hx, X0, P0, Q, R, dt=DT, n_inputs=1, vectorized=vectorized, alpha=alpha, kappa=kappa
    )
    peer = filterpy_pendulum(alpha, kappa=kappa)
    worst = 0.0
    for u, y in zip(us, ys, strict=True):
        mine.step(u, y)
        peer.predict(u=u)
        peer.update(y)
        scale = np.sqrt(np.diag(peer.P))
        worst = max(worst, float(np.max(np.abs(mine.x - peer.x) / scale)))
        np.testing.assert_allclose(mine.x, peer.x, rtol=0, atol=1e-9)
        np.testing.assert_allclose(mine.P, peer.P, rtol=0, atol=1e-9 * np.abs(peer.P).max())
    assert mine.health.steps == 400 and worst < 1e-6


def test_the_vectorised_form_equals_the_per_point_form():
    us, ys = pendulum_log(200, seed=2)
    a = ck.SrUkf.from_functions(pendulum_fx, tip_hx, X0, P0, Q, R, dt=DT, n_inputs=1, alpha=0.3)
    b = ck.SrUkf.from_functions(
        pendulum_fx_many, tip_hx_many, X0, P0, Q, R, dt=DT, n_inputs=1, vectorized=True, alpha=0.3
    )
    ra, rb = a.run(us, ys), b.run(us, ys)
    np.testing.assert_allclose(ra.x, rb.x, rtol=0, atol=1e-13)
    np.testing.assert_allclose(ra.S, rb.S, rtol=0, atol=1e-13)


def test_a_user_linear_model_equals_the_built_in_linear_model_and_the_reference():
    """``F·x + B·u`` and ``H·x`` as callbacks: the built-in linear filter (closed-form
    measurement, folded downdate) and the NumPy reference filter, to 1e-9, at the seed's
    α = 1e-3 (a negative 0th weight)."""
    f, b, h, q, r, p0, x0 = linear_system()
    us, ys = linear_log(300, seed=4)
    mine = ck.SrUkf.from_functions(
        lambda x, dt, u: f @ x + b @ u, lambda x: h @ x, x0, p0, q, r, dt=1.0, n_inputs=b.shape[1]
    )
    built_in = ck.SrUkf.linear(f, h, x0, p0, q, r, B=b)
    ref = SrUkfRef(lambda x, u: f @ x + b @ u, lambda x, u: h @ x, x0, p0, q, r, alpha=1e-3)
    for k in range(300):
        mine.step(us[k], ys[k])
        built_in.step(us[k], ys[k])
        ref.step(us[k], ys[k])
        np.testing.assert_allclose(mine.x, built_in.x, rtol=0, atol=1e-9)
        np.testing.assert_allclose(mine.P, built_in.P, rtol=0, atol=1e-9 * np.abs(built_in.P).max())
        np.testing.assert_allclose(mine.x, ref.x, rtol=0, atol=1e-9)


def test_where_filterpy_fails_not_positive_definite_the_user_model_recovers():
    """A camera far more precise than the prior (R = 1e-30 against P₀ = 1): filterpy's update
    leaves a covariance that is not positive definite, and its next predict raises in the
    Cholesky factorisation (rlabbe/filterpy #62, #214, #218). The same model in cablekit:
    the failed downdate is detected, the covariance rebuilt and projected, the recovery
    counted, and the filter keeps going."""
    r = np.diag([1e-30, 1e-30])
    p0 = np.eye(2)
    peer = filterpy_pendulum(1e-3)
    peer.P, peer.R = p0.copy(), r.copy()
    us, ys = pendulum_log(20, seed=3)
    with pytest.raises(np.linalg.LinAlgError):
        for u, y in zip(us, ys, strict=True):
            peer.predict(u=u)
            peer.update(y)
    mine = ck.SrUkf.from_functions(pendulum_fx, tip_hx, X0, p0, Q, r, dt=DT, n_inputs=1)
    mine.run(us, ys)
    assert mine.health.recoveries_total >= 1 and mine.health.steps == 20
    assert np.all(np.isfinite(mine.x)) and np.all(np.linalg.eigvalsh(mine.P) >= 0.0)
    seen = math.atan2(ys[-1][0], -ys[-1][1])  # the angle the last (noisy) camera sample shows
    assert abs(mine.x[0] - seen) < 0.05


def test_an_exception_in_a_callback_is_raised_and_the_step_undone():
    calls = {"n": 0}

    def flaky(x, dt, u):
        calls["n"] += 1
        if calls["n"] == 12:
            raise ValueError("the user's model failed")
        return pendulum_fx(x, dt, u)

    ukf = ck.SrUkf.from_functions(flaky, tip_hx, X0, P0, Q, R, dt=DT, n_inputs=1)
    us, ys = pendulum_log(3, seed=5)
    ukf.step(us[0], ys[0])  # five sigma points: calls 1-5
    ukf.step(us[1], ys[1])  # 6-10
    x, p, steps = ukf.x.copy(), ukf.P.copy(), ukf.health.steps
    with pytest.raises(ValueError, match="the user's model failed"):
        ukf.step(us[2], ys[2])
    assert np.array_equal(ukf.x, x) and np.array_equal(ukf.P, p) and ukf.health.steps == steps
    ukf.step(us[2], ys[2])  # and the filter goes on
    assert ukf.health.steps == steps + 1


@pytest.mark.parametrize(
    ("fx", "hx", "error"),
    [
        (lambda x, dt: np.zeros(3), tip_hx, ck.ShapeError),
        (lambda x, dt: "abc", tip_hx, ck.DTypeError),
        (pendulum_fx, lambda x: np.zeros((2, 2)), ck.ShapeError),
        (lambda x, dt: np.array([np.nan, 0.0]), tip_hx, ck.NotFiniteError),
        (pendulum_fx, lambda x: [x[0], None], ck.NotFiniteError),  # NumPy reads None as NaN
        (pendulum_fx, lambda x: {"a": 1}, ck.DTypeError),
    ],
)
def test_a_wrong_return_is_a_typed_error_and_loses_nothing(fx, hx, error):
    ukf = ck.SrUkf.from_functions(fx, hx, X0, P0, Q, R, dt=DT)
    with pytest.raises(error):
        ukf.step(np.zeros(0), np.zeros(2))
    assert np.array_equal(ukf.x, X0) and np.allclose(ukf.P, P0) and ukf.health.steps == 0


def test_the_vectorised_form_checks_the_rows_it_gets_back():
    ukf = ck.SrUkf.from_functions(lambda xs, dt: xs[:-1], tip_hx_many, X0, P0, Q, R, dt=DT, vectorized=True)
    with pytest.raises(ck.ShapeError, match="one row per state"):
        ukf.predict(np.zeros(0))


_BAD = st.one_of(
    st.sampled_from([None, "abc", 5, 1.5, math.nan, math.inf, -1.0, 0.0, 1e308, [1.0, 2.0], object()]),
    st.builds(np.zeros, st.sampled_from([(0,), (3,), (2, 3), (3, 3)])),
    st.just(np.eye(2, dtype=np.float32)),
    st.just(np.array([[1.0, 2.0], [2.0, 1.0]])),  # not positive definite
    st.just(np.array([[np.nan, 0.0], [0.0, 1.0]])),
)


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(slot=st.sampled_from(["fx", "hx", "x0", "P0", "Q", "R", "dt", "n_inputs", "alpha", "kappa"]), bad=_BAD)
def test_from_functions_refuses_bad_arguments_with_typed_errors(slot, bad):
    """Any argument replaced by a drawn bad value: a typed error at construction, or a filter
    whose step is finite or a typed error — never a builtin error, a crash or a NaN."""
    args = {"fx": pendulum_fx, "hx": tip_hx, "x0": X0, "P0": P0, "Q": Q, "R": R}
    kwargs = {"dt": DT, "n_inputs": 0}
    (args if slot in args else kwargs)[slot] = bad
    try:
        ukf = ck.SrUkf.from_functions(*args.values(), **kwargs)
    except ck.CablekitError:
        return
    except (TypeError, OverflowError):
        # PyO3's conversion of a scalar of another Python type (documented for the bindings)
        assert slot in ("dt", "n_inputs", "alpha", "kappa"), slot
        return
    try:
        with np.errstate(all="ignore"):  # an overflow in the user's NumPy is their inf, refused
            ukf.step(np.zeros(ukf.n_inputs), np.zeros(2))
    except ck.CablekitError:
        return
    assert np.all(np.isfinite(ukf.x)) and np.all(np.isfinite(ukf.P))


def test_the_migration_example_runs_and_agrees(tmp_path):
    """`examples/filterpy_migration.py` (the docs' migration guide): agreement with filterpy
    (exit 0 only below 1e-9), filterpy's failure and cablekit's recovery in its table."""
    from tests.examples import run_example

    done = run_example("filterpy_migration.py", tmp_path, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    table = (tmp_path / "table.md").read_text()
    assert "LinAlgError" in table and "covariance recoveries" in table


# ---- DualSrUkf over your own model ----------------------------------------------------------------


def test_a_user_dual_model_equals_the_built_in_dual_filter_on_the_raven_transmission():
    """The built-in dual filter over a transmission's named parameter, and the same model as a
    user's ``fx(x, θ, dt, u)`` (the transmission rebuilt with θ, one RK4 step) and ``hx``:
    states, parameters and their standard deviations agree to 1e-9 of their scales at α = 0.5
    (4e-13 measured). At the seed's α = 1e-3 (W₀ ≈ −1e6) the two roundings — the built-in's
    closed-form linear update and SIMD RK4, the sigma points through the callbacks — part at
    1e-13 and grow to 1e-7 over the 120 steps of this stiff identification."""
    model = ck.CableTransmission.raven2(1)
    names = ["cable_stiffness[0]"]
    k = float(model.parameter_values(names)[0])
    n, steps, dt = model.n_states, 120, 1e-3
    t = np.arange(steps) * dt
    u = np.ascontiguousarray(np.column_stack([0.2 * np.sin(20 * t), np.zeros(steps)]))
    truth = model.with_parameter_values(names, np.array([1.1 * k]))
    y = np.ascontiguousarray(ck.simulate(truth, u, dt, np.zeros(n)).states[:, [0, 2]])
    y += 1e-6 * np.random.default_rng(0).standard_normal(y.shape)
    p0, q, r = 1e-6 * np.eye(n), 1e-9 * np.eye(n), 1e-10 * np.eye(2)
    p0_theta, q_theta = np.array([[(0.2 * k) ** 2]]), np.array([[(1e-3 * k) ** 2]])
    built_in = ck.DualSrUkf(
        model, names, np.zeros(n), p0, q, p0_theta, q_theta, r, dt=dt, states=[0, 2], alpha=0.5
    )

    def fx(x, theta, dt_, uk):
        return model.with_parameter_values(names, theta).rk4_step(x, uk, dt_)

    mine = ck.DualSrUkf.from_functions(
        fx, lambda x: x[[0, 2]], np.zeros(n), p0, q, np.array([k]), p0_theta, q_theta, r, dt=dt, n_inputs=2,
        bounds=[(0.01 * k, 100 * k)], alpha=0.5,
    )  # fmt: skip
    a, b = built_in.run(u, y), mine.run(u, y)
    np.testing.assert_allclose(b.theta, a.theta, rtol=1e-9)
    np.testing.assert_allclose(b.theta_std, a.theta_std, rtol=1e-9)
    np.testing.assert_allclose(b.x, a.x, rtol=0, atol=1e-9 * np.abs(a.x).max())
    assert abs(b.theta[-1, 0] / k - 1.0) > 0.02  # the estimate moved: the agreement is not trivial


def test_a_user_dual_model_finds_an_unknown_parameter():
    """``x' = x + dt·(−a·x + u)``, ``a`` unknown (prior 1, truth 2.5): the parameter filter
    finds it within 3 % and its standard deviation covers the error."""
    dt, steps, a_true = 0.01, 1500, 2.5
    rng = np.random.default_rng(7)
    us = np.sin(0.7 * np.arange(steps) * dt)[:, None] * 3.0
    x, ys = np.zeros(1), []
    for k in range(steps):
        x = x + dt * (-a_true * x + us[k])
        ys.append(x + 1e-3 * rng.standard_normal(1))

    def fx(x, theta, dt_, u):
        return x + dt_ * (-theta[0] * x + u[0])

    one = np.eye(1)
    dual = ck.DualSrUkf.from_functions(
        fx, lambda x: x, np.zeros(1), 1e-4 * one, 1e-8 * one, np.ones(1), one, 1e-8 * one, 1e-6 * one,
        dt=dt, n_inputs=1,
    )  # fmt: skip
    run = dual.run(np.ascontiguousarray(us), np.array(ys))
    assert abs(run.theta[-1, 0] - a_true) < 0.03 * a_true
    assert abs(run.theta[-1, 0] - a_true) < 4 * run.theta_std[-1, 0] + 1e-3


def test_a_user_dual_model_raises_its_exception_and_refuses_bad_arguments():
    def fx(x, theta, dt_):
        if theta[0] < 0:
            raise RuntimeError("negative parameter")
        return x

    def dual(fx=fx, theta0=None, **kw):
        one, theta0 = np.eye(1), -np.ones(1) if theta0 is None else theta0
        return ck.DualSrUkf.from_functions(
            fx, lambda x: x, np.zeros(1), one, one, theta0, one, one, one, dt=0.1, **kw
        )

    with pytest.raises(RuntimeError, match="negative parameter"):
        dual().run(np.zeros((3, 0)), np.zeros((3, 1)))
    with pytest.raises(ck.DTypeError, match="fx"):
        dual(fx=5)
    with pytest.raises(ck.CablekitError, match="theta0"):
        dual(theta0=np.full(1, np.nan))
    with pytest.raises(ck.CablekitError, match="bounds"):
        dual(theta0=np.ones(1), bounds=[(2.0, 1.0)])
