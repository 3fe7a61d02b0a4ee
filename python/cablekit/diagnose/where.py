"""Where the gap lies: the nominal residual by operating condition, its whiteness,
input correlation and hysteresis loops, per channel."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from cablekit._cablekit import JointProblem
from cablekit.diagnose import localise
from cablekit.diagnose.data import Run, scored_start
from cablekit.diagnose.fit import CandidateFit
from cablekit.diagnose.prepare import NOISE_LEVEL, Prepared, joint_run
from cablekit.diagnose.spec import OUTPUTS

__all__ = ["localise_all"]

_F = NDArray[np.float64]


def _nominal_contact(prep: Prepared, runs: list[Run]) -> list[NDArray[np.bool_]] | None:
    """Per run, where the nominal model is in contact (contact force > 0); None without contact."""
    if "contact_angle" not in prep.spec.parameters:
        return None
    model = prep.spec.model()
    core_runs = [joint_run(prep.spec, r, prep.columns, model) for r in runs]
    core_runs = [c.with_measured(np.zeros((len(c), 1))) for c in core_runs]
    probe = JointProblem(model, [(OUTPUTS["contact_force"][0], 1.0, True)], core_runs, [], prep.substeps)
    return [probe.predict(np.zeros(0), i)[:, 0] > 0.0 for i in range(len(runs))]


def localise_all(prep: Prepared, base: CandidateFit) -> dict[str, Any]:
    """Conditions, whiteness, cross-correlation and loops of the nominal residual."""
    out: dict[str, Any] = {}
    for label, runs, resid in (
        ("fit", prep.fit_runs, base.fit_resid),
        ("held_out", prep.hold_runs, base.hold_resid),
    ):
        masks = []
        energies = []
        contact = _nominal_contact(prep, runs)
        for i, (run, r) in enumerate(zip(runs, resid, strict=False)):
            start = scored_start(prep.spec.warmup, run)
            x = run.column(prep.spec.primary()[0])[start:]
            t = run.t[start:]
            sensors = [c for c, n in enumerate(prep.channel_names) if prep.spec.output(n)[2]]
            load = (
                np.sum(
                    np.abs(np.column_stack([run.column(prep.columns[c])[start:] for c in sensors])), axis=1
                )
                if sensors
                else np.abs(x)
            )
            masks.append(
                localise.condition_masks(t, x, run.dt, load, None if contact is None else contact[i][start:])
            )
            energies.append(np.sum(r * r, axis=1))
        table = localise.conditions_table(energies, masks)
        out[f"conditions_{label}"] = [c.to_dict() for c in table]
        if label == "held_out":
            out["_hold_masks"] = masks
    r0 = base.fit_resid[0]
    start0 = scored_start(prep.spec.warmup, prep.fit_runs[0])
    x0 = prep.fit_runs[0].column(prep.spec.primary()[0])[start0:]
    u0 = prep.fit_runs[0].column(prep.spec.inputs[0])[start0:]
    v0 = np.gradient(x0, prep.fit_runs[0].dt)
    out["residual_tests"] = {
        name: {
            "whiteness": {k: v for k, v in localise.whiteness(r0[:, c]).items() if k != "acf"},
            "input_correlation": {
                k: v for k, v in localise.cross_correlation(r0[:, c], u0).items() if k != "ccf"
            },
            "loop_area_velocity": localise.loop_area(r0[:, c], v0),
            "loop_area_position": localise.loop_area(r0[:, c], x0),
        }
        for c, name in enumerate(prep.channel_names)
    }
    for c, t in enumerate(out["residual_tests"].values()):
        w, x = t["whiteness"]["white"], t["input_correlation"]["independent"]
        g = float(np.mean(np.concatenate([r[:, c] for r in base.fit_resid]) ** 2))
        t["gap"] = g
        if w and x:
            t["reading"] = "consistent with white measurement noise"
        elif g < NOISE_LEVEL:
            t["reading"] = "structured, but below the noise level"
        elif x:
            t["reading"] = (
                "coloured but independent of the input: coloured noise or an unmodelled disturbance"
            )
        else:
            t["reading"] = "depends on the input: the model is wrong"
    return out
