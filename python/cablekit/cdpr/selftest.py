"""The parallel robots' self-test through the one diagnosis engine (issue #39 §2): the Mini CDPR
twin (:func:`cablekit.cdpr.diagnose.twin_run`: seed 002's robot with seed 003's winches and the
twin's platform-side Dahl pulleys, one effect withheld at a drawn cable, the internal forces
excited so that the tensions vary, a tracker's noise on the poses) diagnosed as a network of
drives (:mod:`cablekit.cdpr.drives`): fitted on the run's first 15 s, scored on its last 15 s
(replayed from the run's start: its first half is the second's history, :attr:`Run.context`).

A withheld effect is named right when the diagnosis's first effect is one of the engine's
effects for it, at its site (the withheld cable ``j``):

=================  ============================================  ==========================
withheld           the engine's effects                          site
=================  ============================================  ==========================
pulley_friction    capstan_friction, dahl_hysteresis             ``routing.c<j>``
sensor_lag         sensor_lag, sensor_sampling, time_delay       ``sensor.T@drum_side<j>:c<j>``
sensor_gain        sensor_gain_bias                              ``sensor.T@drum_side<j>:c<j>``
drum_friction      coulomb_friction, stribeck_friction           ``motor.drum<j>``
cable_elasticity   nonlinear_stiffness                           ``cable.c<j>``
cable_creep        creep                                         ``cable.c<j>``
=================  ============================================  ==========================

(The twin's drum-side pulley is seed 002's additive Dahl law, ``μ·N·T·z + σ_v·v``; the engine's
routing candidates are the capstan's ``T·e^{μφ·s}`` and its pre-sliding: the same physics to first
order in ``μ``, without the viscous part. The HX711 + BLE chain holds and delays; the engine's
lag, sampling and delay forms are all "the sensor lags".) A control (nothing withheld) is right
when the verdict is ``no_significant_gap``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from cablekit import _log
from cablekit._args import Seed, Stride, checked, choice, count, instance, real

#: per withheld effect: the engine's effects that name it and the site's pattern (cable j, 1-based)
ENGINE_NAMES: dict[str, tuple[frozenset[str], str]] = {
    "pulley_friction": (frozenset({"capstan_friction", "dahl_hysteresis"}), "routing.c{j}"),
    "sensor_lag": (frozenset({"sensor_lag", "sensor_sampling", "time_delay"}), "sensor.T@drum_side{j}:c{j}"),
    "sensor_gain": (frozenset({"sensor_gain_bias"}), "sensor.T@drum_side{j}:c{j}"),
    "drum_friction": (frozenset({"coulomb_friction", "stribeck_friction"}), "motor.drum{j}"),
    "cable_elasticity": (frozenset({"nonlinear_stiffness"}), "cable.c{j}"),
    "cable_creep": (frozenset({"creep"}), "cable.c{j}"),
}
#: the twin's cables' damping (N·s/m; cablekit.cdpr.CdprPlant's default), part of the nominal
TWIN_CABLE_DAMPING = 50.0


@dataclass(frozen=True)
class EngineCase:
    """A withheld effect (``None``: none) at a cable (0-based), and the diagnosis."""

    effect: str | None
    cable: int | None
    diagnosis: Any
    seconds: float

    @property
    def top(self) -> Any:
        """The first effect the diagnosis names (``None`` when it finds no significant gap)."""
        d = self.diagnosis
        return d.effects[0] if d.effects and d.verdict != "no_significant_gap" else None

    @property
    def correct_effect(self) -> bool:
        """The first effect is the withheld one's (none when none is withheld)."""
        if self.effect is None:
            return self.diagnosis.verdict == "no_significant_gap"
        return self.top is not None and self.top.name in ENGINE_NAMES[self.effect][0]

    @property
    def correct_site(self) -> bool:
        """... and at its cable's site."""
        if self.effect is None or self.cable is None:
            return self.correct_effect
        site = ENGINE_NAMES[self.effect][1].format(j=self.cable + 1)
        return self.correct_effect and self.top.site == site


