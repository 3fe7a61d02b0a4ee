"""Physics tests of the independent cable-network simulator (``netsim_independent``).

The module is loaded from its file so that nothing else of the package is imported."""

from __future__ import annotations

import ast
import copy
import importlib.util
import math
import re
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

MODULE_PATH = (
    Path(__file__).resolve().parents[1] / "python" / "cablekit" / "diagnose" / "netsim_independent.py"
)


def _load():
    name = "netsim_independent_under_test"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, MODULE_PATH)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


ns = _load()


@pytest.fixture(scope="module")
def all_cases():
    return ns.cases(seed=0)


@pytest.fixture(scope="module")
def hold_deviations(all_cases):
    return ns.deviations(all_cases, "hold")


def _batch(net, effect=None, b=1):
    return ns.stack_params([ns.member_params(net, effect)] * b)


def _zero_input(b, m):
    def pm_input(t):
        return np.zeros((b, m)), np.zeros((b, m))

    return pm_input


def _lossless(spec):
    spec = copy.deepcopy(spec)
    for j in spec["joints"]:
        j["coulomb"] = j["viscous"] = 0.0
    for m in spec["motors"]:
        m["coulomb"] = m["viscous"] = 0.0
    for c in spec["cables"]:
        c["damping"] = 0.0
        for ct in c["routing"]:
            ct["mu"] = 0.0
    return spec


# ------------------------------------------------------------------------------------------
# independence and file format
# ------------------------------------------------------------------------------------------


def test_module_imports_only_stdlib_numpy_scipy():
    tree = ast.parse(MODULE_PATH.read_text())
    roots = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            roots |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, "no relative imports"
            roots.add(node.module.split(".")[0])
    assert "cablekit" not in roots
    assert re.search(r"^\s*(from|import)\s+cablekit", MODULE_PATH.read_text(), re.MULTILINE) is None
    allowed = {"__future__", "json", "math", "time", "tomllib", "zlib", "dataclasses", "numpy", "scipy"}
    assert roots <= allowed, roots - allowed


def _check_names(case):
    spec = tomllib.loads(case.network_toml)
    assert spec["name"] == case.plant
    bodies = {b["name"] for b in spec["bodies"]}
    joints = {j["name"] for j in spec["joints"]}
    pulleys = {p["name"] for p in spec["pulleys"]}
    motors = {m["name"]: m for m in spec["motors"]}
    cables = {c["name"]: c for c in spec["cables"]}
    for j in spec["joints"]:
        assert j["child"] in bodies and j["parent"] == "base" and j["kind"] == "revolute"
    for p in spec["pulleys"]:
        assert "joint" not in p or p["joint"] in joints
    for m in motors.values():
        assert m["drive"] in ("torque", "position")
        assert (m["drive"] == "torque") == ("inertia" in m)
    for c in cables.values():
        assert c["routing"], c["name"]
        assert all(ct["pulley"] in pulleys and ct["sense"] in (-1, 1) for ct in c["routing"])
        assert "motor" not in c or c["motor"] in motors
        assert c["law"] == "linear" and c["stiffness"] > 0
    assert set(case.inputs) == set(motors)
    for name in case.outputs:
        kind, _, el = name.partition(":")
        pool = {"q": joints, "q_m": motors, "T": cables, "T_motor": cables, "tau": joints, "load_m": motors}
        assert el in pool[kind], name
    if case.truth_site is not None:
        group, _, el = case.truth_site.partition(".")
        pool = {
            "joint": joints,
            "cable": cables,
            "routing": cables,
            "motor": motors,
            "sensor": set(case.outputs),
            "input": {""},
        }
        assert el in pool[group], case.truth_site
    return spec


