"""Issue #39 §1: cable-network model files. The length map, moment arms, torques and energy
against a NumPy reference computed here from the file's routing; the shipped joint and Raven-II
networks simulate as the built-in models; bad networks are typed errors naming the element."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import cablekit as ck
from cablekit import network
from cablekit.errors import (
    CablekitError,
    DataError,
    NetworkError,
    NonFiniteResultError,
    NotFiniteError,
    ShapeError,
)

# ---- a NumPy reference from the file's own routing -------------------------------------------------


def _reference(doc: dict) -> dict:
    """J, the motors' ρ and the cables' laws, read from the document by the rules of
    docs/models.md, independently of the core."""
    joints = [j["name"] for j in doc["joints"]]
    pulleys = {p["name"]: p for p in doc["pulleys"]}
    motors = [m["name"] for m in doc.get("motors", [])]
    arms = np.zeros((len(doc["cables"]), len(joints)))
    for c, cable in enumerate(doc["cables"]):
        for k in cable["routing"]:
            p = pulleys[k["pulley"]]
            if "joint" in p:
                arms[c, joints.index(p["joint"])] += k.get("sense", 1) * p["radius"]
    rho = {m["name"]: m["capstan_radius"] / m.get("gear_ratio", 1.0) for m in doc.get("motors", [])}
    return {"joints": joints, "motors": motors, "arms": arms, "rho": rho}


def _elongations(doc: dict, ref: dict, q: np.ndarray, qm: dict[str, float]) -> np.ndarray:
    e = -ref["arms"] @ q
    for c, cable in enumerate(doc["cables"]):
        if "motor" in cable:
            e[c] += cable.get("motor_sense", 1) * ref["rho"][cable["motor"]] * qm[cable["motor"]]
    return e


def _law_energy(cable: dict, s: float) -> float:
    k = cable["stiffness"]
    if cable.get("law", "linear") == "linear":
        return 0.5 * k * s * s
    ell = cable.get("length_scale", 1.0)
    return k * ell * (ell * math.expm1(s / ell) - s)


def _energy(doc: dict, ref: dict, x: np.ndarray, u: np.ndarray) -> float:
    n = len(ref["joints"])
    q, dq = x[0 : 2 * n : 2], x[1 : 2 * n : 2]
    inertia = {b["name"]: b["inertia"] for b in doc["bodies"]}
    e = sum(0.5 * inertia[j["child"]] * v * v for j, v in zip(doc["joints"], dq, strict=True))
    qm, slot_x, slot_u = {}, 2 * n, 0
    for m in doc["motors"]:
        if m["drive"] == "torque":
            qm[m["name"]] = x[slot_x]
            e += 0.5 * m["inertia"] * x[slot_x + 1] ** 2
            slot_x += 2
        else:
            qm[m["name"]] = u[slot_u]
            slot_u += 2
    for cable, s in zip(doc["cables"], _elongations(doc, ref, q, qm), strict=True):
        e += cable.get("pretension", 0.0) * s + _law_energy(cable, s)
    return e


@pytest.fixture(scope="module", params=["antagonistic_joint", "raven2", "tendon_finger", "two_stage_forceps"])
def shipped(request):
    return request.param, network.shipped(request.param), network.shipped_document(request.param)


def test_shipped_networks_are_listed_and_cite_their_source():
    assert network.shipped_names() == ["antagonistic_joint", "raven2", "tendon_finger", "two_stage_forceps"]
    for name in network.shipped_names():
        doc = network.shipped_document(name)
        assert doc["name"] == name and len(doc["reference"]) > 20 and doc["description"]


def test_length_map_moment_arms_torques_and_energy_match_the_reference(shipped):
    _, net, doc = shipped
    ref = _reference(doc)
    np.testing.assert_array_equal(net.moment_arms, ref["arms"])
    assert net.joint_names == ref["joints"] and net.motor_names == ref["motors"]
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = rng.uniform(-0.3, 0.3, len(ref["joints"]))
        np.testing.assert_allclose(net.length_change(q), -ref["arms"] @ q, rtol=1e-14, atol=1e-18)
        t = rng.uniform(0.0, 20.0, len(doc["cables"]))
        np.testing.assert_allclose(net.joint_torques(t), ref["arms"].T @ t, rtol=1e-13, atol=1e-16)
        x = rng.uniform(-1e-3, 1e-3, net.n_states)
        u = rng.uniform(-1e-3, 1e-3, net.n_inputs)
        assert net.energy(x, u) == pytest.approx(_energy(doc, ref, x, u), rel=1e-10, abs=1e-15)
    # the sensors read the outputs they name
    names = net.output_names
    for sensor in doc.get("sensors", []):
        (index,) = [i for s, i in net.sensors if s == sensor["name"]]
        tension = "T:" if sensor.get("at") == "joint" else "T_motor:"
        prefix = {"encoder": ("q:", "q_m:"), "tension": (tension,)}
        prefix |= {"joint_torque": ("tau:",), "motor_current": ("load_m:",)}
        assert names[index].split(":")[1] == sensor["target"]
        assert names[index].startswith(prefix[sensor["kind"]])


def test_the_finger_has_more_tendons_than_joints_and_can_be_pretensioned():
    net = network.shipped("tendon_finger")
    arms = net.moment_arms
    m, n = arms.shape
    assert m == n + 1
    # tendon controllability: the null space of the structure matrix J^T has a strictly positive
    # vector (every tendon taut with zero joint torque)
    _, s, vt = np.linalg.svd(arms.T)
    assert s.min() > 1e-6 * s.max() and len(s) == n
    null = vt[-1] * np.sign(vt[-1][0])
    assert np.all(null > 0), null
    np.testing.assert_allclose(arms.T @ null, 0.0, atol=1e-15)


def _inputs(t: np.ndarray, *cols: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(np.column_stack(cols))


def test_the_shipped_joint_simulates_as_the_built_in_joint():
    params = ck.AntagonisticJoint.forceps_example().params()
    params = {k: v for k, v in params.items() if not k.startswith("contact")}
    joint = ck.AntagonisticJoint(**params)
    net = network.shipped("antagonistic_joint")
    t = np.arange(0.0, 1.5, 1e-3)
    x, v = 2e-3 * np.sin(7 * t) + 5e-4 * np.sin(31 * t), 14e-3 * np.cos(7 * t) + 15.5e-3 * np.cos(31 * t)
    a = ck.simulate(joint, _inputs(t, x, v), 1e-3, substeps=8, hold="foh")
    b = ck.simulate(net, _inputs(t, x, v, 0 * t), 1e-3, substeps=8, hold="foh")
    # the same equations summed in another order: rounding, amplified near the reversals by the
    # sharp friction (1e-12 away from them), stays within 1e-9 of each signal's range
    for k in range(2):
        ref = a.states[:, k]
        np.testing.assert_allclose(b.states[:, k], ref, rtol=0, atol=1e-9 * np.abs(ref).max())
    ya, yb = a.outputs, b.outputs
    # joint [T_m1, T_m2, T_j1, T_j2, θ, F_c]; network [q, q_m, T1, T2, T_m1, T_m2, τ, load]
    for ia, ib in ((0, 4), (1, 5), (2, 2), (3, 3), (4, 0)):
        np.testing.assert_allclose(yb[:, ib], ya[:, ia], rtol=0, atol=1e-9 * np.abs(ya[:, ia]).max())


def test_the_shipped_raven_simulates_as_the_built_in_transmission():
    tx = ck.CableTransmission.raven2(3)
    net = network.shipped("raven2")
    same = ck.CableNetwork.from_transmission(tx)
    np.testing.assert_array_equal(net.moment_arms, same.moment_arms)
    t = np.arange(0.0, 0.8, 1e-3)
    zero = 0 * t
    u = _inputs(t, 0.3 * np.sin(5 * t), -0.2 * np.sin(3 * t), 0.25 * np.cos(4 * t), zero, 0.05 + zero, zero)
    a = ck.simulate(tx, u, 1e-3, substeps=10)
    b = ck.simulate(net, u, 1e-3, substeps=10)
    for i in range(3):  # transmission [q_m, q̇_m, q_l, q̇_l] per link; network joints, then motors
        pairs = ((4 * i, 6 + 2 * i), (4 * i + 1, 7 + 2 * i), (4 * i + 2, 2 * i), (4 * i + 3, 2 * i + 1))
        for sa, sb in pairs:
            ref = a.states[:, sa]
            np.testing.assert_allclose(b.states[:, sb], ref, rtol=1e-9, atol=1e-9 * np.abs(ref).max())


def test_the_two_stage_forceps_moves_the_jaw_through_the_spindle():
    net = network.shipped("two_stage_forceps")
    t = np.arange(0.0, 2.0, 1e-3)
    angle = 0.4 * np.sin(2 * np.pi * 0.5 * t)
    rate = 0.4 * 2 * np.pi * 0.5 * np.cos(2 * np.pi * 0.5 * t)
    res = ck.simulate(net, _inputs(t, angle, rate, 0 * t, 0 * t), 1e-3, substeps=4, hold="foh")
    y = dict(zip(net.output_names, res.outputs.T, strict=True))
    # two stages: spindle follows the motor (ratio 1), the jaw the spindle (ratio 4 / 2.5)
    steady = t > 0.5
    assert np.corrcoef(y["q:spindle"][steady], angle[steady])[0, 1] > 0.99
    gain = np.polyfit(y["q:spindle"][steady], y["q:jaw"][steady], 1)[0]
    assert gain == pytest.approx(4.0 / 2.5, rel=0.1)
    # the wrist's capstan friction (mu·phi = 0.2): the spindle-side tension is the jaw-side one
    # times exp(±0.2) as the cable is hauled or paid out — both directions occur
    ratio = y["T_motor:jaw_drive"] / y["T:jaw_drive"]
    assert np.all(y["T:jaw_drive"] > 0)
    assert ratio.max() <= math.exp(0.2) + 1e-12 and ratio.min() >= math.exp(-0.2) - 1e-12
    assert ratio.max() > math.exp(0.15) and ratio.min() < math.exp(-0.15)
    # and the friction acts in the dynamics: the spindle, which hauls the jaw cables through the
    # wrist, feels their spindle-side tensions on its capstan (radius 4 mm, sense -1), the jaw
    # their jaw-side ones (docs/models.md)
    arms = net.moment_arms
    cables = ["coupling_a", "coupling_b", "jaw_drive", "jaw_return"]
    tau = sum(arms[c, 0] * y[f"T:{name}"] for c, name in enumerate(cables))
    sense = {"jaw_drive": -1.0, "jaw_return": 1.0}
    tau += sum(sense[n] * 4e-3 * (y[f"T_motor:{n}"] - y[f"T:{n}"]) for n in sense)
    np.testing.assert_allclose(y["tau:spindle"], tau, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(
        y["tau:jaw"], sum(arms[c, 1] * y[f"T:{n}"] for c, n in enumerate(cables)), atol=1e-12
    )


# ---- bad networks -------------------------------------------------------------------------------


def _bad(doc: dict) -> NetworkError:
    with pytest.raises(NetworkError) as e:
        network.from_dict(doc)
    return e.value


def test_bad_networks_are_typed_errors_naming_the_element():
    doc = network.shipped_document("tendon_finger")
    d = copy.deepcopy(doc)
    d["cables"][1]["routing"] = []
    assert _bad(d).element == 'cable "t2"'
    d = copy.deepcopy(doc)
    d["cables"][2]["routing"][1]["wrap"] = -0.5
    assert _bad(d).element.startswith('cable "t3".routing[1]')
    d = copy.deepcopy(doc)
    d["bodies"].append({"name": "loose", "inertia": 1e-6})
    err = _bad(d)
    assert err.element == 'body "loose"' and "disconnected" in str(err)
    d = copy.deepcopy(doc)  # every tendon turns MCP and PIP alike: a singular coupling
    for p in d["pulleys"]:
        if p["name"] in ("mcp_flexor", "mcp", "pip"):
            p["radius"] = 4e-3
    for c in d["cables"]:
        c["routing"][2]["sense"] = c["routing"][1].get("sense", 1)
    err = _bad(d)
    assert err.element.startswith("joint") and "singular" in str(err)
    d = copy.deepcopy(doc)
    d["cables"][0]["colour"] = "red"
    err = _bad(d)
    assert err.element == 'cable "t1"' and "colour" in str(err)
    d = copy.deepcopy(doc)
    d["cables"][0]["routing"][0]["pulley"] = "nowhere"
    assert "nowhere" in str(_bad(d))
    d = copy.deepcopy(doc)
    d["joints"][2]["child"] = "proximal"
    assert "two joints" in str(_bad(d))
    d = copy.deepcopy(doc)
    d["cables"][0]["stiffness"] = float("nan")
    with pytest.raises(DataError, match="stiffness"):
        network.from_dict(d)
    d = copy.deepcopy(doc)
    d["cables"][0]["stiffness"] = -1.0
    with pytest.raises(ck.ParameterError):
        network.from_dict(d)
    with pytest.raises(DataError, match="not valid TOML"):
        network.from_toml("[[cables]\nname=", "x.toml")


def test_the_network_methods_check_their_arguments():
    net = network.shipped("raven2")
    with pytest.raises(ShapeError):
        net.length_change(np.zeros(2))
    with pytest.raises(NotFiniteError):
        net.length_change(np.array([0.0, np.nan, 0.0]))
    with pytest.raises(ShapeError):
        net.joint_torques(np.zeros(5))
    with pytest.raises(NotFiniteError):
        net.energy(np.full(12, np.inf), np.zeros(6))


_ODD = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(10**30), 10**30),
    st.text(max_size=5),
    st.none(),
    st.lists(st.integers(), max_size=3),
    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2),
    st.booleans(),
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    section=st.sampled_from(["bodies", "joints", "pulleys", "cables", "motors", "sensors"]),
    key=st.sampled_from(
        [
            "name",
            "inertia",
            "radius",
            "stiffness",
            "routing",
            "motor",
            "kind",
            "wrap",
            "x",
            "end_motor",
            "end_sense",
            "free_length",
            "at",
        ]
    ),
    value=_ODD,
)
def test_any_odd_value_in_a_file_is_a_typed_error_or_a_valid_network(section, key, value):
    doc = copy.deepcopy(network.shipped_document("two_stage_forceps"))
    doc[section][0][key] = value
    try:
        net = network.from_dict(doc)
    except (CablekitError, TypeError) as exc:
        assert isinstance(exc, CablekitError), exc  # a typed error, never a bare TypeError
        return
    # accepted: a valid mechanism whose kinematics are finite
    assert np.all(np.isfinite(net.moment_arms))
    assert np.all(np.isfinite(net.length_change(np.full(len(net.joint_names), 0.1))))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=0, max_size=5))
def test_length_change_takes_any_vector_with_a_typed_error_or_a_finite_answer(q):
    net = network.shipped("tendon_finger")
    arr = np.asarray(q, dtype=np.float64)
    try:
        out = net.length_change(arr)
    except (ShapeError, NotFiniteError):
        assert arr.size != 3 or not np.all(np.isfinite(arr))
        return
    except NonFiniteResultError:
        assert arr.size == 3 and np.abs(arr).max() > 1e300  # finite, but J·q overflows
        return
    assert arr.size == 3 and np.all(np.isfinite(out))


def test_step_advice_on_the_shipped_networks_equals_the_built_in_models():
    params = {k: v for k, v in ck.AntagonisticJoint.forceps_example().params().items() if "contact" not in k}
    pairs = (
        (ck.AntagonisticJoint(**params), network.shipped("antagonistic_joint"), np.zeros(2), np.zeros(3)),
        (ck.CableTransmission.raven2(3), network.shipped("raven2"), np.zeros(6), np.zeros(6)),
    )
    for built_in, net, u_a, u_b in pairs:
        a = ck.propose_step(built_in, 1e-3, u=u_a)
        b = ck.propose_step(net, 1e-3, u=u_b)
        assert b.substeps == a.substeps
        assert b.max_stable_step == pytest.approx(a.max_stable_step, rel=1e-6)
        assert abs(b.stiffest_eigenvalue) == pytest.approx(abs(a.stiffest_eigenvalue), rel=1e-6)


# ---- tension closure and the command ------------------------------------------------------------


def test_tension_closure_matches_the_null_vector_of_the_structure_matrix():
    finger = network.shipped("tendon_finger")
    share, t = finger.tension_closure()
    # n + 1 tendons: the torque-free tensions are the one null vector of Jᵀ, scaled to sum 1
    null = np.linalg.svd(finger.moment_arms.T)[2][-1]
    null = null / null.sum()
    np.testing.assert_allclose(t, null, atol=1e-6)
    assert share == pytest.approx(null.min(), abs=1e-6) and share > 0.05
    # antagonistic pairs: every cable an equal share
    for name, m in (("antagonistic_joint", 2), ("raven2", 6)):
        share, t = network.shipped(name).tension_closure()
        assert share == pytest.approx(1.0 / m, abs=1e-6)
        np.testing.assert_allclose(t, 1.0 / m, atol=1e-6)
    # one-sided routing: no closure
    doc = copy.deepcopy(network.shipped_document("tendon_finger"))
    for c in doc["cables"]:
        c["routing"][1]["sense"] = 1
    share, t = network.from_dict(doc).tension_closure()
    assert share < -1e-3 and t.min() < 0  # torque-free only with a cable pushing
    np.testing.assert_allclose(network.from_dict(doc).joint_torques(t), 0.0, atol=1e-9)


def test_the_network_command_lists_checks_and_refuses(tmp_path, capsys):
    from cablekit.cli import main

    assert main(["network", "list"]) == 0
    out = capsys.readouterr().out
    assert all(name in out for name in network.shipped_names())
    assert main(["network", "check", "tendon_finger", "--json", str(tmp_path / "d.json")]) == 0
    out = capsys.readouterr().out
    assert "tension closure: yes" in out and "condition number" in out
    # the pull of every cable on every joint it passes, signed as the moment arms
    pulls = {
        line.split()[0]: line.split()[1:] for line in out.split("its tension turns")[1].splitlines()[1:5]
    }
    arms = network.shipped("tendon_finger").moment_arms
    for c, name in enumerate(network.shipped("tendon_finger").cable_names):
        signs = [("+" if a > 0 else "-") for a in arms[c] if a]
        assert pulls[name][1::2] == [s + "," for s in signs[:-1]] + [signs[-1]], (name, pulls[name])
    import json as _json

    d = _json.loads((tmp_path / "d.json").read_text())
    assert d["joints"] == ["mcp", "pip", "dip"] and d["tension_closure"]["closed"]
    assert d["sensors"]["q_dip"] == "q:dip"
    text = (network.files_folder() / "two_stage_forceps.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("wrap = 2.0", "wrap = -2.0", 1))
    assert main(["network", "check", str(bad)]) == 4
    err = capsys.readouterr().err
    assert "NetworkError" in err and 'cable "jaw_drive".routing[1]' in err


def test_a_network_files_sensors_drive_the_square_root_ukf():
    """The two-stage forceps without a jaw encoder: the sr-UKF on the network estimates the jaw
    angle from the spindle's angle and torque (the file's other sensors), from a wrong start."""
    doc = copy.deepcopy(network.shipped_document("two_stage_forceps"))
    for j in doc["joints"]:
        j["coulomb"] = 0.0  # a smooth plant: the filter's RK4 needs no friction substeps
    net = network.from_dict(doc)
    dt, n_steps = 1e-3, 1500
    t = np.arange(n_steps) * dt
    angle = 0.3 * np.sin(2 * np.pi * 1.3 * t) + 0.1 * np.sin(2 * np.pi * 3.1 * t)
    rate = 0.3 * 2 * np.pi * 1.3 * np.cos(2 * np.pi * 1.3 * t) + 0.1 * 2 * np.pi * 3.1 * np.cos(
        2 * np.pi * 3.1 * t
    )
    u = _inputs(t, angle, rate, 0 * t, 0 * t)
    advice = ck.propose_step(net, dt)
    truth = ck.simulate(net, u, dt, substeps=advice.substeps)
    sensors = dict(net.sensors)
    used = [sensors["spindle_angle"], sensors["spindle_torque"]]
    noise = np.array([2e-4, 2e-3])  # rad, N·m
    rng = np.random.default_rng(5)
    y = truth.outputs[:, used] + noise * rng.standard_normal((n_steps, 2))
    x0 = np.array([0.0, 0.0, 0.2, 0.0])  # the jaw 0.2 rad off
    f = ck.SrUkf(
        net,
        x0,
        np.diag([1e-4, 1e-2, 0.1, 1.0]),
        np.diag([1e-10, 1e-6, 1e-10, 1e-6]),
        np.diag(noise**2),
        dt=dt,
        substeps=advice.substeps,
        outputs=used,
    )
    run = f.run(np.ascontiguousarray(u[:-1]), np.ascontiguousarray(y[1:]))
    jaw = truth.states[1:, 2]
    err = run.x[:, 2] - jaw
    late = slice(300, None)
    assert abs(x0[2] - truth.states[0, 2]) > 0.19  # it started 0.2 rad off, and the first
    assert abs(err[0]) < 0.05  # spindle torque pulls it in: the jaw cables' stretch shows there
    rmse = np.sqrt(np.mean(err[late] ** 2))
    # better than the kinematic estimate (the spindle encoder times the pulley ratio), which its
    # noise limits: the filter also reads the torque the jaw cables put on the spindle
    kinematic = y[1:, 0] * 4.0 / 2.5 - jaw
    assert rmse < 0.2 * np.sqrt(np.mean(kinematic[late] ** 2)) and rmse < 1e-3 * np.ptp(jaw), rmse


# ---- drives without joints: a winch to a moving end (a parallel robot's cable, #39) -------------


def _winch_doc() -> dict:
    return {
        "name": "winch",
        "capstan_smoothing": 1e-6,
        "pulleys": [{"name": "u", "radius": 0.01}, {"name": "d", "radius": 0.01}],
        "motors": [
            {"name": "drum", "drive": "torque", "inertia": 1e-4, "capstan_radius": 0.02},
            {"name": "end", "drive": "position", "capstan_radius": 1.0},
        ],
        "cables": [
            {
                "name": "c",
                "motor": "drum",
                "end_motor": "end",
                "free_length": 0.8,
                "stiffness": 2.5e4,
                "pretension": 20.0,
                "routing": [
                    {"pulley": "u", "wrap": 1.5, "mu": 0.1},
                    {"pulley": "d", "wrap": 1.0, "mu": 0.05},
                ],
            }
        ],
        "sensors": [
            {"name": "angle", "kind": "encoder", "target": "drum"},
            {"name": "cell", "kind": "tension", "target": "c", "at": "u"},
        ],
    }


@settings(max_examples=60, deadline=None)
@given(
    alpha=st.floats(-5.0, 15.0),
    rate=st.floats(-2.0, 2.0).filter(lambda v: abs(v) > 1e-3),
    end=st.floats(-2e-3, 2e-3),
)
def test_a_winch_to_a_moving_end_matches_the_rod_and_capstan_reference(alpha, rate, end):
    """A network of drives alone: the winch's cable, its free length shortened by what the drum
    winds (ρ·α), stretched by the drum and the end; its tension a rod's ``E·A·(l − L)/L`` (from
    the file's stiffness and pretension at the free length), the drum side through both
    contacts' capstan, the cell between them through the far one only (NumPy reference)."""
    net = network.from_dict(_winch_doc())
    assert net.joint_names == [] and net.n_states == 2 and net.n_inputs == 3
    names = list(net.output_names)
    y = ck.simulate(net, np.array([[end, 0.0, 0.0], [end, 0.0, 0.0]]), 1e-4, np.array([alpha, rate])).outputs[
        0
    ]
    rho, length, k, t0 = 0.02, 0.8, 2.5e4, 20.0
    free = max(length - rho * alpha, 0.01 * length)
    t = max(0.0, (t0 + k * (rho * alpha + end)) * length / free)
    haul = rho * rate
    sign = haul / math.hypot(haul, 1e-6)  # the file's capstan smoothing
    assert y[names.index("T:c")] == pytest.approx(t, rel=1e-9, abs=1e-9)
    assert y[names.index("T_motor:c")] == pytest.approx(t * math.exp(sign * (0.1 * 1.5 + 0.05)), rel=1e-9)
    assert y[names.index("T@u:c")] == pytest.approx(t * math.exp(sign * 0.05), rel=1e-9)
    assert dict(net.sensors)["cell"] == names.index("T@u:c")
    assert y[names.index("load_m:drum")] == pytest.approx(rho * y[names.index("T_motor:c")], rel=1e-12)


@pytest.mark.parametrize(
    ("key", "value", "says"),
    [
        ("end_motor", "drum", "already hauls"),
        ("end_motor", "ghost", "ghost"),
        ("end_sense", 0.5, "end_sense"),
        ("free_length", 0.0, "free_length"),
        ("free_length", "long", "free_length"),
    ],
)
def test_a_winch_files_new_keys_are_checked(key, value, says):
    doc = _winch_doc()
    doc["cables"][0][key] = value
    with pytest.raises(CablekitError, match=says):
        network.from_dict(doc)
    doc = _winch_doc()
    doc["sensors"][1]["at"] = "nowhere"
    with pytest.raises(NetworkError, match="nowhere"):
        network.from_dict(doc)
