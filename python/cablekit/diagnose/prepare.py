"""Prepare a diagnosis: validate the runs against the model file, estimate each channel's
noise, build the nominal problems and the candidate library; the knobs (:class:`Options`) and
the thresholds every later stage shares."""

from __future__ import annotations

import math
import uuid
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cablekit._cablekit import JointProblem, JointRun, effect_catalogue
from cablekit.diagnose import localise
from cablekit.diagnose.data import Run, check_units, scored_start
from cablekit.diagnose.spec import (
    NOT_IN_NETWORK,
    NOT_IN_TRANSMISSION,
    SHARP_DRY_FRICTION,
    ModelSpec,
    _network_document,
    network_output_info,
    sharpen_dry_friction,
)
from cablekit.errors import DataError
from cablekit.simulation import state_indices

__all__ = ["MAX_SUBSTEPS", "MIN_CLOSED", "NOISE_LEVEL", "Options", "Prepared", "joint_run", "prepare"]

_F = NDArray[np.float64]


#: held-out mean squared residual (noise units) below which the gap counts as noise
NOISE_LEVEL = 1.15

#: smallest held-out share of the gap an effect must close to count
MIN_CLOSED = 0.05

#: RK4 substeps per sample a candidate may use; beyond, the stiff trial points diverge and the
#: fit rejects them, which bounds e.g. how sharp a fitted friction sign can get
MAX_SUBSTEPS = 16


@dataclass
class Options:
    """Knobs of the diagnosis (defaults are what the self-test and the docs use)."""

    max_effects: int = 3
    #: candidates fitted in full after the screen (by fit cost of a short fit); 0 = all
    shortlist: int = 14
    #: and the best of each channel's own fit cost, however they rank pooled
    shortlist_per_channel: int = 2
    #: iterations of the screening fits
    screen_fit_iter: int = 4
    #: iterations of the screening fits of later selection rounds, and how many are refined
    screen_iter: int = 5
    refine: int = 3
    #: seconds at the start of every fit run that screening fits search on (the cheap objective
    #: of the core's global stage); they are then scored on the whole runs. 0 = whole runs
    screen_head_s: float = 8.0
    bootstrap: int = 1000
    segment_s: float = 1.0
    max_iter: int = 30
    workers: int = 0
    seed: int = 0
    progress: bool = True
    #: bootstrap-segment refits of the selected model for ``ci95_refit`` (0 = linearised only)
    interval_refits: int = 0
    #: where candidate fits run: None = this machine's threads; an object with
    #: ``map(prep, jobs, max_iter, bar, head_s)`` (e.g. :class:`cablekit.diagnose.many.RayFits`) otherwise
    executor: Any = None


@dataclass
class Prepared:
    """Data and problems shared by every candidate fit."""

    spec: ModelSpec
    fit_runs: list[Run]
    hold_runs: list[Run]
    channel_names: list[str]
    columns: list[str]
    sigma: _F
    substeps: int
    fit0: JointProblem
    hold0: JointProblem
    candidates: list[str]
    skipped: dict[str, str]
    warnings: list[str] = field(default_factory=list)
    #: candidate id → its description from the core (effect, site, form, sentence, parameters)
    info: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: per channel: mains-interference lines (Hz) found in the fit runs, counted as noise
    interference_hz: list[list[float]] = field(default_factory=list)
    #: per channel: the width (samples) of the centred mean its residual is scored through (1:
    #: sample by sample; a derived load channel's, :func:`_load_window`)
    windows: list[int] = field(default_factory=list)
    #: identity of this preparation (a distributed executor ships its data once per token)
    token: str = field(default_factory=lambda: uuid.uuid4().hex)

    @property
    def q(self) -> int:
        return len(self.channel_names)


