"""The typed result of a diagnosis (:class:`Diagnosis`) and its JSON form.

Every class mirrors one object of ``diagnosis.json`` (schema ``cablekit.diagnosis/3``,
docs/diagnosis.md): field names are the JSON keys (``with_`` is ``with``), so
:meth:`Diagnosis.to_json` is the document and :meth:`Diagnosis.from_json` reads one back. The
objects a fresh result keeps for plots (the prepared problems, the fitted candidates) live in
:attr:`Diagnosis.internal`, never in the JSON.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = [
    "Ambiguity",
    "ChannelChange",
    "ChannelError",
    "ConditionChange",
    "ConditionShare",
    "Diagnosis",
    "Discovery",
    "DiscoveryTerm",
    "EffectFit",
    "EffectResult",
    "FitScore",
    "GapSummary",
    "HeldOutScore",
    "IdentifiabilityNote",
    "Meta",
    "Parameter",
    "PerChannel",
    "ResidualTest",
    "RunInfo",
    "Selection",
    "Step",
    "Veto",
    "Where",
    "jsonable",
]

#: the schema of diagnosis.json (docs/diagnosis.md)
SCHEMA = "cablekit.diagnosis/3"


@dataclass(frozen=True)
class HeldOutScore:
    """A comparison on the held-out runs (gaps in noise units; 1 = noise only)."""

    gap_before: float
    gap_after: float | None
    closed_fraction: float | None
    interval: list[float | None]
    p_no_improvement: float
    significant: bool
    worsened_channels: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class FitScore:
    """The same on the fit runs."""

    gap_before: float
    gap_after: float | None
    closed_fraction: float | None


@dataclass(frozen=True)
class EffectFit(FitScore):
    """A candidate's fit-run score with its BIC."""

    bic: float | None = None


@dataclass(frozen=True)
class Parameter:
    """A fitted parameter with its 95 % interval (None for grid parameters)."""

    effect: str
    name: str
    unit: str
    value: float | None
    ci95: list[float | None] | None
    #: from refits on bootstrap segments of the fit runs (selected effects, when asked for)
    ci95_refit: list[float | None] | None = None


@dataclass(frozen=True)
class IdentifiabilityNote:
    """Another candidate whose residual signature is collinear, and the separating experiment."""

    with_: str
    signature_cosine: float
    experiment: str


@dataclass(frozen=True)
class EffectResult:
    """One candidate (an effect at a site in a form), fitted alone."""

    name: str
    id: str
    site: str
    form: str
    sentence: str
    selected: bool
    status: str
    description: str
    parameters: list[Parameter]
    fit: EffectFit
    held_out: HeldOutScore
    identifiability: list[IdentifiabilityNote]
    converged: bool
    error: str | None
    #: parameters that stayed on a bound away from their "off" value after the retries
    bound: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class Step:
    """One forward-selection step."""

    added: list[str]
    held_out: HeldOutScore
    worsened_channels: list[str]
    #: schema 3: a revisited form or site (``refine_forms``): the candidate the added one replaces
    replaces: str | None = None
    #: schema 3: an effect the later ones made superfluous (``backward_eliminate``); ``added`` is empty
    removed: str | None = None


@dataclass(frozen=True)
class ChannelChange:
    """One channel's held-out gap before and after the selected effects."""

    channel: str
    gap_before: float
    gap_after: float
    change: float
    closed_fraction: float | None
    interval: list[float | None]
    worsened: bool
    significantly_worse: bool
    better: bool


@dataclass(frozen=True)
class ChannelError:
    """RMSE (channel units) and gap (noise units) of one channel."""

    rmse: float
    gap: float
    unit: str


@dataclass(frozen=True)
class PerChannel:
    """Per-channel errors before and after, fit and held-out."""

    held_out_before: dict[str, ChannelError]
    held_out_after: dict[str, ChannelError]
    fit_before: dict[str, ChannelError]
    fit_after: dict[str, ChannelError]


@dataclass(frozen=True)
class ConditionChange:
    """Residual energy of one operating condition before and after (held-out runs)."""

    family: str
    condition: str
    energy_before: float
    energy_after: float
    reduction: float


@dataclass(frozen=True)
class Selection:
    """The selected effects and how far they close the gap."""

    effects: list[str]
    steps: list[Step]
    parameters: list[Parameter]
    held_out: HeldOutScore
    fit: FitScore
    channels_held_out: list[ChannelChange]
    per_channel: PerChannel
    per_condition_held_out: list[ConditionChange]
    unexplained_gap: float


@dataclass(frozen=True)
class ConditionShare:
    """One operating condition's share of samples and of the residual energy."""

    family: str
    condition: str
    time_share: float
    energy_share: float
    concentration: float


@dataclass(frozen=True)
class ResidualTest:
    """Tests of one channel's nominal residual (fit run)."""

    whiteness: dict[str, Any]
    input_correlation: dict[str, Any]
    loop_area_velocity: float
    loop_area_position: float
    gap: float
    reading: str


@dataclass(frozen=True)
class Where:
    """Where the gap lies."""

    conditions_fit: list[ConditionShare]
    conditions_held_out: list[ConditionShare]
    residual_tests: dict[str, ResidualTest]


@dataclass(frozen=True)
class GapSummary:
    """The nominal model's gap (noise units) and whether it is significant."""

    fit: float
    held_out: float
    held_out_lower: float
    noise_level: float
    significant: bool


