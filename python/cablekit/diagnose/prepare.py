"""Prepare a diagnosis: validate the runs against the model file, estimate each channel's
noise, build the nominal problems and the candidate library; the knobs (:class:`Options`) and
the thresholds every later stage shares."""

from __future__ import annotations

import math
import uuid
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cablekit._cablekit import JointProblem, JointRun, effect_catalogue
from cablekit.diagnose import localise
from cablekit.diagnose.data import Run, check_units
from cablekit.diagnose.spec import NOT_IN_NETWORK, NOT_IN_TRANSMISSION, ModelSpec
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
    return JointRun(
        run.dt,
        np.ascontiguousarray(cols[0] if len(cols) == 1 else np.column_stack(cols)),
        np.ascontiguousarray(measured),
        coupled=np.ascontiguousarray(run.column(spec.coupled)) if spec.coupled else None,
        external=external,
        x0=x0,
        start=round(spec.warmup / run.dt),
    )


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
    for run in fit_runs + hold_runs:
        check_units(run, spec.units())
        if spec.warmup >= 0.5 * run.duration:
            raise DataError(
                f"run {run.name!r} ({run.duration:g} s) is too short for a warm-up of {spec.warmup:g} s"
            )
    dts = {round(r.dt, 12) for r in fit_runs + hold_runs}
    if max(dts) > 1.01 * min(dts):
        raise DataError(f"runs have different sample intervals {sorted(dts)}; resample them to one")
    names = [o for o, _ in spec.outputs]
    columns = [c for _, c in spec.outputs]
    # measurement error per channel: white noise plus stationary mains lines, pooled over fit runs
    sigma_list, lines = [], []
    for c in columns:
        per_run = [localise.measurement_sigma(r.column(c), r.dt) for r in fit_runs]
        sigma_list.append(math.sqrt(np.mean([s * s for s, _ in per_run])))
        lines.append(sorted({f for _, ls in per_run for f, _ in ls}))
    sigma = np.array(sigma_list)
    chans = [(spec.output(o)[0], 1.0 / s, spec.output(o)[2]) for o, s in zip(names, sigma, strict=False)]
    model = spec.model()
    fit_core = [joint_run(spec, r, columns, model) for r in fit_runs]
    hold_core = [joint_run(spec, r, columns, model) for r in hold_runs]
    servo = spec.servo()
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
    warnings = _servo_saturation(spec, model, fit_runs + hold_runs, fit_core + hold_core, substeps)
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
    )


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
