"""Seed 003's winch (issue #23): linearised, the transfer function against a NumPy reference
written from eq. 26 and eqs 12–13, Table 5's values, the root locus, bad input, the CLI; as a
nonlinear model (``WinchDrive``), f, h and RK4 against a NumPy reference, its linearisation
against eq. 26, and the step study."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import cablekit as ck
from cablekit.cdpr import Winch, WinchDrive
from cablekit.cdpr.winch import inconsistencies, linearised_poles, report, step_table, table5, with_modulus
from cablekit.errors import NotFiniteError, ParameterError, ShapeError
from tests.reference.winch import WinchRef

NAMES = list(Winch.NAMES)


def _reference(v: dict[str, float], setup: str, lpf: bool) -> tuple[np.ndarray, np.ndarray]:
    """Open loop PID·plant with K_p = 1 from the seed's equations, with numpy.polymul."""
    j = v["rotor_inertia"] * v["gear_ratio"] ** 2 + v["gearbox_inertia"] + v["drum_inertia"]
    b = v["rotor_viscous"] * v["gear_ratio"] ** 2 + v["drum_viscous"]
    ka, kb = (
        (v["stiffness_a"], v["stiffness_b"])
        if setup == "fixed"
        else (v["stiffness_a"] + v["stiffness_b"], 0.0)
    )
    m, r, k = v["ee_mass"], v["drum_radius"], v["torque_constant"] * v["gear_ratio"]
    num = np.array([m, 0.0, ka + kb]) * k
    den = np.array([j * m, b * m, j * (ka + kb) + ka * m * r * r, b * (ka + kb), ka * kb * r * r])
    td, ti, wc = v["td"], v["ti"], v["cutoff"]
    if lpf:
        pn, pd = np.array([ti + td * ti * wc, wc * ti + 1, wc]), np.array([ti, wc * ti, 0.0])
    else:
        pn, pd = np.array([td * ti, ti, 1.0]), np.array([ti, 0.0])
    return np.polymul(pn, num), np.polymul(pd, den)


@settings(max_examples=30, deadline=None)
@given(
    scale=st.lists(st.floats(0.5, 2.0), min_size=16, max_size=16),
    setup=st.sampled_from(["fixed", "synchronized"]),
    lpf=st.booleans(),
)
def test_open_loop_and_roots_equal_the_numpy_reference(scale, setup, lpf):
    w = Winch(Winch.seed003().values * np.asarray(scale))
    num, den = w.open_loop(setup, lpf)
    rn, rd = _reference(dict(zip(NAMES, w.values, strict=True)), setup, lpf)
    np.testing.assert_allclose(num, rn, rtol=1e-12)
    np.testing.assert_allclose(den, rd, rtol=1e-12, atol=1e-300)
    z, p = w.zeros_and_poles(setup, lpf)
    for ours, poly in ((z, rn), (p, rd)):
        got = np.sort_complex(ours[:, 0] + 1j * ours[:, 1])
        want = np.sort_complex(np.roots(np.trim_zeros(poly, "f")))
        # each of ours is a root of the polynomial: |p(z)| small against its terms
        for root in got:
            terms = np.abs(poly) * np.abs(root) ** np.arange(len(poly) - 1, -1, -1)
            assert abs(np.polyval(poly, root)) <= 1e-7 * terms.sum() + 1e-300
        assert len(got) == len(want)


def test_table5_recomputed_agrees_with_the_seed_where_its_equations_do():
    cols = table5()
    assert len(cols) == 6
    for c in cols:
        # the cable zeros and poles: within 0.2 % of the printed values
        assert abs(c.zeros[-1].imag) == pytest.approx(abs(c.seed_zeros[-1].imag), rel=2e-3)
        assert abs(c.poles[-1].imag) == pytest.approx(abs(c.seed_poles[-1].imag), rel=3e-3)
        # the PID's slow zero −2.13 within 1 %
        assert c.zeros[0].real == pytest.approx(-2.13, rel=0.01)
    s1 = [c for c in cols if c.setup == "fixed"]
    # Setup 1's slow pair: imaginary parts within 1 % of 21.58 (48.9 GPa) and 30.89 (100 GPa)
    for c, im in zip(s1, (21.58, 21.58, 30.89), strict=True):
        slow = [p for p in c.poles if 5 < abs(p.imag) < 100]
        assert abs(slow[0].imag) == pytest.approx(im, rel=0.01)
    # the LPF's pole at −ω_c = −200
    assert any(abs(p + 200.0) < 1e-6 for p in cols[1].poles)
    notes = inconsistencies()
    assert "15,404 N/m" in notes[0] and "-30.68" in notes[3] and "-28.17" in notes[3]


