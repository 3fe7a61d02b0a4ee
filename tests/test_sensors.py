"""Seed 003's tension sensors (issue #23): the load-cell pulley (eqs 31–32), the calibration
(eq. 33) against NumPy's least squares, the signal chain against a NumPy reference, the
calibration and Fig. 18 experiments on the twin, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import cablekit as ck
from cablekit.cdpr import Calibration, LoadCellPulley, SignalChain, Winch
from cablekit.cdpr.sensors import calibrate, current_sweep, fig18_table
from tests.reference.sensors import signal_chain


@given(a1=st.floats(1e-3, np.pi / 2), a2=st.floats(1e-3, np.pi / 2), t=st.floats(0.0, 1e4))
def test_load_cell_pulley_is_eq31(a1, a2, t):
    s = LoadCellPulley(a1, a2)
    assert s.push(t) == pytest.approx(t * (np.sin(a1) + np.sin(a2)), rel=1e-14, abs=1e-300)
    assert s.tension_range(s.push(t)) == pytest.approx(t, rel=1e-12, abs=1e-300)


@settings(max_examples=60, deadline=None)
@given(
    gain=st.floats(-1e4, 1e4).filter(lambda g: abs(g) > 1e-3),
    offset=st.floats(-1e5, 1e5),
    n=st.integers(2, 12),
    seed=st.integers(0, 2**32 - 1),
)
def test_calibration_fit_equals_numpy_least_squares(gain, offset, n, seed):
    """The line equals np.polyfit through all points and the correlation np.corrcoef's, to
    1e-9; the residuals are those of the line; loads met both ways give the hysteresis."""
    rng = np.random.default_rng(seed)
    up = np.sort(rng.uniform(0.0, 70.0, n))
    up[-1] = up[0] + 1.0 + up[-1]  # at least two distinct loads
    r_up = gain * up + offset + rng.normal(0, 1.0, n)
    down = up[::-1].copy()
    r_down = gain * down + offset + rng.normal(0, 1.0, n) + 0.2 * gain
    fit = Calibration.fit(up, r_up, down, r_down)
    t, r = np.r_[up, down], np.r_[r_up, r_down]
    slope, icpt = np.polyfit(t, r, 1)
    scale = np.abs(r).max()
    assert fit.calibration.gain == pytest.approx(slope, rel=1e-9, abs=1e-9 * scale / t.max())
    assert fit.calibration.offset == pytest.approx(icpt, rel=1e-9, abs=1e-9 * scale)
    assert fit.correlation == pytest.approx(np.corrcoef(t, r)[0, 1], rel=1e-9, abs=1e-12)
    res = t - (r - fit.calibration.offset) / fit.calibration.gain
    assert fit.residual_rms == pytest.approx(np.sqrt(np.mean(res**2)), rel=1e-7, abs=1e-9)
    diffs = (r_down[::-1] - r_up) / fit.calibration.gain
    assert fit.hysteresis == pytest.approx(diffs[np.argmax(np.abs(diffs))], rel=1e-9, abs=1e-9)
    np.testing.assert_allclose(
        fit.calibration.tension(r), (r - fit.calibration.offset) / fit.calibration.gain
    )


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(1, 400),
    conv=st.floats(1e-3, 0.5),
    latency=st.floats(0.0, 0.2),
    seed=st.integers(0, 2**32 - 1),
)
def test_signal_chain_equals_the_numpy_reference(n, conv, latency, seed):
    """Irregular sampling, windows with and without samples, any latency: the core's readings
    equal the NumPy reference sample for sample."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(1e-4, 0.05, n))
    signal = rng.normal(0.0, 10.0, n)
    got = SignalChain(conv, latency).apply(t, signal)
    np.testing.assert_allclose(got, signal_chain(t, signal, conv, latency), rtol=1e-12, atol=1e-12)


def test_hx711_ble_step_is_averaged_and_late():
    """A 10 N step at 0.25 s on a 1 kHz signal: 0 until 0.33 s, the half-window mean 5 N from
    0.33 s (window (0.2, 0.3] ends, +30 ms), 10 N from 0.43 s."""
    t = np.arange(1001) * 1e-3
    seen = SignalChain.hx711_ble().apply(t, np.where(t > 0.25, 10.0, 0.0))
    assert seen[329] == 0.0 and seen[330] == pytest.approx(5.0) and seen[430] == pytest.approx(10.0)


def test_calibration_experiment_finds_the_line_and_the_rigs_hysteresis():
    """Figs 14–15 on the twin: without friction the fitted line is the sensor's (gain to 0.1 %)
    and the loop is noise; the rig's pulley (μφ = 0.02) puts a loop of 2·sinh(μφ)·m·g at the top
    load, which the fit reports within 10 %."""
    clean = calibrate("inline", 2000.0, 500.0, noise=20.0, seed=3)
    assert clean.fit.calibration.gain == pytest.approx(2000.0, rel=1e-3)
    assert abs(clean.fit.hysteresis) < 0.1 and clean.fit.correlation > 0.9999
    rig = calibrate("pulley", 400.0, 100.0, capstan=0.02, noise=2.0, seed=4)
    top = rig.loads.max()
    assert rig.fit.hysteresis == pytest.approx(2 * np.sinh(0.02) * top, rel=0.1)
    assert rig.fit.correlation > 0.9994  # the seed's bound holds although the loop is there


def test_fig18_current_estimate_reads_high_loading_and_low_unloading():
    """The motor-current estimate against the sensed tension (seed 003 Fig. 18), current in
    0.25 A steps: while loading the tension is below the estimate, while unloading above it,
    never by more than the static friction's band τ_st/r, and the loop between is positive and
    at most the band's width. (Larger steps carry the drum further into the band: with 0.5 A
    steps a loading level can land above the estimate.)"""
    w = dict(zip(Winch.NAMES, Winch.seed003().values, strict=True))
    band = w["static_friction"] / w["drum_radius"]
    s = current_sweep(0.5)
    live = s.currents > 0.9
    err = s.measured - s.estimate
    assert np.all(err[live & s.up] < 0) and np.all(err[live & ~s.up] > 0)
    assert np.all(np.abs(err[live]) <= band * 1.01)
    assert 0.2 * band < s.hysteresis <= 2 * band
    # the held reading is the true tension (the chain has caught up by the end of a hold)
    np.testing.assert_allclose(s.measured, s.true, atol=0.05)
    assert "EE position" in fig18_table([s])


def test_sensor_bad_input_is_a_typed_error():
    with pytest.raises(ck.ParameterError):
        LoadCellPulley(0.0, 0.1)
    with pytest.raises(ck.ParameterError):
        Calibration(0.0, 1.0)
    with pytest.raises(ck.ParameterError):
        Calibration.fit(np.array([1.0, 1.0]), np.array([2.0, 3.0]), np.zeros(0), np.zeros(0))
    with pytest.raises(ck.ShapeError):
        Calibration.fit(np.array([1.0, 2.0]), np.array([2.0]), np.zeros(0), np.zeros(0))
    with pytest.raises(ck.NotFiniteError):
        Calibration.fit(np.array([1.0, np.nan]), np.array([2.0, 3.0]), np.zeros(0), np.zeros(0))
    with pytest.raises(ck.ParameterError):
        SignalChain(0.0, 0.01)
    with pytest.raises(ck.ParameterError):
        SignalChain.hx711_ble().apply(np.array([0.0, 0.0]), np.array([1.0, 2.0]))
    with pytest.raises(ck.ParameterError):
        SignalChain(1e-300, 0.0).apply(np.array([0.0, 1.0]), np.array([1.0, 2.0]))
