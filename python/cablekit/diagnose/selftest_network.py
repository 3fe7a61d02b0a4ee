"""Self-test of the diagnosis on cable-network plants (issue #39 §2), on runs from an
independent simulator.

:mod:`cablekit.diagnose.netsim_independent` was written from the literature without cablekit's
code: its plants — a two-stage instrument (motor → compliant coupling → spindle → cables over a
wrist idler → jaw), a tendon-driven finger with four tendons on three joints and a two-link
coupled transmission — are integrated by SciPy's stiff solvers with their own effect laws (a
capstan friction that acts in the dynamics at one contact, its own friction and stiffening
forms). Each case gives the diagnoser the plant's nominal network file (what the user believes)
and the runs; one effect is inserted at one element (or none, or one outside the library). The
scores are those of the independent self-test: top-1 effect and site over the cases in the
library, honesty on the cases outside it (any verdict but ``explained`` or
``no_significant_gap``), false alarms on the controls, the median held-out gap closed.
"""

from __future__ import annotations

import time
import tomllib
from typing import Any

import numpy as np

from cablekit import _log
from cablekit.diagnose.data import Run
from cablekit.diagnose.engine import Options, diagnose
from cablekit.diagnose.selftest_independent import judge, summarise
from cablekit.diagnose.spec import ModelSpec, model_spec_from_dict

__all__ = ["nominal_document", "run_network_self_test", "to_cablekit_senses"]


def to_cablekit_senses(doc: dict[str, Any]) -> dict[str, Any]:
    """The simulator's network document in cablekit's sense convention.

    The independent simulator reads a contact's ``sense = +1`` as "turning the joint positively
    takes cable up" (stretching it) — how it read the words "winds the cable on the pulley" that
    cablekit's file format used to say — where cablekit's +1 means "the cable's tension turns the
    joint positively" (turning it positively lets cable off): the same mechanism has every
    contact's sense flipped. The motors' senses agree. This is the one place the two meet
    (tests/test_netsim_independent.py checks the structure matrices against each other)."""
    out = dict(doc)
    out["cables"] = [
        dict(c, routing=[dict(ct, sense=-ct.get("sense", 1)) for ct in c["routing"]]) for c in doc["cables"]
    ]
    return out


#: the network format's default routing-friction smoothing (m/s) when the simulator was written,
#: which its file writer copies into every nominal file; the format's default is now 1e-6 m/s (a
#: capstan sticks), and its plants' capstans stick exactly
FORMAT_DEFAULT_THEN = 1e-3


def nominal_document(network_toml: str) -> dict[str, Any]:
    """The simulator's nominal network file as cablekit reads it: senses converted
    (:func:`to_cablekit_senses`), and a ``capstan_smoothing`` equal to the format's default at the
    time of writing (:data:`FORMAT_DEFAULT_THEN`) left out, so that the format's present default
    applies — the value was the format's, not a statement about the plant."""
    doc = to_cablekit_senses(tomllib.loads(network_toml))
    if doc.get("capstan_smoothing") == FORMAT_DEFAULT_THEN:
        doc = {k: v for k, v in doc.items() if k != "capstan_smoothing"}
    return doc


def _case_spec(case: Any) -> ModelSpec:
    """The model file a user of the case's plant would write: its nominal network inline
    (:func:`nominal_document`)."""
    return model_spec_from_dict(
        {
            "model": "cable_network",
            "parameters": {"definition": nominal_document(case.network_toml)},
            "inputs": dict(case.inputs),
            "outputs": dict(case.outputs),
            "diagnosis": {"warmup": 0.1},
        },
        source=f"network self-test case {case.name}",
    )


def _case_runs(runs: list[tuple[str, float, dict[str, np.ndarray]]]) -> list[Run]:
    """The simulator's runs as cablekit runs."""
    out = []
    for name, _dt, cols in runs:
        out.append(
            Run(
                name,
                np.asarray(cols["t"], dtype=float),
                {k: np.asarray(v, dtype=float) for k, v in cols.items() if k != "t"},
            )
        )
    return out