def test_root_locus_starts_at_the_open_loop_poles_and_kp6_is_stable():
    w = Winch.seed003()
    locus = w.root_locus("fixed", True, [0.0, 6.0])
    _, p = w.zeros_and_poles("fixed", True)
    np.testing.assert_allclose(
        np.sort_complex(locus[0, :, 0] + 1j * locus[0, :, 1]),
        np.sort_complex(p[:, 0] + 1j * p[:, 1]),
        atol=1e-6,
    )
    assert np.all(locus[1, :, 0] < 1e-9)  # stable at the seed's gain
    dom = w.dominant("fixed", True, 6.0)
    assert dom is not None and dom[2] == pytest.approx(np.pi / dom[1])
    stiffer = with_modulus(w, 100e9).dominant("fixed", True, 6.0)
    assert stiffer is not None and stiffer[1] > dom[1]  # stiffer cables, faster response (seed §3.3)


def test_bad_input_is_a_typed_error(tmp_path):
    v = Winch.seed003().values
    bad = v.copy()
    bad[NAMES.index("rotor_inertia")] = -1.0
    with pytest.raises(ParameterError, match="rotor_inertia"):
        Winch(bad)
    with pytest.raises(ShapeError):
        Winch(v[:15])
    nan = v.copy()
    nan[0] = np.nan
    with pytest.raises((ParameterError, NotFiniteError)):
        Winch(nan)
    with pytest.raises(ParameterError, match="setup"):
        Winch.seed003().zeros_and_poles("both", False)
    with pytest.raises(ParameterError):
        Winch.seed003().root_locus("fixed", False, [float("nan")])
    text = report(tmp_path, plots=False)
    assert "Table 5" in text and (tmp_path / "winch.md").exists()


# --- the nonlinear model (WinchDrive) ----------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(
    scale=st.lists(st.floats(0.5, 2.0), min_size=16, max_size=16),
    x=st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6),
    u=st.lists(st.floats(-2.0, 2.0), min_size=2, max_size=2),
    setup=st.sampled_from(["fixed", "synchronized"]),
    lpf=st.booleans(),
    extra=st.tuples(st.floats(0.0, 50.0), st.floats(0.5, 20.0), st.floats(1e-3, 0.1), st.floats(0.0, 100.0)),
)
def test_winch_drive_equals_the_numpy_reference(scale, x, u, setup, lpf, extra):
    """f and h of the binding against the NumPy reference at 1e-12 relative over drawn
    parameters, states (cables slack or taut, the current limited or not) and inputs."""
    values = Winch.seed003().values * np.asarray(scale)
    t0, imax, eps, c = extra
    # states scaled to the model: angles ~ rad, EE position ~ mm
    x = np.asarray(x) * np.array([0.05, 2.0, 1e-3, 0.05, 0.1, 0.5])
    u = np.asarray(u)
    model = WinchDrive(
        Winch(values),
        setup=setup,
        lpf=lpf,
        pretension=t0,
        current_limit=imax,
        friction_smoothing=eps,
        cable_damping=c,
    )
    ref = WinchRef(values, setup, lpf, t0, imax, eps, c)
    for got, want in ((model.derivative(x, u), ref.f(x, u)), (model.output(x, u), ref.h(x, u))):
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * (1.0 + np.abs(want).max()))