@checked
def twin_diagnosis(
    effect: str | None, cable: int, *, seed: Seed = 0, duration: float = 30.0, progress: bool = False
) -> Any:
    """The engine's diagnosis (:class:`cablekit.diagnose.result.Diagnosis`) of one twin run with
    ``effect`` withheld at ``cable`` (0-based), its first ``duration`` s (at most the run's 30 s):
    the first half fitted, the second held out."""
    from cablekit.cdpr import drives
    from cablekit.cdpr.compensate import TWIN_FRICTION
    from cablekit.cdpr.diagnose import twin_run
    from cablekit.diagnose.data import Run
    from cablekit.diagnose.engine import diagnose
    from cablekit.diagnose.prepare import Options

    duration = real(duration, "duration", lo=4.0, hi=30.0)
    cable = count(cable, "cable", lo=0, hi=7)
    run = twin_run(effect, cable, seed=seed)
    lg = run.lengths
    cols = drives.drive_columns(
        lg.robot, run.winch, lg.rest_length, run.t, run.alpha, run.current, run.sensor, lg.poses
    )
    spec = drives.drive_spec(
        lg.robot, run.winch, lg.rest_length, cols.input_noise, TWIN_FRICTION, cable_damping=TWIN_CABLE_DAMPING
    )
    dt = cols.t[1] - cols.t[0]
    half = round(duration / dt) // 2
    whole = Run("run", cols.t[: 2 * half], {k: v[: 2 * half] for k, v in cols.columns.items()})
    fit = whole.segment(0.0, (half - 0.5) * dt, "first half")
    # the second half continues the first: replayed from the run's start (a creeping cable's
    # relaxation, a pulley's pre-sliding enter it as they were), scored after it
    hold = whole.segment((half - 0.5) * dt, 2 * half * dt, "second half", context=float(cols.t[half]))
    return diagnose(spec, [fit], [hold], Options(progress=progress))


@checked
def self_test(
    *,
    cases: Stride = 2,
    seed: Seed = 0,
    duration: float = 30.0,
    effects: tuple[str, ...] | None = None,
    progress: bool = False,
) -> list[EngineCase]:
    """``cases`` twin runs per withheld effect (:data:`cablekit.cdpr.diagnose.WITHHELD`, or those
    of ``effects``) at drawn cables and ``cases`` with none — the plan (cables, seeds) of the
    retired engine's self-test — each of ``duration`` s."""
    from cablekit.cdpr.diagnose import WITHHELD

    chosen = WITHHELD if effects is None else tuple(choice(e, "effects", WITHHELD) for e in effects)
    rng = np.random.default_rng(seed)
    plan: list[tuple[str | None, int]] = [(e, int(rng.integers(8))) for e in WITHHELD for _ in range(cases)]
    plan += [(None, 0)] * cases
    # (a case keeps its cable and seed whichever effects are chosen)
    todo = [(k, e, c) for k, (e, c) in enumerate(plan) if e is None or e in chosen]
    out = []
    for k, effect, cable in todo:
        t0 = time.perf_counter()
        d = twin_diagnosis(effect, cable, seed=seed + k, duration=duration)
        case = EngineCase(effect, None if effect is None else cable, d, time.perf_counter() - t0)
        out.append(case)
        if progress:
            what = "nothing" if effect is None else f"{effect} at cable {cable + 1}"
            top = case.top.id if case.top else "—"
            mark = "ok " if case.correct_site else "MISS"
            _log.info(
                f"[{len(out)}/{len(todo)}] {mark} withheld {what}: {d.verdict}, "
                f"first {top} ({case.seconds:.0f} s)"
            )
    return out


@checked
def markdown(cases: list[EngineCase]) -> str:
    """The self-test table and its totals."""
    instance(cases, "cases", list)
    lines = [
        "| withheld | verdict | first effect | held-out gap closed | effect | cable | s |",
        "|---|---|---|---|---|---|---|",
    ]
    for c in cases:
        what = "nothing" if c.effect is None else f"{c.effect} at cable {c.cable + 1}"
        d = c.diagnosis
        top = c.top.id if c.top else "—"
        closed = d.selected.held_out.closed_fraction if c.top else float("nan")
        lines.append(
            f"| {what} | {d.verdict} | {top} | {100 * closed:.0f} % | "
            f"{'yes' if c.correct_effect else 'NO'} | {'yes' if c.correct_site else 'NO'} | {c.seconds:.0f} |"
        )
    withheld = [c for c in cases if c.effect is not None]
    none = [c for c in cases if c.effect is None]
    lines += [
        "",
        f"Effect right in {sum(c.correct_effect for c in withheld)}/{len(withheld)}, cable right in "
        f"{sum(c.correct_site for c in withheld)}/{len(withheld)}, false alarms "
        f"{sum(not c.correct_effect for c in none)}/{len(none)}.",
    ]
    return "\n".join(lines)
