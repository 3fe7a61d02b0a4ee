"""Your own model in the sr-UKF (issue #39 §3): the cost per step of `SrUkf.from_functions`
against the built-in models and against filterpy's `UnscentedKalmanFilter` on the same callbacks,
measured in one run (the machines are shared: compare the ratios, not the microseconds).

* Raven-II 3-link transmission (n = 12, m = 3 motor encoders, 10 kHz): the built-in model
  (`SrUkf(model, ...)`, RK4 in Rust, sigma points in SIMD lanes) against the same RK4 step
  called from Python per sigma point (`fx = model.rk4_step`), in cablekit and in filterpy.
* A nonlinear pendulum seen by a camera (n = 2, p = 2) in NumPy: per sigma point, vectorised
  (all 2n + 1 points in one call) and filterpy.
* A 4-state linear system: the built-in `SrUkf.linear` against the same matrices as callbacks.

Usage (with a release build installed): python benches/srukf_user_bench.py
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import cablekit as ck  # noqa: E402
from tests.test_srukf import linear_log, linear_system  # noqa: E402
from tests.test_srukf_user import (  # noqa: E402
    DT,
    P0,
    X0,
    Q,
    R,
    pendulum_fx,
    pendulum_fx_many,
    pendulum_log,
    tip_hx,
    tip_hx_many,
)


def per_step_us(step: Callable[[int], None], steps: int, reps: int = 5) -> float:
    """Median over ``reps`` of the mean µs per call of ``step(k)``, ``k < steps``."""
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        for k in range(steps):
            step(k)
        times.append((time.perf_counter() - t0) / steps)
    return 1e6 * float(np.median(times))


def filterpy_filter(fx, hx, n, p, x0, p0, q, r, dt, alpha=1e-3) -> UnscentedKalmanFilter:
    pts = MerweScaledSigmaPoints(n, alpha=alpha, beta=2.0, kappa=0.0)
    peer = UnscentedKalmanFilter(dim_x=n, dim_z=p, dt=dt, fx=fx, hx=hx, points=pts)
    peer.x, peer.P, peer.Q, peer.R = x0.copy(), p0.copy(), q.copy(), r.copy()
    return peer


def raven_rows() -> list[tuple[str, float]]:
    model = ck.CableTransmission.raven2(3)
    n, dt, steps = model.n_states, 1e-4, 400
    t = np.arange(steps) * dt
    u = np.zeros((steps, 6))
    u[:, :3] = np.array([0.1, 0.05, 0.2]) * np.sin(6.0 * t)[:, None]
    u = np.ascontiguousarray(u)
    y = np.ascontiguousarray(ck.simulate(model, u, dt, np.zeros(n)).states[:, [0, 4, 8]])
    p0, q, r = 1e-6 * np.eye(n), 1e-9 * np.eye(n), 1e-8 * np.eye(3)

    def fx(x, dt_, uk):
        return model.rk4_step(x, uk, dt_)

    def hx(x):
        return x[[0, 4, 8]]

    built_in = ck.SrUkf(model, np.zeros(n), p0, q, r, dt=dt, states=[0, 4, 8])
    mine = ck.SrUkf.from_functions(fx, hx, np.zeros(n), p0, q, r, dt=dt, n_inputs=6)
    peer = filterpy_filter(fx, hx, n, 3, np.zeros(n), p0, q, r, dt)

    def peer_step(k: int) -> None:
        peer.predict(uk=u[k])
        peer.update(y[k])

    name = "Raven-II 3-link"
    return [
        (f"{name}, built-in model (Rust RK4)", per_step_us(lambda k: built_in.step(u[k], y[k]), steps)),
        (f"{name}, fx = model.rk4_step per sigma point", per_step_us(lambda k: mine.step(u[k], y[k]), steps)),
        (f"{name}, filterpy with the same fx", per_step_us(peer_step, steps, reps=3)),
    ]


def pendulum_rows() -> list[tuple[str, float]]:
    us, ys = pendulum_log(400, seed=1)
    one = ck.SrUkf.from_functions(pendulum_fx, tip_hx, X0, P0, Q, R, dt=DT, n_inputs=1, alpha=0.5)
    many = ck.SrUkf.from_functions(
        pendulum_fx_many, tip_hx_many, X0, P0, Q, R, dt=DT, n_inputs=1, vectorized=True, alpha=0.5
    )
    peer = filterpy_filter(pendulum_fx, tip_hx, 2, 2, X0, P0, Q, R, DT, alpha=0.5)

    def peer_step(k: int) -> None:
        peer.predict(u=us[k])
        peer.update(ys[k])

    return [
        ("pendulum (NumPy), per sigma point", per_step_us(lambda k: one.step(us[k], ys[k]), 400)),
        ("pendulum (NumPy), vectorised", per_step_us(lambda k: many.step(us[k], ys[k]), 400)),
        ("pendulum (NumPy), filterpy", per_step_us(peer_step, 400)),
    ]


def linear_rows() -> list[tuple[str, float]]:
    f, b, h, q, r, p0, x0 = linear_system()
    us, ys = linear_log(400, seed=4)
    built_in = ck.SrUkf.linear(f, h, x0, p0, q, r, B=b)
    mine = ck.SrUkf.from_functions(
        lambda x, dt, u: f @ x + b @ u, lambda x: h @ x, x0, p0, q, r, dt=1.0, n_inputs=b.shape[1]
    )
    many = ck.SrUkf.from_functions(
        lambda xs, dt, u: xs @ f.T + b @ u,
        lambda xs: xs @ h.T,
        x0,
        p0,
        q,
        r,
        dt=1.0,
        n_inputs=b.shape[1],
        vectorized=True,
    )
    return [
        ("linear n = 4, built-in SrUkf.linear", per_step_us(lambda k: built_in.step(us[k], ys[k]), 400)),
        ("linear n = 4, callbacks per sigma point", per_step_us(lambda k: mine.step(us[k], ys[k]), 400)),
        ("linear n = 4, callbacks vectorised", per_step_us(lambda k: many.step(us[k], ys[k]), 400)),
    ]


def main() -> int:
    groups = [raven_rows(), pendulum_rows(), linear_rows()]
    print("| model and form | µs per step | against the group's first row |")
    print("|---|---|---|")
    for rows in groups:
        base = rows[0][1]
        for name, us in rows:
            print(f"| {name} | {us:,.1f} | {us / base:,.1f}× |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
