"""Seed 000's clamping experiments in the forceps twin, its PSO-BPNN + JTDO pipeline beside the
physics-informed estimator, and the transfer to other instruments (issue #22 §1–2).

The protocol (every number is measured by :func:`seed_experiments` and :func:`transfer_study`):

* **Free motion** (§3.1): both jaws close over their whole range and open again at 0.5, 0.6,
  0.7, 0.8 and 1.0 mm/s, block removed. The seed's free-motion tension model, a PSO-BPNN 4-10-4
  (Table 1), is trained on it (``cablekit.nn``, torch) and runs in Rust.
* **Clamping** (§3.3): from a 120° opening onto the block (first contact at 65°):
  continuous clamping to 2 N held 3 s (Fig. 7); stair loading in five increments to 2 N at
  0.5 mm/s (group 1, Fig. 8) and to 1.6 N at 0.8 mm/s (group 2, Fig. 9), 2 s per step.
  Each run has its own sensor noise.
* **Estimators**: the seed's JTDO on the network's ``F̂_E``, without compensation (as in the
  seed's Fig. 7) and compensated by group 1's mean errors (as in its Figs 8–9); the
  physics-informed estimator calibrated on one free-motion sweep
  (0.8 mm/s, no force sensor needed); the same calibrated on group 1 with its pressure-sensor
  forces (the data the seed's compensation uses). Group 1 is therefore a calibration run for
  two of the four; continuous clamping and group 2 are held out for all.
* **Metrics** against the pressure sensors (as the seed): RMSE and mean error of ``F_ext^A``,
  ``F_ext^B`` and ``F_CF``; the interval of the ``F_CF`` errors; static accuracy
  ``1 − mean|F̂ − F| / mean F`` in the constant-loading region (both motors at rest, measured
  ``F_CF`` above the threshold); the delay from the measured clamping force crossing the
  collision threshold to the first detection; and the share of no-contact samples flagged.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np

from cablekit._args import Seed, checked, count, instance
from cablekit._cablekit import ClampRun, Jtdo, Mlp, PhysicsObserver, Twin, TwinRun
from cablekit.diagnose.progress import Progress
from cablekit.forceps.twin import TRANSFER_VARIATIONS, Variation, another_instrument

SEED_THRESHOLD = 0.11
#: the seed's figures (seed 000 §3.3): clamp RMSE, mean CF error, CF error interval, static accuracy
SEED_FIGURES = {
    "continuous (Fig. 7)": dict(rmse=(0.1010, 0.4035, 0.2321), mean=(-0.0088, -0.3042, -0.1751),
                                interval=(-0.3482, 0.1718), accuracy=(0.9383, 0.8013, 0.8691)),
    "stair group 1 (Fig. 8)": dict(rmse=(0.0825, 0.0956, 0.070), mean=(0.00002, -0.00004, -0.013),
                                   interval=(-0.1343, 0.2256), accuracy=None),
    "stair group 2 (Fig. 9)": dict(rmse=(0.1316, 0.1087, 0.080), mean=(-0.1223, 0.0628, 0.0736),
                                   interval=(-0.0100, 0.2794), accuracy=None),
}  # fmt: skip
#: the clamping experiments: (speed m/s, peak N, load steps, dwell s, noise seed)
EXPERIMENTS = {
    "continuous (Fig. 7)": (0.5e-3, 2.0, 1, 3.0, 101),
    "stair group 1 (Fig. 8)": (0.5e-3, 2.0, 5, 2.0, 102),
    "stair group 2 (Fig. 9)": (0.8e-3, 1.6, 5, 2.0, 103),
}
CALIBRATION = "stair group 1 (Fig. 8)"
#: the sensorless calibration run: one free-motion sweep at this speed (m/s), its noise seed
FREE_SWEEP = (0.8e-3, 104)
ESTIMATORS = (
    "PSO-BPNN + JTDO, uncompensated",
    "PSO-BPNN + JTDO, group-1 compensation (seed 000)",
    "physics, free-motion calibration",
    "physics, group-1 calibration",
)
#: issue #22's goals: clamp RMSE in the twin (N), transfer ratio
GOAL_RMSE = 0.07
GOAL_TRANSFER = 1.5


@dataclass(frozen=True)
class Metrics:
    """One estimator on one run; forces in N, ``(A, B, CF)`` triples."""

    rmse: tuple[float, float, float]
    mean: tuple[float, float, float]
    interval: tuple[float, float]
    accuracy: tuple[float, float, float] | None
    detection_delay_s: float
    false_alarm_share: float


def _triple(x: np.ndarray) -> tuple[float, float, float]:
    return (float(x[0]), float(x[1]), float(x[2]))


@checked
def metrics(run: TwinRun, est: ClampRun, threshold: float = SEED_THRESHOLD) -> Metrics:
    """The seed's figures of merit for ``est`` on ``run`` (see the module docs)."""
    meas = np.column_stack([run.external, 0.5 * np.abs(run.external).sum(axis=1)])
    ests = np.column_stack([est.external, est.clamping])
    err = ests - meas
    still = (run.motors[:, 1] == 0.0) & (run.motors[:, 3] == 0.0)
    loaded = still & (meas[:, 2] > threshold)
    accuracy = None
    if loaded.any():
        acc = 1.0 - np.abs(err[loaded]).mean(axis=0) / np.abs(meas[loaded]).mean(axis=0)
        accuracy = _triple(acc)
    touching = np.flatnonzero(meas[:, 2] > threshold)
    flagged = est.contact.any(axis=1)
    delay = math.nan
    if touching.size:
        # the first detection from the true first touch on, against the measured threshold crossing
        start = int(np.flatnonzero(run.external_true.max(axis=1) > 0.0)[0])
        det = np.flatnonzero(flagged[start:])
        if det.size:
            delay = float(run.time[start + det[0]] - run.time[touching[0]])
    no_contact = run.external_true.max(axis=1) <= 0.0
    false_share = float(flagged[no_contact].mean()) if no_contact.any() else 0.0
    return Metrics(
        rmse=_triple(np.sqrt((err**2).mean(axis=0))),
        mean=_triple(err.mean(axis=0)),
        interval=(float(err[:, 2].min()), float(err[:, 2].max())),
        accuracy=accuracy,
        detection_delay_s=delay,
        false_alarm_share=false_share,
    )