def test_cases_are_well_formed(all_cases):
    assert len({c.name for c in all_cases}) == len(all_cases)
    assert {c.plant for c in all_cases} == {"two_stage", "finger", "transmission2"}
    effects = {c.truth_effect for c in all_cases} - {None}
    assert effects == set(ns.LIBRARY_EFFECTS) | set(ns.OUTSIDE_EFFECTS)
    for case in all_cases:
        spec = _check_names(case)
        assert ns.to_toml(spec) == case.network_toml  # the TOML is a faithful round trip
        assert case.in_library == (case.truth_effect not in ns.OUTSIDE_EFFECTS)
        assert (case.truth_effect is None) == (case.truth_site is None)
        assert 1 <= len(case.fit_runs) <= 2 and len(case.hold_runs) == 1
        columns = {"t", *case.inputs.values(), *case.outputs.values()}
        for _, dt, cols in case.fit_runs + case.hold_runs:
            assert dt == 1e-3 and set(cols) == columns
            n = len(cols["t"])
            assert 2000 <= n <= 4000 and np.allclose(np.diff(cols["t"]), dt)
            assert all(len(v) == n and np.all(np.isfinite(v)) for v in cols.values())
        # the held-out trajectory differs from the fit ones
        hold_in = case.hold_runs[0][2]
        for _, _, cols in case.fit_runs:
            col = next(iter(case.inputs.values()))
            assert np.max(np.abs(cols[col] - hold_in[col])) > 1e-3


def test_quick_subset(all_cases):
    quick = ns.cases(seed=0, quick=True)
    assert 6 <= len(quick) <= 10
    assert {c.plant for c in quick} == {"two_stage", "finger", "transmission2"}
    sites = {c.truth_site.partition(".")[0] for c in quick if c.truth_site}
    assert {"joint", "cable", "routing", "motor", "sensor"} <= sites
    assert any(not c.in_library for c in quick) and any(c.truth_effect is None for c in quick)
    full = {c.name: c for c in all_cases}
    for c in quick:  # same data as in the full set (noise is keyed by case name)
        ref = full[c.name]
        for (_, _, a), (_, _, b) in zip(c.fit_runs + c.hold_runs, ref.fit_runs + ref.hold_runs, strict=True):
            for col in a:
                np.testing.assert_allclose(a[col], b[col], rtol=0, atol=1e-9)


# ------------------------------------------------------------------------------------------
# physics
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("plant", ["two_stage", "finger", "transmission2"])
def test_static_equilibrium_with_pretension(plant):
    setup = ns.SETUPS[plant]()
    net = ns.compile_network(setup.spec)
    P = _batch(net)
    kw = {}
    if net.pmotors:
        kw["pm_input"] = _zero_input(1, len(net.pmotors))
    else:
        nj = net.nj
        kw["pd"] = ns.make_pd(net, setup, np.zeros((1, nj, 2)), np.ones((1, nj, 2)))
    sim = ns.simulate(net, P, 400, **kw)
    assert np.max(np.abs(sim["x"])) < 1e-9
    np.testing.assert_allclose(sim["T"][0], np.broadcast_to(net.pretension, sim["T"][0].shape), atol=1e-6)
    if net.tmotors:  # the held torques balance the pretension exactly
        np.testing.assert_allclose(net.D[:, : net.nj].T @ net.pretension, 0.0, atol=1e-12)


def test_slack_cable_under_a_torque_motor_keeps_the_held_tension():
    """A torque-driven motor holds the tension it is asked for: a longer (slack) tendon starts
    at rest with the held tension and a stretch of (T_held - T0_true) / k."""
    setup = ns.SETUPS["finger"]()
    net = ns.compile_network(setup.spec)
    P = _batch(net, ns.Effect("slack", "cable.t3", {"pretension": 3.0}))
    hold = net.pretension * 0.005  # motor torques R * T0 (gear ratio 1, motor_sense +1)
    sim = ns.simulate(net, P, 200, replay=np.broadcast_to(hold, (1, 200, 4)))
    np.testing.assert_allclose(sim["T"][0], np.broadcast_to(net.pretension, (200, 4)), atol=1e-6)
    np.testing.assert_allclose(sim["x"][0] - sim["x"][0, 0], 0.0, atol=1e-9)
    stretch = sim["x"][0, 0] @ net.D.T
    np.testing.assert_allclose(stretch, [0.0, 0.0, 7.0 / 2e4, 0.0], atol=1e-12)


