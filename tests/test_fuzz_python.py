"""Property tests over the public Python functions of ``cablekit.cdpr`` and ``cablekit.forceps``
(issue #38): a valid call with one argument replaced by a drawn bad value — NaN, ±inf, ±1e308,
an empty, huge or wrongly shaped array, another dtype, another Python type.

The contract, as for the bindings (``test_fuzz_bindings.py``), but stricter on types: a Python
function checks its arguments itself, so a wrong type is cablekit's own typed error too, never a
bare ``TypeError``/``AttributeError`` from deep inside. Every draw either raises a
:class:`cablekit.CablekitError`, or returns, and then every number it returns is finite whenever
every number it was given is finite.

File readers are fuzzed byte by byte in ``test_fuzz_loaders.py``; renderers of a result object
(markdown tables, plots, reports) and the whole studies (minutes each) are listed in
``NOT_IN_TABLE`` with the reason; ``test_every_public_function_is_in_the_table`` keeps the two
lists complete. Every one of them — and every function of the table — is drawn against as well
(the second half of this file): each argument replaced by a value its annotation does not admit
is a typed error naming the argument, raised before any work is done.
"""

from __future__ import annotations

import functools
import importlib
import inspect
import pkgutil
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import cablekit as ck
import cablekit.cdpr
import cablekit.forceps
from tests.test_fuzz_bindings import Call, _finite_numbers, _mlp, mutated


@functools.cache
def _planar() -> Any:
    from cablekit.cdpr import shipped

    return shipped("seed003_planar")


@functools.cache
def _mini_file() -> str:
    from importlib import resources

    return str(resources.files("cablekit.cdpr") / "robots" / "seed002_mini.toml")


@functools.cache
def _plant() -> Any:
    from cablekit.cdpr.planar import planar_plant

    return planar_plant()


@functools.cache
def _twin() -> Any:
    from cablekit.forceps import load_twin

    return load_twin()


@functools.cache
def _drive() -> Any:
    from cablekit.cdpr.winch import step_cases

    return step_cases()[0][1]


@functools.cache
def _drum_run() -> tuple[Any, ...]:
    from cablekit.cdpr.diagnose import twin_run

    run = twin_run(None, 0, seed=0)
    k = slice(0, 400)
    return (
        run.winch,
        np.ascontiguousarray(run.t[k]),
        np.ascontiguousarray(run.alpha[k]),
        np.ascontiguousarray(run.current[k]),
        np.ascontiguousarray(run.sensor[k]),
    )


def _bench_run() -> Any:
    """A da Vinci bench run of 600 samples: a jaw closing and opening, noise on the rest."""
    from pathlib import Path

    from cablekit.forceps.davinci import BenchRun

    rng = np.random.default_rng(0)
    signals = 0.01 * rng.standard_normal((600, 5))
    signals[:, 0] += np.cos(np.linspace(0.0, 4.0 * np.pi, 600))
    return BenchRun("00", Path("00"), 1e-3, signals, np.zeros(600), None, None)


def _mlp_4_4() -> ck.Mlp:
    return _mlp(4, 3, 4)


def _home() -> np.ndarray:
    return np.asarray(_plant().home)


def _x() -> np.ndarray:
    return np.sin(np.linspace(0.0, 6.0, 300))


def _drive_run(robot: Any) -> tuple[Any, ...]:
    """A short valid run of the Mini CDPR's drives: 40 samples about its centre."""
    from cablekit.cdpr import Winch

    t = np.arange(40) * 1e-3
    poses = np.zeros((40, 6))
    poses[:, 2] = 0.45 + 1e-3 * np.sin(t * 50)
    alpha = np.tile(np.linspace(0.0, 0.1, 40)[:, None], (1, 8))
    return (
        robot,
        Winch.seed003(),
        np.full(8, 0.9),
        t,
        alpha,
        np.full((40, 8), 0.2),
        np.full((40, 8), 10.0),
        poses,
    )