@checked
def with_seed(twin: Twin, seed: Seed) -> Twin:
    """The same bench with another noise realisation."""
    instance(twin, "twin", Twin)
    seed = count(seed, "seed", hi=2**63 - 1)
    tn, pn, _, dt, sub = twin.bench
    return Twin(twin.a, twin.b, tension_noise=tn, pressure_noise=pn, seed=seed, sample_time=dt, substeps=sub)


@checked
def train_free_motion_network(free: TwinRun, seed: Seed = 0, progress: bool = False) -> Mlp:
    """Seed 000's free-motion tension model: a PSO-BPNN 4-10-4 (Table 1) from
    ``[x_a, v_a, x_b, v_b]`` to the four measured tensions, loaded into Rust."""
    from cablekit.nn import to_mlp, train_mlp

    res = train_mlp(free.motors, free.measured, method="pso-lm", seed=seed, progress=progress)
    return to_mlp(
        res,
        input_names=("x_a", "v_a", "x_b", "v_b"),
        input_units=("m", "m/s", "m", "m/s"),
        output_names=("F_A1", "F_A2", "F_B1", "F_B2"),
        output_units=("N", "N", "N", "N"),
    )


def _geometry(twin: Twin) -> dict[str, float]:
    names = list(Twin.JAW_NAMES)
    return dict(r2=float(twin.a[names.index("r2")]), arm_a=float(twin.a[names.index("arm")]),
                arm_b=float(twin.b[names.index("arm")]))  # fmt: skip


@checked
def neutral_physics(twin: Twin) -> PhysicsObserver:
    """A physics estimator with the core's neutral start (``Losses::START``) for ``twin``'s
    lever geometry."""
    instance(twin, "twin", Twin)
    return PhysicsObserver(**_geometry(twin))


@dataclass
class Instrument:
    """The three estimators set up for one twin instrument, and the runs they were set up on."""

    twin: Twin
    network: Mlp
    jtdo: Jtdo
    physics_free: PhysicsObserver
    physics_loaded: PhysicsObserver
    runs: dict[str, TwinRun] = field(default_factory=dict)

    @checked
    def estimates(self, run: TwinRun) -> dict[str, ClampRun]:
        free = self.network.predict(run.motors)
        return {
            ESTIMATORS[0]: self.jtdo.with_bias((0.0, 0.0)).estimate(run.measured, free),
            ESTIMATORS[1]: self.jtdo.estimate(run.measured, free),
            ESTIMATORS[2]: self.physics_free.estimate(run.motors, run.measured),
            ESTIMATORS[3]: self.physics_loaded.estimate(run.motors, run.measured),
        }


