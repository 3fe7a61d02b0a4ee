"""ROS 2 logs in (issue #40 §1): a run recorded as a rosbag2 bag (MCAP and SQLite3), written with
``rosbags`` in standard message types (Float64, JointState, WrenchStamped) and a custom type with
its definition, gives the CSV run's diagnosis; bad bags are DataErrors naming the topic."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

import cablekit as ck
from cablekit.bags import is_bag, parse_field, read_bag
from cablekit.diagnose.data import load_run, write_csv
from cablekit.diagnose.selftest import make_case
from cablekit.diagnose.spec import write_model_toml

#: the model's columns → where the bag carries them
FIELDS = {
    "x_m": "/motor/command:data",  # Float64: no header, receive times
    "x_c": "/joint_states:position[1]",  # JointState: header stamps
    "theta": "/joint_states:position[0]",
    "T_drive": "/tension/drive:wrench.force.x",  # WrenchStamped
    "T_return": "/tension/cells:return_side",  # a custom type, its definition in the bag
}
TENSION = "cablekit_msgs/msg/Tension"
TENSION_DEF = "float64 drive_side\nfloat64 return_side\n"


def _typestore():
    ts = get_typestore(Stores.ROS2_HUMBLE)
    ts.register(get_types_from_msg(TENSION_DEF, TENSION))
    return ts


def write_bag(run, folder: Path, plugin=StoragePlugin.MCAP, *, t0_ns=1_700_000_000_000_000_000, **faults):
    """``run`` as a bag: each column on its topic (FIELDS), stamped at ``t0 + t``; ``faults``:
    ``stamp_back`` (a JointState stamp goes back), ``no_definition`` (the custom type written
    without its definition)."""
    ts = _typestore()
    T = ts.types
    bare = bool(faults.get("no_definition"))
    with Writer(folder, version=9, storage_plugin=plugin) as w:
        conns = {
            "/motor/command": w.add_connection("/motor/command", "std_msgs/msg/Float64", typestore=ts),
            "/joint_states": w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=ts),
            "/tension/drive": w.add_connection(
                "/tension/drive", "geometry_msgs/msg/WrenchStamped", typestore=ts
            ),
            "/tension/cells": w.add_connection(
                "/tension/cells",
                TENSION,
                **({"msgdef": "", "rihs01": "RIHS01_" + "0" * 64} if bare else {"typestore": ts}),
            ),
        }
        c = run.columns
        for k, t in enumerate(run.t):
            ns = t0_ns + round(t * 1e9)
            stamp_ns = ns - 1_500_000 if faults.get("stamp_back") and k == 7 else ns
            hdr = T["std_msgs/msg/Header"](
                stamp=T["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9),
                frame_id="j",
            )
            vec = T["geometry_msgs/msg/Vector3"]
            msgs = {
                "/motor/command": T["std_msgs/msg/Float64"](data=c["x_m"][k]),
                "/joint_states": T["sensor_msgs/msg/JointState"](
                    header=hdr,
                    name=["theta", "x_c"],
                    position=np.array([c["theta"][k], c["x_c"][k]]),
                    velocity=np.zeros(0),
                    effort=np.zeros(0),
                ),
                "/tension/drive": T["geometry_msgs/msg/WrenchStamped"](
                    header=hdr,
                    wrench=T["geometry_msgs/msg/Wrench"](
                        force=vec(x=c["T_drive"][k], y=0.0, z=0.0), torque=vec(x=0.0, y=0.0, z=0.0)
                    ),
                ),
                "/tension/cells": T[TENSION](drive_side=c["T_drive"][k], return_side=c["T_return"][k]),
            }
            # the recorder receives a stamped message 20 µs after its stamp (the reader takes the
            # stamp), an unstamped one as it is sent (its receive time is its only time)
            for topic, msg in msgs.items():
                late = 20_000 if hasattr(msg, "header") else 0
                w.write(conns[topic], ns + late, ts.serialize_cdr(msg, msg.__msgtype__))
    return folder


@pytest.fixture(scope="module")
def case():
    return make_case(("sensor_lag",), seed=5, duration=5.0)


def _model(case, path: Path, fields: dict[str, str]) -> Path:
    write_model_toml(case.spec, path)
    text = path.read_text()
    for col, field in fields.items():
        text = text.replace(f'"{col}"', f'"{field}"')
    path.write_text(text)
    return path


@pytest.mark.parametrize("plugin", [StoragePlugin.MCAP, StoragePlugin.SQLITE3])
def test_a_bag_reads_as_the_csv_run(case, tmp_path, plugin):
    bag = write_bag(case.fit[0], tmp_path / "fit", plugin)
    assert is_bag(bag) and is_bag(next(bag.glob("*.mcap" if plugin == StoragePlugin.MCAP else "*.db3")))
    run = load_run(bag, columns=list(FIELDS.values()))
    np.testing.assert_allclose(run.t, case.fit[0].t, rtol=0, atol=1e-12)
    for col, field in FIELDS.items():
        np.testing.assert_array_equal(run.column(field), case.fit[0].column(col))
    assert "topic /motor/command: receive times (no header)" in run.notes
    assert "topic /joint_states: header stamps" in run.notes


def test_the_diagnosis_of_bags_equals_the_csv_diagnosis(case, tmp_path):
    """``cablekit diagnose FIT --holdout HOLD --model M``: CSV files and a model naming columns,
    or bags (MCAP fitted, SQLite3 held out) and the same model naming bag fields — the same
    diagnosis, numbers to 1e-9."""
    from cablekit.cli import main

    write_csv(case.fit[0], tmp_path / "fit.csv")
    write_csv(case.hold[0], tmp_path / "hold.csv")
    _model(case, tmp_path / "csv.toml", {})
    # (the bags carry the CSV files' numbers: a CSV cell keeps fewer digits than a float64)
    write_bag(load_run(tmp_path / "fit.csv"), tmp_path / "fit_bag", StoragePlugin.MCAP)
    write_bag(load_run(tmp_path / "hold.csv"), tmp_path / "hold_bag", StoragePlugin.SQLITE3)
    _model(case, tmp_path / "bag.toml", FIELDS)
    docs = {}
    for kind, fit, hold in (("csv", "fit.csv", "hold.csv"), ("bag", "fit_bag", "hold_bag")):
        args = [
            str(tmp_path / fit),
            "--holdout",
            str(tmp_path / hold),
            "--model",
            str(tmp_path / f"{kind}.toml"),
        ]
        out = tmp_path / f"out_{kind}"
        assert main(["diagnose", *args, "--out", str(out), "--quiet", "--no-html", "--intervals", "0"]) == 0
        docs[kind] = json.loads((out / "diagnosis.json").read_text())
    a, b = docs["csv"], docs["bag"]
    assert a["verdict"] == b["verdict"] and a["selected"]["effects"] == b["selected"]["effects"]
    assert a["effects"][0]["id"].startswith("sensor_lag")
    assert [e["id"] for e in a["effects"]] == [e["id"] for e in b["effects"]]
    ha, hb = a["selected"]["held_out"], b["selected"]["held_out"]
    for key in ("gap_before", "gap_after", "closed_fraction"):
        assert hb[key] == pytest.approx(ha[key], rel=1e-9), key


def test_bad_bags_are_data_errors_naming_the_topic(case, tmp_path):
    run = case.fit[0]
    bag = write_bag(run, tmp_path / "ok")
    fields = list(FIELDS.values())
    with pytest.raises(ck.DataError, match="no topic '/tension/other'"):
        read_bag(bag, [*fields, "/tension/other:data"])
    with pytest.raises(ck.DataError, match=r"/joint_states:effort\[0\].*out of range"):
        read_bag(bag, ["/joint_states:effort[0]"])
    with pytest.raises(ck.DataError, match=r"no field 'force_x'.*fields: \['header', 'wrench'\]"):
        read_bag(bag, ["/tension/drive:force_x"])
    with pytest.raises(ck.DataError, match="not a number"):
        read_bag(bag, ["/joint_states:name[0]"])
    with pytest.raises(ck.DataError, match="not a bag field"):
        read_bag(bag, ["joint_states.position"])
    with pytest.raises(ck.DataError, match="model's columns"):
        load_run(bag)
    # stamps that go back
    back = write_bag(run, tmp_path / "back", stamp_back=True)
    with pytest.raises(ck.DataError, match=r"/joint_states.*header stamps go backwards at message 8"):
        read_bag(back, fields)
    # a custom type whose definition the bag does not carry
    bare = write_bag(run, tmp_path / "bare", StoragePlugin.SQLITE3, no_definition=True)
    with pytest.raises(
        ck.DataError, match=r"'/tension/cells' has type 'cablekit_msgs/msg/Tension', whose defin"
    ):
        read_bag(bare, ["/tension/cells:return_side"])
    with pytest.raises(ck.DataError, match=r"'/tension/cells' has type"):  # read or not
        read_bag(bare, ["/motor/command:data"])
    # a truncated MCAP file
    cut = write_bag(run, tmp_path / "cut")
    mcap = next(cut.glob("*.mcap"))
    mcap.write_bytes(mcap.read_bytes()[: mcap.stat().st_size // 2])
    with pytest.raises(ck.DataError, match="cut"):
        read_bag(cut, fields)
    # not a bag
    (tmp_path / "empty").mkdir()
    assert not is_bag(tmp_path / "empty")
    with pytest.raises(ck.DataError, match="not a rosbag2"):
        read_bag(tmp_path / "empty", fields)


@settings(max_examples=200, deadline=None)
@given(name=st.text(max_size=30))
def test_any_field_name_parses_or_is_a_data_error(name):
    """Any string: a ``(topic, path)`` whose parts rebuild it, or a DataError saying the form."""
    try:
        topic, path = parse_field(name)
    except ck.DataError as e:
        assert "/topic:field" in str(e)
        return
    rebuilt = (
        topic
        + ":"
        + "".join((f"[{p}]" if isinstance(p, int) else ("." if i else "") + p) for i, p in enumerate(path))
    )
    assert rebuilt == name and topic.startswith("/")


@settings(max_examples=30, deadline=None)
@given(
    path=st.one_of(st.none(), st.integers(), st.floats(allow_nan=True), st.just("/no/such/bag"), st.binary()),
    fields=st.one_of(st.none(), st.text(max_size=5), st.lists(st.text(max_size=8), max_size=3), st.just([])),
)
def test_read_bag_answers_any_arguments_with_a_typed_error(path, fields):
    with pytest.raises(ck.CablekitError):
        read_bag(path, fields)
    try:
        assert is_bag(path) is False
    except ck.CablekitError:
        assert not isinstance(path, str)


# -- a parallel robot's runs (``cablekit cdpr diagnose --run BAG``, the robot file's [topics])

#: the Mini CDPR's run columns in a bag: the winches' JointState (angles, currents), the load
#: cells as one Float64MultiArray (no header), the tracker's position and orientation
CDPR_TOPICS = {
    "alpha": "/winches:position",
    "current": "/winches:effort",
    "sensor": "/load_cells:data",
    "x": "/tracker/position:point.x",
    "y": "/tracker/position:point.y",
    "z": "/tracker/position:point.z",
    "roll": "/tracker/rpy:vector.x",
    "pitch": "/tracker/rpy:vector.y",
    "yaw": "/tracker/rpy:vector.z",
}


def write_cdpr_bag(run, folder: Path, rows: int, plugin=StoragePlugin.MCAP) -> Path:
    """A CDPR run (``RunFile``) as a bag on CDPR_TOPICS' topics, stamped at ``t0 + t``."""
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    types = {
        "/winches": "sensor_msgs/msg/JointState",
        "/load_cells": "std_msgs/msg/Float64MultiArray",
        "/tracker/position": "geometry_msgs/msg/PointStamped",
        "/tracker/rpy": "geometry_msgs/msg/Vector3Stamped",
    }
    t0 = 1_700_000_000_000_000_000
    layout = T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
    with Writer(folder, version=9, storage_plugin=plugin) as w:
        conns = {k: w.add_connection(k, v, typestore=ts) for k, v in types.items()}
        for k in range(rows):
            ns = t0 + round(run.t[k] * 1e9)
            hdr = T["std_msgs/msg/Header"](
                stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9), frame_id="w"
            )
            p = run.poses[k]
            msgs = {
                "/winches": T["sensor_msgs/msg/JointState"](
                    header=hdr,
                    name=[f"drum{j + 1}" for j in range(8)],
                    position=run.alpha[k].copy(),
                    velocity=np.zeros(0),
                    effort=run.current[k].copy(),
                ),
                "/load_cells": T["std_msgs/msg/Float64MultiArray"](layout=layout, data=run.sensor[k].copy()),
                "/tracker/position": T["geometry_msgs/msg/PointStamped"](
                    header=hdr, point=T["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2])
                ),
                "/tracker/rpy": T["geometry_msgs/msg/Vector3Stamped"](
                    header=hdr, vector=T["geometry_msgs/msg/Vector3"](x=p[3], y=p[4], z=p[5])
                ),
            }
            for topic, msg in msgs.items():
                w.write(
                    conns[topic],
                    ns + (20_000 if hasattr(msg, "header") else 0),
                    ts.serialize_cdr(msg, msg.__msgtype__),
                )
    return folder


@pytest.fixture(scope="module")
def cdpr_csv(tmp_path_factory):
    """A Mini CDPR twin run with its poses as a CSV run file (4 s) and the robot file that
    names the bag's topics."""
    import csv
    import tomllib

    from cablekit.cdpr.diagnose import twin_run

    run = twin_run("sensor_gain", 1, seed=2)
    rows = 4000
    d = tmp_path_factory.mktemp("cdpr")
    header = ["t", *(f"{k}_{j + 1}" for k in ("alpha", "current", "sensor") for j in range(8))]
    header += ["x", "y", "z", "roll", "pitch", "yaw"]
    table = np.hstack([run.t[:, None], run.alpha, run.current, run.sensor, run.lengths.poses])[:rows]
    with (d / "run.csv").open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(table.tolist())
    from importlib import resources

    text = (resources.files("cablekit.cdpr") / "robots" / "seed002_mini.toml").read_text(encoding="utf-8")
    text += "\n[topics]\n" + "".join(f'{k} = "{v}"\n' for k, v in CDPR_TOPICS.items())
    tomllib.loads(text)
    (d / "mini.toml").write_text(text, encoding="utf-8")
    return d


def test_a_cdpr_bag_reads_as_its_csv_run_through_the_robot_files_topics(cdpr_csv, tmp_path):
    from cablekit._files import load_toml
    from cablekit.cdpr import Robot, topics_of
    from cablekit.cdpr.formats import load_cdpr_run

    robot = Robot.load(cdpr_csv / "mini.toml")
    csv_run = load_cdpr_run(cdpr_csv / "run.csv", robot)
    bag = write_cdpr_bag(csv_run, tmp_path / "bag", len(csv_run.t))
    topics = topics_of(load_toml(cdpr_csv / "mini.toml", "robot file"))
    bag_run = load_cdpr_run(bag, robot, topics=topics)
    np.testing.assert_allclose(bag_run.t, csv_run.t, rtol=0, atol=1e-12)
    for k in ("alpha", "current", "sensor", "poses"):
        np.testing.assert_array_equal(getattr(bag_run, k), getattr(csv_run, k), err_msg=k)
    assert "topic /load_cells: receive times (no header)" in bag_run.notes
    assert "topic /winches: header stamps" in bag_run.notes
    # a single column overrides its group's entry; a list names each cable's field
    swapped = {
        **topics,
        "sensor_3": "/load_cells:data[0]",
        "current": [f"/winches:effort[{j}]" for j in range(8)],
    }
    other = load_cdpr_run(bag, robot, topics=swapped)
    np.testing.assert_array_equal(other.sensor[:, 2], csv_run.sensor[:, 0])
    np.testing.assert_array_equal(other.current, csv_run.current)


def test_the_cdpr_diagnosis_of_a_bag_equals_the_csv_files(cdpr_csv, tmp_path):
    """``cablekit cdpr diagnose --run BAG --robot mini.toml`` (the robot file's [topics]) and
    the same run as CSV: the same report but for the file names (the retired force check, the
    drives through the one engine with poses are covered by the CSV tests)."""
    from cablekit.cdpr import Robot
    from cablekit.cdpr.formats import load_cdpr_run
    from cablekit.cli import main

    robot = Robot.load(cdpr_csv / "mini.toml")
    csv_run = load_cdpr_run(cdpr_csv / "run.csv", robot)
    nopose = {k: v for k, v in CDPR_TOPICS.items() if k in ("alpha", "current", "sensor")}
    text = (cdpr_csv / "mini.toml").read_text(encoding="utf-8").split("\n[topics]\n")[0]
    (tmp_path / "mini.toml").write_text(
        text + "\n[topics]\n" + "".join(f'{k} = "{v}"\n' for k, v in nopose.items()), encoding="utf-8"
    )
    bag = write_cdpr_bag(csv_run, tmp_path / "run", len(csv_run.t), StoragePlugin.SQLITE3)
    lines = (cdpr_csv / "run.csv").read_text(encoding="utf-8").splitlines()
    keep = 25  # t and the 24 drum columns (no poses: the force check)
    (tmp_path / "run.csv").write_text(
        "\n".join(",".join(r.split(",")[:keep]) for r in lines) + "\n", encoding="utf-8"
    )
    reports = {}
    for kind, path in (("csv", tmp_path / "run.csv"), ("bag", bag)):
        out = tmp_path / f"out_{kind}"
        args = ["cdpr", "diagnose", "--run", str(path), "--robot", str(tmp_path / "mini.toml")]
        assert main([*args, "--out", str(out), "--quiet", "--no-plots"]) == 0
        reports[kind] = (out / "diagnose.md").read_text(encoding="utf-8")

    def body(r: str) -> str:
        keep = [x for x in r.splitlines() if not x.startswith(("run.csv,", "run,", "Note: run:"))]
        return re.sub(r"\n{2,}", "\n\n", "\n".join(keep))

    strip = [body(reports["csv"]), body(reports["bag"])]
    assert strip[0] == strip[1]
    assert "sensor_gain" in reports["csv"] or "calibration" in reports["csv"]


def test_bad_cdpr_topics_are_data_errors_naming_the_key(cdpr_csv, tmp_path):
    from cablekit.cdpr import Robot
    from cablekit.cdpr.formats import bag_topics, load_cdpr_run

    robot = Robot.load(cdpr_csv / "mini.toml")
    with pytest.raises(ck.DataError, match=r"unknown key\(s\) \['alpha_9', 'theta'\]"):
        bag_topics({"alpha_9": "/a:b", "theta": "/a:c"}, robot)
    with pytest.raises(ck.DataError, match=r"topics\.sensor: 8 fields \(one per cable\), got 2"):
        bag_topics({"sensor": ["/a:b", "/a:c"]}, robot)
    with pytest.raises(ck.DataError, match=r"topics\.alpha: an array field without an index"):
        bag_topics({"alpha": "/winches:position[0]"}, robot)
    with pytest.raises(ck.DataError, match=r"topics\.x: .*not a bag field"):
        bag_topics({"x": "tracker.x"}, robot)
    with pytest.raises(ck.DataError, match=r"topics\.current\[1\]: a bag field"):
        bag_topics({"current": ["/a:b", 3, *["/a:b"] * 6]}, robot)
    run = load_cdpr_run(cdpr_csv / "run.csv", robot)
    bag = write_cdpr_bag(run, tmp_path / "bag", 200)
    with pytest.raises(ck.DataError, match=r"needs a \[topics\] table"):
        load_cdpr_run(bag, robot)
    with pytest.raises(ck.DataError, match=r"missing column\(s\) \['current_1'"):
        load_cdpr_run(bag, robot, topics={"alpha": "/winches:position", "sensor": "/load_cells:data"})
    with pytest.raises(ck.DataError, match=r"/winches:effort\[8\].*out of range"):
        load_cdpr_run(bag, robot, topics={**CDPR_TOPICS, "current_1": "/winches:effort[8]"})


@settings(max_examples=150, deadline=None)
@given(
    table=st.dictionaries(
        st.sampled_from(
            ["alpha", "current", "sensor", "alpha_1", "sensor_8", "x", "yaw", "theta", "", "alpha_0"]
        ),
        st.one_of(
            st.text(max_size=12),
            st.sampled_from(["/a:b", "/a:b[1]", "/a:b.c", "/a", ":b"]),
            st.lists(st.sampled_from(["/a:b", "/c:d[2]", 1.5]), max_size=9),
            st.sampled_from([None, 3, 1e308, float("nan"), {"a": 1}]),
        ),
        max_size=6,
    )
)
def test_bag_topics_answers_any_table_with_fields_or_a_data_error(table):
    from cablekit.cdpr import shipped
    from cablekit.cdpr.formats import bag_topics

    try:
        out = bag_topics(table, shipped("seed002_mini"))
    except ck.DataError:
        return
    for col, field in out.items():
        assert isinstance(col, str) and parse_field(field)[0].startswith("/")


# -- the estimators' inputs (``read_signals``)


def test_an_estimator_reads_its_arrays_from_a_bag(tmp_path):
    """Raven-II's motor angles and torques recorded as JointState (header stamps with a 30 µs
    jitter): ``read_signals`` gives the arrays on the clock's grid, and the sr-UKF's joint states
    from them equal those from the arrays themselves."""
    from cablekit.bags import read_signals
    from cablekit.estimate import estimate_joint_states
    from cablekit.twins import raven_joint_state_experiment

    run = raven_joint_state_experiment("A", seconds=1.5, seed=1)
    rows = 1500
    q_m, tau_m = run.q_m[:rows], run.tau_m[:rows]
    n = q_m.shape[1]
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    jitter = np.random.default_rng(0).uniform(-3e-5, 3e-5, rows)
    t0 = 1_700_000_000_000_000_000
    with Writer(tmp_path / "bag", version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection("/motors", "sensor_msgs/msg/JointState", typestore=ts)
        for k in range(rows):
            ns = t0 + round((k * run.dt + jitter[k]) * 1e9)
            msg = T["sensor_msgs/msg/JointState"](
                header=T["std_msgs/msg/Header"](
                    stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9), frame_id="m"
                ),
                name=[f"m{i}" for i in range(n)],
                position=q_m[k].copy(),
                velocity=np.zeros(0),
                effort=tau_m[k].copy(),
            )
            w.write(conn, ns, ts.serialize_cdr(msg, msg.__msgtype__))
    sig = read_signals(
        tmp_path / "bag",
        {
            "q_m": [f"/motors:position[{i}]" for i in range(n)],
            "tau_m": [f"/motors:effort[{i}]" for i in range(n)],
            "shoulder": "/motors:position[0]",
        },
    )
    # (the period is the jittered stamps' fitted clock)
    assert sig.dt == pytest.approx(run.dt, rel=1e-5)
    np.testing.assert_array_equal(sig["q_m"], q_m)
    np.testing.assert_array_equal(sig["tau_m"], tau_m)
    np.testing.assert_array_equal(sig["shoulder"], q_m[:, 0])
    assert any("jitter" in n for n in sig.notes), sig.notes
    est = estimate_joint_states(run.nominal, sig["q_m"], sig["tau_m"], sig.dt, encoder_noise=1e-4)
    ref = estimate_joint_states(run.nominal, q_m, tau_m, sig.dt, encoder_noise=1e-4)
    np.testing.assert_array_equal(est.q_l, ref.q_l)
    assert np.abs(est.q_l - run.q_l_true[:rows]).max() < 0.05 * np.ptp(run.q_l_true[:rows])
    with pytest.raises(ck.DataError, match="no signal 'x'"):
        sig["x"]
    with pytest.raises(ck.DataError, match="name the signals"):
        read_signals(tmp_path / "bag", {})
    with pytest.raises(ck.DataError, match="non-empty list"):
        read_signals(tmp_path / "bag", {"q": []})
    with pytest.raises(ck.DataError, match=r"no field 'pos'"):
        read_signals(tmp_path / "bag", {"q": "/motors:pos"})
    (tmp_path / "run.csv").write_text("t,q\n0,1\n0.001,2\n", encoding="utf-8")
    with pytest.raises(ck.DataError, match="not a rosbag2 recording"):
        read_signals(tmp_path / "run.csv", {"q": "/motors:position[0]"})


@settings(max_examples=100, deadline=None)
@given(
    signals=st.one_of(
        st.dictionaries(
            st.text(max_size=5),
            st.one_of(
                st.text(max_size=10), st.lists(st.text(max_size=10), max_size=3), st.none(), st.integers()
            ),
            max_size=3,
        ),
        st.none(),
        st.integers(),
    )
)
def test_read_signals_answers_any_mapping_with_a_typed_error(tmp_path_factory, signals):
    from cablekit.bags import read_signals

    folder = tmp_path_factory.mktemp("nobag")
    with pytest.raises(ck.CablekitError):
        read_signals(folder, signals)
