"""The forceps twin from a TOML file (``instruments/seed000.toml`` is seed 000's bench), and
instruments that differ from it the way two real ones of the same model do.

:func:`load_twin` reads ``[a]``, ``[b]`` (the keys of ``Twin.JAW_NAMES``, SI units) and
``[bench]`` (``tension_noise``, ``pressure_noise``, ``seed``, ``sample_time``, ``substeps``); a
key left out takes the seed bench's value, an unknown key or a value that is not a number is a
``DataError`` naming it, and the core checks the ranges (``ParameterError``).
:func:`another_instrument` scales cable stiffness, pretension and friction of both forceps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cablekit._args import checked
from cablekit._cablekit import Twin
from cablekit._files import parse_toml, read_text
from cablekit.errors import DataError

SEED_FILE = Path(__file__).with_name("instruments") / "seed000.toml"
BENCH_KEYS = ("tension_noise", "pressure_noise", "seed", "sample_time", "substeps")
#: the friction parameters :func:`another_instrument` scales together
FRICTION_KEYS = ("joint_friction", "joint_viscous", "capstan", "pulley_viscous")


def _number(where: str, key: str, value: object, integer: bool = False) -> float | int:
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    if not ok or (integer and not isinstance(value, int)):
        kind = "a whole number" if integer else "a number"
        raise DataError(f"{where}: {key} must be {kind}, got {value!r}")
    if not math.isfinite(value):
        raise DataError(f"{where}: {key} must be finite, got {value!r}")
    return value


@checked
def twin_from_toml(text: str, source: str = "<twin>") -> Twin:
    """A twin from TOML text (see the module docs)."""
    doc = parse_toml(text, source)
    unknown = sorted(set(doc) - {"a", "b", "bench"})
    if unknown:
        raise DataError(f"{source}: unknown section(s) {unknown}; known: a, b, bench")
    base = Twin.seed()
    jaws = []
    for side, default in (("a", base.a), ("b", base.b)):
        table = doc.get(side, {})
        if not isinstance(table, dict):
            raise DataError(f"{source}: [{side}] must be a table")
        names = list(Twin.JAW_NAMES)
        bad = sorted(set(table) - set(names))
        if bad:
            raise DataError(f"{source}: [{side}] unknown key(s) {bad}; known: {', '.join(names)}")
        values = default.copy()
        for k, v in table.items():
            values[names.index(k)] = _number(f"{source} [{side}]", k, v)
        jaws.append(values)
    bench = doc.get("bench", {})
    if not isinstance(bench, dict):
        raise DataError(f"{source}: [bench] must be a table")
    bad = sorted(set(bench) - set(BENCH_KEYS))
    if bad:
        raise DataError(f"{source}: [bench] unknown key(s) {bad}; known: {', '.join(BENCH_KEYS)}")
    b = dict(zip(BENCH_KEYS, base.bench, strict=True))
    for k, v in bench.items():
        b[k] = _number(f"{source} [bench]", k, v, integer=k in ("seed", "substeps"))
    if b["seed"] < 0 or b["substeps"] < 1:
        raise DataError(f"{source}: [bench] seed must be >= 0 and substeps >= 1")
    return Twin(jaws[0], jaws[1], **b)


@checked
def load_twin(path: str | Path | None = None) -> Twin:
    """The twin of a TOML file; the seed 000 bench without one."""
    p = Path(path) if path is not None else SEED_FILE
    return twin_from_toml(read_text(p, "twin file"), source=str(p))


@dataclass(frozen=True)
class Variation:
    """How another instrument differs: factors on cable stiffness, pretension and friction."""

    stiffness: float
    pretension: float
    friction: float
    seed: int

    @checked
    def label(self) -> str:
        def pct(f: float) -> str:
            return f"{(f - 1) * 100:+.0f} %"

        return f"k {pct(self.stiffness)}, T0 {pct(self.pretension)}, friction {pct(self.friction)}"


#: the transfer study's instruments: every sign pattern of ±30 % that is not all alike
TRANSFER_VARIATIONS = (
    Variation(0.7, 1.3, 1.3, 11),
    Variation(1.3, 0.7, 1.3, 12),
    Variation(1.3, 1.3, 0.7, 13),
    Variation(0.7, 0.7, 1.3, 14),
)


@checked
def another_instrument(twin: Twin, v: Variation) -> Twin:
    """``twin`` with cable stiffness, pretension and friction (joint Dahl level and viscous
    friction, capstan exponent, pulley drag) scaled by ``v``'s factors, and its own noise."""
    names = list(Twin.JAW_NAMES)
    jaws = []
    for jaw in (twin.a, twin.b):
        j = jaw.copy()
        j[names.index("cable_stiffness")] *= v.stiffness
        j[names.index("pretension")] *= v.pretension
        for k in FRICTION_KEYS:
            j[names.index(k)] *= v.friction
        jaws.append(j)
    tn, pn, _, dt, sub = twin.bench
    return Twin(
        np.ascontiguousarray(jaws[0]),
        np.ascontiguousarray(jaws[1]),
        tension_noise=tn,
        pressure_noise=pn,
        seed=v.seed,
        sample_time=dt,
        substeps=sub,
    )