@checked
def set_up(
    twin: Twin,
    network: Mlp,
    start_free: PhysicsObserver,
    start_loaded: PhysicsObserver,
    advance: Callable[[str], None] = lambda _: None,
) -> Instrument:
    """Run ``twin``'s experiments and set the estimators up on its calibration runs: the JTDO
    of ``network`` with group 1's bias, ``start_free`` calibrated on one free-motion sweep,
    ``start_loaded`` on group 1."""
    runs = {}
    for name, (speed, peak, steps, dwell, seed) in EXPERIMENTS.items():
        runs[name] = with_seed(twin, seed).clamp(speed, peak, steps, dwell)
        advance(name)
    speed, seed = FREE_SWEEP
    sweep = with_seed(twin, seed).free_motion([speed])
    cal = runs[CALIBRATION]
    jtdo = Jtdo(**_geometry(twin)).calibrated(cal.measured, network.predict(cal.motors), cal.external)
    physics_free, _ = start_free.calibrated(sweep.motors, sweep.measured, np.zeros((sweep.time.size, 2)))
    physics_loaded, _ = start_loaded.calibrated(cal.motors, cal.measured, cal.external)
    advance("calibrations")
    return Instrument(twin, network, jtdo, physics_free, physics_loaded, runs)


@dataclass(frozen=True)
class SeedReport:
    """Seed 000's experiments in the twin: per experiment and estimator the metrics, plus the
    free-motion network's test RMSE and the instrument (for the plots)."""

    table: dict[str, dict[str, Metrics]]
    network_rmse: float
    free_samples: int
    instrument: Instrument

    @checked
    def held_out_rmse(self, estimator: str) -> float:
        """Clamping-force RMSE pooled over the runs no estimator was set up on (N)."""
        return pooled_rmse(self.instrument, estimator, [n for n in EXPERIMENTS if n != CALIBRATION])


@checked
def pooled_rmse(inst: Instrument, estimator: str, names: list[str]) -> float:
    """``F_CF`` RMSE of ``estimator`` pooled over the runs ``names`` of ``inst`` (N)."""
    sq, n = 0.0, 0
    for name in names:
        run = inst.runs[name]
        est = inst.estimates(run)[estimator]
        err = est.clamping - 0.5 * np.abs(run.external).sum(axis=1)
        sq += float((err**2).sum())
        n += err.size
    return math.sqrt(sq / n)


@checked
def seed_experiments(twin: Twin, progress: bool = True) -> SeedReport:
    """Seed 000's pipeline and experiments on ``twin`` beside the physics estimator."""
    with Progress(7, "forceps experiments", enabled=progress) as bar:
        free = twin.free_motion()
        bar.advance("free motion")
        network = train_free_motion_network(free)
        pred = network.predict(free.motors)
        network_rmse = float(np.sqrt(((pred - free.measured) ** 2).mean()))
        bar.advance("PSO-BPNN")
        start = neutral_physics(twin)
        inst = set_up(twin, network, start, start, bar.advance)
        table = {n: {k: metrics(r, e) for k, e in inst.estimates(r).items()} for n, r in inst.runs.items()}
        bar.advance("metrics")
    return SeedReport(table, network_rmse, free.time.size, inst)


@dataclass(frozen=True)
class TransferRow:
    """One other instrument: its variation and, per estimator, the held-out ``F_CF`` RMSE on it
    (N) and the ratio to the first instrument's."""

    variation: Variation
    rmse: dict[str, float]
    ratio: dict[str, float]