def _factories() -> dict[str, Any]:
    """Each public function's valid call, built on first use (some simulate a run)."""
    from cablekit.cdpr import Winch, compensate, drives, force, formats, mjcf, planar, sensors, winch
    from cablekit.cdpr import diagnose as cdiag

    ws = importlib.import_module("cablekit.cdpr.workspace")
    from cablekit.forceps import bench, experiments, paper, posture, twin

    seed003 = Winch.seed003
    mini = cablekit.cdpr.shipped("seed002_mini")
    short = compensate.first_test_trajectory()
    short = type(short)(short.name, short.dt, short.poses[:80], short.velocity[:80], short.acceleration[:80])
    return {
        "cablekit.cdpr.shipped": lambda: Call(cablekit.cdpr.shipped, ("seed003_planar",)),
        "cablekit.cdpr.shipped_names": lambda: Call(cablekit.cdpr.shipped_names),
        "cablekit.cdpr.compensate.path": lambda: Call(
            compensate.path, ("p", [np.zeros(3), np.array([0.05, 0.02, 0.0])]), {"speed": 0.1, "dt": 0.01}
        ),
        "cablekit.cdpr.compensate.rmse": lambda: Call(compensate.rmse, (np.ones((6, 2)), np.zeros((6, 2)))),
        "cablekit.cdpr.compensate.first_test_trajectory": lambda: Call(compensate.first_test_trajectory),
        "cablekit.cdpr.compensate.second_test_trajectory": lambda: Call(
            compensate.second_test_trajectory, (), {"seed": 2, "speed": 0.1}
        ),
        "cablekit.cdpr.compensate.training_trajectories": lambda: Call(compensate.training_trajectories),
        "cablekit.cdpr.compensate.tensions": lambda: Call(
            compensate.tensions, (mini, short), {"rng": np.random.default_rng(0)}
        ),
        "cablekit.cdpr.compensate.statics": lambda: Call(
            compensate.statics, (mini, compensate.tensions(mini, short, rng=np.random.default_rng(0)))
        ),
        "cablekit.cdpr.force.mini_plant": lambda: Call(force.mini_plant),
        "cablekit.cdpr.sensors.seed_calibrations": lambda: Call(sensors.seed_calibrations),
        "cablekit.cdpr.winch.step_cases": lambda: Call(winch.step_cases, (seed003(),)),
        "cablekit.cdpr.diagnose.drum_residual": lambda: Call(cdiag.drum_residual, _drum_run()),
        "cablekit.cdpr.drives.drive_network": lambda: Call(
            drives.drive_network,
            (mini, seed003(), np.full(8, 0.9)),
            {"platform_side": compensate.TWIN_FRICTION},
        ),
        "cablekit.cdpr.drives.drive_columns": lambda: Call(drives.drive_columns, _drive_run(mini)),
        "cablekit.cdpr.drives.drive_spec": lambda: Call(
            drives.drive_spec, (mini, seed003(), np.full(8, 0.9), {"T1": (1.0, (1.0,))})
        ),
        "cablekit.cdpr.drives.smoothing_kernel": lambda: Call(drives.smoothing_kernel, (5,)),
        "cablekit.cdpr.drives.estimate_rest_length": lambda: Call(
            drives.estimate_rest_length, tuple(_drive_run(mini)[i] for i in (0, 1, 3, 4, 6, 7))
        ),
        "cablekit.cdpr.topics_of": lambda: Call(
            cablekit.cdpr.topics_of, ({"topics": {"alpha": "/winches:position"}}, "robot.toml")
        ),
        "cablekit.cdpr.formats.bag_topics": lambda: Call(
            formats.bag_topics,
            ({"alpha": "/winches:position", "sensor_2": "/cell2:data"}, mini),
        ),
        "cablekit.cdpr.path_friction_of": lambda: Call(
            cablekit.cdpr.path_friction_of,
            ({"cables": [{}, {}], "path_friction": {"coefficient": [0.02, 0.03], "presliding": 2e-3}},),
        ),
        "cablekit.cdpr.force.excitation": lambda: Call(
            force.excitation,
            (
                force.plant_robot(),
                np.tile(np.asarray(force.mini_plant().home), (50, 1)),
                np.random.default_rng(0),
            ),
            {"rms": 2.0, "dt": 1e-3, "correlation": 0.5},
        ),
        "cablekit.cdpr.force.plant_robot": lambda: Call(force.plant_robot),
        "cablekit.cdpr.planar.circle": lambda: Call(
            planar.circle, (_home(),), {"radius": 0.1, "period": 0.5, "turns": 1.0, "dt": 0.01}
        ),
        "cablekit.cdpr.planar.planar_plant": lambda: Call(planar.planar_plant, (_planar(),)),
        "cablekit.cdpr.planar.step_response": lambda: Call(
            planar.step_response, (_plant(),), {"axis": 0, "size": 0.02, "t_end": 0.3, "dt": 1e-3}
        ),
        "cablekit.cdpr.sensors.calibrate": lambda: Call(
            sensors.calibrate, ("cell", 1.0, 0.0), {"capstan": 0.0, "noise": 0.0, "readings_per_mass": 2}
        ),
        "cablekit.cdpr.sensors.current_sweep": lambda: Call(
            sensors.current_sweep, (0.5,), {"hold": 0.1, "ramp": 0.05}
        ),
        "cablekit.cdpr.winch.inconsistencies": lambda: Call(winch.inconsistencies, (seed003(),)),
        "cablekit.cdpr.winch.linearise": lambda: Call(winch.linearise, (seed003(), "fixed")),
        "cablekit.cdpr.winch.linearised_poles": lambda: Call(winch.linearised_poles, (_drive(),)),
        "cablekit.cdpr.winch.root_locus": lambda: Call(
            winch.root_locus, (seed003(), "fixed"), {"kps": np.array([0.5, 1.0, 2.0])}
        ),
        "cablekit.cdpr.winch.step_response": lambda: Call(
            winch.step_response, (_drive(), 0.2), {"duration": 0.1, "dt": 1e-3, "substeps": 4}
        ),
        "cablekit.cdpr.winch.table5": lambda: Call(winch.table5, (seed003(),)),
        "cablekit.cdpr.winch.with_modulus": lambda: Call(winch.with_modulus, (seed003(), 1e9)),
        "cablekit.cdpr.workspace.workspace": lambda: Call(ws.workspace, (_planar(),), {"counts": 4}),
        "cablekit.cdpr.mjcf.to_mjcf": lambda: Call(mjcf.to_mjcf, (_mini_file(),)),
        "cablekit.cdpr.mjcf.swivel_angles": lambda: Call(
            mjcf.swivel_angles, (_mini_file(), np.array([[0.05, -0.02, 0.4, 0.1, 0.0, -0.1]]))
        ),
        "cablekit.cdpr.mjcf.mujoco_state": lambda: Call(
            mjcf.mujoco_state, (_mini_file(), np.array([0.05, -0.02, 0.4, 0.1, 0.0, -0.1]))
        ),
        "cablekit.forceps.free_motion_tensions": lambda: Call(
            cablekit.forceps.free_motion_tensions, (_mlp_4_4(), 0.1 * np.ones((20, 4)))
        ),
        "cablekit.forceps.bench.condition": lambda: Call(bench.condition, ("31",)),
        "cablekit.forceps.experiments.neutral_physics": lambda: Call(experiments.neutral_physics, (_twin(),)),
        "cablekit.forceps.experiments.with_seed": lambda: Call(experiments.with_seed, (_twin(), 3)),
        "cablekit.forceps.twin.another_instrument": lambda: Call(
            twin.another_instrument, (_twin(), twin.TRANSFER_VARIATIONS[0])
        ),
        "cablekit.forceps.paper.closing_mask": lambda: Call(paper.closing_mask, (_bench_run(),)),
        "cablekit.forceps.paper.holoborodko": lambda: Call(paper.holoborodko, (_x(), 1e-3)),
        "cablekit.forceps.paper.lowpass_zero_phase": lambda: Call(
            paper.lowpass_zero_phase, (_x(), 1e-3), {"hz": 50.0, "order": 3}
        ),
        "cablekit.forceps.paper.paper_split": lambda: Call(
            paper.paper_split, ([np.arange(300) % 7 == 0],), {"seed": 0}
        ),
        "cablekit.forceps.posture.parse_posture": lambda: Call(posture.parse_posture, ("pitch=30,roll=-45",)),
        "cablekit.forceps.posture.posture_from_text": lambda: Call(
            posture.posture_from_text, ("This is a pitch of +60 degrees", "README")
        ),
        "cablekit.forceps.posture.run_posture": lambda: Call(
            posture.run_posture, (posture.parse_posture("pitch=30"), "310")
        ),
        "cablekit.forceps.twin.twin_from_toml": lambda: Call(
            twin.twin_from_toml, (twin.SEED_FILE.read_text(),)
        ),
    }


