"""sr-UKF step against filterpy's ``UnscentedKalmanFilter`` (Merwe's points, the same α, β, κ),
on the same measurement log, checked step by step before timing.

* Raven-II 3-link transmission (n = 12, 3 motor encoders, 10 kHz, one RK4 step per period), as
  ``benches/srukf_bench.py`` runs it: cablekit's built-in model against filterpy with the process
  (a) in NumPy — the test suite's reference RK4, as a filterpy user writes it — and (b) calling
  cablekit's Rust ``rk4_step`` (the filters alone). α = 0.5, as the filterpy peer test of
  ``tests/test_srukf.py`` on this model: at the seed's α = 1e-3 (W₀ = −1.3e5) filterpy's literal
  weighted sums drift from the exact transform by ~1e-8 within a few steps, which would blur the
  check (the filter's cost does not depend on α).
* Your own model: the nonlinear pendulum and camera of ``examples/filterpy_migration.py``
  (``SrUkf.from_functions`` against filterpy on the same callbacks, α = 0.5, its log), whose
  agreement the example and the docs give as ≤ 1e-9.

Tolerance: at every step ``|Δx| ≤ 1e-9·(|x| + σ)`` and ``|ΔP| ≤ 1e-9·σᵢσⱼ`` (filterpy's
covariance as the scale), the per-step test of ``tests/test_srukf.py`` at 1e-9.
"""

from __future__ import annotations

import functools
import importlib.util
from pathlib import Path
from typing import Any

import numpy as np

from .core import Config, Kernel, Pair, Peer, Side, Verdict

ROOT = Path(__file__).resolve().parents[2]
TOL = 1e-9
ALPHA = 0.5
DT = 1e-4
OBSERVED = [0, 4, 8]  # the three motor angles


@functools.cache
def _raven() -> dict[str, Any]:
    import cablekit as ck

    model = ck.CableTransmission.raven2(3)
    n, steps = model.n_states, 2000
    t = np.arange(steps) * DT
    u = np.zeros((steps, 6))
    u[:, :3] = np.array([0.1, 0.05, 0.2]) * np.sin(6.0 * t)[:, None]
    u = np.ascontiguousarray(u)
    sim = ck.simulate(model, u, DT, np.zeros(n))
    noise = 1e-5 * np.random.default_rng(0).normal(size=(steps, 3))
    y = np.ascontiguousarray(sim.states[:, OBSERVED] + noise)
    return {
        "model": model,
        "u": u,
        "y": y,
        "x0": np.zeros(n),
        "p0": 1e-6 * np.eye(n),
        "q": 1e-9 * np.eye(n),
        "r": 1e-8 * np.eye(3),
    }


def _filterpy(fx: Any, hx: Any, x0, p0, q, r, dt: float) -> Any:
    from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

    pts = MerweScaledSigmaPoints(len(x0), alpha=ALPHA, beta=2.0, kappa=0.0)
    ukf = UnscentedKalmanFilter(dim_x=len(x0), dim_z=r.shape[0], dt=dt, fx=fx, hx=hx, points=pts)
    ukf.x, ukf.P, ukf.Q, ukf.R = x0.copy(), p0.copy(), q.copy(), r.copy()
    return ukf


def _run(step: Any, state: Any, u: np.ndarray, y: np.ndarray, steps: int, record: bool):
    """``steps`` filter steps; with ``record`` the mean and covariance after each."""
    xs, ps = [], []
    for k in range(steps):
        step(u[k], y[k])
        if record:
            xs.append(np.array(state().x))
            ps.append(np.array(state().P))
    return (np.array(xs), np.array(ps)) if record else None


def agree_filters(ours: Any, theirs: Any) -> Verdict:
    """Means and covariances step by step, scaled by filterpy's |x| + σ and σᵢσⱼ."""
    (xa, pa), (xb, pb) = ours, theirs
    if xa.shape != xb.shape or pa.shape != pb.shape:
        return Verdict(False, f"shapes differ: {xa.shape}/{pa.shape} and {xb.shape}/{pb.shape}")
    var = np.abs(np.diagonal(pb, axis1=1, axis2=2))
    dx = np.abs(xa - xb) / (np.abs(xb) + np.sqrt(var))
    dp = np.abs(pa - pb) / np.sqrt(var[:, :, None] * var[:, None, :])
    wx, wp = float(np.nanmax(dx)), float(np.nanmax(dp))
    ok = bool(np.all(np.isfinite(dx)) and np.all(np.isfinite(dp)) and max(wx, wp) <= TOL)
    return Verdict(
        ok, f"{len(xa)} steps: x to {wx:.1e} of |x|+σ, P to {wp:.1e} of σᵢσⱼ (tolerance {TOL:.0e})"
    )