@checked
def transfer_study(report: SeedReport, progress: bool = True) -> list[TransferRow]:
    """Trained on the first instrument (the network; the physics fits as starting points),
    set up on one calibration run of each other instrument (group 1 for the JTDO's bias and the
    loaded physics fit, one free-motion sweep for the sensorless fit), scored on its held-out
    runs."""
    base = report.instrument
    held = [n for n in EXPERIMENTS if n != CALIBRATION]
    first = {e: pooled_rmse(base, e, held) for e in ESTIMATORS}
    rows = []
    with Progress(len(TRANSFER_VARIATIONS), "transfer", enabled=progress) as bar:
        for v in TRANSFER_VARIATIONS:
            other = another_instrument(base.twin, v)
            inst = set_up(other, base.network, base.physics_free, base.physics_loaded)
            rmse = {e: pooled_rmse(inst, e, held) for e in ESTIMATORS}
            rows.append(TransferRow(v, rmse, {e: rmse[e] / first[e] for e in ESTIMATORS}))
            bar.advance(v.label())
    return rows


def _fmt(x: float, digits: int = 3) -> str:
    return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}f}"


@checked
def seed_table(report: SeedReport) -> str:
    """The seed-vs-cablekit table (markdown)."""
    lines = [
        "| experiment | estimator | RMSE F_ext^A / F_ext^B / F_CF (N) | mean error A / B / CF (N) "
        "| F_CF error interval (N) | static accuracy A / B / CF | detection delay (s) | false alarms |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, row in report.table.items():
        s = SEED_FIGURES[name]
        acc = s["accuracy"]
        lines.append(
            f"| {name} | **seed 000 (published, real bench)** | "
            + " / ".join(_fmt(v) for v in s["rmse"])
            + " | "
            + " / ".join(_fmt(v, 4) for v in s["mean"])
            + f" | [{s['interval'][0]:.3f}, {s['interval'][1]:.3f}] | "
            + (" / ".join(f"{100 * a:.1f} %" for a in acc) if acc else "–")
            + " | threshold 0.11 N | – |"
        )
        for est, m in row.items():
            cal = " (its calibration run)" if name == CALIBRATION and est in ESTIMATORS[1::2] else ""
            acc_m = " / ".join(f"{100 * a:.1f} %" for a in m.accuracy) if m.accuracy else "–"
            lines.append(
                f"| {name} | {est}{cal} | "
                + " / ".join(_fmt(v) for v in m.rmse)
                + " | "
                + " / ".join(_fmt(v, 4) for v in m.mean)
                + f" | [{m.interval[0]:.3f}, {m.interval[1]:.3f}] | {acc_m} | "
                + f"{_fmt(m.detection_delay_s, 2)} | {100 * m.false_alarm_share:.1f} % |"
            )
    return "\n".join(lines)


@checked
def transfer_table(report: SeedReport, rows: list[TransferRow]) -> str:
    """The transfer table (markdown): held-out ``F_CF`` RMSE per instrument and the ratio."""
    head = "| instrument | " + " | ".join(ESTIMATORS) + " |"
    lines = [head, "|---|" + "---|" * len(ESTIMATORS)]
    held = [n for n in EXPERIMENTS if n != CALIBRATION]
    first = {e: pooled_rmse(report.instrument, e, held) for e in ESTIMATORS}
    lines.append("| first (seed bench) | " + " | ".join(f"{first[e]:.3f} N" for e in ESTIMATORS) + " |")
    for r in rows:
        cells = [f"{r.rmse[e]:.3f} N ({r.ratio[e]:.2f}×)" for e in ESTIMATORS]
        lines.append(f"| {r.variation.label()} | " + " | ".join(cells) + " |")
    worst = {e: max(r.ratio[e] for r in rows) for e in ESTIMATORS}
    lines.append("| **worst ratio** | " + " | ".join(f"**{worst[e]:.2f}×**" for e in ESTIMATORS) + " |")
    return "\n".join(lines)


@checked
def as_dict(report: SeedReport, rows: list[TransferRow]) -> dict[str, object]:
    """Everything measured, for results.json."""
    return {
        "network_free_motion_rmse_N": report.network_rmse,
        "free_motion_samples": report.free_samples,
        "experiments": {n: {e: asdict(m) for e, m in row.items()} for n, row in report.table.items()},
        "held_out_clamp_rmse_N": {e: report.held_out_rmse(e) for e in ESTIMATORS},
        "transfer": [{"variation": asdict(r.variation), "rmse_N": r.rmse, "ratio": r.ratio} for r in rows],
        "goals": {"clamp_rmse_N": GOAL_RMSE, "transfer_ratio": GOAL_TRANSFER},
    }