@pytest.mark.parametrize("plant", ["two_stage", "transmission2"])
def test_energy_conserved_without_losses(plant):
    spec = _lossless(ns.SETUPS[plant]().spec)
    net = ns.compile_network(spec)
    P = _batch(net)
    x0 = np.zeros((1, net.ncoord))
    v0 = np.zeros((1, net.ncoord))
    v0[0, : net.nd] = [3.0, -2.0] if net.nd == 2 else [0.3, -0.2, 5.0, -5.0]
    kw = {"pm_input": _zero_input(1, len(net.pmotors))} if net.pmotors else {}

    def energy_error(n_sub):
        sim = ns.simulate(net, P, 300, n_sub=n_sub, x0=x0, v0=v0, **kw)
        x, v = sim["x"][0], sim["v"][0]
        delta = x @ net.D.T
        assert np.all(sim["T"][0] > 0)  # the cables stay taut, so V = T0 d + k d^2 / 2 holds
        kinetic = 0.5 * (v[:, : net.nd] ** 2 * net.inertia).sum(1)
        potential = (net.pretension * delta + 0.5 * net.stiffness * delta**2).sum(1)
        e = kinetic + potential
        return np.max(np.abs(e - e[0])) / e[0]

    e10, e40 = energy_error(10), energy_error(40)
    assert e10 < 2e-2 and e40 < 1e-3  # (the stiff jaw mode has omega * dt = 0.19 at 10 sub-steps)
    assert e40 < e10 / 8  # second order: 16x smaller for 4x smaller steps


def test_coulomb_friction_stops_exactly_and_sticks():
    spec = {
        "name": "block",
        "description": "",
        "capstan_smoothing": 1e-3,
        "bodies": [{"name": "b", "inertia": 1e-5}],
        "joints": [ns._joint("j", "b", 1e-3, 0.0)],
        "pulleys": [],
        "motors": [],
        "cables": [],
    }
    net = ns.compile_network(spec)
    sim = ns.simulate(net, _batch(net), 50, x0=np.zeros((1, 1)), v0=np.ones((1, 1)))
    a = 1e-3 / 1e-5
    stop_angle = 1.0 / (2 * a)  # v0^2 / (2 a), reached at t = v0 / a = 10 ms
    x = sim["x"][0, :, 0]
    assert abs(x[-1] - stop_angle) < 1e-6
    assert np.all(x[11:] == x[-1])  # stuck right after the stop, no creep
    t = np.arange(10) * 1e-3
    np.testing.assert_allclose(x[:10], t - 0.5 * a * t**2, atol=1e-6)


def _capstan_rig(mu, wrap):
    return {
        "name": "capstan_rig",
        "description": "torque motor -> cable over a fixed rough idler -> joint held by a spring cable",
        "capstan_smoothing": 1e-3,
        "bodies": [{"name": "link", "inertia": 1e-4}],
        "joints": [ns._joint("j", "link", 0.0, 1e-3)],
        "pulleys": [
            {"name": "idler", "radius": 0.005},
            {"name": "drum", "radius": 0.01, "joint": "j"},
            {"name": "drum2", "radius": 0.01, "joint": "j"},
            {"name": "anchor", "radius": 0.005},
        ],
        "motors": [ns._torque_motor("m", 0.005, 1.0, 1e-6, 0.0)],
        "cables": [
            ns._cable(
                "c",
                [ns._contact("idler", wrap, 1, mu), ns._contact("drum", math.pi, -1)],
                1e4,
                5.0,
                10.0,
                motor="m",
            ),
            ns._cable(
                "spring", [ns._contact("drum2", math.pi, 1), ns._contact("anchor", 1.0)], 1e4, 5.0, 10.0
            ),
        ],
    }