def _raven_pair(cfg: Config, numpy_process: bool) -> Pair:
    import cablekit as ck

    d = _raven()
    model, u, y, x0, p0, q, r = (d[k] for k in ("model", "u", "y", "x0", "p0", "q", "r"))
    if numpy_process:
        from tests.reference import rk4
        from tests.reference.transmission import TransmissionRef

        ref = TransmissionRef(model.params())

        def fx(x, dt, uk):
            return rk4.advance(ref.derivative, x.copy(), uk, uk, dt, 1)

        check_steps, peer_steps = (10, 5) if cfg.quick else (40, 20)
    else:

        def fx(x, dt, uk):
            return model.rk4_step(x, uk, dt)

        check_steps, peer_steps = (100, 20) if cfg.quick else (400, 100)

    def hx(x):
        return x[OBSERVED]

    mine = ck.SrUkf(model, x0, p0, q, r, dt=DT, substeps=1, states=OBSERVED, alpha=ALPHA)

    def ours(steps: int, record: bool):
        mine.reset(x0, p0)
        return _run(mine.step, lambda: mine, u, y, steps, record)

    def theirs(steps: int, record: bool):
        peer = _filterpy(fx, hx, x0, p0, q, r, DT)

        def step(uk, yk):
            peer.predict(uk=uk)
            peer.update(yk)

        return _run(step, lambda: peer, u, y, steps, record)

    own_steps = 200 if cfg.quick else 1000
    kind = "NumPy" if numpy_process else "cablekit's Rust rk4_step"
    return Pair(
        Side(
            "SrUkf.step, built-in model (Rust RK4)",
            lambda: ours(own_steps, False),
            own_steps,
            lambda: ours(check_steps, True),
        ),
        Side(
            f"filterpy UKF, process in {kind}",
            lambda: theirs(peer_steps, False),
            peer_steps,
            lambda: theirs(check_steps, True),
        ),
        agree_filters,
        "step",
    )


@functools.cache
def migration_example() -> Any:
    """``examples/filterpy_migration.py`` as a module: its pendulum, camera, noise and log."""
    path = ROOT / "examples" / "filterpy_migration.py"
    spec = importlib.util.spec_from_file_location("filterpy_migration", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _pendulum_pair(cfg: Config) -> Pair:
    import cablekit as ck

    ex = migration_example()
    steps = 100 if cfg.quick else 400
    us, ys = ex.log(steps, seed=1)

    def ours(record: bool):
        mine = ck.SrUkf.from_functions(
            ex.fx, ex.hx, ex.X0, ex.P0, ex.Q, ex.R, dt=ex.DT, n_inputs=1, alpha=ALPHA
        )
        return _run(mine.step, lambda: mine, us, ys, steps, record)

    def theirs(record: bool):
        peer = _filterpy(ex.fx, ex.hx, ex.X0, ex.P0, ex.Q, ex.R, ex.DT)

        def step(uk, yk):
            peer.predict(u=uk)
            peer.update(yk)

        return _run(step, lambda: peer, us, ys, steps, record)

    return Pair(
        Side("SrUkf.from_functions, the NumPy callbacks per sigma point", lambda: ours(False), steps,
             lambda: ours(True)),
        Side("filterpy UKF, the same callbacks", lambda: theirs(False), steps, lambda: theirs(True)),
        agree_filters,
        "step",
    )  # fmt: skip


KERNEL = Kernel(
    "srukf",
    "sr-UKF step",
    "one predict + update of the square-root UKF on a logged run, Merwe's points with the same "
    "α, β, κ; means and covariances agree step by step to 1e-9 of their scale before timing",
    (
        Peer("filterpy, Raven-II model in NumPy", ("filterpy",), lambda cfg: _raven_pair(cfg, True)),
        Peer("filterpy, Raven-II model in Rust", ("filterpy",), lambda cfg: _raven_pair(cfg, False)),
        Peer("filterpy, your model (NumPy pendulum)", ("filterpy",), _pendulum_pair),
    ),
)