def joint_run(spec: ModelSpec, run: Run, columns: list[str], model: Any = None) -> JointRun:
    """The core's view of a run: inputs (servo references: angles then rates, given or the
    angles' derivative), the measured ``columns``, and the optional coupled axis, external torques
    and initial state."""
    measured = np.column_stack([run.column(c) for c in columns])
    cols = [run.column(c) for c in spec.inputs]
    if spec.servo():
        rates = spec.extra.get("dq_m_ref")
        cols += [run.column(c) for c in rates] if rates else [np.gradient(c, run.dt) for c in cols]
    external = None
    if spec.kind == "cable_network" and spec.external:
        # one column per joint of the network, zero where no load is recorded
        given = dict(spec.extra["external_joints"])
        ext = [run.column(given[j]) if j in given else np.zeros(len(run)) for j in spec.network().joint_names]
        external = np.ascontiguousarray(np.column_stack(ext))
    elif spec.external:
        ext = [run.column(c) for c in spec.external]
        external = np.ascontiguousarray(ext[0] if len(ext) == 1 else np.column_stack(ext))
    x0 = None
    if spec.kind == "cable_transmission" and model is not None:
        x0 = _transmission_x0(spec, run, model)
    # the torque commands the derived load channels hold, in :func:`commanded` order, as the
    # channels hold them (held over the stencil, or sampled as they are)
    derived = spec.extra.get("derived_load", {})
    cmds = []
    for c in commanded(spec):
        tau, held = derived[c][0], derived[c][3] if len(derived[c]) > 3 else True
        cmds.append(_held_torque(run.column(tau)) if held else run.column(tau))
    return JointRun(
        run.dt,
        np.ascontiguousarray(cols[0] if len(cols) == 1 else np.column_stack(cols)),
        np.ascontiguousarray(measured),
        coupled=np.ascontiguousarray(run.column(spec.coupled)) if spec.coupled else None,
        external=external,
        x0=x0,
        start=scored_start(spec.warmup, run),
        commands=np.ascontiguousarray(np.column_stack(cmds)) if cmds else None,
    )


def commanded(spec: ModelSpec) -> list[str]:
    """The measured columns that hold a recorded command (a motor's load ``τ − J·q̈`` when the
    motor is replayed from its measured angle), in the order of the runs' command columns."""
    derived = spec.extra.get("derived_load", {})
    return [c for _, c in spec.outputs if c in derived]


def _transmission_x0(spec: ModelSpec, run: Run, model: Any) -> _F:
    """Initial state of a transmission run from its first measured angles, at rest: a link's
    missing motor (joint) angle follows from its joint (motor) angle through the rigid-cable
    kinematics ``q_m = T·q_l``; unmeasured links start at 0."""
    n = spec.links
    q_m = np.full(n, np.nan)
    q_l = np.full(n, np.nan)
    for out, col in spec.outputs:
        base, idx = out.rstrip("0123456789"), out[len(out.rstrip("0123456789")) :]
        if base == "q_m":
            q_m[int(idx) - 1] = run.column(col)[0]
        elif base == "q_l":
            q_l[int(idx) - 1] = run.column(col)[0]
    if not np.isnan(q_m).any():
        # motor encoders resolve the cable stretch ~100x better than joint encoders: start
        # from the motor angles with the cables at rest length
        q_l = model.motor_to_joint(q_m)
    else:
        q_l = np.where(np.isnan(q_l), 0.0, q_l)
        q_m = np.where(np.isnan(q_m), model.joint_to_motor(q_l), q_m)
    x0 = np.zeros(model.n_states)
    x0[state_indices(model, "q_m")], x0[state_indices(model, "q_l")] = q_m, q_l
    return x0


