"""Python-side sr-UKF budgets (issue #4): `SrUkf.step()` on the Raven-II 3-link transmission
(n = 12, m = 3 motor encoders, RK4), and filterpy's `UnscentedKalmanFilter` with Merwe's points
on the same model in the same run, two ways:

* the process in NumPy (the test suite's reference RK4), as a Python user of filterpy writes it
  and as the issue's anchor was measured (filterpy ≈ 1.9 ms per step): the ratio the >= 500x
  goal is checked on;
* the process calling cablekit's Rust RK4 step, so that only the filters differ: printed as
  the filters-only ratio.

Usage (with a release build installed): python benches/srukf_bench.py
"""

from __future__ import annotations

import sys
import time
import tomllib
from pathlib import Path

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import cablekit as ck  # noqa: E402
from tests.reference import rk4  # noqa: E402
from tests.reference.transmission import TransmissionRef  # noqa: E402


def setup(dt: float):
    model = ck.CableTransmission.raven2(3)
    n = model.n_states
    steps = 4000
    t = np.arange(steps) * dt
    u = np.zeros((steps, 6))
    u[:, :3] = np.array([0.1, 0.05, 0.2]) * np.sin(6.0 * t)[:, None]
    u = np.ascontiguousarray(u)
    sim = ck.simulate(model, u, dt, np.zeros(n))
    y = np.ascontiguousarray(
        sim.states[:, [0, 4, 8]] + 1e-5 * np.random.default_rng(0).normal(size=(steps, 3))
    )
    p0, q, r = 1e-6 * np.eye(n), 1e-9 * np.eye(n), 1e-8 * np.eye(3)
    return model, u, y, p0, q, r


def main() -> int:
    budgets = tomllib.loads((ROOT / "benches" / "budgets.toml").read_text())["python"]
    dt = 1e-4
    model, u, y, p0, q, r = setup(dt)
    n = model.n_states
    f = ck.SrUkf(model, np.zeros(n), p0, q, r, dt=dt, substeps=1, states=[0, 4, 8])
    for k in range(200):  # warm-up
        f.step(u[k], y[k])
    per = []
    for _rep in range(7):
        f.reset(np.zeros(n), p0)
        t0 = time.perf_counter()
        for k in range(2000):
            f.step(u[k], y[k])
        per.append((time.perf_counter() - t0) / 2000)
    step_us = 1e6 * float(np.median(per))
    f.reset(np.zeros(n), p0)
    t0 = time.perf_counter()
    f.run(u, y)
    run_us = 1e6 * (time.perf_counter() - t0) / len(u)

    pts = MerweScaledSigmaPoints(n, alpha=1e-3, beta=2.0, kappa=0.0)

    def peer_step_us(fx, steps: int) -> float:
        """filterpy's UKF with process ``fx``: mean µs per predict + update over ``steps``."""
        peer = UnscentedKalmanFilter(dim_x=n, dim_z=3, dt=dt, fx=fx, hx=lambda x: x[[0, 4, 8]], points=pts)
        peer.x, peer.P, peer.Q, peer.R = np.zeros(n), p0.copy(), q.copy(), r.copy()
        t0 = time.perf_counter()
        for k in range(steps):
            peer.predict(uk=u[k])
            peer.update(y[k])
        return 1e6 * (time.perf_counter() - t0) / steps

    peer_us = peer_step_us(lambda x, dt_, uk: model.rk4_step(x, uk, dt_), 200)
    # and as a Python user would write it: the process in NumPy (the test suite's reference)
    ref = TransmissionRef(model.params())
    peer_np_us = peer_step_us(lambda x, dt_, uk: rk4.advance(ref.derivative, x.copy(), uk, uk, dt_, 1), 20)
    ratio = peer_np_us / step_us
    ok_step = step_us <= budgets["srukf_step_us"]
    ok_ratio = ratio >= budgets["srukf_min_ratio_vs_filterpy"]
    print("sr-UKF, Raven-II 3-link (n = 12, m = 3 motor encoders), 10 kHz, one RK4 step per period")
    print(
        f"  SrUkf.step() from Python    {step_us:8.2f} us   budget {budgets['srukf_step_us']:.1f} us   "
        f"{'ok' if ok_step else 'OVER BUDGET'}"
    )
    print(f"  SrUkf.run() per step        {run_us:8.2f} us   (GIL released, no per-step conversion)")
    print(f"  filterpy UKF, NumPy model   {peer_np_us:8.1f} us")
    print(f"  filterpy UKF, Rust process  {peer_us:8.1f} us   (process: cablekit's RK4 step)")
    goal = budgets["srukf_min_ratio_vs_filterpy"]
    verdict = "ok" if ok_ratio else "BELOW GOAL"
    print(f"  ratio filterpy / cablekit   {ratio:8.0f}x     goal >= {goal:.0f}x   {verdict}")
    print(f"  ratio, filters only         {peer_us / step_us:8.0f}x     (same Rust process in both)")
    return 0 if ok_step and ok_ratio else 1


if __name__ == "__main__":
    sys.exit(main())
