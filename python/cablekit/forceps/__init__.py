"""Cable-driven forceps (seed 000): clamping-force estimation without a sensor in the jaws.

* :class:`Jtdo` — the joint torque disturbance observer and clamping-force estimator (seed 000
  eqs 8, 15–17) of the Rust core: from the four measured cable tensions ``F_M`` and the tensions
  a free-motion model predicts for the same motor motion ``F̂_E`` (columns ``[A drive, A return,
  B drive, B return]``, N) it gives the tension disturbances, the joint torque disturbances
  ``τ̂_D = r₂·(F̂_D¹ − F̂_D²)``, the external force on each forceps ``τ̂_D / l_e`` less a
  calibration group's mean errors (:meth:`Jtdo.calibrated`), the clamping force
  ``½(|F̂_ext^A| + |F̂_ext^B|)`` and contact above the collision threshold (0.11 N by default,
  the seed's). :meth:`Jtdo.step` takes one sample (a controller's rate), :meth:`Jtdo.estimate`
  a whole log.
* :func:`free_motion_tensions` — ``F̂_E`` from a free-motion network (a ``cablekit.Mlp`` trained
  on ``[x_a, v_a, x_b, v_b] → [F_A¹, F_A², F_B¹, F_B²]``, e.g. by ``cablekit nn``).
* :class:`Twin` — seed 000's two-forceps bench (stepping motors with S-curves, pretensioned cable
  pairs, capstan and pulley losses, hysteretic joint friction, a block with pads, tension and
  pressure sensors) simulated in Rust; :func:`load_twin` reads it from TOML
  (``instruments/seed000.toml``), :func:`another_instrument` varies it.
* :class:`PhysicsObserver` — the physics-informed estimator: capstan and joint friction with
  rate-independent direction states, a few parameters per forceps fitted on one calibration run
  (:meth:`PhysicsObserver.calibrated`); no network.
* :mod:`cablekit.forceps.experiments` — the seed's experiments and the transfer study
  (``cablekit forceps experiments``).
* :class:`DriveModel` and :mod:`cablekit.forceps.davinci` — the jaw torque of a real instrument
  from drive-side signals (transmission with Maxwell-slip friction driven by the motor angle),
  the bench loader, held-out folds and the new-instrument protocol (``cablekit forceps davinci``).

See docs/forceps.md.
"""

from __future__ import annotations

import numpy as np

from cablekit._args import checked, instance
from cablekit._cablekit import (
    ClampRun,
    ClampStep,
    DriveModel,
    JawEstimate,
    JawObserver,
    JawSample,
    Jtdo,
    Mlp,
    PhysicsCalibration,
    PhysicsObserver,
    Twin,
    TwinRun,
)
from cablekit.errors import ShapeError
from cablekit.forceps.twin import another_instrument, load_twin, twin_from_toml

__all__ = [
    "ClampRun",
    "ClampStep",
    "DriveModel",
    "JawEstimate",
    "JawObserver",
    "JawSample",
    "Jtdo",
    "PhysicsCalibration",
    "PhysicsObserver",
    "Twin",
    "TwinRun",
    "another_instrument",
    "free_motion_tensions",
    "load_twin",
    "twin_from_toml",
]


@checked
def free_motion_tensions(model: Mlp, motors: np.ndarray) -> np.ndarray:
    """The free-motion tensions ``F̂_E`` ``(T, 4)`` a network predicts from the motor motion
    ``motors`` ``(T, 4)`` (``[x_a, v_a, x_b, v_b]``, m and m/s)."""
    instance(model, "model", Mlp)
    if model.n_inputs != 4 or model.n_outputs != 4:
        raise ShapeError(
            f"a free-motion model maps 4 motor signals to 4 tensions; this one maps "
            f"{model.n_inputs} to {model.n_outputs}"
        )
    return model.predict(motors)