def prepare(spec: ModelSpec, fit_runs: list[Run], hold_runs: list[Run]) -> Prepared:
    """Validate runs against the model file, estimate noise, build the base problems."""
    if not fit_runs:
        raise DataError("the diagnosis needs at least one fit run")
    if not hold_runs:
        raise DataError("the diagnosis needs at least one held-out run (a different trajectory, load or rig)")
    spec, fit_runs, hold_runs, replay_notes = _measured_motor_replay(spec, fit_runs, hold_runs)
    for run in fit_runs + hold_runs:
        check_units(run, spec.units())
        if not (math.isfinite(run.context) and 0.0 <= run.context < run.duration):
            raise DataError(
                f"run {run.name!r}: its history (context) must be in [0, {run.duration:g}) s, "
                f"got {run.context!r}"
            )
        if spec.warmup >= 0.5 * (run.duration - run.context):
            raise DataError(
                f"run {run.name!r} ({run.duration - run.context:g} s after its history) is too short for "
                f"a warm-up of {spec.warmup:g} s"
            )
    dts = {round(r.dt, 12) for r in fit_runs + hold_runs}
    if max(dts) > 1.01 * min(dts):
        raise DataError(f"runs have different sample intervals {sorted(dts)}; resample them to one")
    names = [o for o, _ in spec.outputs]
    columns = [c for _, c in spec.outputs]
    # measurement error per channel: white noise plus stationary mains lines, pooled over fit runs
    sigma_list, lines, windows = [], [], []
    derived = spec.extra.get("derived_load", {})
    # white noise a channel's prediction carries from a measured input (a parallel robot's
    # tension from its measured pose: cablekit.cdpr.drives), per sample, by column
    in_noise = spec.extra.get("input_noise", {})
    for c in columns:
        if c in derived:  # τ_m − J·q̈_m: the torque's noise and the encoder's through the difference
            tau, enc, inertia = derived[c][:3]
            held = derived[c][3] if len(derived[c]) > 3 else True
            dt = fit_runs[0].dt
            s_tau = _pooled([localise.measurement_sigma(r.column(tau), r.dt)[0] for r in fit_runs])
            s_acc = (
                inertia
                * _pooled([localise.measurement_sigma(r.column(enc), r.dt)[0] for r in fit_runs])
                / dt**2
            )
            window, s = _load_window(s_tau, s_acc, dt, in_noise.get(tau), held=held)
            sigma_list.append(s)
            lines.append([])
            windows.append(window)
            continue
        per_run = [localise.measurement_sigma(r.column(c), r.dt) for r in fit_runs]
        window, s = _input_window(_pooled([s for s, _ in per_run]), in_noise.get(c), fit_runs[0].dt)
        sigma_list.append(s)
        lines.append(sorted({f for _, ls in per_run for f, _ in ls}))
        windows.append(window)
    sigma = np.array(sigma_list)
    # a derived load channel holds its motor's torque command as recorded: a late command acts
    # on that part, not on the measured angle that drives the motor (``time_delay@input``)
    held = commanded(spec)
    chans = [
        (spec.output(o)[0], 1.0 / s, spec.output(o)[2], w, held.index(c) if c in held else None)
        for o, c, s, w in zip(names, columns, sigma, windows, strict=True)
    ]
    model = spec.model()
    fit_core = [joint_run(spec, r, columns, model) for r in fit_runs]
    hold_core = [joint_run(spec, r, columns, model) for r in hold_runs]
    servo = spec.servo()
    spec, nominal_notes = _dry_friction_nominal(spec, chans, fit_core)
    model = spec.model()
    probe = JointProblem(model, chans, fit_core, [], 1, servo)
    substeps = spec.substeps or max(1, probe.advised_substeps(np.zeros(0)))
    fit0 = JointProblem(model, chans, fit_core, [], substeps, servo)
    hold0 = JointProblem(model, chans, hold_core, [], substeps, servo)
    all_effects = [e["name"] for e in effect_catalogue()]
    wanted = spec.effects or []
    library = [
        c for c in probe.candidate_library() if not wanted or c["effect"] in wanted or c["id"] in wanted
    ]
    # explicitly named candidates outside the default library (a form or site the user asks for)
    for w in wanted:
        if "@" in w and all(c["id"] != w for c in library):
            library.append(probe.describe(w))
    info = {c["id"]: c for c in library}
    skipped: dict[str, str] = {}
    has_sensor = any(spec.output(o)[2] for o in names)
    motor_tension = any(o.startswith("tension_motor") or o == "net_motor_force" for o in names)
    offered = {c["effect"] for c in library}
    for e in all_effects:
        if e in offered:
            continue
        if wanted and not any(w.split("@")[0] == e for w in wanted):
            skipped[e] = "not in the model file's [diagnosis] effects"
        elif spec.kind == "cable_network" and e in NOT_IN_NETWORK:
            skipped[e] = NOT_IN_NETWORK[e]
        elif spec.kind == "cable_transmission" and e in NOT_IN_TRANSMISSION:
            skipped[e] = "no counterpart in the cable transmission model"
        elif e == "coupling" and spec.kind == "cable_transmission" and spec.links < 2:
            skipped[e] = "a single link has no coupling"
        elif e == "coupling" and spec.kind == "antagonistic_joint" and not spec.coupled:
            skipped[e] = "no coupled-axis column in [inputs]"
        elif e in ("sensor_lag", "sensor_sampling", "sensor_gain_bias") and not has_sensor:
            skipped[e] = "no force-sensor channel measured"
        elif e == "capstan_friction" and not motor_tension:
            skipped[e] = "no motor-side tension measured"
        else:
            skipped[e] = "no site of this plant where it can act on the measured channels"
    candidates = list(info)
    warnings = (
        replay_notes
        + nominal_notes
        + _servo_saturation(spec, model, fit_runs + hold_runs, fit_core + hold_core, substeps)
    )
    warnings += unknown_conditions(spec, fit_runs, hold_runs)
    return Prepared(
        spec,
        fit_runs,
        hold_runs,
        names,
        columns,
        sigma,
        substeps,
        fit0,
        hold0,
        candidates,
        skipped,
        warnings,
        info,
        interference_hz=lines,
        windows=windows,
    )


