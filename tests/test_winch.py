"""Seed 003's winch linearised (issue #23): the transfer function against a NumPy reference
written from eq. 26 and eqs 12–13, Table 5's values, the root locus, bad input, the CLI."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cablekit.cdpr import Winch
from cablekit.cdpr.winch import inconsistencies, report, table5, with_modulus
from cablekit.errors import NotFiniteError, ParameterError, ShapeError

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
        pn, pd = np.array([ti * ti + td * ti * wc, wc * ti + 1, wc]), np.array([ti, wc * ti, 0.0])
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
    assert "15,404 N/m" in notes[0] and "-30.68" in notes[3]


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