#: public functions not drawn here, and why
NOT_IN_TABLE = {
    # file readers: fuzzed byte by byte in test_fuzz_loaders.py (or read a folder of them)
    "cablekit.cdpr.caspr.caspr_document": "two XML files; tests/test_caspr.py feeds it broken files",
    "cablekit.cdpr.mjcf.export_mjcf": "writes a file (to_mjcf's text is in the table): tests/test_mjcf.py",
    "cablekit.cdpr.formats.load_cdpr_run": "a run file: test_fuzz_loaders.py",
    "cablekit.cdpr.formats.read_trajectory": "a run file: test_fuzz_loaders.py",
    "cablekit.cdpr.diagnose.diagnose_file": "a run file, then diagnose",
    "cablekit.cdpr.diagnose.diagnose_runs": "run files, then diagnose",
    "cablekit.cdpr.diagnose.is_robot_file": "a model file: test_cdpr_diagnose.py feeds it any bytes",
    "cablekit.cdpr.diagnose.diagnose_loaded": "runs read from files: test_cdpr_diagnose.py draws its splits",
    "cablekit.cdpr.drives.drive_runs": "runs read from files: test_cdpr_drives.py and the CLI tests",
    "cablekit.forceps.bench.read_raw": "a bench file: test_fuzz_loaders.py",
    "cablekit.forceps.davinci.bench_folder": "a folder",
    "cablekit.forceps.davinci.read_bench_file": "a bench file: test_fuzz_loaders.py",
    "cablekit.forceps.davinci.read_bench_folder": "a folder of bench files",
    "cablekit.forceps.posture.folder_posture": "a folder's README: test_fuzz_loaders.py",
    "cablekit.forceps.twin.load_twin": "a twin file: test_fuzz_loaders.py",
    "cablekit.forceps.protocols.protocols_present": "a folder tree",
    # renderers of a result object the library made (their input is never the user's numbers)
    **{
        f"cablekit.{name}": "renders a result object"
        for name in (
            "cdpr.compensate.plot_cable cdpr.compensate.report cdpr.compensate.table_markdown "
            "cdpr.diagnose.markdown cdpr.diagnose.plot cdpr.diagnose.report cdpr.diagnose.run_report "
            "cdpr.selftest.markdown "
            "cdpr.force.markdown "
            "cdpr.force.plot cdpr.planar.markdown cdpr.planar.plot cdpr.planar.report "
            "cdpr.sensors.calibration_table cdpr.sensors.fig18_table cdpr.sensors.plot_fig18 "
            "cdpr.winch.plot_root_locus cdpr.winch.plot_steps cdpr.winch.report "
            "cdpr.winch.step_markdown cdpr.winch.table5_markdown cdpr.workspace.plot_workspace "
            "forceps.experiments.as_dict forceps.experiments.seed_table "
            "forceps.experiments.transfer_table forceps.protocols.cv_markdown "
            "forceps.protocols.markdown "
        ).split()
    },
    # whole studies and the seed's fixed cases (minutes each; their goals are asserted in their own tests)
    **{
        f"cablekit.{name}": "a whole study or the seed's fixed cases: asserted in its own test"
        for name in (
            "cdpr.compensate.compensate cdpr.diagnose.diagnose "
            "cdpr.diagnose.length_residual cdpr.diagnose.rest_from_first_sample "
            "cdpr.diagnose.self_test cdpr.diagnose.twin_run cdpr.force.force_control "
            "cdpr.selftest.self_test cdpr.selftest.twin_diagnosis "
            "cdpr.force.plant_network cdpr.planar.trajectory_response cdpr.sensors.fig18 "
            "cdpr.winch.step_table forceps.calibrate.calibrate forceps.davinci.estimator_fitters "
            "forceps.davinci.leave_one_out forceps.davinci.new_instrument forceps.davinci.score "
            "forceps.experiments.metrics forceps.experiments.pooled_rmse "
            "forceps.experiments.seed_experiments forceps.experiments.set_up "
            "forceps.experiments.train_free_motion_network forceps.experiments.transfer_study "
            "forceps.paper.paper_protocol forceps.paper.strict_folds "
            "forceps.protocols.calibration_cv forceps.protocols.calibration_runs "
            "forceps.protocols.protocols forceps.protocols.transfer "
        ).split()
    },
}  # fmt: skip