def test_winch_drive_simulation_equals_the_reference_rk4():
    """A 0.3 s step simulated by ``cablekit.simulate`` equals the reference RK4 of the NumPy
    model to 1e-10 relative (static friction on, the current limited at the start)."""
    from tests.reference.rk4 import simulate as ref_simulate

    model = WinchDrive(Winch.seed003(), current_limit=2.0, cable_damping=5.0)
    ref = WinchRef(Winch.seed003().values, current_limit=2.0, damping=5.0)
    inputs = np.zeros((301, 2))
    inputs[1:, 0] = 0.5
    run = ck.simulate(model, inputs, 1e-3, substeps=10)
    # the default initial state is the working point: the reference's equilibrium
    np.testing.assert_allclose(run.states[0], ref.rest(), rtol=1e-14)
    assert np.abs(ref.f(ref.rest(), np.zeros(2))).max() < 1e-12
    xs, ys = ref_simulate(ref.f, ref.h, inputs, ref.rest(), 1e-3, substeps=10)
    np.testing.assert_allclose(run.states, xs, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(run.outputs, ys, rtol=1e-10, atol=1e-10)
    assert np.max(np.abs(run["current"])) == pytest.approx(2.0, abs=1e-12)


@pytest.mark.parametrize("lpf", [True, False])
@pytest.mark.parametrize("kp", [2.0, 6.0, 15.0])
def test_linearised_poles_are_eq26_closed_by_the_pid(lpf, kp):
    """Setup 1 without static friction: the nonlinear model's linearisation has the roots of
    den + K_p·num of the NumPy eq. 26 reference (to 1e-4 of their modulus)."""
    v = Winch.seed003().values.copy()
    v[NAMES.index("kp")] = kp
    v[NAMES.index("static_friction")] = 0.0
    num, den = _reference(dict(zip(NAMES, v, strict=True)), "fixed", lpf)
    poly = den.copy()
    poly[len(den) - len(num) :] += kp * num
    want = np.sort_complex(np.roots(np.trim_zeros(poly, "f")))
    got = np.sort_complex(linearised_poles(WinchDrive(Winch(v), setup="fixed", lpf=lpf)))
    np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-6)


def test_frictionless_small_step_is_the_linear_systems_exact_response():
    """Without static friction, away from the current limit and with taut cables the model is
    linear: its simulated step equals the exact response exp(A·t) of its Jacobian (to 1e-6 of
    the step), so the table's linear figures describe that case and only that case."""
    from scipy.linalg import expm

    v = Winch.seed003().values.copy()
    v[NAMES.index("static_friction")] = 0.0
    model = WinchDrive(Winch(v))
    step = 0.01
    inputs = np.zeros((501, 2))
    inputs[:, 0] = step
    run = ck.simulate(model, inputs, 1e-3, substeps=10)
    rest = run.states[0]  # the working point (an equilibrium)
    a = model.jacobian(rest, np.zeros(2))
    # the input enters f linearly: f(rest, [s, 0]) is B·[s, 0]
    b = model.derivative(rest, np.array([step, 0.0]))
    n = a.shape[0]
    big = np.zeros((n + 1, n + 1))
    big[:n, :n], big[:n, n] = a, b
    for k in (50, 118, 300, 500):
        x = expm(big * (1e-3 * k))[:n, n]
        tol = 1e-6 * step * np.array([1, 100, 1, 100, 10, 100])
        assert np.all(np.abs(run.states[k] - rest - x) <= tol), (k, run.states[k] - rest, x)


def test_step_table_shows_what_the_linear_analysis_cannot():
    """The step study from the working point: the first peak of α within 15 % of the linear
    π/ω_d (Setups 1 and 2); the stiff cable holds the first peak below the step and the
    integral closes the rest on its linear time constant (90 % after one to three of them);
    static friction lowers the first peak and, on a small step, makes the integral hunt (no
    settling, overshoot); the antagonist fixed raises the tension by K·r·α/2 (a whole radian:
    about 190 N over T₀), the synchronised one does not."""
    rows = {r.label: r for r in step_table()}
    free = rows["Setup 1, LPF, no static friction"]
    sync = rows["Setup 2, LPF, static friction"]
    for r in (free, sync):
        assert r.peak_time == pytest.approx(r.linear_peak_time, rel=0.15), r.label
    assert 0.5 < free.peak_fraction < 0.95
    assert free.linear_slowest < free.rise_time < 3 * free.linear_slowest
    rub = rows["Setup 1, LPF, static friction"]
    assert rub.peak_fraction < free.peak_fraction - 0.05
    small = rows["Setup 1, LPF, static friction, 0.02 rad"]
    assert small.settling_time is None and small.overshoot > 0.05
    w = dict(zip(NAMES, Winch.seed003().values, strict=True))
    rise = w["stiffness_a"] * w["drum_radius"] * 1.0 / 2
    big = rows["Setup 1, LPF, static friction, 1 rad"]
    assert big.peak_tension - 20.0 == pytest.approx(rise, rel=0.1)
    assert sync.peak_tension < 20.5
    for r in rows.values():
        assert abs(r.final_error) < 0.2 * abs(r.step), r.label