@dataclass(frozen=True)
class RunInfo:
    """A run's name, length, sample interval, loader notes and attributes (conditions such as a
    wrist posture; :attr:`cablekit.diagnose.Run.attributes`)."""

    name: str
    samples: int
    dt: float
    notes: list[str]
    attributes: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class ChannelInfo:
    """A measured channel: model output, run column, measurement-error standard deviation (white
    noise and any stationary mains lines, whose frequencies are listed). ``residual_window``:
    the samples of the centred mean its residual is scored through (1: sample by sample; a load
    derived as ``τ − J·q̈``, whose noise is blue), ``noise_sigma`` then being the mean's."""

    output: str
    column: str
    noise_sigma: float
    interference_hz: list[float] = field(default_factory=list)
    residual_window: int = 1


@dataclass(frozen=True)
class Meta:
    """What was diagnosed and how."""

    model: dict[str, Any]
    fit_runs: list[RunInfo]
    held_out_runs: list[RunInfo]
    channels: list[ChannelInfo]
    substeps: int
    candidates: list[str]
    screened_out: dict[str, str]
    warnings: list[str]
    options: dict[str, Any]


@dataclass(frozen=True)
class DiscoveryTerm:
    """A kind of term a channel's gap follows (discrepancy discovery, ``discover.py``)."""

    channel: str
    kind: str
    held_out_share: float
    description: str


@dataclass(frozen=True)
class Discovery:
    """What the gap follows before any candidate (``nominal``) and after the selected effects
    (``remaining``), each kind with the held-out share of its channel's excess it removes."""

    nominal: list[DiscoveryTerm]
    remaining: list[DiscoveryTerm]


@dataclass(frozen=True)
class Ambiguity:
    """Two candidates of different effects that the runs cannot tell apart, and the experiment
    that would."""

    between: list[str]
    closed_fractions: list[float | None]
    signature_cosine: float
    experiment: str


@dataclass(frozen=True)
class Veto:
    """A candidate kept from selection because the gap lacks its physical signature."""

    id: str
    reason: str


@dataclass(frozen=True)
class Diagnosis:
    """The result of :func:`cablekit.diagnose.diagnose`."""

    schema: str
    verdict: str
    flags: list[str]
    effects: list[EffectResult]
    selected: Selection
    where: Where
    gap: GapSummary
    skipped: dict[str, str]
    meta: Meta
    #: schema 3: what the gap follows by physical kind, before and after the selected effects
    discovery: Discovery = field(default_factory=lambda: Discovery([], []))
    #: schema 3: the structure the selected effects leave unexplained, in words
    unexplained: list[str] = field(default_factory=list)
    #: schema 3: set when the first selected effect cannot be told from another effect
    ambiguity: Ambiguity | None = None
    #: schema 3: candidates not selected because the gap lacks their signature
    vetoed: list[Veto] = field(default_factory=list)
    #: objects of a fresh result for the HTML plots (prepared problems, fits); not in the JSON
    internal: dict[str, Any] | None = field(default=None, repr=False, compare=False)

    def effect(self, id_: str) -> EffectResult:
        """The candidate with this id (``effect@site/form``)."""
        for e in self.effects:
            if e.id == id_:
                return e
        raise KeyError(id_)

    def to_json(self) -> dict[str, Any]:
        """The ``diagnosis.json`` document (NaN and inf → null)."""
        return {
            f.name: jsonable(getattr(self, f.name)) for f in dataclasses.fields(self) if f.name != "internal"
        }

    @classmethod
    def from_json(cls, doc: dict[str, Any], internal: dict[str, Any] | None = None) -> Diagnosis:
        """Read a ``diagnosis.json`` document (or the engine's dict) back into typed objects."""
        out = _from_json(cls, {k: v for k, v in doc.items() if k != "internal"})
        return dataclasses.replace(out, internal=internal)


def _key(name: str) -> str:
    return name[:-1] if name.endswith("_") else name


def jsonable(obj: Any) -> Any:
    """Dataclasses, dicts, lists and numpy values as JSON values (NaN and inf → None)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {_key(f.name): jsonable(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    return obj


_HINTS: dict[type, dict[str, Any]] = {}


def _from_json(tp: Any, value: Any) -> Any:
    """Build ``tp`` (a dataclass, list/dict of them, or a plain type) from JSON-like ``value``."""
    if value is None:
        return None
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        inner = [a for a in typing.get_args(tp) if a is not type(None)]
        return _from_json(inner[0], value) if len(inner) == 1 else value
    if origin is list:
        (arg,) = typing.get_args(tp)
        return [_from_json(arg, v) for v in value]
    if origin is dict:
        _, arg = typing.get_args(tp)
        return {k: _from_json(arg, v) for k, v in value.items()}
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        hints = _HINTS.get(tp)
        if hints is None:
            hints = _HINTS[tp] = typing.get_type_hints(tp)
        kw = {}
        known = {_key(f.name) for f in dataclasses.fields(tp)}
        unknown = sorted(set(value) - known)
        if unknown:
            raise ValueError(f"diagnosis JSON: {tp.__name__} has unknown keys {unknown}")
        for f in dataclasses.fields(tp):
            if f.name == "internal":
                continue
            key = _key(f.name)
            if key in value:
                kw[f.name] = _from_json(hints[f.name], value[key])
            elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise ValueError(f"diagnosis JSON: {tp.__name__} lacks {key!r}")
        return tp(**kw)
    if tp is float and isinstance(value, (int, float, np.floating, np.integer)):
        return float(value)
    return value