def test_capstan_ratio_in_the_dynamics():
    """Motor-side tension from the motor's equation of motion vs joint-side tension: their
    ratio is exp(+mu phi) while hauling in, exp(-mu phi) while paying out, and in between
    while the cable sticks on the idler (the motor then does not move)."""
    mu, wrap = 0.05, math.pi
    net = ns.compile_network(_capstan_rig(mu, wrap))
    n = 3000
    t = np.arange(n) * 1e-3
    torque = 0.005 * (10.0 + 4.0 * np.sin(2 * math.pi * 1.0 * t))
    sim = ns.simulate(net, _batch(net), n, replay=torque[None, :, None])
    im = net.coord("m")
    qm, vm = sim["x"][0, :, im], sim["v"][0, :, im]
    acc = np.gradient(np.gradient(qm, 1e-3), 1e-3)
    t_motor = (torque - 1e-6 * acc) / 0.005  # J qdd = tau - R T_motor
    ratio = t_motor / sim["T"][0, :, 0]
    sliding = np.abs(vm) > 1e-3
    steady = np.convolve(sliding.astype(float), np.ones(21), "same") == 21  # away from transitions
    steady[:50] = False
    bound = math.exp(mu * wrap)
    up, down = steady & (vm > 0), steady & (vm < 0)
    assert up.sum() > 300 and down.sum() > 300
    np.testing.assert_allclose(ratio[up], bound, rtol=5e-3)
    np.testing.assert_allclose(ratio[down], 1 / bound, rtol=5e-3)
    stuck = np.convolve((vm == 0).astype(float), np.ones(5), "same") == 5
    assert stuck.sum() > 100  # a genuine stick phase at each reversal
    assert np.all(ratio[stuck] < bound * 1.005) and np.all(ratio[stuck] > 1 / bound / 1.005)
    both = stuck[:-1] & stuck[1:]
    assert np.all(np.diff(qm)[both] == 0.0)  # the motor does not move while the cable sticks


def test_creep_relaxes_like_a_standard_linear_solid():
    spec = {
        "name": "creep_rig",
        "description": "",
        "capstan_smoothing": 1e-3,
        "bodies": [{"name": "anvil", "inertia": 1e6}],
        "joints": [ns._joint("j", "anvil", 0.0, 0.0)],
        "pulleys": [{"name": "drum", "radius": 0.01, "joint": "j"}],
        "motors": [
            {
                "name": "m",
                "drive": "position",
                "capstan_radius": 0.005,
                "gear_ratio": 1.0,
                "coulomb": 0.0,
                "viscous": 0.0,
                "smoothing": 0.1,
            }
        ],
        "cables": [ns._cable("c", [ns._contact("drum", math.pi, -1)], 1e4, 0.0, 10.0, motor="m")],
    }
    net = ns.compile_network(spec)
    alpha, tau, step, ramp = 0.5, 0.1, 0.02, 0.002

    def pm_input(tt):
        s = np.clip(tt / ramp, 0.0, 1.0)
        q = step * (s - np.sin(2 * math.pi * s) / (2 * math.pi))
        qd = np.where((tt > 0) & (tt < ramp), step * (1 - np.cos(2 * math.pi * s)) / ramp, 0.0)
        return q[:, None], qd[:, None]

    P = _batch(net, ns.Effect("creep", "cable.c", {"alpha": alpha, "tau": tau}))
    sim = ns.simulate(net, P, 500, pm_input=pm_input, x0=np.zeros((1, 2)))
    jump = 1e4 * 0.005 * step  # k * stretch
    t = np.arange(500) * 1e-3
    expected = 10.0 + jump * ((1 - alpha) + alpha * np.exp(-(t - ramp / 2) / tau))
    later = t > 0.01
    np.testing.assert_allclose(sim["T"][0, later, 0], expected[later], rtol=2e-3)