def _members() -> list[tuple[str, str, Any]]:
    """``(module, name, object)`` for the public names of every module of the two packages."""
    out = []
    for pkg in (cablekit.cdpr, cablekit.forceps):
        mods = [pkg.__name__] + [f"{pkg.__name__}.{m.name}" for m in pkgutil.iter_modules(pkg.__path__)]
        for m in mods:
            mod = importlib.import_module(m)
            for n in getattr(mod, "__all__", None) or [n for n in dir(mod) if not n.startswith("_")]:
                out.append((m, n, getattr(mod, n, None)))
    return out


def _public_functions() -> set[str]:
    return {f"{m}.{n}" for m, n, f in _members() if inspect.isfunction(f) and f.__module__ == m}


@functools.cache
def _call(name: str) -> Call:
    return _factories()[name]()


def test_every_public_function_is_in_the_table():
    """A new public function of cablekit.cdpr or cablekit.forceps joins the table (or
    ``NOT_IN_TABLE`` with a reason)."""
    public = _public_functions()
    missing = sorted(public - set(NAMES) - set(NOT_IN_TABLE))
    assert not missing, f"public functions without property draws: {missing}"
    gone = sorted((set(NAMES) | set(NOT_IN_TABLE)) - public)
    assert not gone, f"listed but no longer public: {gone}"


