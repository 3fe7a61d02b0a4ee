"""Property tests over every file loader (issue #20): a valid file with one mutation — a byte
changed, the file cut short, a token inserted (NaN, inf, 1e308, a separator, a non-UTF-8 byte,
a bracket, a 400-digit number), the file doubled — or random bytes.

The contract for every draw: the loader returns, or raises a :class:`cablekit.CablekitError`
subclass; never another exception type (``UnicodeDecodeError``, ``RecursionError``, a CSV or
gzip error), and a loaded table holds finite numbers only. The atheris targets in
``fuzz/fuzz_loaders.py`` search the same loaders guided by coverage.

What these tests found (now regression tests below): a twin file or a campaign manifest that
is not UTF-8 raised ``UnicodeDecodeError``; a TOML robot, twin or manifest with deeply nested
arrays raised ``RecursionError``.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import cablekit as ck
from cablekit.cdpr import Robot
from cablekit.cdpr.formats import read_trajectory
from cablekit.diagnose.davinci import load_bench_run
from cablekit.diagnose.many import load_manifest
from cablekit.diagnose.spec import load_model_spec
from cablekit.forceps.davinci import read_bench_file
from cablekit.forceps.twin import SEED_FILE, load_twin

ROBOT_FILE = Path(ck.__file__).parent / "cdpr" / "robots" / "seed003_planar.toml"
BENCH = "% a header line\n" + "".join(
    f"{1e-3 * i},{3 * i},{100 + i},0.5,{2 * i},{50 - i},0,0,{70 * i}\n" for i in range(40)
)
TRAJECTORY = "t,x,y,theta\n" + "".join(f"{0.01 * i},{0.6 + 1e-3 * i},0.5,0.0\n" for i in range(20))
MODEL = """model = "antagonistic_joint"
[parameters]
radius = 0.0025
stiffness = 31800.0
inertia = 2e-6
pretension = 10.0
[inputs]
x_m = "x_m"
[outputs]
tension_motor_drive = "T1"
"""
MANIFEST = '[[group]]\nname = "a"\nmodel = "m.toml"\nfit = ["a.csv"]\nheld_out = ["b.csv"]\n'


def _finite(obj: Any) -> bool:
    """Every float array reachable from a loaded object is finite."""
    if isinstance(obj, np.ndarray):
        return obj.dtype.kind != "f" or bool(np.isfinite(obj).all())
    if isinstance(obj, list | tuple):
        return all(_finite(v) for v in obj)
    if isinstance(obj, dict):
        return all(_finite(v) for v in obj.values())
    if hasattr(obj, "__dataclass_fields__"):
        return all(_finite(getattr(obj, f)) for f in obj.__dataclass_fields__)
    return True


def _manifest(path: Path) -> Any:
    for name in ("a.csv", "b.csv", "m.toml"):
        (path.parent / name).write_text("x")
    return load_manifest(path.parent)


#: loader name → (file name, a valid file, the call)
LOADERS: dict[str, tuple[str, bytes, Callable[[Path], Any]]] = {
    "model file": ("m.toml", MODEL.encode(), load_model_spec),
    "manifest": ("manifest.toml", MANIFEST.encode(), _manifest),
    "twin file": ("twin.toml", SEED_FILE.read_bytes(), load_twin),
    "robot file": ("robot.toml", ROBOT_FILE.read_bytes(), Robot.load),
    "bench file (forceps)": ("00.TXT", BENCH.encode(), read_bench_file),
    "bench file (diagnosis)": ("00.TXT", BENCH.encode(), load_bench_run),
    "trajectory": ("poses.csv", TRAJECTORY.encode(), lambda p: read_trajectory(p, "planar")),
}
TOKENS = [b"nan", b"inf", b"-1e999", b"1e308", b"-", b",", b"\n", b"\xff", b'"', b"[", b"=", b"0" * 400]


@st.composite
def mutated(draw: st.DrawFn, valid: bytes) -> bytes:
    kind = draw(st.sampled_from(["byte", "cut", "token", "double", "random"]))
    if kind == "random":
        return draw(st.binary(max_size=300))
    b = bytearray(valid)
    i = draw(st.integers(0, len(b) - 1))
    if kind == "byte":
        b[i] = draw(st.integers(0, 255))
    elif kind == "cut":
        del b[i:]
    elif kind == "token":
        b[i:i] = draw(st.sampled_from(TOKENS))
    else:
        b = b + b
    return bytes(b)


@pytest.mark.parametrize("name", sorted(LOADERS))
def test_the_valid_file_loads_and_is_finite(tmp_path, name):
    file_name, valid, load = LOADERS[name]
    (tmp_path / file_name).write_bytes(valid)
    assert _finite(load(tmp_path / file_name))


@pytest.mark.parametrize("name", sorted(LOADERS))
@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_a_mutated_file_loads_finite_or_raises_a_cablekit_error(tmp_path_factory, name, data):
    file_name, valid, load = LOADERS[name]
    path = tmp_path_factory.mktemp("loader") / file_name
    path.write_bytes(data.draw(mutated(valid)))
    try:
        loaded = load(path)
    except ck.CablekitError:
        return
    assert _finite(loaded), f"{name}: non-finite numbers loaded from {path.read_bytes()[:200]!r}"


@pytest.mark.parametrize("name", ["model file", "manifest", "twin file", "robot file"])
def test_toml_that_is_not_utf8_or_nested_too_deeply_is_a_data_error(tmp_path, name):
    file_name, valid, load = LOADERS[name]
    for blob in (b"\xff" + valid, valid + b"deep = " + b"[" * 5000 + b"]" * 5000 + b"\n"):
        (tmp_path / file_name).write_bytes(blob)
        with pytest.raises(ck.DataError, match=r"UTF-8|nested too deeply"):
            load(tmp_path / file_name)