def test_the_srukf_runs_on_the_winch_and_recovers_the_unmeasured_tension():
    """The sr-UKF with the WinchDrive as its model, measuring the encoder angle and the driven
    cable's tension (0.2 N noise): its driven tension is better than the sensor (below 0.8 × the
    noise) and the antagonist's tension, not measured, is within 5 % of its swing."""
    m = WinchDrive(cable_damping=20.0)
    dt, n = 1e-3, 3000
    t = np.arange(n) * dt
    w = 2 * np.pi * 0.7
    ref = np.column_stack([0.3 * np.sin(w * t), 0.3 * w * np.cos(w * t)])
    run = ck.simulate(m, ref, dt, substeps=10)
    rng = np.random.default_rng(0)
    y = run.outputs[:, [0, 1]] + rng.normal(0, [1e-4, 0.2], (n, 2))
    p0 = np.diag([1e-6, 1e-4, 1e-10, 1e-6, 1e-6, 1e-4])
    q = np.diag([1e-10, 1e-6, 1e-14, 1e-8, 1e-12, 1e-8])
    f = ck.SrUkf(m, run.states[0], p0, q, np.diag([1e-8, 0.04]), dt=dt, substeps=10, outputs=[0, 1])
    est = f.run(ref, y)
    h = np.array([m.output(x, u) for x, u in zip(est.x, ref, strict=True)])
    rms = lambda e: float(np.sqrt(np.mean(e[500:] ** 2)))  # noqa: E731
    assert rms(h[:, 1] - run["tension_a"]) < 0.8 * 0.2
    swing = rms(run["tension_b"] - 20.0)
    assert swing > 10.0
    assert rms(h[:, 2] - run["tension_b"]) < 0.05 * swing


def test_winch_drive_bad_input_is_a_typed_error():
    for kwargs in (
        dict(pretension=-1.0),
        dict(current_limit=0.0),
        dict(friction_smoothing=float("nan")),
        dict(cable_damping=-2.0),
        dict(setup="sideways"),
    ):
        with pytest.raises(ck.ParameterError):
            WinchDrive(**kwargs)
    with pytest.raises(ck.NotFiniteError):
        WinchDrive.seed003().derivative(np.full(6, np.nan), np.zeros(2))
    with pytest.raises(ck.ShapeError):
        WinchDrive.seed003().derivative(np.zeros(5), np.zeros(2))


def test_linearise_and_root_locus_are_the_polynomials_roots():
    """``linearise``: the zeros and poles are the roots of ``num`` and ``den`` (NumPy); the root
    locus at each gain is the roots of ``den + K_p·num`` (the PID closing the loop)."""
    from cablekit.cdpr import linearise, root_locus

    for setup in ("fixed", "synchronized"):
        for lpf in (True, False):
            lin = linearise(setup=setup, lpf=lpf)
            for got, poly in ((lin.zeros, lin.num), (lin.poles, lin.den)):
                want = np.roots(np.trim_zeros(poly, "f"))
                np.testing.assert_allclose(np.sort_complex(got), np.sort_complex(want), rtol=1e-6, atol=1e-6)
            kps, locus = root_locus(setup=setup, lpf=lpf, kps=np.array([0.5, 5.0]))
            for kp, poles in zip(kps, locus, strict=True):
                num = np.concatenate([np.zeros(len(lin.den) - len(lin.num)), lin.num])
                want = np.roots(lin.den + kp * num)
                np.testing.assert_allclose(
                    np.sort_complex(poles), np.sort_complex(want), rtol=1e-6, atol=1e-6 * np.abs(want).max()
                )
