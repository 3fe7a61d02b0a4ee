"""Diagnosis: a generated self-test case (``cablekit.diagnose.selftest.make_case``, an
antagonistic joint with backlash at the motor, one 8 s fit run and one held-out run at 1 kHz;
3 s with ``--quick``) against scipy's ``least_squares`` fitting the same candidate.

* The fit alone: the same least-squares problem (the candidate's weighted residuals from
  cablekit's Rust simulator, the same start, bounds and scales) minimised by cablekit's search
  (``JointProblem.fit``: Levenberg–Marquardt in Rust) and by ``least_squares`` (TRF, finite
  differences): only the optimisers differ.
* The whole diagnosis (about 50 candidates screened, fitted, scored on the held-out run,
  selected, bootstrapped) against ``least_squares`` told the answer: the peer fits the one
  candidate the diagnosis finds. The ratio compares unequal work and is shown for scale: what
  a diagnosis costs over one fit of a candidate known in advance.

The check: the selected candidate is the generating effect, and every fitted parameter agrees
to 1 % (they minimise the same cost; the backlash gap agrees to ~1e-8 in practice).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from .core import Config, Kernel, Pair, Peer, Side, Verdict

EFFECT = "backlash"
CANDIDATE = "backlash@input"
SEED = 2027
RTOL = 1e-2


@functools.cache
def _case(quick: bool) -> dict[str, Any]:
    from cablekit.diagnose.data import common_interval
    from cablekit.diagnose.prepare import prepare
    from cablekit.diagnose.selftest import make_case

    case = make_case((EFFECT,), SEED, 3.0 if quick else 8.0)
    runs = common_interval([case.spec.in_si(r) for r in [*case.fit, *case.hold]])
    prep = prepare(case.spec, runs[:1], runs[1:])
    base = prep.fit0.with_effects([CANDIDATE], prep.substeps)
    specs = base.param_specs()
    x0 = np.array([s.initial for s in specs])
    problem = base.with_effects([CANDIDATE], max(prep.substeps, base.advised_substeps(x0)))
    return {
        "case": case,
        "problem": problem,
        "names": [s.name for s in specs],
        "x0": x0,
        "bounds": (np.array([s.lower for s in specs]), np.array([s.upper for s in specs])),
        "scale": np.array([s.scale for s in specs]),
    }


def least_squares_fit(d: dict[str, Any]) -> dict[str, float]:
    """The candidate fitted by ``scipy.optimize.least_squares`` (defaults, TRF) on cablekit's
    residuals: parameter name → value."""
    from scipy.optimize import least_squares

    res = least_squares(d["problem"].residuals, d["x0"], bounds=d["bounds"], x_scale=d["scale"])
    if not res.success:
        raise RuntimeError(f"least_squares did not converge: {res.message}")
    return dict(zip(d["names"], res.x.tolist(), strict=True))


def agree_parameters(ours: tuple[list[str], dict[str, float]], theirs: dict[str, float]) -> Verdict:
    selected, params = ours
    if selected != [CANDIDATE]:
        return Verdict(False, f"selected {selected}, the case was generated with {CANDIDATE}")
    if params.keys() != theirs.keys():
        return Verdict(False, f"parameters {sorted(params)} and {sorted(theirs)}")
    rel = {k: abs(params[k] - theirs[k]) / max(abs(theirs[k]), 1e-300) for k in params}
    worst = max(rel, key=rel.__getitem__)
    values = ", ".join(f"{k} {params[k]:.6g} / {theirs[k]:.6g}" for k in params)
    return Verdict(
        rel[worst] <= RTOL, f"{CANDIDATE}: {values} (cablekit / peer), {rel[worst]:.1e} apart (tolerance 1 %)"
    )


def _fit_pair(cfg: Config) -> Pair:
    d = _case(cfg.quick)

    def ours() -> tuple[list[str], dict[str, float]]:
        rep = d["problem"].fit(d["x0"])
        return [CANDIDATE], dict(zip(d["names"], rep.params.tolist(), strict=True))

    return Pair(
        Side("JointProblem.fit (LM in Rust) from the same start", ours),
        Side("scipy least_squares (TRF) on the same residuals", lambda: least_squares_fit(d)),
        agree_parameters,
        "fit",
        max_reps=5,
    )


def _diagnosis_pair(cfg: Config) -> Pair:
    from cablekit.diagnose import Options, diagnose

    d = _case(cfg.quick)
    case = d["case"]

    def ours() -> tuple[list[str], dict[str, float]]:
        res = diagnose(case.spec, case.fit, case.hold, Options(progress=False, seed=0))
        return list(res.selected.effects), {p.name: p.value for p in res.selected.parameters}

    return Pair(
        Side("diagnose(): every candidate, selection, held-out scores", ours),
        Side("scipy least_squares of the answer alone", lambda: least_squares_fit(d)),
        agree_parameters,
        "diagnosis",
        max_reps=3,
        note="unequal work: the peer is told the candidate",
    )


KERNEL = Kernel(
    "diagnose",
    "diagnosis of one run",
    "a generated joint with backlash: the candidate's fit by cablekit's search and by scipy on the "
    "same residuals, and the whole diagnosis against that one fit; the same parameter to 1 %",
    (
        Peer("scipy least_squares, one candidate", ("scipy",), _fit_pair),
        Peer("scipy least_squares vs the whole diagnosis", ("scipy",), _diagnosis_pair),
    ),
)