def test_backlash_loses_motion_at_reversals():
    setup = ns.SETUPS["two_stage"]()
    b = 0.01
    effects = [None, ns.Effect("backlash", "motor.drive", {"half_gap": b})]
    runs = setup.runs[:1]
    setup = ns.PlantSetup(**{**setup.__dict__, "runs": runs})
    net, P, sim, _ = ns.run_plant(setup, effects, 2000)
    spindle = net.coord("spindle")
    diff = sim["x"][1, :, spindle] - sim["x"][0, :, spindle]
    vm = sim["qmd_pm"][0, :, 0]
    fwd = np.convolve((vm > 0.3).astype(float), np.ones(51), "same") == 51
    back = np.convolve((vm < -0.3).astype(float), np.ones(51), "same") == 51
    assert fwd.sum() > 100 and back.sum() > 100
    assert -1.1 * b < np.median(diff[fwd]) < -0.8 * b  # the spindle trails by the half gap
    assert 0.8 * b < np.median(diff[back]) < 1.1 * b
    # inside the gap the capstan transmits nothing
    load = ns.channels(net, P, sim, 1, ["load_m:drive"])["load_m:drive"]
    xc = sim["x"][1, :, net.coord("drive")]
    inside = np.abs(xc - sim["qm_pm"][1, :, 0]) < b * (1 - 1e-6)
    assert inside.sum() > 20
    assert np.max(np.abs(load[inside])) < 0.05 * np.max(np.abs(load))


def test_first_order_lag_is_exact_for_a_ramp():
    tau = 0.02
    t = np.arange(200) * 1e-3
    y = ns.first_order_lag(t.copy(), tau)
    np.testing.assert_allclose(y, t - tau * (1 - np.exp(-t / tau)), atol=1e-12)


def test_integrator_converges():
    """The case data are integrated to well below the noise: 4x finer sub-steps change no
    output by more than 0.1 noise standard deviation."""
    for plant in ("two_stage", "transmission2"):
        setup = ns.SETUPS[plant]()
        setup = ns.PlantSetup(**{**setup.__dict__, "runs": setup.runs[2:]})
        net, P, sim, _ = ns.run_plant(setup, [None], 800)
        kw = {"replay": sim["u"]} if net.tmotors else {}
        if net.pmotors:
            amps, omegas = setup.runs[0][1][None], setup.runs[0][2][None]

            def pm_input(t, amps=amps, omegas=omegas):
                return ns.multisine(t, amps, omegas)[:2]

            kw["pm_input"] = pm_input
        coarse = ns.channels(net, P, ns.simulate(net, P, 800, n_sub=10, **kw), 0, setup.outputs)
        fine = ns.channels(net, P, ns.simulate(net, P, 800, n_sub=40, **kw), 0, setup.outputs)
        for name in setup.outputs:
            err = np.sqrt(np.mean((coarse[name] - fine[name]) ** 2))
            assert err < 0.1 * ns.noise_sigma(name, net, fine[name]), (plant, name)


# ------------------------------------------------------------------------------------------
# the cases against the nominal model
# ------------------------------------------------------------------------------------------


def test_control_cases_differ_from_nominal_only_by_noise(all_cases, hold_deviations):
    controls = [i for i, c in enumerate(all_cases) if c.truth_effect is None]
    assert len(controls) == 6
    fit = ns.deviations([all_cases[i] for i in controls], "fit")
    for i, fit_dev in zip(controls, fit, strict=True):
        for dev in (hold_deviations[i], fit_dev):
            for name, d in dev.items():
                assert 0.5 < d < 1.5, (all_cases[i].name, name, d)


def test_effects_are_visible_on_held_out_runs(all_cases, hold_deviations):
    for case, dev in zip(all_cases, hold_deviations, strict=True):
        if case.truth_effect is not None:
            assert max(dev.values()) >= 3.0, (case.name, dev)


def test_sensor_effects_touch_only_their_channel(all_cases, hold_deviations):
    for case, dev in zip(all_cases, hold_deviations, strict=True):
        if case.truth_site and case.truth_site.startswith("sensor."):
            channel = case.truth_site.removeprefix("sensor.")
            others = [d for name, d in dev.items() if name != channel]
            assert dev[channel] >= 3.0 and max(others) < 1.5, (case.name, dev)
