"""Data sets for the trainers: twins of the two seeds' experiments and MATLAB's BR toy problem.

* :func:`forceps_free_motion` — seed 000 §3.1: two forceps, each opened 0→65° and closed by a
  linear stepping motor pulling an antagonistic cable pair, at 0.5, 0.6, 0.7, 0.8 and
  1.0 mm/s with S-curve ramps of 0.02 s; inputs the motor displacement and velocity of A and B,
  outputs the four cable tensions; 5,436 samples (4,892 train + 544 test at 90/10). The
  tension model: pretension, a jaw return stiffness with a cubic term, viscous drag, a Dahl
  hysteresis state over the displacement, capstan friction on the guide pulleys
  (``e^{±μβ}`` by direction) and 0.3 N sensor noise.
* :func:`cdpr_pulley_friction` — seed 002 §3: an 8-cable spatial CDPR moving a 1 kg point mass
  in a 0.6 m cube; end-effector tensions by the closed-form distribution
  ``t = t_m + A⁺(w − A·t_m)``; the winch-side sensor reads them through pulley friction
  (capstan with a wrap angle that changes with the pose, viscous, Dahl hysteresis) plus
  0.1 N noise. Inputs ``[x, y, z, ẋ, ẏ, ż, f_PUL1…8]`` (14), outputs ``f_EE1…8`` (8). Training
  paths: four cube diagonals and three circles (xy, xz, yz); test paths: a circle with a line,
  and lines through 20 random points — both unseen in training, as in the seed.
* :func:`davinci_jaw_torque` — real data (da Vinci Maryland bipolar forceps bench, O'Neill et al.
  2018, ODbL 1.0 / DbCL 1.0, read from where the user keeps it, never copied): the jaw (grip)
  torque from drive-side signals only — spindle angle, spindle velocity, spindle torque and
  back-end motor current — trained on the 0.1, 0.3 and 0.5 Hz runs at all four loads, scored on
  the 0.2 and 0.4 Hz runs the fit never saw. Baseline: the best linear map of the same signals.
* :func:`noisy_sine` — MATLAB's ``trainbr`` example: ``t = sin(2πp) + 0.1·ε`` on 41 points.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class Dataset:
    """Inputs ``x`` ``(N, n_in)`` and outputs ``y`` ``(N, n_out)`` with names and units; for
    trajectory-split sets, ``x_test``/``y_test`` hold the held-out paths."""

    name: str
    x: F64
    y: F64
    input_names: tuple[str, ...]
    input_units: tuple[str, ...]
    output_names: tuple[str, ...]
    output_units: tuple[str, ...]
    x_test: F64 | None = None
    y_test: F64 | None = None
    #: what a user would use without a network, and its predictions of ``y_test``
    baseline: str = ""
    baseline_test: F64 | None = None


def _s_curve_sweep(x_max: float, speed: float, ramp: float, dt: float) -> tuple[F64, F64]:
    """Open to ``x_max`` and back at ``speed`` with raised-cosine ramps of ``ramp`` s."""
    t_move = x_max / speed + ramp
    t = np.arange(0.0, 2 * t_move, dt)
    v = np.zeros_like(t)
    for k, tk in enumerate(t):
        tau, sign = (tk, 1.0) if tk < t_move else (tk - t_move, -1.0)
        ramp_up = 0.5 * (1 - np.cos(np.pi * min(tau, ramp) / ramp))
        ramp_dn = 0.5 * (1 - np.cos(np.pi * min(max(t_move - tau, 0.0), ramp) / ramp))
        v[k] = sign * speed * min(ramp_up, ramp_dn)
    x = np.cumsum(v) * dt
    return x, v


def _dahl(x: F64, v: F64, sigma0: float, fc: float) -> F64:
    """Dahl friction state over displacement: dz/dx = σ₀(1 − z/F_c·sgn v)."""
    z = np.zeros_like(x)
    for k in range(1, x.size):
        dx = x[k] - x[k - 1]
        s = np.sign(v[k])
        z[k] = z[k - 1] + sigma0 * (1 - z[k - 1] / fc * s) * dx if s != 0 else z[k - 1]
        z[k] = np.clip(z[k], -fc, fc)
    return z


def forceps_free_motion(n_samples: int = 5436, seed: int = 0) -> Dataset:
    rng = np.random.default_rng(seed)
    r = 4.0e-3  # jaw pulley radius, m
    x_max = np.deg2rad(65.0) * r  # motor stroke for 65°, m
    dt = 1e-3
    xs, vs = [], []
    for speed_mm in (0.5, 0.6, 0.7, 0.8, 1.0):
        x, v = _s_curve_sweep(x_max, speed_mm * 1e-3, 0.02, dt)
        xs.append(x)
        vs.append(v)
    x_a, v_a = np.concatenate(xs), np.concatenate(vs)
    x_b, v_b = -x_a, -v_a  # forceps B opens the opposite way (seed 000 §3.1)

    def tensions(
        x: F64, v: F64, t0: float, k_q: float, k3: float, mu_beta: float, c: float
    ) -> tuple[F64, F64]:
        q = x / r
        spring = (k_q * q + k3 * q**3) / (2 * r)  # jaw return torque as a cable-force split, N
        z = _dahl(x, v, sigma0=4.0e3, fc=0.8)
        drag = c * v
        s = np.tanh(v / 2e-5)  # smooth direction of motion
        pull = (t0 + spring + z + drag) * np.exp(mu_beta * s)
        release = (t0 - spring - z - drag) * np.exp(-mu_beta * s)
        return pull, release

    fa1, fa2 = tensions(x_a, v_a, 10.0, 0.012, 0.004, 0.12, 600.0)
    fb1, fb2 = tensions(-x_b, -v_b, 11.0, 0.014, 0.003, 0.10, 500.0)
    x_all = np.column_stack([x_a, v_a, x_b, v_b])
    y_all = np.column_stack([fa1, fa2, fb1, fb2]) + rng.normal(0.0, 0.3, (x_a.size, 4))
    pick = np.sort(rng.choice(x_a.size, size=min(n_samples, x_a.size), replace=False))
    return Dataset(
        "forceps free motion (seed 000 twin)",
        x_all[pick],
        y_all[pick],
        ("x_m_a", "v_m_a", "x_m_b", "v_m_b"),
        ("m", "m/s", "m", "m/s"),
        ("F_a1", "F_a2", "F_b1", "F_b2"),
        ("N", "N", "N", "N"),
    )


def _cdpr_geometry(side: float) -> F64:
    h = side / 2
    return np.array([[sx * h, sy * h, sz * h] for sz in (-1, 1) for sy in (-1, 1) for sx in (-1, 1)])


def _path_samples(points: list[F64], speed: float, dt: float) -> tuple[F64, F64]:
    """Piecewise path through ``points`` at constant speed, with velocity by differences."""
    segs = []
    for a, b in itertools.pairwise(points):
        n = max(2, int(np.linalg.norm(b - a) / speed / dt))
        segs.append(a + (b - a) * np.linspace(0, 1, n, endpoint=False)[:, None])
    p = np.vstack(segs)
    kernel = np.ones(25) / 25  # smooth the corners (a 0.25 s moving average)
    p = np.column_stack([np.convolve(np.pad(p[:, i], 12, mode="edge"), kernel, "valid") for i in range(3)])
    v = np.gradient(p, dt, axis=0)
    return p, v


def _circle(center: F64, radius: float, plane: tuple[int, int], n: int) -> list[F64]:
    pts = []
    for a in np.linspace(0, 2 * np.pi, n):
        p = center.copy()
        p[plane[0]] += radius * np.cos(a)
        p[plane[1]] += radius * np.sin(a)
        pts.append(p)
    return pts


def _cdpr_run(p: F64, v: F64, anchors: F64, rng: np.random.Generator, dt: float) -> tuple[F64, F64]:
    m, g = 1.0, np.array([0.0, 0.0, -9.81])
    acc = np.gradient(v, dt, axis=0)
    t_m = 15.0
    f_ee = np.zeros((p.shape[0], 8))
    for k in range(p.shape[0]):
        d = anchors - p[k]
        u = d / np.linalg.norm(d, axis=1, keepdims=True)
        a_mat = u.T  # (3, 8): Σ t_i u_i + m g = m a
        w = m * (acc[k] - g)
        t = t_m + np.linalg.pinv(a_mat) @ (w - a_mat @ np.full(8, t_m))
        f_ee[k] = t
    lengths = np.linalg.norm(anchors[None, :, :] - p[:, None, :], axis=2)
    ldot = np.gradient(lengths, dt, axis=0)
    # wrap angle on the exit pulley: angle between the cable and the frame's vertical
    wrap = np.arccos(np.clip(np.abs(anchors[None, :, 2] - p[:, None, 2]) / lengths, 0, 1)) + 0.3
    s = np.tanh(ldot / 5e-3)
    mu = np.array([0.08, 0.10, 0.09, 0.11, 0.07, 0.10, 0.12, 0.09])
    dahl = np.column_stack([_dahl(lengths[:, i], ldot[:, i], 300.0, 0.6) for i in range(8)])
    f_pul = f_ee * np.exp(mu * wrap * s) + 8.0 * ldot + dahl + rng.normal(0.0, 0.1, f_ee.shape)
    return np.column_stack([p, v, f_pul]), f_ee


def cdpr_pulley_friction(seed: int = 0, dt: float = 0.01) -> Dataset:
    rng = np.random.default_rng(seed)
    side = 0.6
    anchors = _cdpr_geometry(side)
    c = np.zeros(3)
    e = 0.15
    corners = [np.array([sx, sy, sz]) * e for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    train_pts: list[F64] = []
    for k in range(4):  # four cube diagonals, there and back
        a = corners[k]
        train_pts += [a, -a, a]
    for plane in ((0, 1), (0, 2), (1, 2)):
        train_pts += _circle(c, e, plane, 60)
    p, v = _path_samples(train_pts, 0.08, dt)
    x, y = _cdpr_run(p, v, anchors, rng, dt)
    test_pts = [
        *_circle(np.array([0.0, 0.0, 0.05]), 0.1, (0, 1), 60),
        np.array([0.0, -0.12, 0.05]),
        np.array([0.0, 0.12, 0.05]),
    ]
    test_pts += list(rng.uniform(-e, e, (20, 3)))
    pt, vt = _path_samples(test_pts, 0.08, dt)
    xt, yt = _cdpr_run(pt, vt, anchors, rng, dt)
    cables = tuple(str(i + 1) for i in range(8))
    return Dataset(
        "CDPR pulley friction (seed 002 twin)",
        x,
        y,
        ("x", "y", "z", "vx", "vy", "vz", *(f"f_PUL{i}" for i in cables)),
        ("m", "m", "m", "m/s", "m/s", "m/s", *("N",) * 8),
        tuple(f"f_EE{i}" for i in cables),
        ("N",) * 8,
        xt,
        yt,
        baseline="uncompensated: f_EE = f_PUL (the winch-side sensor reading)",
        baseline_test=xt[:, 6:14].copy(),
    )


#: the bench's frequency indices (0.1 … 0.5 Hz) fitted and held out by :func:`davinci_jaw_torque`
DAVINCI_TRAIN_FREQS, DAVINCI_HELDOUT_FREQS = (0, 2, 4), (1, 3)


def davinci_jaw_torque(
    directory: str | Path,
    every: int = 40,
    train_freqs: tuple[int, ...] = DAVINCI_TRAIN_FREQS,
    heldout_freqs: tuple[int, ...] = DAVINCI_HELDOUT_FREQS,
    warmup: float = 1.0,
) -> Dataset:
    """Jaw torque (mN·m) from the drive-side signals of the real bench runs in ``directory``
    (``tool4_load_sweep/XY.TXT.gz``; X the frequency index, Y the load index 0..3). The
    spindle velocity is the central difference of the angle after a 21 ms moving average
    (computed at 1 kHz, then every ``every``-th sample is kept, 25 Hz by default, after
    ``warmup`` s)."""
    from cablekit.diagnose.davinci import load_bench_run
    from cablekit.errors import DataError

    directory = Path(directory)
    sub = directory / "tool4_load_sweep" if (directory / "tool4_load_sweep").is_dir() else directory
    if every < 1:
        raise DataError(f"every must be >= 1, got {every}")

    def features(freqs: tuple[int, ...]) -> tuple[F64, F64]:
        xs, ys = [], []
        for f, load in itertools.product(freqs, range(4)):
            run = load_bench_run(sub / f"{f}{load}.TXT.gz")
            angle = run.column("spindle_angle")
            smooth = np.convolve(angle, np.ones(21) / 21, mode="same")
            keep = slice(int(warmup / run.dt), None, every)
            velocity = np.gradient(smooth, run.dt)
            cols = [angle, velocity, run.column("spindle_torque"), run.column("motor_current")]
            xs.append(np.column_stack(cols)[keep])
            ys.append(1e3 * run.column("jaw_torque")[keep, None])
        return np.vstack(xs), np.vstack(ys)

    x, y = features(train_freqs)
    xt, yt = features(heldout_freqs)
    lin = np.linalg.lstsq(np.column_stack([x, np.ones(len(x))]), y, rcond=None)[0]
    return Dataset(
        "da Vinci Maryland forceps, real bench (O'Neill et al. 2018): jaw torque from drive-side signals",
        x,
        y,
        ("spindle_angle", "spindle_velocity", "spindle_torque", "motor_current"),
        ("rad", "rad/s", "N·m", "A"),
        ("jaw_torque",),
        ("mN·m",),
        xt,
        yt,
        baseline="linear least squares on the same four signals (fitted on the training runs)",
        baseline_test=np.column_stack([xt, np.ones(len(xt))]) @ lin,
    )


def noisy_sine(seed: int = 0, noise: float = 0.1) -> tuple[F64, F64, F64, F64]:
    """MATLAB's ``trainbr`` example: training ``p ∈ [−1, 1]`` step 0.05 with
    ``t = sin(2πp) + noise·ε``; test on a fine grid of the noise-free function. Returns
    ``(p, t, p_test, t_test)`` as column arrays."""
    rng = np.random.default_rng(seed)
    p = np.arange(-1.0, 1.0 + 1e-9, 0.05)
    t = np.sin(2 * np.pi * p) + noise * rng.standard_normal(p.size)
    pt = np.linspace(-1.0, 1.0, 401)
    return p[:, None], t[:, None], pt[:, None], np.sin(2 * np.pi * pt)[:, None]
