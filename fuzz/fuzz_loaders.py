"""Coverage-guided fuzzing of cablekit's loaders with atheris (libFuzzer for Python and its
native extensions): weight files (``Mlp.from_bytes``, the Rust safetensors parser), model files
(``load_model_spec``, TOML), run files (``load_run``, CSV), CDPR trajectory CSVs
(``read_trajectory``), CASPR bodies files (``Robot.from_caspr``, XML), robot, twin and campaign
manifest files (``Robot.load``, ``load_twin``, ``load_manifest``, TOML), da Vinci bench files
(``read_bench_file``) and CDPR run CSVs (``load_cdpr_run``).

Every input must load or raise a ``cablekit.CablekitError`` subclass; any other exception, a
crash or a hang (``-timeout``) is a finding, written by libFuzzer as ``crash-*``/``timeout-*``
in the working folder. Turn each into a regression test.

Bounded runs (``pip install '.[fuzz]'``), e.g. 20 000 inputs per target::

    python fuzz/fuzz_loaders.py weights -runs=20000 -timeout=10
    python fuzz/fuzz_loaders.py model -runs=20000 -timeout=10
    python fuzz/fuzz_loaders.py run -runs=20000 -timeout=10
    python fuzz/fuzz_loaders.py trajectory -runs=20000 -timeout=10
    python fuzz/fuzz_loaders.py caspr -runs=20000 -timeout=10
    python fuzz/fuzz_loaders.py robot -runs=20000 -timeout=10
    python fuzz/fuzz_loaders.py twin -runs=20000 -timeout=10
    python fuzz/fuzz_loaders.py manifest -runs=20000 -timeout=10
    python fuzz/fuzz_loaders.py bench -runs=20000 -timeout=10
    python fuzz/fuzz_loaders.py cdpr_run -runs=20000 -timeout=10

or by time: ``-max_total_time=60``. Seeds are valid files built at start-up, so the fuzzer
mutates real structure from the first input.
"""

from __future__ import annotations

import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import atheris

with atheris.instrument_imports():
    import numpy as np

    import cablekit as ck
    from cablekit.cdpr import Robot, shipped
    from cablekit.cdpr.cli import read_trajectory
    from cablekit.cdpr.diagnose import load_cdpr_run
    from cablekit.diagnose.data import load_run
    from cablekit.diagnose.many import load_manifest
    from cablekit.diagnose.spec import load_model_spec
    from cablekit.forceps.davinci import read_bench_file
    from cablekit.forceps.twin import SEED_FILE, load_twin
    from cablekit.nn import MapMinMax
    from cablekit.nn.export import write_weights

TMP = Path(tempfile.mkdtemp(prefix="cablekit-fuzz-"))


def _seed_weights() -> bytes:
    rng = np.random.default_rng(0)
    path = write_weights(
        TMP / "seed.safetensors",
        [rng.normal(size=(4, 2)), rng.normal(size=(1, 4))],
        [np.zeros(4), np.zeros(1)],
        ["tansig", "purelin"],
        MapMinMax(-np.ones(2), np.ones(2)),
        MapMinMax(np.zeros(1), np.ones(1)),
        input_names=["x", "v"],
        output_names=["T"],
    )
    return path.read_bytes()


SEED_MODEL = b"""model = "antagonistic_joint"
[parameters]
radius = 0.0025
stiffness = 31800.0
inertia = 2e-6
pretension = 10.0
[inputs]
x_m = "x_m"
external = "tau"
[outputs]
tension_motor_drive = "T1"
theta = "theta"
[diagnosis]
warmup = 0.2
substeps = 0
effects = ["coulomb_friction", "sensor_lag@sensors.force"]
"""

SEED_RUN = "t,x_m,T1\n" + "".join(
    f"{k * 1e-3:.6f},{1e-3 * np.sin(k / 50):.6e},{10 + k % 7:.3f}\n" for k in range(40)
)


def _weights(data: bytes) -> None:
    try:
        net = ck.Mlp.from_bytes(data)
    except ck.CablekitError:
        return
    y = net.predict(np.zeros(net.n_inputs))
    assert np.isfinite(y).all(), "a loaded network predicts non-finite numbers at zero input"


def _model(data: bytes) -> None:
    path = TMP / "model.toml"
    path.write_bytes(data)
    try:
        load_model_spec(path)
    except ck.CablekitError:
        return


def _run(data: bytes) -> None:
    path = TMP / "run.csv"
    path.write_bytes(data)
    try:
        run = load_run(path)
    except ck.CablekitError:
        return
    assert len(run) >= 10 and np.isfinite(run.t).all()


