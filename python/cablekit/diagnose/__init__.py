"""Sim-to-real gap diagnosis: where the gap lies, which unmodelled effect causes it, and how far
it closes once that effect is added — checked on held-out runs no fit ever sees.

Entry points: :func:`diagnose` (runs + model file → a typed :class:`Diagnosis`, whose
``to_json()`` is ``diagnosis.json``), :func:`load_run`,
:func:`load_model_spec`, :func:`run_self_test`; the CLI is ``cablekit diagnose``.
See ``docs/diagnosis.md`` for the method and the JSON schema.
"""

from __future__ import annotations

from cablekit.diagnose.data import Run, load_run
from cablekit.diagnose.engine import diagnose
from cablekit.diagnose.prepare import Options
from cablekit.diagnose.result import Diagnosis
from cablekit.diagnose.selftest import run_self_test
from cablekit.diagnose.spec import ModelSpec, load_model_spec, model_spec_from_dict

__all__ = [
    "Diagnosis",
    "ModelSpec",
    "Options",
    "Run",
    "diagnose",
    "load_model_spec",
    "load_run",
    "model_spec_from_dict",
    "run_self_test",
]