NAMES = sorted(_factories())


@pytest.mark.parametrize("name", NAMES)
def test_the_valid_call_works_and_is_finite(name):
    call = _call(name)
    assert _finite_numbers(call.fn(*call.args, **(call.kwargs or {})))


@pytest.mark.parametrize("name", NAMES)
@settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large]
)
@given(data=st.data())
def test_a_bad_argument_is_a_typed_error_or_a_finite_result(name, data):
    call = _call(name)
    if not [a for a in call.args if not isinstance(a, ck.Model)] and not call.kwargs:
        return  # nothing to draw (a model argument is the bindings' suite's)
    args, kwargs, finite, _ = data.draw(mutated(call))
    try:
        result = call.fn(*args, **kwargs)
    except ck.CablekitError:
        return
    if finite:
        assert _finite_numbers(result), f"{name}{args, kwargs} returned non-finite numbers"


# ---- every argument of every public function against its annotation -------------------------
#
# The table above calls the functions that are cheap to call with one argument replaced. Every
# public function of the two packages — the studies and renderers too — checks its arguments
# against its annotations before its body runs (``cablekit._args.checked``): a value its
# annotation does not admit is a typed error that names the argument, at once. Which values an
# annotation admits is judged here from the annotation's kinds alone, not by the checker.

_POOL = st.one_of(
    st.sampled_from(
        [None, "abc", b"x", 7, 2.5, True, object(), [object()], np.array(["x"]), {"k": object()}]
    ),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.text(max_size=8),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=4),
    st.lists(st.text(max_size=3), min_size=1, max_size=3),
)