#: the longest averaging of a derived load channel's residual (s): a motor's friction, a routing
#: friction or a delay of its command changes the load at the trajectory's frequencies, well
#: below the 50 Hz this window still passes (the parallel robots' length channel uses the same)
LOAD_WINDOW_S = 0.02


def _pooled(sigmas: list[float]) -> float:
    return math.sqrt(float(np.mean(np.square(sigmas))))


def _odd_windows(dt: float) -> range:
    """The odd averaging windows (samples) up to :data:`LOAD_WINDOW_S`."""
    k_max = max(1, int(LOAD_WINDOW_S / dt))
    k_max -= 1 - k_max % 2
    return range(1, k_max + 1, 2)


#: a prediction's noise from a measured input: its white noise per sample and the kernel the
#: input was filtered with before the replay (``None``: none)
InputNoise = tuple[float, tuple[float, ...]] | None


def _input_part(noise: InputNoise, mean: _F) -> float:
    """The input's noise in a residual averaged by ``mean``."""
    if noise is None or noise[0] <= 0.0:
        return 0.0
    return noise[0] * float(np.linalg.norm(np.convolve(mean, np.asarray(noise[1], float))))


def _input_window(sigma: float, noise: InputNoise, dt: float) -> tuple[int, float]:
    """The averaging window (odd, samples) of a channel measured with white noise ``sigma``
    whose prediction carries noise from a measured input (:data:`InputNoise`), and the noise of
    its averaged residual: the shortest window for which the input's part is no larger than
    the measurement's per-sample noise, at most :data:`LOAD_WINDOW_S` (1 without input noise)."""
    inp = _input_part(noise, np.ones(1))
    best = (1, math.hypot(sigma, inp))
    if inp == 0.0:
        return best
    for k in _odd_windows(dt):
        mean = np.full(k, 1.0 / k)
        inp = _input_part(noise, mean)
        best = (k, math.hypot(sigma / math.sqrt(k), inp))
        if inp <= sigma:
            break
    return best


def _load_window(
    sigma_tau: float, sigma_acc: float, dt: float, noise: InputNoise = None, *, held: bool = True
) -> tuple[int, float]:
    """The averaging window (odd, samples) of a load channel ``τ − J·q̈`` and the noise of its
    averaged residual: the torque's white noise ``sigma_tau`` through :data:`_HELD_TORQUE` and
    ``sigma_acc = J·σ_q/dt²`` of the encoder through the five-point stencil.

    The stencil's noise is blue (it rises as ω² and dwarfs the torque's at a few mN·m for a 14-bit
    encoder at 1 kHz), which hides a motor's friction of 1 mN·m sample by sample. A centred mean
    over ``k`` samples telescopes the stencil to its ends (noise ∝ 1/k) and the torque's by √k;
    the window is the shortest for which the encoder's part is no larger than the torque's, and
    at most :data:`LOAD_WINDOW_S`. The noise is exact for the stated noises (the mean's weights
    through the stencil), so that a correct model still scores 1.

    ``noise`` is the noise the prediction carries from a measured input (see
    :func:`_input_window`): the window then also grows until its part is no larger than the
    torque's per-sample noise. ``held=False``: the torque is a sampled measurement, taken as it
    is (no :data:`_HELD_TORQUE`).
    """
    kernel = _HELD_TORQUE if held else np.ones(1)
    best = (1, math.hypot(sigma_tau, sigma_acc, _input_part(noise, np.ones(1))))
    for k in _odd_windows(dt):
        mean = np.full(k, 1.0 / k)
        acc = sigma_acc * float(np.linalg.norm(np.convolve(mean, _ACCEL_STENCIL)))
        tau = sigma_tau * float(np.linalg.norm(np.convolve(mean, kernel)))
        inp = _input_part(noise, mean)
        best = (k, math.hypot(tau, acc, inp))
        if acc <= tau and inp <= sigma_tau:
            break
    return best