SEED_TRAJECTORY = "t,x,y,theta,fx,fy,mz\n0,0.5,0.4,0,0,0,0\n0.1,0.55,0.42,0.05,1,0,0.01\n"
SEED_BODIES = """<links><link_rigid num="1" name="p"><joint type="PLANAR_XY" /><physical><mass>1.0</mass>
<com_location>0 0 0</com_location><inertia ref="com"><Ixx>0</Ixx><Iyy>0</Iyy><Izz>1e-3</Izz><Ixy>0</Ixy>
<Ixz>0</Ixz><Iyz>0</Iyz></inertia></physical></link_rigid></links>"""
SEED_CABLES = "".join(
    f'<cable_ideal name="c{i}" attachment_reference="joint"><properties><force_min>1</force_min>'
    f"<force_max>50</force_max></properties><attachments><attachment><link>0</link><location>{a}</location>"
    f"</attachment><attachment><link>1</link><location>{b}</location></attachment></attachments></cable_ideal>"
    for i, (a, b) in enumerate(
        [
            ("0 1 0", "-0.05 0.05 0"),
            ("1 1 0", "0.05 0.05 0"),
            ("0 0 0", "-0.05 -0.05 0"),
            ("1 0 0", "0.05 -0.05 0"),
        ]
    )
)


def _trajectory(data: bytes) -> None:
    path = TMP / "trajectory.csv"
    path.write_bytes(data)
    try:
        tr = read_trajectory(path, "planar")
    except ck.CablekitError:
        return
    assert tr.poses.shape[1] == 3 and np.isfinite(tr.poses).all()


def _caspr(data: bytes) -> None:
    bodies, cables = TMP / "bodies.xml", TMP / "cables.xml"
    bodies.write_bytes(data)
    cables.write_text(f'<cables default_cable_set="a"><cable_set id="a">{SEED_CABLES}</cable_set></cables>')
    try:
        Robot.from_caspr(bodies, cables)
    except ck.CablekitError:
        return


PLANAR = shipped("seed003_planar")
SEED_BENCH = "% header\n" + "".join(
    f"{1e-3 * i},{3 * i},{100 + i},0.5,{2 * i},{50 - i},0,0,{70 * i}\n" for i in range(40)
)
SEED_MANIFEST = '[[group]]\nname = "a"\nmodel = "m.toml"\nfit = ["a.csv"]\nheld_out = ["b.csv"]\n'
_CDPR_COLUMNS = [f"{k}{i}" for k in ("alpha", "current", "sensor") for i in range(4)]
_CDPR_CELLS = ",".join(["0.0"] * 4 + ["0.1"] * 4 + ["10.0"] * 4)
SEED_CDPR_RUN = (
    ",".join(["t", *_CDPR_COLUMNS, "x", "y", "theta"])
    + "\n"
    + "".join(f"{0.01 * j},{_CDPR_CELLS},{0.6 + 1e-4 * j},0.5,0.0\n" for j in range(30))
)


def _file(name: str, load: Callable[[Path], object]) -> Callable[[bytes], None]:
    """A target that writes the input to ``name`` and loads it (a loaded table must be finite)."""

    def target(data: bytes) -> None:
        path = TMP / name
        path.write_bytes(data)
        try:
            loaded = load(path)
        except ck.CablekitError:
            return
        for v in vars(loaded).values() if hasattr(loaded, "__dict__") else ():
            if isinstance(v, np.ndarray) and v.dtype.kind == "f":
                assert np.isfinite(v).all(), f"{name}: non-finite numbers loaded"

    return target


def _cdpr_run(path: Path) -> object:
    return load_cdpr_run(path, PLANAR)


def _manifest(path: Path) -> object:
    for name in ("a.csv", "b.csv", "m.toml"):
        (path.parent / name).write_text("x")
    return load_manifest(path.parent)


TARGETS = {"weights": (_weights, _seed_weights), "model": (_model, lambda: SEED_MODEL),
           "run": (_run, lambda: SEED_RUN.encode()), "trajectory": (_trajectory, SEED_TRAJECTORY.encode),
           "caspr": (_caspr, SEED_BODIES.encode),
           "robot": (_file("robot.toml", Robot.load), lambda: shipped_text("seed003_planar")),
           "twin": (_file("twin.toml", load_twin), SEED_FILE.read_bytes),
           "manifest": (_file("manifest.toml", _manifest), SEED_MANIFEST.encode),
           "bench": (_file("00.TXT", read_bench_file), SEED_BENCH.encode),
           "cdpr_run": (_file("run.csv", _cdpr_run), SEED_CDPR_RUN.encode)}  # fmt: skip


def shipped_text(name: str) -> bytes:
    return (Path(ck.__file__).parent / "cdpr" / "robots" / f"{name}.toml").read_bytes()


def main() -> None:
    if len(sys.argv) < 2 or sys.argv[1] not in TARGETS:
        sys.exit(f"usage: {sys.argv[0]} {{{'|'.join(TARGETS)}}} [libFuzzer flags, e.g. -runs=20000]")
    name = sys.argv.pop(1)
    target, seed = TARGETS[name]
    corpus = TMP / f"corpus-{name}"
    corpus.mkdir()
    (corpus / "seed").write_bytes(seed())
    atheris.Setup([sys.argv[0], *sys.argv[1:], str(corpus)], target)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
