"""Identifiability: candidates whose residual signatures are collinear, and the experiment
that would separate them."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from cablekit.diagnose.fit import CandidateFit
from cablekit.diagnose.prepare import MIN_CLOSED, Prepared

__all__ = ["SEPARATING", "identifiability", "separating_experiment"]

_F = NDArray[np.float64]


#: pairs of effects that look alike on some data, and the experiment that separates them
SEPARATING = {
    frozenset({"dahl_hysteresis", "stribeck_friction"}): (
        "add small-amplitude motions (below the break-away angle) and steady sliding at several speeds: "
        "Dahl shows pre-sliding stiffness, Stribeck friction falls with speed"
    ),
    frozenset(
        {"sensor_lag", "time_delay"}
    ): "excite at several frequencies (a chirp): a delay's phase grows linearly with frequency, a "
    "lag's saturates at 90°",
    frozenset(
        {"sensor_lag", "cable_damping"}
    ): "vary the speed at a fixed frequency content and add a second sensor: damping scales with "
    "speed, a sensor lag with the signal's rate of change at every load",
    frozenset(
        {"sensor_lag", "viscous_friction"}
    ): "record the joint angle too: viscous friction changes the motion, a sensor lag does not",
    frozenset(
        {"coulomb_friction", "dahl_hysteresis"}
    ): "add small-amplitude motions (below the break-away angle) and slow reversals: Dahl shows "
    "pre-sliding stiffness, Coulomb does not",
    frozenset(
        {"coulomb_friction", "stribeck_friction"}
    ): "add slow reversals (under 10 % of the present speed): Stribeck friction peaks at low speed",
    frozenset(
        {"coulomb_friction", "capstan_friction"}
    ): "add slow reversals at two load levels: capstan loss scales with tension, Coulomb friction does not",
    frozenset(
        {"dahl_hysteresis", "backlash"}
    ): "add slow reversals at two load levels: play gives a fixed dead band, Dahl friction a "
    "load-independent rounded loop",
    frozenset(
        {"coulomb_friction", "backlash"}
    ): "add slow reversals at two load levels and record the joint angle: play shows as a dead "
    "band in angle, friction does not",
    frozenset(
        {"slack", "sensor_gain_bias"}
    ): "repeat at two pretension levels: a sensor bias stays, lost pretension changes where the "
    "cables slacken",
    frozenset(
        {"creep", "sensor_gain_bias"}
    ): "hold still at two tension levels for longer than the creep time constant: creep relaxes, a "
    "bias does not",
    frozenset(
        {"inertia_error", "cable_damping"}
    ): "add faster accelerations (higher-frequency content): inertia scales with acceleration, "
    "damping with speed",
    frozenset(
        {"nonlinear_stiffness", "sensor_gain_bias"}
    ): "repeat at two pretension levels: a stiffening law changes with the tension level, a gain "
    "error does not",
}


def separating_experiment(a: str, b: str) -> str:
    """The experiment that separates two candidates (ids or effect names)."""
    ea, eb = a.split("@")[0], b.split("@")[0]
    if ea == eb:
        return (
            "the same effect at two sites: add a sensor on each side of the suspected sites (motor "
            "side and joint side), or repeat with one cable's pretension changed"
        )
    return SEPARATING.get(
        frozenset({ea, eb}),
        "repeat the run at another frequency and another load level, and add an independent sensor "
        "(for example the joint angle)",
    )


def identifiability(
    prep: Prepared, base: CandidateFit, fits: dict[str, CandidateFit], scores: dict[str, dict[str, Any]]
) -> dict[str, list[dict[str, Any]]]:
    """Collinear residual signatures among the candidates that close a real share of the gap."""
    r0 = np.concatenate([r.ravel() for r in base.fit_resid])
    sig = {}
    for name, c in fits.items():
        if c.error or scores[name]["closed_fraction"] < MIN_CLOSED:
            continue
        v = r0 - np.concatenate([r.ravel() for r in c.fit_resid])
        n = np.linalg.norm(v)
        if n > 0:
            sig[name] = v / n
    notes: dict[str, list[dict[str, Any]]] = {k: [] for k in fits}
    names = sorted(sig, key=lambda k: -scores[k]["closed_fraction"])
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            cos = float(sig[a] @ sig[b])
            ca, cb = scores[a]["closed_fraction"], scores[b]["closed_fraction"]
            if abs(cos) > 0.9 and cb >= 0.8 * ca:
                exp = separating_experiment(a, b)
                notes[a].append({"with": b, "signature_cosine": cos, "experiment": exp})
                notes[b].append({"with": a, "signature_cosine": cos, "experiment": exp})
    return notes
