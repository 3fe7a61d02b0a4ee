"""The 1 kHz controller loop (issue #40 §2, ``examples/controller_loop.py``) and the allocation-free
calls it relies on. Its timing lives in the example's report and docs/benchmarks.md, not here."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import cablekit as ck
from cablekit.nn import MapMinMax
from cablekit.nn.export import write_weights

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "controller_loop.py"


@pytest.fixture(scope="module")
def loop():
    spec = importlib.util.spec_from_file_location("controller_loop", EXAMPLE)
    mod = importlib.util.module_from_spec(spec)
    sys.modules["controller_loop"] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def network(tmp_path_factory):
    """A 14-10-8 network with drawn weights (the loop's shape; no torch needed): the comparison
    with the core's loop holds for any network."""
    rng = np.random.default_rng(1)
    w = [rng.normal(0, 0.3, (10, 14)), rng.normal(0, 0.3, (8, 10))]
    b = [rng.normal(0, 0.1, 10), rng.normal(0, 0.1, 8)]
    lo = np.array([-0.2, -0.2, 0.3, -0.3, -0.3, -0.3] + [0.0] * 8)
    hi = np.array([0.2, 0.2, 0.6, 0.3, 0.3, 0.3] + [60.0] * 8)
    path = tmp_path_factory.mktemp("net") / "loop.safetensors"
    out_map = MapMinMax(np.zeros(8), np.full(8, 60.0))
    write_weights(path, w, b, ["tansig", "purelin"], MapMinMax(lo, hi), out_map)
    return ck.Mlp.load(path)


def test_the_python_loop_is_the_cores_closed_loop_tick_by_tick(loop, network):
    """Fed the plan's motion, the Python loop's tensions, estimates and poses are those of
    ``CdprPlant.closed_loop`` (the same law in Rust) — every array and sign of the loop checked."""
    from cablekit.cdpr.force import mini_plant

    poses = loop.plan(0.4)
    noise = np.random.default_rng(3).normal(0.0, 0.2, (poses.shape[0], 8))
    rep = loop.run(network, poses, network_inputs="desired", sensor_noise=noise)
    ref = mini_plant(home=poses[0]).closed_loop(
        poses, 1e-3, gain=loop.GAIN, feedback="network", sensor_noise=noise, network=network
    )
    np.testing.assert_allclose(rep.desired_tension, ref.desired, rtol=0, atol=1e-9)
    np.testing.assert_allclose(rep.estimate, ref.feedback, rtol=0, atol=1e-8)
    np.testing.assert_allclose(rep.tension, ref.ee, rtol=0, atol=1e-8)
    np.testing.assert_allclose(rep.pose, ref.pose, rtol=0, atol=1e-12)
    # the drawn network pushes the tensions far from the distribution: the comparison is not of
    # a loop that does nothing
    assert np.abs(ref.ee - ref.desired).max() > 1.0


def test_the_filtered_loop_tracks_and_its_filter_beats_the_tracker(loop, network):
    poses = loop.plan(2.0)
    rep = loop.run(network, poses, seed=4)
    rms, worst = rep.position_error_mm()
    assert rms < 3.0 and worst < 10.0
    # the constant-velocity filter averages the tracker's 0.2 mm noise per axis down
    err = np.linalg.norm(rep.filtered_pose[:, :3] - rep.pose[:, :3], axis=1)[200:]
    assert np.sqrt(np.mean(err**2)) < 0.5 * np.sqrt(3) * loop.TRACKER_NOISE[0]
    pc = rep.percentiles()
    assert 0 < pc["median"] <= pc["p99"] <= pc["p99.9"] <= pc["max"]
    assert rep.stage_ns.shape == (poses.shape[0], 5) and (rep.stage_ns >= 0).all()
    assert np.all(rep.stage_ns.sum(axis=1) <= rep.tick_ns)
    with pytest.raises(ValueError, match="network_inputs"):
        loop.run(network, poses[:5], network_inputs="truth")


# -- the allocation-free calls


MODELS = {
    "raven3": ck.CableTransmission.raven2(3),
    "joint": ck.AntagonisticJoint.forceps_example(),
}


@pytest.mark.parametrize("name", sorted(MODELS))
def test_rk4_step_and_output_write_into_out_and_equal_the_allocating_calls(name):
    m = MODELS[name]
    rng = np.random.default_rng(0)
    x = m.rest_state() + 1e-3 * rng.normal(size=m.n_states)
    u = 0.1 * rng.normal(size=m.n_inputs)
    want = m.rk4_step(x, u, 1e-3, 3, u_next=2 * u)
    out = np.full(m.n_states, 9.0)
    got = m.rk4_step(x, u, 1e-3, 3, u_next=2 * u, out=out)
    assert got is out
    np.testing.assert_array_equal(out, want)
    # in place: out may be x itself
    xx = x.copy()
    m.rk4_step(xx, u, 1e-3, 3, u_next=2 * u, out=xx)
    np.testing.assert_array_equal(xx, want)
    y = np.full(m.n_outputs, 9.0)
    assert m.output(want, u, out=y) is y
    np.testing.assert_array_equal(y, m.output(want, u))


def test_out_is_left_as_it_was_on_any_error():
    m = MODELS["raven3"]
    x, u = m.rest_state(), np.zeros(m.n_inputs)
    out = np.full(m.n_states, 7.0)
    with pytest.raises(ck.NotFiniteError):
        m.rk4_step(x, np.full(m.n_inputs, np.nan), 1e-3, out=out)
    with pytest.raises(ck.ParameterError):
        m.rk4_step(x, u, -1e-3, out=out)
    with pytest.raises(ck.ShapeError):
        m.rk4_step(x, u, 1e-3, out=np.zeros(3))
    with pytest.raises(ck.CablekitError):
        m.rk4_step(x, u, 1e-3, out=np.zeros(m.n_states, dtype=np.float32))
    ro = np.zeros(m.n_states)
    ro.flags.writeable = False
    with pytest.raises(ck.CablekitError):
        m.rk4_step(x, u, 1e-3, out=ro)
    # a state the model cannot integrate diverges: an error, out untouched
    with pytest.raises(ck.CablekitError):
        m.rk4_step(np.full(m.n_states, 1e150), u, 1e-3, out=out)
    assert np.all(out == 7.0)
    y = np.full(m.n_outputs, 7.0)
    with pytest.raises(ck.NotFiniteError):
        m.output(np.full(m.n_states, np.inf), u, out=y)
    assert np.all(y == 7.0)


def test_srukf_x_into_writes_the_mean():
    r1 = ck.CableTransmission.raven2(1)
    f = ck.SrUkf(r1, np.zeros(4), np.eye(4), 1e-6 * np.eye(4), np.eye(2), dt=1e-3, states=[0, 2])
    f.step(np.array([0.1, 0.0]), np.array([0.01, 0.02]))
    out = np.zeros(4)
    assert f.x_into(out) is out
    np.testing.assert_array_equal(out, f.x)
    with pytest.raises(ck.ShapeError):
        f.x_into(np.zeros(5))


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(0, 30),
    dtype=st.sampled_from([np.float64, np.float32, np.int64, np.complex128, object]),
    value=st.sampled_from([0.0, np.nan, np.inf, -1e308, 1e308]),
)
def test_out_arguments_of_any_shape_dtype_and_content_are_typed_errors_or_written(n, dtype, value):
    m = MODELS["joint"]
    x, u = m.rest_state(), np.zeros(m.n_inputs)
    out = np.full(n, value) if dtype is np.float64 else np.array([0] * n, dtype=dtype)
    for call in (
        lambda: m.rk4_step(x, u, 1e-4, out=out),
        lambda: m.output(x, u, out=out),
    ):
        try:
            res = call()
        except ck.CablekitError:
            continue
        # accepted only as a float64 vector of the right length, then finite
        assert out.dtype == np.float64 and res is out and np.all(np.isfinite(out))
