"""The wrist posture of a bench run (issue #37 §3-§4): the wrist's pitch and the shaft's roll, as
the recording folder's README states them (the upstream MRDLab folders say, e.g., "This is a roll
of -90 degrees" and "This is a pitch of +60 degrees") or as the user gives them, and the jaw
stopping position — the ``Z`` of a run named ``ZXY``.

The pitch and roll change the wrap angles of the cables over the wrist's pulleys, the stopping
position the jaw angle at which the load acts; friction and effective stiffness change with all
three. A model calibrated at one posture knows nothing of another: :meth:`Posture.attributes` are
the run attributes the diagnosis compares with the conditions its nominal was calibrated at, and
warns about (:data:`cablekit.diagnose.spec.ModelSpec.conditions`).
"""

from __future__ import annotations

import gzip
import math
import re
from dataclasses import dataclass
from pathlib import Path

from cablekit._args import checked, instance, text
from cablekit.errors import DataError

__all__ = ["Posture", "folder_posture", "parse_posture", "posture_from_text", "run_posture"]

#: "pitch of +60 degrees", "roll: -45 deg", "pitch = 30°": the first number after the word
_ANGLE = re.compile(
    r"\b(pitch|roll)\b\s*(?:of|=|:)?\s*([+\-\u2212]?\d+(?:\.\d+)?)\s*(?:degrees|degree|deg|°)",
    re.IGNORECASE,
)
#: the most a wrist joint of a surgical instrument turns (pitch) or a shaft rolls, in degrees
_LIMIT = {"pitch": 180.0, "roll": 360.0}
#: a README is read only this far (the upstream ones are a few lines)
_README_BYTES = 65536


@dataclass(frozen=True)
class Posture:
    """Wrist pitch and shaft roll (degrees; None where nothing states them), the jaw stopping
    position index (None for a run name without one) and where pitch and roll came from."""

    pitch_deg: float | None = None
    roll_deg: float | None = None
    yaw_index: int | None = None
    source: str = "not stated"

    def __post_init__(self) -> None:
        for name, value in (("pitch", self.pitch_deg), ("roll", self.roll_deg)):
            if value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise DataError(f"posture: {name} must be a number of degrees, got {value!r}")
            if not math.isfinite(value) or abs(value) > _LIMIT[name]:
                raise DataError(f"posture: {name} {value!r} is not an angle within ±{_LIMIT[name]:g}°")
        if self.yaw_index is not None and (
            isinstance(self.yaw_index, bool) or not isinstance(self.yaw_index, int) or self.yaw_index < 0
        ):
            raise DataError(
                f"posture: the jaw stopping position index must be an integer >= 0, got {self.yaw_index!r}"
            )

    @property
    def stated(self) -> bool:
        """Whether pitch or roll was stated (by a README or the user)."""
        return self.pitch_deg is not None or self.roll_deg is not None

    @checked
    def attributes(self) -> dict[str, float]:
        """The run attributes of this posture: ``pitch_deg`` and ``roll_deg`` when stated (an
        unstated one is 0 when the other is stated: the upstream READMEs name only the angle
        that is not at zero), ``yaw_index`` when the run name has one."""
        out: dict[str, float] = {}
        if self.stated:
            out["pitch_deg"] = float(self.pitch_deg or 0.0)
            out["roll_deg"] = float(self.roll_deg or 0.0)
        if self.yaw_index is not None:
            out["yaw_index"] = float(self.yaw_index)
        return out

    @checked
    def with_yaw(self, yaw_index: int | None) -> Posture:
        return Posture(self.pitch_deg, self.roll_deg, yaw_index, self.source)

    @checked
    def describe(self) -> str:
        parts = []
        if self.stated:
            parts.append(
                f"pitch {self.pitch_deg or 0.0:+g}°, roll {self.roll_deg or 0.0:+g}° ({self.source})"
            )
        else:
            parts.append("pitch and roll not stated")
        if self.yaw_index is not None:
            parts.append(f"jaw stopping position {self.yaw_index}")
        return ", ".join(parts)


@checked
def posture_from_text(text: str, source: str) -> Posture:
    """The pitch and roll a README's text states (the first angle after each word); a text that
    states neither gives an unstated posture, one that states an angle twice differently is a
    :class:`DataError`."""
    if not isinstance(text, str):
        raise DataError(f"{source}: expected text, got {type(text).__name__}")
    found: dict[str, float] = {}
    for m in _ANGLE.finditer(text):
        word, value = m.group(1).lower(), float(m.group(2).replace("\u2212", "-"))
        if word in found and found[word] != value:
            raise DataError(f"{source}: states the {word} twice ({found[word]:g}° and {value:g}°)")
        found[word] = value
    if not found:
        return Posture(source="not stated")
    return Posture(found.get("pitch"), found.get("roll"), None, source)


@checked
def parse_posture(text: str) -> Posture:
    """A posture the user gives: ``"pitch=30,roll=-45"`` (degrees; either may be left out and is
    then 0)."""
    if not isinstance(text, str) or not text.strip():
        raise DataError(f"posture: expected 'pitch=DEG,roll=DEG', got {text!r}")
    values: dict[str, float] = {}
    for item in text.split(","):
        key, sep, value = item.partition("=")
        key = key.strip().lower()
        if not sep or key not in ("pitch", "roll"):
            raise DataError(f"posture: {item.strip()!r} is not pitch=DEG or roll=DEG (in {text!r})")
        if key in values:
            raise DataError(f"posture: {key} given twice in {text!r}")
        try:
            values[key] = float(value)
        except ValueError:
            raise DataError(f"posture: {key} {value.strip()!r} is not a number of degrees") from None
    return Posture(values.get("pitch", 0.0), values.get("roll", 0.0), None, "given")


@checked
def folder_posture(folder: str | Path) -> Posture:
    """The posture a bench folder's README (``README.txt``, ``ReadME.txt.gz``, any case) states;
    unstated when there is none or it names no angle."""
    folder = Path(folder)
    readmes = sorted(
        p
        for p in (folder.iterdir() if folder.is_dir() else [])
        if p.is_file() and re.fullmatch(r"readme(\.txt|\.md)?(\.gz)?", p.name, re.IGNORECASE)
    )
    for p in readmes:
        try:
            if p.suffix.lower() == ".gz":
                with gzip.open(p, "rb") as fh:
                    raw = fh.read(_README_BYTES)
            else:
                with p.open("rb") as fh:
                    raw = fh.read(_README_BYTES)
        except (OSError, EOFError) as exc:
            raise DataError(f"{p}: cannot read the folder's README ({exc})") from None
        posture = posture_from_text(raw.decode("utf-8", errors="replace"), p.name)
        if posture.stated:
            return posture
    return Posture(source="not stated")


@checked
def run_posture(folder_posture: Posture, stem: str) -> Posture:
    """The posture of the run named ``stem`` in a folder of ``folder_posture``: a ``ZXY`` name
    adds the jaw stopping position ``Z``."""
    instance(folder_posture, "folder_posture", Posture)
    text(stem, "stem")
    yaw = int(stem[0]) if len(stem) == 3 and stem.isascii() and stem.isdigit() else None
    return folder_posture.with_yaw(yaw)