#: the five-point central stencil of ``q̈·dt²`` (error O(dt⁴): 0.07 % at a tenth of the sampling
#: rate where the three-point one is off by 3 % — a motor's mode with its cables at 80 Hz
#: otherwise leaves its ``J·q̈`` error in the load channel)
_ACCEL_STENCIL = np.array([-1.0, 16.0, -30.0, 16.0, -1.0]) / 12.0


#: the torque a zero-order-held command applies over the five-point stencil's span: the stencil
#: weighs ``q̈`` on the four sample intervals around ``t_k`` by ``[−1, 13, 13, −1]/24``, so that
#: ``J·q̈_k`` balances this mean of ``τ_{k−2} … τ_{k+1}``, not ``τ_k`` (which would leave
#: ``τ̇·dt/2`` in the load: 10–40 µN·m on a finger moved at 1–2 Hz, above an averaged load's noise)
_HELD_TORQUE = np.array([-1.0, 13.0, 13.0, -1.0]) / 24.0


def _held_torque(tau: _F) -> _F:
    """A held torque command as the five-point acceleration of the same sample sees it
    (:data:`_HELD_TORQUE`; the ends repeat their neighbour's)."""
    a = np.array(tau, dtype=float)
    if len(a) >= 4:
        a[2:-1] = np.correlate(tau, _HELD_TORQUE, mode="valid")
        a[:2], a[-1] = a[2], a[-2]
    return a


def _acceleration(q: _F, dt: float) -> _F:
    """``q̈`` by the five-point central stencil (the two samples at each end repeat their
    neighbour's)."""
    a = np.empty_like(q)
    if len(q) < 5:
        a[:] = 0.0
        return a
    a[2:-2] = np.correlate(q, _ACCEL_STENCIL, mode="valid") / (dt * dt)
    a[:2], a[-2:] = a[2], a[-3]
    return a


def _measured_motor_replay(
    spec: ModelSpec, fit_runs: list[Run], hold_runs: list[Run]
) -> tuple[ModelSpec, list[Run], list[Run], list[str]]:
    """A network whose torque-driven motors all have a measured angle is replayed with those
    angles as the motors' positions (``[diagnosis] replay = "measured_motors"``, the default
    ``"auto"``), not open loop from their torques (``"open_loop"``).

    An open-loop torque replay integrates the rigid-body modes of every motor and joint: a
    2e-5 rad error of the initial state, or any effect, makes it drift by hundreds or millions of
    noise units (docs/diagnosis.md), so that a control case shows a gap and every fit starts far
    from its answer. Driven by the measured motor angles, the cables and joints are anchored to
    the data as a position-driven instrument is. The torque input then becomes a measured
    channel: ``load_m:<motor>`` (what the cables and the motor's own friction take) is compared
    with ``τ_m − J_m·q̈_m``, ``q̈_m`` the encoder's five-point central difference; the encoder itself
    is the input and is no longer scored. Returns the spec, the runs with the derived columns and
    a note for the diagnosis's warnings.
    """
    mode = spec.extra.get("replay", "auto")
    if spec.kind != "cable_network" or mode == "open_loop" or "derived_load" in spec.extra:
        return spec, fit_runs, hold_runs, []  # (a re-preparation's spec and runs are replayed so already)
    doc, _ = _network_document(spec.parameters, spec.source)
    net = spec.network()
    motors = list(net.motor_names)
    tables = {m.get("name"): m for m in doc.get("motors", []) if isinstance(m, dict)}
    torque = [m for m in motors if tables.get(m, {}).get("drive") == "torque"]
    names = list(net.output_names)
    encoder: dict[str, tuple[str, str]] = {}
    for out, col in spec.outputs:
        base = names[network_output_info(net, out)[0]]
        if base.startswith("q_m:") and base[4:] in torque:
            encoder.setdefault(base[4:], (out, col))
    missing = [m for m in torque if m not in encoder]
    if not torque or missing:
        if mode == "measured_motors":
            raise DataError(
                f'{spec.source}: [diagnosis] replay = "measured_motors" needs a measured angle (an output '
                f"q_m:<motor>) for every torque-driven motor; "
                + (f"missing for {missing}" if torque else "the network has no torque-driven motor")
            )
        return spec, fit_runs, hold_runs, []
    derived = {m: f"{spec.inputs[motors.index(m)]} − J·q̈ ({m})" for m in torque}
    # a held command as the stencil sees it, or a sampled torque (a measured current) as it is
    held = spec.extra.get("torque", "held") == "held"

    def with_load(run: Run) -> Run:
        cols = dict(run.columns)
        for m in torque:
            inertia = float(tables[m].get("inertia", 0.0))
            tau = run.column(spec.inputs[motors.index(m)])
            cols[derived[m]] = (_held_torque(tau) if held else tau) - inertia * _acceleration(
                run.column(encoder[m][1]), run.dt
            )
        return replace(run, columns=cols)

    new_doc = dict(
        doc, motors=[dict(t, drive="position") if t.get("name") in torque else t for t in doc["motors"]]
    )
    scored = {encoder[m] for m in torque}
    new = replace(
        spec,
        parameters={"definition": new_doc},
        inputs=[
            encoder[m][1] if m in torque else c
            for m, c in zip([*motors, *net.signal_names], spec.inputs, strict=True)
        ],
        outputs=[oc for oc in spec.outputs if oc not in scored]
        + [(f"load_m:{m}", derived[m]) for m in torque],
        extra={k: v for k, v in spec.extra.items() if k != "_network"}
        | {
            "replay": "measured_motors",
            "derived_load": {
                derived[m]: (
                    spec.inputs[motors.index(m)],
                    encoder[m][1],
                    float(tables[m].get("inertia", 0.0)),
                    held,
                )
                for m in torque
            },
        },
    )
    note = (
        f"the torque-driven motors {', '.join(torque)} are replayed from their measured angles "
        f"({', '.join(encoder[m][1] for m in torque)}), not open loop from their torques; their torques are "
        "scored as load_m = τ_m − J_m·q̈_m; "
        '[diagnosis] replay = "open_loop" replays the torques'
    )
    return new, [with_load(r) for r in fit_runs], [with_load(r) for r in hold_runs], [note]


