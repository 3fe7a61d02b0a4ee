"""A parallel robot's cable drives as a cable network, so that the one diagnosis engine
(:mod:`cablekit.diagnose`) diagnoses a parallel robot's runs as it does a joint's, a
transmission's or a network's (issue #39 §2: the separate engine of
:mod:`cablekit.cdpr.diagnose` retired into it).

Given the platform's measured pose, each cable is a drive of its own: its winch's drum angle
``α`` winds it in, the platform's attachment moves its far end by ``l_j(q)`` (inverse
kinematics of the pose), and its tension follows from the stretch (seed 002 eq. 15)::

    T_EE = E·A·(l_j(q) − L0_j + r·α) / (L0_j − r·α) + b·(l̇_j + r·α̇)       elastic piece
    T_PUL = T_EE + μ·N(θ_g, θ_e)·T_EE·z + σ_v·v                            platform-side pulleys
    T_drum = T_PUL·exp(Σμφ·s)                                             drum-side pulley
    k_φ·N_gb·i − J_l·α̈ = r·T_drum + B_l·α̇ + τ_st·σ_ε(α̇)                     drum (seed 003 eqs 16–19)

So the network of a robot has per cable ``c<j>``: a torque-driven motor ``drum<j>`` (the winch:
inertia ``J_l``, viscous ``B_l`` and static friction ``τ_st`` at the drum, capstan radius ``r``),
a position-driven motor ``platform<j>`` at the cable's far end whose "angle" is
``l_j(q) − L0_j`` (m), a fixed pulley ``drum_side<j>`` (the routing, where a drum-side pulley's
friction would act; nominally none), a path with the platform-side pulleys' friction whose exit
wrap is the signal ``wrap<j>`` (``θ_e`` at the measured pose), a tension sensor ``tension<j>``
between the drum-side pulley and the path (the winch-side load cell) and an encoder ``alpha<j>``
on the drum. The run's columns are ``tau<j> = k_φ·N_gb·i_j``, ``alpha<j>``, ``T<j>`` (the load
cell), ``stretch<j> = l_j(q) − L0_j`` and ``wrap<j>``; the drums are replayed from their measured
angles and their currents become the load channels ``load_m:drum<j>`` (``τ − J_l·α̈``).

**The measured pose's noise.** A Dyneema cable of ``E·A ≈ 94 kN`` over 0.8 m turns a tracker's
10 µm into 1 N of predicted tension, ten times a load cell's noise. The residuals of the tension
and load channels are therefore averaged over a window (:data:`cablekit.diagnose.prepare`'s
``input_noise``): each run's stretch noise (estimated from the data as any channel's) times the
cable's stiffness is handed to the preparation, which widens the channel's averaging until the
pose's part is no larger than the sensor's (at most 20 ms) and counts it in the channel's noise.

Sites on the network's vocabulary: ``motor.drum<j>`` (the winch's friction, its inertia),
``routing.c<j>`` (the drum-side pulley: capstan friction, its pre-sliding), ``cable.c<j>``
(stiffness, creep, slack: a rest length, damping) and each channel's sensor sites.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from cablekit._args import Width, checked, count, instance, real, signal
from cablekit.cdpr import Robot, Winch
from cablekit.errors import ParameterError, ShapeError

#: the smoothing of the drum's static friction sign (rad/s; the twin's, and the old engine's)
DRUM_SMOOTHING = 0.01
#: the drum-side pulley's wrap (rad) — the scale of a fitted capstan coefficient
DRUM_SIDE_WRAP = float(np.pi)
#: half-width (s) of the local cubic through which the measured pose's cable lengths and wraps
#: are smoothed (:func:`smoothing_kernel`)
POSE_SMOOTHING_S = 0.012
#: the sample interval (s) a run is averaged down to (block means), when it is sampled faster:
#: the drives' effects (a pulley's pre-sliding over millimetres, a load cell's hold and latency of
#: 10-100 ms, creep over seconds) are slower, and the diagnosis's replays cost in proportion
DRIVE_DT = 0.004


@checked
def smoothing_kernel(half: Width) -> np.ndarray:
    """The Savitzky–Golay weights ``(2·half + 1,)`` of a cubic's value at the centre of its
    least-squares fit: exact for a cubic (no lag, no bias of a smooth trajectory's curvature),
    the white noise through it ``‖w‖ ≈ 1.5/√(2·half + 1)``."""
    i = np.arange(-half, half + 1, dtype=float)
    basis = np.vander(i, 4, increasing=True)
    return np.linalg.pinv(basis)[0]


def _smoothed(x: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``x`` through the centred kernel ``w``, its ends padded by odd reflection (which keeps a
    linear trend)."""
    h = len(w) // 2
    if len(x) <= 2 * h:
        return x.copy()
    pad = np.concatenate([2 * x[0] - x[h:0:-1], x, 2 * x[-1] - x[-2 : -h - 2 : -1]])
    return np.correlate(pad, w, mode="valid")


def _winch_values(winch: Winch) -> dict[str, float]:
    return dict(zip(Winch.NAMES, (float(v) for v in winch.values), strict=True))


@checked
def drive_network(
    robot: Robot,
    winch: Winch,
    rest_length: np.ndarray,
    platform_side: Mapping[str, Any] | None = None,
    *,
    cable_damping: float = 0.0,
) -> dict[str, Any]:
    """The network document (docs/models.md) of ``robot``'s drives: one winch ``winch`` per cable,
    the unstretched lengths ``rest_length`` ``(m,)`` at ``α = 0`` (m), the platform-side pulleys'
    friction ``platform_side`` (``coefficient``, ``viscous``, ``guide_wrap`` per cable,
    ``presliding``: seed 002's Dahl law, as :data:`cablekit.cdpr.compensate.TWIN_FRICTION`) and
    the cables' damping (N·s/m)."""
    instance(robot, "robot", Robot)
    instance(winch, "winch", Winch)
    m = robot.n_cables
    rest = signal(rest_length, "rest_length", 1)
    if rest.shape != (m,):
        raise ShapeError(f"rest_length must be ({m},) lengths, got shape {rest.shape}")
    if not (np.isfinite(rest).all() and (rest >= 1e-4).all() and (rest <= 1e4).all()):
        raise ParameterError(f"rest_length must be finite lengths in [1e-4, 1e4] m, got {rest}")
    cable_damping = real(cable_damping, "cable_damping", lo=0.0, hi=1e9)
    w = _winch_values(winch)
    j_l, b_l = (float(v) for v in winch.load)
    r = w["drum_radius"]
    side = None
    if platform_side is not None:
        side = {}
        for k, hi in (("coefficient", 10.0), ("viscous", 1e6), ("guide_wrap", 2 * np.pi)):
            if k not in platform_side:
                raise ParameterError(f"platform_side needs {k}")
            v = np.asarray(signal(platform_side[k], f"platform_side[{k!r}]", (0, 1)), float)
            ok = np.isfinite(v).all() and (v >= 0).all() and (v <= hi).all()
            if v.shape not in ((), (1,), (m,)) or not ok:
                raise ParameterError(f"platform_side[{k!r}] must be one or {m} numbers in [0, {hi:g}]: {v}")
            side[k] = np.broadcast_to(v.reshape(-1) if v.ndim else v, (m,))
        presliding = real(
            platform_side.get("presliding", 1e-3), "platform_side['presliding']", lo=1e-9, hi=1.0
        )
    doc: dict[str, Any] = {
        "name": f"{robot.name} drives",
        "description": "the cable drives of a parallel robot at its measured poses (cablekit.cdpr.drives)",
        "signals": [f"wrap{j + 1}" for j in range(m)] if side is not None else [],
        "pulleys": [{"name": f"drum_side{j + 1}", "radius": r} for j in range(m)],
        "motors": [],
        "cables": [],
        "sensors": [],
    }
    for j in range(m):
        k = j + 1
        doc["motors"] += [
            {
                "name": f"drum{k}",
                "drive": "torque",
                "inertia": j_l,
                "gear_ratio": 1.0,
                "capstan_radius": r,
                "coulomb": w["static_friction"],
                "viscous": b_l,
                "smoothing": DRUM_SMOOTHING,
            },
            {"name": f"platform{k}", "drive": "position", "capstan_radius": 1.0},
        ]
        cable: dict[str, Any] = {
            "name": f"c{k}",
            "motor": f"drum{k}",
            "end_motor": f"platform{k}",
            "free_length": float(rest[j]),
            "stiffness": float(robot.ea[j]) / float(rest[j]),
            "damping": float(cable_damping),
            "routing": [{"pulley": f"drum_side{k}", "wrap": DRUM_SIDE_WRAP}],
        }
        if side is not None:
            cable["path"] = {
                "coefficient": float(side["coefficient"][j]),
                "viscous": float(side["viscous"][j]),
                "guide_wrap": float(side["guide_wrap"][j]),
                "exit_wrap": f"wrap{k}",
                "law": "dahl",
                "presliding": presliding,
            }
        doc["cables"].append(cable)
        doc["sensors"] += [
            {"name": f"alpha{k}", "kind": "encoder", "target": f"drum{k}"},
            {"name": f"tension{k}", "kind": "tension", "target": f"c{k}", "at": f"drum_side{k}"},
        ]
    return doc


@dataclass(frozen=True)
class DriveRun:
    """A parallel robot's run as the network diagnosis reads it: the columns (module docs) and
    each column's pose-borne noise (``input_noise``: the tension and torque columns whose
    prediction carries the measured pose's noise — its white noise per sample and the kernel
    the cable lengths were smoothed with)."""

    t: np.ndarray
    columns: dict[str, np.ndarray]
    input_noise: dict[str, tuple[float, tuple[float, ...]]]


@checked
def drive_columns(
    robot: Robot,
    winch: Winch,
    rest_length: np.ndarray,
    t: np.ndarray,
    alpha: np.ndarray,
    current: np.ndarray,
    sensor: np.ndarray,
    poses: np.ndarray,
    *,
    smoothing: float = POSE_SMOOTHING_S,
    decimate: int | None = None,
) -> DriveRun:
    """The network run of a parallel robot's run: times ``t`` (s), drum angles ``alpha``,
    currents ``current`` (A), load cells ``sensor`` (N) ``(T, m)`` and measured poses ``(T, n)``,
    averaged over blocks of ``decimate`` samples (default: to :data:`DRIVE_DT`; 1: as sampled),
    the cable lengths and wraps smoothed over ``smoothing`` s either side (0: not smoothed)."""
    from cablekit.diagnose.localise import measurement_sigma

    instance(robot, "robot", Robot)
    instance(winch, "winch", Winch)
    m, n = robot.n_cables, robot.dof
    t = signal(t, "t", 1)
    alpha, current, sensor = (
        signal(a, name, 2) for a, name in ((alpha, "alpha"), (current, "current"), (sensor, "sensor"))
    )
    poses = signal(poses, "poses", 2)
    rest = signal(rest_length, "rest_length", 1)
    size = t.size
    if size < 8 or any(a.shape != (size, m) for a in (alpha, current, sensor)) or poses.shape != (size, n):
        raise ShapeError(
            f"t (T ≥ 8,), alpha, current, sensor ({size}, {m}) and poses ({size}, {n}) are needed; got "
            f"{alpha.shape}, {current.shape}, {sensor.shape}, {poses.shape}"
        )
    if rest.shape != (m,):
        raise ShapeError(f"rest_length must be ({m},), got {rest.shape}")
    if not all(np.isfinite(a).all() for a in (t, alpha, current, sensor, poses, rest)):
        raise ParameterError("the run has non-finite samples")
    if not (np.diff(t) > 0).all():
        raise ParameterError("t must increase")
    dt = float(np.median(np.diff(t)))
    p = np.ascontiguousarray(poses)
    length = robot.inverse_kinematics(p).length
    zeros = np.zeros(1)
    wrap = robot.path_friction(p, np.zeros((size, m)), dt, zeros, zeros, zeros).wrap
    # block means (each block's samples equally weighted; the last partial block dropped)
    block = (
        max(1, round(DRIVE_DT / dt)) if decimate is None else count(decimate, "decimate", lo=1, hi=size // 8)
    )
    if block > 1:
        n_blocks = size // block

        def mean(a: np.ndarray) -> np.ndarray:
            return a[: n_blocks * block].reshape(n_blocks, block, *a.shape[1:]).mean(axis=1)

        t, alpha, current, sensor, length, wrap = map(mean, (t, alpha, current, sensor, length, wrap))
        dt, size = dt * block, n_blocks
    w = _winch_values(winch)
    r = w["drum_radius"]
    # a tracker's noise differentiated sample by sample is mm/s of cable speed, which would drive
    # the path's pre-sliding state (and relax it) where the pulleys see none: the lengths and
    # wraps are smoothed by a local cubic, and their remaining noise handed over with its kernel
    smoothing = real(smoothing, "smoothing", lo=0.0, hi=10.0)
    half = min(round(smoothing / dt), (size - 1) // 2)
    kernel = smoothing_kernel(half) if half >= 2 else np.ones(1)
    cols: dict[str, np.ndarray] = {}
    noise: dict[str, tuple[float, tuple[float, ...]]] = {}
    for j in range(m):
        k = j + 1
        stretch = length[:, j] - rest[j]
        cols[f"tau{k}"] = w["torque_constant"] * w["gear_ratio"] * current[:, j]
        cols[f"alpha{k}"] = alpha[:, j].copy()
        cols[f"T{k}"] = sensor[:, j].copy()
        cols[f"stretch{k}"] = _smoothed(stretch, kernel)
        cols[f"wrap{k}"] = _smoothed(wrap[:, j], kernel)
        # the pose's noise through the cable's stiffness at its mean free length
        stiffness = float(robot.ea[j]) / float(np.mean(rest[j] - r * alpha[:, j]))
        s_len = measurement_sigma(stretch, dt)[0]
        noise[f"T{k}"] = (stiffness * s_len, tuple(kernel))
        noise[f"tau{k}"] = (r * stiffness * s_len, tuple(kernel))
    return DriveRun(t.copy(), cols, noise)


@checked
def drive_spec(
    robot: Robot,
    winch: Winch,
    rest_length: np.ndarray,
    input_noise: Mapping[str, tuple[float, tuple[float, ...]]],
    platform_side: Mapping[str, Any] | None = None,
    *,
    cable_damping: float = 0.0,
    warmup: float = 0.5,
    effects: list[str] | None = None,
) -> Any:
    """The diagnosis's model (:class:`cablekit.diagnose.spec.ModelSpec`) of ``robot``'s drives
    (:func:`drive_network`) reading :func:`drive_columns`' columns; ``input_noise`` is theirs."""
    from cablekit.diagnose.spec import model_spec_from_dict

    net = drive_network(robot, winch, rest_length, platform_side, cable_damping=cable_damping)
    m = robot.n_cables
    inputs: dict[str, str] = {}
    outputs: dict[str, str] = {}
    for k in range(1, m + 1):
        inputs[f"drum{k}"] = f"tau{k}"
        inputs[f"platform{k}"] = f"stretch{k}"
        if net["signals"]:
            inputs[f"wrap{k}"] = f"wrap{k}"
        outputs[f"alpha{k}"] = f"alpha{k}"
        outputs[f"tension{k}"] = f"T{k}"
    # the currents are measurements of a continuous current (sampled, not held commands)
    warmup = real(warmup, "warmup", lo=0.0, hi=1e6)
    diagnosis: dict[str, Any] = {"warmup": warmup, "torque": "sampled"}
    if effects is not None:
        diagnosis["effects"] = list(effects)
    doc = {
        "model": "cable_network",
        "parameters": {"definition": net},
        "inputs": inputs,
        "outputs": outputs,
        "diagnosis": diagnosis,
    }
    spec = model_spec_from_dict(doc, source=f"{robot.name} drives")
    noise: dict[str, tuple[float, tuple[float, ...]]] = {}
    for key, value in input_noise.items():
        if not isinstance(value, tuple | list) or len(value) != 2:
            raise ParameterError(f"input_noise[{key!r}] must be (sigma, kernel), got {value!r}")
        kernel = signal(value[1], f"input_noise[{key!r}] kernel", 1)
        if not (0 < kernel.size <= 100_001 and np.isfinite(kernel).all()):
            raise ParameterError(f"input_noise[{key!r}] kernel must be 1 to 100001 finite weights")
        sigma = real(value[0], f"input_noise[{key!r}] sigma", lo=0.0, hi=1e12)
        noise[str(key)] = (sigma, tuple(float(x) for x in kernel))
    spec.extra["input_noise"] = noise
    return spec


@checked
def estimate_rest_length(
    robot: Robot,
    winch: Winch,
    t: np.ndarray,
    alpha: np.ndarray,
    sensor: np.ndarray,
    poses: np.ndarray,
    platform_side: Mapping[str, Any] | None = None,
) -> np.ndarray:
    """Each cable's unstretched length at ``α = 0`` (m) for one run, by least squares of the
    nominal elastic law over the run: ``L0 = l(q) + r·α − T·(L0 − r·α)/(E·A)`` with ``T`` the
    load cell's tension taken back through the nominal platform-side friction (computed from the
    load cell's tension: a second-order error). A constant per cable and run, as a re-homed
    winch's offset is; the constant part of a load cell's bias or a lost pretension is then the
    calibration's, not a finding (the diagnosis says so)."""
    instance(robot, "robot", Robot)
    instance(winch, "winch", Winch)
    t = signal(t, "t", 1)
    alpha, sensor, poses = (
        signal(a, n, 2) for a, n in ((alpha, "alpha"), (sensor, "sensor"), (poses, "poses"))
    )
    m = robot.n_cables
    if (
        any(a.shape != (t.size, m) for a in (alpha, sensor))
        or poses.shape != (t.size, robot.dof)
        or t.size < 2
    ):
        raise ShapeError(f"alpha, sensor ({t.size}, {m}) and poses ({t.size}, {robot.dof}) are needed")
    if not all(np.isfinite(a).all() for a in (t, alpha, sensor, poses)):
        raise ParameterError("the run has non-finite samples")
    dt = float(np.median(np.diff(t)))
    if not dt > 0:
        raise ParameterError("t must increase")
    p = np.ascontiguousarray(poses)
    length = robot.inverse_kinematics(p).length
    tension = np.maximum(sensor, 0.0)
    if platform_side is not None:
        path = robot.path_friction(
            p,
            np.ascontiguousarray(tension),
            dt,
            np.asarray(platform_side["coefficient"], float),
            np.asarray(platform_side["viscous"], float),
            np.asarray(platform_side["guide_wrap"], float),
            law="dahl",
            presliding=float(platform_side.get("presliding", 1e-3)),
        )
        tension = np.maximum(sensor - path.friction, 0.0)
    r = float(_winch_values(winch)["drum_radius"])
    ea = np.asarray(robot.ea, float)[None, :]
    wound = r * alpha
    # l − L0 + rα = T·(L0 − rα)/EA  ⇔  L0·(1 + T/EA) = l + rα + T·rα/EA
    rest = np.mean((length + wound + tension * wound / ea) / (1.0 + tension / ea), axis=0)
    if not (np.isfinite(rest).all() and (rest > 0).all()):
        raise ParameterError(
            "the run's rest lengths are not positive: check the drum angles' zero and the poses"
        )
    return rest


@checked
def drive_runs(
    robot: Robot,
    winch: Winch,
    runs: list[tuple[str, Any]],
    platform_side: Mapping[str, Any] | None = None,
    *,
    cable_damping: float = 0.0,
) -> tuple[Any, list[Any]]:
    """A parallel robot's measured runs (``(name, RunFile)``, each with poses) as the diagnosis
    reads them: the model (:func:`drive_spec`, the rest lengths the runs' mean) and the runs
    (:class:`cablekit.diagnose.data.Run`; each run's stretch on its own rest lengths,
    :func:`estimate_rest_length`, noted in the run's notes)."""
    from cablekit.diagnose.data import Run

    if not runs:
        raise ParameterError("give at least one run")
    rests, out = [], []
    noise: dict[str, tuple[float, tuple[float, ...]]] = {}
    for name, run in runs:
        if getattr(run, "poses", None) is None:
            raise ParameterError(
                f"run {name!r} has no pose columns: the drives' diagnosis needs measured poses"
            )
        rest = estimate_rest_length(robot, winch, run.t, run.alpha, run.sensor, run.poses, platform_side)
        rests.append(rest)
        cols = drive_columns(robot, winch, rest, run.t, run.alpha, run.current, run.sensor, run.poses)
        for k, v in cols.input_noise.items():
            if k not in noise or v[0] > noise[k][0]:
                noise[k] = v
        calibrated = "rest lengths calibrated on the run (mm): " + ", ".join(f"{1e3 * x:.2f}" for x in rest)
        out.append(Run(name, cols.t - cols.t[0], cols.columns, [*getattr(run, "notes", ()), calibrated]))
    nominal = np.mean(rests, axis=0)
    spec = drive_spec(robot, winch, nominal, noise, platform_side, cable_damping=cable_damping)
    return spec, out
