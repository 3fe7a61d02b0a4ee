"""Campaigns (``cablekit diagnose --many``): the manifest loader's errors, and the Ray path (a
local Ray with 2 workers) giving exactly the serial path's results, for joint, cable-network and
parallel-robot groups (without poses: the drum-side check; with poses: the one engine) in one
campaign."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import cablekit as ck
from cablekit.diagnose.data import write_csv
from cablekit.diagnose.many import load_manifest, manifest_from_dict, run_many
from cablekit.diagnose.selftest import make_case
from cablekit.diagnose.spec import write_model_toml


def _campaign(root: Path) -> Path:
    """Two groups, each with its own nominal model: a withheld sensor lag (its model named in
    its group) and a control with nothing withheld (the manifest's default model)."""
    lines = ['model = "control/model.toml"', ""]
    for name, effects, seed in (("lag", ("sensor_lag",), 5), ("control", (), 3)):
        case = make_case(effects, seed=seed, duration=5.0)
        (root / name).mkdir(parents=True)
        write_csv(case.fit[0], root / name / "fit.csv")
        write_csv(case.hold[0], root / name / "hold.csv")
        write_model_toml(case.spec, root / name / "model.toml")
        lines += [
            "[[group]]",
            f'name = "{name}"',
            f'fit = ["{name}/fit.csv"]',
            f'held_out = ["{name}/hold.csv"]',
        ]
        lines += ['model = "lag/model.toml"', ""] if name == "lag" else [""]
    # a cable-network group (issue #39 §4): the two-stage instrument with extra friction at its jaw,
    # its model file naming the network file beside it
    from tests.test_diagnose_network import network_group

    lines += network_group(root / "network")
    # a parallel-robot group (issue #39 §4): the Mini CDPR twin with a Dahl pulley before cable 6's
    # sensor, its robot file as the group's model
    from importlib import resources

    from cablekit.cdpr.diagnose import twin_run
    from tests.test_cdpr_diagnose import _write

    (root / "robot").mkdir()
    for name, seed in (("fit", 3), ("hold", 4)):
        # (without poses: the drum-side force check; with poses a robot's drives go through the
        # engine as a network's, tests/test_cdpr_diagnose.py)
        _write(root / "robot" / f"{name}.csv", twin_run("pulley_friction", 5, seed=seed), poses=False)
    mini = resources.files("cablekit.cdpr") / "robots" / "seed002_mini.toml"
    (root / "robot" / "mini.toml").write_text(mini.read_text(encoding="utf-8"), encoding="utf-8")
    lines += [
        "[[group]]",
        'name = "robot"',
        'model = "robot/mini.toml"',
        'fit = ["robot/fit.csv"]',
        'held_out = ["robot/hold.csv"]',
        "",
    ]
    # the same robot with measured poses (3 s runs): its drives at the poses go through the one
    # engine as a network's, the robot file (with the platform side's pulley friction) the model
    from tests.test_cdpr_diagnose import robot_file

    (root / "posed").mkdir()
    for name, seed in (("fit", 3), ("hold", 4)):
        _write(root / "posed" / f"{name}.csv", twin_run("pulley_friction", 5, seed=seed), rows=3_000)
    robot_file(root / "posed" / "mini.toml")
    lines += [
        "[[group]]",
        'name = "posed"',
        'model = "posed/mini.toml"',
        'fit = ["posed/fit.csv"]',
        'held_out = ["posed/hold.csv"]',
        "",
    ]
    (root / "manifest.toml").write_text("\n".join(lines))
    return root


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _campaign(tmp_path_factory.mktemp("campaign"))


GROUPS = ("lag", "control", "network", "robot", "posed")


def _docs(out: Path) -> dict[str, dict]:
    docs = {}
    for name in GROUPS:
        doc = json.loads((out / name / "diagnosis.json").read_text())
        if "meta" in doc:  # (the grey-box engine's; a parallel robot's has no options)
            doc["meta"].pop("options")  # holds the executor-independent knobs only; compared below
        docs[name] = doc
    return docs


def _assert_same(a: object, b: object, path: str = "") -> None:
    if isinstance(a, dict) and isinstance(b, dict):
        assert a.keys() == b.keys(), path
        for k in a:
            _assert_same(a[k], b[k], f"{path}/{k}")
    elif isinstance(a, list) and isinstance(b, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_same(x, y, f"{path}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        assert a == pytest.approx(b, rel=1e-9, abs=1e-300), path
    else:
        assert a == b, path


@pytest.mark.filterwarnings("ignore")  # Ray's own start-up warnings are not ours
def test_ray_campaign_equals_the_serial_campaign(campaign, tmp_path):
    ray = pytest.importorskip("ray")  # the [test] extra installs it; CI runs this
    serial = run_many(campaign, tmp_path / "serial", engine="serial", progress=False, html=False)
    ray.init(num_cpus=2, include_dashboard=False, logging_level="ERROR", log_to_driver=False)
    try:
        distributed = run_many(campaign, tmp_path / "ray", engine="ray", progress=False, html=False)
    finally:
        ray.shutdown()
    assert [r.error for r in serial + distributed] == [None] * 2 * len(GROUPS)
    summary = json.loads((tmp_path / "ray" / "summary.json").read_text())
    groups = [g["group"] for g in summary["groups"]]
    assert summary["engine"] == "ray" and groups == list(GROUPS)
    assert json.loads((tmp_path / "serial" / "summary.json").read_text())["engine"] == "serial"
    # the same results, whichever process fitted them: names, verdicts and flags exactly, numbers
    # to 1e-9 (the parameter intervals' linear algebra runs single-threaded in Ray's workers and
    # multi-threaded here, which moves the last bits)
    _assert_same(_docs(tmp_path / "ray"), _docs(tmp_path / "serial"))
    by = {r.group.name: r.diagnosis for r in serial}
    assert by["lag"] is not None and by["lag"].effects[0].name == "sensor_lag"
    assert by["control"] is not None and by["control"].verdict == "no_significant_gap"
    assert by["network"] is not None and by["network"].effects[0].site == "joint.jaw"
    # the parallel robot's group: the force channel names the pulley at its cable, as the single
    # diagnosis of the same files does, and the summary row says so
    from cablekit.cdpr import Robot
    from cablekit.cdpr.diagnose import diagnose_runs

    robot = by["robot"]
    here = campaign / "robot"
    alone = diagnose_runs([here / "fit.csv"], [here / "hold.csv"], Robot.load(here / "mini.toml"))
    assert robot is not None and robot.to_dict() == alone.to_dict()
    assert [(f.effect, f.cable) for f in robot.findings][:1] == [("pulley_friction", 5)]
    row = summary["groups"][3]
    assert row["verdict"] == "found" and row["selected"][0] == "pulley_friction@cable.6"
    assert "pulley_friction at cable 6" in (tmp_path / "serial" / "robot" / "diagnose.md").read_text()
    # the posed robot's group went through the one engine: its first effect is that pulley's
    # hysteresis at cable 6's routing, found in Ray's workers as in this process (compared above)
    posed = by["posed"]
    assert posed is not None and hasattr(posed, "selected"), type(posed)
    assert posed.effects[0].site == "routing.c6", posed.effects[0].id
    assert summary["groups"][4]["selected"][0].endswith("@routing.c6")


def test_a_failing_group_is_reported_and_the_others_go_on(campaign, tmp_path):
    broken = tmp_path / "c"
    broken.mkdir()
    for p in campaign.rglob("*"):
        if p.is_file():
            (broken / p.relative_to(campaign)).parent.mkdir(parents=True, exist_ok=True)
            (broken / p.relative_to(campaign)).write_bytes(p.read_bytes())
    (broken / "lag" / "hold.csv").write_text("t,theta\n0,1\n")  # lacks the model's columns
    (broken / "robot" / "hold.csv").write_text("t,alpha_1\n0,1\n")  # lacks the robot's columns
    # the posed robot's held-out run loses its third winch's current (its poses kept)
    rows = (broken / "posed" / "hold.csv").read_text().splitlines()[:3]
    drop = rows[0].split(",").index("current_3")
    (broken / "posed" / "hold.csv").write_text(
        "\n".join(",".join(c for i, c in enumerate(r.split(",")) if i != drop) for r in rows) + "\n"
    )
    res = run_many(broken, tmp_path / "out", engine="serial", progress=False, html=False)
    assert res[0].error is not None and "DataError" in res[0].error
    assert res[3].error is not None and "DataError" in res[3].error and "hold.csv" in res[3].error
    posed = res[4].error
    assert posed is not None and "DataError" in posed and "current_3" in posed, posed
    assert res[1].error is None and res[1].diagnosis is not None
    assert "error" in (tmp_path / "out" / "summary.txt").read_text()


@pytest.mark.parametrize(
    ("manifest", "message"),
    [
        ("", "no \\[\\[group\\]\\] tables"),
        ('colour = "red"\n[[group]]\nname = "a"', "unknown keys \\['colour'\\]"),
        (
            '[[group]]\nname = "a"\nmodel = "lag/model.toml"\nfit = ["lag/fit.csv"]\nheld_out = []',
            "'held_out'",
        ),
        ('[[group]]\nname = "a"\nfit = ["lag/fit.csv"]\nheld_out = ["lag/hold.csv"]', "no model file"),
        (
            '[[group]]\nname = "a"\nmodel = "lag/model.toml"\nfit = ["lag/fit.csv"]\nheld_out = ["nope.csv"]',
            "no such file",
        ),
        (
            '[[group]]\nname = "a"\nmodel = "lag/model.toml"\n'
            + 'fit = ["lag/fit.csv"]\nheld_out = ["lag/fit.csv"]',
            "both fitted and held out",
        ),
        (
            'model = "lag/model.toml"\n'
            + '[[group]]\nname = "a"\nfit = ["lag/fit.csv"]\nheld_out = ["lag/hold.csv"]\n' * 2,
            "duplicate group names",
        ),
        ('[[group]]\nname = "../x"\nfit = ["a"]\nheld_out = ["b"]', "'name'"),
        ("[[group]\n", r"not valid TOML"),
    ],
)
def test_bad_manifests_are_data_errors(campaign, tmp_path, manifest, message):
    for p in ("lag/model.toml", "lag/fit.csv", "lag/hold.csv"):
        (tmp_path / p).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / p).write_bytes((campaign / p).read_bytes())
    (tmp_path / "manifest.toml").write_text(manifest)
    with pytest.raises(ck.DataError, match=message):
        load_manifest(tmp_path)


def test_a_folder_without_a_manifest_is_a_data_error(tmp_path):
    with pytest.raises(ck.DataError, match=r"no manifest\.toml"):
        load_manifest(tmp_path)


_VALUES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**70), 2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=12),
    st.sampled_from(["lag/fit.csv", "lag/model.toml", "x\x00y", "a" * 5000, "../../etc", ""]),
    st.lists(st.one_of(st.text(max_size=12), st.integers(), st.floats(), st.just("a\x00")), max_size=3),
    st.dictionaries(st.text(max_size=4), st.integers(), max_size=2),
)


@settings(max_examples=80, deadline=None)
@given(key=st.sampled_from(["name", "model", "fit", "held_out", "extra"]), value=_VALUES)
def test_any_wrong_typed_manifest_value_is_a_data_error_or_a_valid_group(campaign, key, value):
    """Whatever one key of a valid group holds — None, huge integers, NaN, strings, mixed lists,
    tables — the manifest either still gives valid groups or raises DataError, nothing else."""
    group = {"name": "a", "model": "lag/model.toml", "fit": ["lag/fit.csv"], "held_out": ["lag/hold.csv"]}
    group[key] = value
    try:
        groups = manifest_from_dict({"group": [group]}, campaign)
    except ck.DataError:
        return
    assert len(groups) == 1 and groups[0].fit and groups[0].held_out and groups[0].model.is_file()