#: a network's dry friction is resolved sharply when that leaves at most this share of the file's
#: nominal gap on the fit runs (:func:`_dry_friction_nominal`)
SHARPEN_SHARE = 0.5


def _dry_friction_nominal(
    spec: ModelSpec, chans: list[tuple[int, float, bool, int, int | None]], fit_core: list[JointRun]
) -> tuple[ModelSpec, list[str]]:
    """The nominal a network diagnosis replays: the file's dry friction, or the same resolved
    sharply (:func:`~cablekit.diagnose.spec.sharpen_dry_friction`) when the fit runs say so.

    A network file's ``smoothing`` of a joint's (or a torque-driven motor's) Coulomb friction is a
    regularisation of the sign: the format's default, 1e-3 rad/s, lets a joint at rest under a
    load below its friction creep, where real dry friction sticks. A plant that sticks then shows
    a gap on every run — controls included — that no inserted effect explains. The diagnosis
    replays the fit runs (never the held-out ones) with both and keeps the sharp one when its gap
    is at most :data:`SHARPEN_SHARE` of the file's and the file's is above noise; a note says so.
    The decision is recorded in the returned spec (``extra["sharp_dry_friction"]``, ``None`` for
    the file's), so that a re-preparation of the same diagnosis (intervals, a worker) keeps it.
    """
    if spec.kind != "cable_network" or "sharp_dry_friction" in spec.extra:
        return spec, []
    keep = {k: v for k, v in spec.extra.items() if k != "_network"}
    as_file = replace(spec, extra=keep | {"sharp_dry_friction": None})
    doc, _ = _network_document(spec.parameters, spec.source)
    changed = sharpen_dry_friction(doc)[1]
    if not changed:
        return as_file, []
    sharp = replace(spec, extra=keep | {"sharp_dry_friction": SHARP_DRY_FRICTION})

    def nominal_gap(s: ModelSpec) -> float:
        model = s.model()
        probe = JointProblem(model, chans, fit_core, [], 1, s.servo())
        substeps = s.substeps or max(1, probe.advised_substeps(np.zeros(0)))
        r = JointProblem(model, chans, fit_core, [], substeps, s.servo()).residuals(np.zeros(0))
        return float(np.mean(r * r))

    g_file, g_sharp = nominal_gap(as_file), nominal_gap(sharp)
    if not (g_file > NOISE_LEVEL and g_sharp <= SHARPEN_SHARE * g_file):
        return as_file, []
    return sharp, [
        f"the nominal's dry friction at {', '.join(changed)} is resolved sharply (sign smoothing "
        f"{SHARP_DRY_FRICTION:g} rad/s or m/s instead of the network file's): the fit runs stick where the "
        f"file's smoothed law creeps — the nominal gap on the fit runs falls from {g_file:.3g} to "
        f"{g_sharp:.3g} noise units (a mechanism whose friction does creep at rest has viscous friction: "
        "state it as such)"
    ]