def _admits(tp: Any, value: Any) -> bool:
    """Whether the annotation ``tp`` may admit ``value`` (generous: when unsure, it admits)."""
    import collections.abc
    import math
    import os
    import types
    import typing

    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin is typing.Annotated:  # a number with a range (cablekit._args.Range: .lo, .hi)
        ranges = [(getattr(m, "lo", None), getattr(m, "hi", None)) for m in args[1:]]
        if not _admits(args[0], value):
            return False
        return all((lo is None or value >= lo) and (hi is None or value <= hi) for lo, hi in ranges)
    if origin in (typing.Union, types.UnionType):
        return any(_admits(a, value) for a in args)
    if tp in (Any, object) or isinstance(tp, typing.TypeVar):
        return True
    if tp is type(None):
        return value is None
    if origin is typing.Literal:
        return value in args
    if tp is bool:
        return isinstance(value, bool)
    if tp is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if tp is float:
        return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    if tp is str:
        return isinstance(value, str)
    if isinstance(tp, type) and issubclass(tp, os.PathLike):
        return isinstance(value, str | os.PathLike)
    if tp is np.ndarray or origin is np.ndarray:
        if isinstance(value, str | bytes | dict) or value is None or type(value) is object:
            return False
        try:
            arr = np.asarray(value)
        except (ValueError, TypeError, OverflowError):
            return False
        return arr.dtype.kind in "biu" or (arr.dtype.kind == "f" and bool(np.isfinite(arr).all()))
    if origin is collections.abc.Callable or tp is collections.abc.Callable:
        return callable(value)
    if origin in (list, tuple, collections.abc.Sequence) or tp in (list, tuple, collections.abc.Sequence):
        if not isinstance(value, collections.abc.Sequence):
            return False
        elem = args[0] if (args and origin is not tuple) or (len(args) == 2 and args[1] is Ellipsis) else None
        return elem is None or all(_admits(elem, v) for v in value)
    if origin in (dict, collections.abc.Mapping) or tp in (dict, collections.abc.Mapping):
        return isinstance(value, collections.abc.Mapping)
    if isinstance(tp, type):
        return isinstance(value, tp)
    return True


def _slots(fn: Any) -> list[tuple[str, Any, bool]]:
    """``(argument, annotation, is **kwargs)`` for every annotated argument but ``*args``."""
    hints = fn.__cablekit_hints__()
    sig = inspect.signature(fn)
    return [
        (p.name, hints[p.name], p.kind is inspect.Parameter.VAR_KEYWORD)
        for p in sig.parameters.values()
        if p.name in hints and p.kind is not inspect.Parameter.VAR_POSITIONAL
    ]


def _public_methods() -> set[str]:
    """``module.Class.method`` for the public methods of the public classes written in Python
    (properties and the bindings' classes aside)."""
    names = set()
    for m, n, cls in _members():
        if not (inspect.isclass(cls) and cls.__module__ == m):
            continue
        for a, v in vars(cls).items():
            f = v.__func__ if isinstance(v, staticmethod | classmethod) else v
            if not a.startswith("_") and inspect.isfunction(f):
                names.add(f"{m}.{n}.{a}")
    return names


PUBLIC = sorted(_public_functions() | _public_methods())


def _function(name: str) -> Any:
    """The function behind ``name`` (a method's, unbound: its ``self``/``cls`` is not drawn)."""
    module, attr = name.rsplit(".", 1)
    try:
        return getattr(importlib.import_module(module), attr)
    except ModuleNotFoundError:
        module, cls = module.rsplit(".", 1)
        v = inspect.getattr_static(getattr(importlib.import_module(module), cls), attr)
        return v.__func__ if isinstance(v, staticmethod | classmethod) else v


@pytest.mark.parametrize("name", PUBLIC)
def test_every_public_function_checks_its_arguments(name):
    """Every public function is wrapped by the argument check, and every annotation resolves
    (an annotation that names nothing would leave its argument unchecked)."""
    fn = _function(name)
    assert hasattr(fn, "__cablekit_hints__"), f"{name} is not wrapped by cablekit._args.checked"
    hints = fn.__cablekit_hints__()
    args = [p.name for p in inspect.signature(fn).parameters.values() if p.name not in ("self", "cls")]
    assert not [a for a in args if a not in hints], f"{name}: arguments without an annotation"


@pytest.mark.parametrize("name", [n for n in PUBLIC if _slots(_function(n))])
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_a_value_its_annotation_does_not_admit_is_a_typed_error_naming_it(name, data):
    fn = _function(name)
    arg, tp, var_kw = data.draw(st.sampled_from(_slots(fn)))
    value = data.draw(_POOL.filter(lambda v: not _admits(tp, v)))
    key = "extra_argument" if var_kw else arg
    with pytest.raises(ck.CablekitError) as err:
        fn(**{key: value})
    assert key in str(err.value), f"{name}({key}={value!r}): {err.value}"