#: effects cablekit offers on a network beyond the simulator's own list of library effects (the
#: simulator's module was written when the network had no hysteresis, creep or play states)
NETWORK_STATE_EFFECTS = ("dahl_hysteresis", "creep", "backlash")


#: the CI subset (`cablekit diagnose --networks ci`, .ci/run): a joint's inertia on the
#: torque-driven finger (replayed from its motor angles), a cable law on the transmission and a
#: control, the transmission's (62 s; the finger's takes 171 s); the two-stage instrument's play
#: and pre-sliding cases run in pytest (tests/test_diagnose_network.py); every case and control
#: is in docs/diagnosis.md's full table
CI_CASES = (
    "finger_inertia_error_joint.mcp",
    "transmission2_nonlinear_stiffness_cable.sh_a",
    "transmission2_control_1",
)


def _kind(case: Any) -> str:
    if case.truth_effect is None:
        return "control"
    return "single" if case.in_library or case.truth_effect in NETWORK_STATE_EFFECTS else "outside"


def run_network_self_test(
    seed: int = 0, quick: bool = False, progress: bool = True, only: list[str] | None = None
) -> dict[str, Any]:
    """Diagnose every case of the independent network simulator; rows and scores in the layout of
    :func:`cablekit.diagnose.selftest_independent.run_independent` (its table formats them)."""
    from cablekit.diagnose import netsim_independent as sim

    t_start = time.perf_counter()
    t_gen = time.perf_counter()
    cases = sim.cases(seed=seed, quick=quick, names=frozenset(only) if only else None)
    gen_s = time.perf_counter() - t_gen
    rows = []
    for i, case in enumerate(cases):
        kind = _kind(case)
        t0 = time.perf_counter()
        res = diagnose(
            _case_spec(case), _case_runs(case.fit_runs), _case_runs(case.hold_runs), Options(progress=False)
        )
        elapsed = time.perf_counter() - t0
        top = res.effects[0] if res.effects and res.verdict != "no_significant_gap" else None
        row: dict[str, Any] = {
            "label": case.name,
            "plant": case.plant,
            "kind": kind,
            "effect": case.truth_effect,
            "site": case.truth_site,
            "size": case.size,
            "verdict": res.verdict,
            "top1": top.name if top else None,
            "top1_site": top.site if top else None,
            "top1_id": top.id if top else None,
            "selected": res.selected.effects,
            "held_out_closed": res.selected.held_out.closed_fraction,
            "gap_held_out": res.gap.held_out,
            "seconds": elapsed,
            "both_found": None,
            "honest": None,
        }
        judge(row, kind, case.truth_effect, case.truth_site, res)
        rows.append(row)
        if progress:
            if kind == "outside":
                mark = "ok  honest" if row["honest"] else "MISS named"
            elif kind == "control":
                mark = "ok " if row["effect_correct"] else "MISS"
            else:
                mark = ("ok " if row["effect_correct"] else "MISS") + (
                    " site-ok" if row["site_correct"] else " site-MISS"
                )
            _log.info(
                f"[{i + 1:>2}/{len(cases)}] {mark:<14} {case.name:<44} verdict={res.verdict:<20} "
                f"top1={row['top1_id']!s:<44} closed={row['held_out_closed']:.2f} ({elapsed:.0f}s)"
            )
    scores, goals, passed = summarise(rows, t_start)
    singles = [r for r in rows if r["kind"] == "single" and r["visible"]]
    scores["generate_seconds"] = gen_s
    scores["by_plant"] = {
        plant: {
            "effect": float(np.mean([r["effect_correct"] for r in singles if r["plant"] == plant])),
            "site": float(np.mean([r["site_correct"] for r in singles if r["plant"] == plant])),
            "cases": sum(r["plant"] == plant for r in singles),
        }
        for plant in sorted({r["plant"] for r in singles})
    }
    return {"cases": rows, "scores": scores, "goals": goals, "passed": passed}