#: share of a run's samples at the servo's torque limit above which the replay is flagged
SATURATION_WARN = 0.02


def _values(values: set[float] | tuple[float, ...]) -> str:
    return ", ".join(f"{v:g}" for v in sorted(values)) or "none"


def unknown_conditions(spec: ModelSpec, fit_runs: list[Run], hold_runs: list[Run]) -> list[str]:
    """A warning for each run attribute (a wrist posture, ...) at a value the model does not know:
    one the nominal was not built at (``spec.conditions``), one a run does not state although the
    nominal's is stated, and one a held-out run has and no fit run does. The model has no input
    for such a condition, so the part of the run's gap it causes would otherwise be read as an
    unmodelled effect; the warning says so, once per attribute and value."""
    out: list[str] = []
    runs = fit_runs + hold_runs

    def known(value: float, among: set[float] | tuple[float, ...]) -> bool:
        return any(math.isclose(value, k, rel_tol=1e-9, abs_tol=1e-9) for k in among)

    for name, built in sorted(spec.conditions.items()):
        missing = [r.name for r in runs if name not in r.attributes]
        if missing:
            out.append(
                f"run(s) {', '.join(missing)} state no {name}; the nominal was built at {name} = "
                f"{_values(built)}: if it differs, part of their gap is that change, not an unmodelled effect"
            )
        other: dict[float, list[str]] = {}
        for r in runs:
            v = r.attributes.get(name)
            if v is not None and not known(v, built):
                other.setdefault(v + 0.0, []).append(r.name)  # + 0.0: -0 is 0
        for v, names in sorted(other.items()):
            out.append(
                f"run(s) {', '.join(names)} at {name} = {v:g}, the nominal was built at "
                f"{_values(built)}: the model has no input for {name}, so part of their gap is that "
                "change, not an unmodelled effect"
            )
    fitted: dict[str, set[float]] = {}
    for r in fit_runs:
        for name, v in r.attributes.items():
            fitted.setdefault(name, set()).add(v)
    new: dict[tuple[str, float], list[str]] = {}
    for r in hold_runs:
        for name, v in r.attributes.items():
            if name not in spec.conditions and not known(v, fitted.get(name, set())):
                new.setdefault((name, v + 0.0), []).append(r.name)
    for (name, v), names in sorted(new.items()):
        out.append(
            f"held-out run(s) {', '.join(names)} at {name} = {v:g}, which no fit run has "
            f"({_values(fitted.get(name, set()))}): the fitted effects never saw it, and the model has no "
            f"input for it"
        )
    return out


def _servo_saturation(
    spec: ModelSpec, model: Any, runs: list[Run], dicts: list[JointRun], substeps: int
) -> list[str]:
    """Warnings for runs whose nominal servo replay sits at the torque limit: a saturated servo
    is open loop, and an open-loop replay of a frictional transmission amplifies any initial
    error (docs/diagnosis.md)."""
    servo = spec.servo()
    if not servo:
        return []
    n = spec.links
    limit = np.asarray(servo[2])
    chans = [(5 * n + i, 1.0, False) for i in range(n)]
    out = []
    for run, d in zip(runs, dicts, strict=True):
        probe = JointProblem(model, chans, [d.with_measured(np.zeros((len(run), n)))], [], substeps, servo)
        tau = probe.predict(np.zeros(0), 0)
        share = np.mean(np.abs(tau) >= 0.99 * limit, axis=0)
        for i in np.flatnonzero(share > SATURATION_WARN):
            out.append(
                f"run {run.name!r}: the nominal servo replay holds axis {i + 1} at its torque limit "
                f"{100 * share[i]:.0f} % of the time; a saturated servo is open loop and its replay "
                "is sensitive to the initial state: slow the references or raise the limit"
            )
    return out
