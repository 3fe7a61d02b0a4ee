"""Seed 003's winch actuator linearised (§3.2–3.3, issue #23): the open-loop zeros and poles of
its Table 5 recomputed from its own Tables 1–4 and Appendices A–B, where the printed values
disagree with those equations (with the arithmetic), the root locus over ``K_p`` and the
dominant pair's damped frequency and peak time ``t_p = π/ω_d`` (eq. 30); and the nonlinear
model (:class:`WinchDrive`: static friction, current limit, the cables' one-sidedness) stepped
where the linear analysis cannot go (:func:`step_response`, :func:`step_table`).

``cablekit cdpr winch --out DIR`` writes the tables, the notes, the root-locus and step plots.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cablekit._args import checked, count, float_array, instance, real, text
from cablekit._cablekit import Winch, WinchDrive
from cablekit.errors import ParameterError
from cablekit.simulation import simulate

#: seed 003 Table 5 as printed: per column, zeros then poles (complex)
_Z48 = [555.61j, -555.61j, -33.17, -2.13]
_Z48L = [555.61j, -555.61j, -28.17, -2.13]
_Z100L = [793.73j, -793.73j, -28.17, -2.13]
_P1 = [556.03j, -556.03j, -1.84 + 21.58j, -1.84 - 21.58j, 0.0]
_P1E = [794.33j, -794.33j, -1.84 + 30.89j, -1.84 - 30.89j, 0.0, -200.0]
_P2 = [-0.01 + 557.30j, -0.01 - 557.30j, 0.0, 0.0, -3.66]
_P2E = [796.14j, -796.14j, 0.0, 0.0, -3.66, -200.0]
SEED_TABLE5 = {
    ("fixed", False, 48.9): (_Z48, _P1),
    ("fixed", True, 48.9): (_Z48L, [*_P1, -200.0]),
    ("fixed", True, 100.0): (_Z100L, _P1E),
    ("synchronized", False, 48.9): (_Z48, _P2),
    ("synchronized", True, 48.9): (_Z48L, [*_P2, -200.0]),
    ("synchronized", True, 100.0): (_Z100L, _P2E),
}
SEED_E = 48.9e9
KP_SEED = 6.0


@checked
def with_modulus(w: Winch, youngs_modulus: float) -> Winch:
    """The same winch with both cables' stiffness scaled to another Young's modulus."""
    instance(w, "w", Winch)
    youngs_modulus = real(youngs_modulus, "youngs_modulus", lo=0.0, lo_open=True, hi=1e15)
    v = w.values.copy()
    names = list(Winch.NAMES)
    for k in ("stiffness_a", "stiffness_b"):
        v[names.index(k)] *= youngs_modulus / SEED_E
    return Winch(v)


@dataclass(frozen=True)
class Column:
    """One column of Table 5: ours and the seed's zeros and poles (complex, by modulus), and the
    dominant closed-loop pair at ``K_p = 6``."""

    setup: str
    lpf: bool
    modulus_gpa: float
    zeros: np.ndarray
    poles: np.ndarray
    seed_zeros: np.ndarray
    seed_poles: np.ndarray
    omega_d: float | None
    peak_time: float | None

    @checked
    def label(self) -> str:
        setup = "Setup 1 (antagonist fixed)" if self.setup == "fixed" else "Setup 2 (synchronized)"
        return f"{setup}, E = {self.modulus_gpa:g} GPa, {'with' if self.lpf else 'without'} LPF"


def _complex(a: np.ndarray) -> np.ndarray:
    z = a[:, 0] + 1j * a[:, 1]
    return z[np.argsort(np.abs(z), kind="stable")]


@checked
def table5(w: Winch | None = None) -> list[Column]:
    """The six columns of seed 003 Table 5 recomputed."""
    w = instance(w, "w", Winch, optional=True) or Winch.seed003()
    cols = []
    for (setup, lpf, e_gpa), (sz, sp) in SEED_TABLE5.items():
        we = with_modulus(w, e_gpa * 1e9)
        z, p = we.zeros_and_poles(setup, lpf)
        dom = we.dominant(setup, lpf, KP_SEED)
        seed_z = np.asarray(sz, dtype=complex)
        seed_p = np.asarray(sp, dtype=complex)
        cols.append(
            Column(
                setup,
                lpf,
                e_gpa,
                _complex(z),
                _complex(p),
                seed_z[np.argsort(np.abs(seed_z), kind="stable")],
                seed_p[np.argsort(np.abs(seed_p), kind="stable")],
                dom[1] if dom else None,
                dom[2] if dom else None,
            )
        )
    return cols


def _fmt(z: complex) -> str:
    if abs(z.imag) < 5e-3:
        return f"{z.real:.2f}"
    return f"{z.real:.2f} {'+' if z.imag > 0 else '−'} {abs(z.imag):.2f}i"


@checked
def table5_markdown(cols: list[Column]) -> str:
    """Ours beside the seed's, per column."""
    lines = [
        "| column | zeros: cablekit | zeros: seed 003 | poles: cablekit | poles: seed 003 "
        "| ω_d at K_p = 6 | t_p |",
        "|---|---|---|---|---|---|---|",
    ]
    for c in cols:

        def row(a: np.ndarray) -> str:
            return ", ".join(_fmt(z) for z in a)

        wd = f"{c.omega_d:.1f} rad/s" if c.omega_d else "–"
        tp = f"{1e3 * c.peak_time:.0f} ms" if c.peak_time else "–"
        cells = [c.label(), row(c.zeros), row(c.seed_zeros), row(c.poles), row(c.seed_poles), wd, tp]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


@checked
def inconsistencies(w: Winch | None = None) -> list[str]:
    """Where seed 003's printed values disagree with its own equations, with the arithmetic."""
    w = instance(w, "w", Winch, optional=True) or Winch.seed003()
    v = dict(zip(Winch.NAMES, w.values, strict=True))
    j_l, b_l = w.load
    ea_l = 48.9e9 * 1.89e-6 / 6.0
    td, ti, wc = v["td"], v["ti"], v["cutoff"]
    lpf = np.roots([ti + td * ti * wc, wc * ti + 1.0, wc])
    typo = np.roots([ti * ti + td * ti * wc, wc * ti + 1.0, wc])
    plain = np.roots([td * ti, ti, 1.0])
    m = v["ee_mass"]
    low = Winch(np.array([*w.values[:9], 7560.0, 7560.0, *w.values[11:]]))
    _, p_low = low.zeros_and_poles("fixed", False)
    slow_low = max(abs(p[1]) for p in p_low if abs(p[1]) < 100)
    r_mm = v["drum_radius"] * 1e3
    slow1, slow2 = -b_l / (2 * j_l), -b_l / (j_l + m * v["drum_radius"] ** 2)
    return [
        f"Appendix B prints K_A = K_B = 7,560 N/m, but E·S/L = 48.9 GPa × 1.89 mm² / 6 m = "
        f"{ea_l:,.0f} N/m (2.04× more). Table 5 agrees with {ea_l:,.0f} N/m: with 7,560 N/m the "
        f"slow pole pair of Setup 1 sits at ±{slow_low:.2f}i, not the printed ±21.58i; we use E·S/L.",
        f"The EE mass m_E is not printed; the cable zeros ±√((K_A + K_B)/m_E) = ±555.61i imply "
        f"m_E = 2 × {ea_l:,.0f} / 555.61² = {2 * ea_l / 555.61**2:.4f} kg; we use {m:g} kg.",
        "The drum radius is not in Tables 1–4; Appendix A's static-friction test (τ_fr = M·g·r, "
        f"M = 0.62 kg, τ_fr = 0.152 N·m) gives r = 0.152 / (0.62 × 9.81) = {r_mm:.2f} mm.",
        "Eq. 13 as printed, K_p((t_i² + t_d·t_i·ω_c)s² + (ω_c·t_i + 1)s + ω_c)/(s(s + ω_c)t_i), "
        "is not the PID it expands (K_p(1 + ω_c·t_d·s/(ω_c + s) + 1/(t_i·s))) and mixes units "
        "(t_i² in s², t_d·t_i·ω_c in s): the first term is t_i. With Table 4 (t_i = "
        f"{ti} s, t_d = {td} s, ω_c = {wc:g} rad/s) the printed form gives zeros {typo[0]:.2f} and "
        f"{typo[1]:.2f}; the expansion, ({ti + td * ti * wc:.4f}) s² + ({wc * ti + 1:.1f}) s + "
        f"{wc:g} = 0, gives {lpf[0]:.2f} and {lpf[1]:.2f}, and Table 5 prints -28.17 and -2.13: "
        "the table was computed right, the equation is misprinted. We use the expansion (the "
        "nonlinear model's linearisation agrees with it, a test). Without the LPF (eq. 12): "
        f"{td * ti:.5f} s² + {ti} s + 1 = 0 gives {plain[0]:.2f} and {plain[1]:.2f} (printed "
        "-33.17, -2.13: the rounding of t_d = K_d/K_p = 0.17/6 = 0.02833).",
        "The real part of Setup 1's slow pair and Setup 2's real pole follow from "
        f"J_l = {j_l:.6f} kg·m² and B_l = {b_l:.6f} N·m·s/rad (eq. 17 with Tables 1–3): "
        f"−B_l/(2J_l) = {slow1:.3f} and −B_l/(J_l + m_E r²) = {slow2:.3f}; Table 5 prints −1.84 "
        "and −3.66, 2–3 % less damping than its own Tables give.",
    ]


@checked
def plot_root_locus(path: str | Path, w: Winch | None = None) -> Path | None:
    """Closed-loop poles over ``K_p`` from 0.01 to 100 for the six columns, ``K_p = 6`` marked."""
    from cablekit.plotting import pyplot_or_none, save_figure

    plt = pyplot_or_none()
    if plt is None:
        return None
    w = instance(w, "w", Winch, optional=True) or Winch.seed003()
    kps = list(np.geomspace(0.01, 100.0, 400))
    fig, axes = plt.subplots(2, 3, figsize=(13, 8))
    for ax, (setup, lpf, e_gpa) in zip(axes.ravel(), SEED_TABLE5, strict=True):
        we = with_modulus(w, e_gpa * 1e9)
        locus = we.root_locus(setup, lpf, kps)
        ax.plot(locus[:, :, 0], locus[:, :, 1], ".", ms=1.2, color="C0")
        at = we.root_locus(setup, lpf, [KP_SEED])[0]
        ax.plot(at[:, 0], at[:, 1], "rx", label="K_p = 6")
        ax.set_xlim(-60, 10)
        ax.set_ylim(-60, 60)
        ax.axvline(0.0, color="k", lw=0.5)
        name = "Setup 1" if setup == "fixed" else "Setup 2"
        ax.set_title(f"{name}, E = {e_gpa:g} GPa, {'LPF' if lpf else 'no LPF'}", fontsize=9)
        ax.set_xlabel("Re (1/s)")
        ax.set_ylabel("Im (rad/s)")
        ax.legend(fontsize=7)
    return save_figure(fig, path)


@checked
def report(out: str | Path, plots: bool = True) -> str:
    """Table 5 ours vs the seed's, the inconsistencies, the root locus; returns the markdown."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cols = table5()
    fig = plot_root_locus(out / "winch_root_locus.png") if plots else None
    steps = step_table()
    steps_fig = plot_steps(out / "winch_steps.png", steps) if plots else None
    from cablekit.cdpr.sensors import calibration_table, fig18, fig18_table, plot_fig18, seed_calibrations

    sweeps = fig18()
    sweeps_fig = plot_fig18(out / "winch_fig18.png", sweeps) if plots else None
    dom = [c for c in cols if c.omega_d]
    text = "\n\n".join(
        [
            "# Seed 003's winch, linearised: Table 5 recomputed",
            table5_markdown(cols),
            "Where the seed's printed values disagree with its own equations:\n\n"
            + "\n".join(f"- {s}" for s in inconsistencies()),
            "Dominant closed-loop pair at K_p = 6: "
            + "; ".join(
                f"{c.label()}: ω_d = {c.omega_d:.1f} rad/s, t_p = {1e3 * (c.peak_time or 0):.0f} ms"
                for c in dom
            )
            + " (seed 003: ω_d ≈ 30 rad/s at 48.9 GPa and ≈ 39 rad/s at 100 GPa, t_p ≈ 80–100 ms).",
            f"![root locus]({fig.name})" if fig else "",
            "## The nonlinear model stepped (WinchDrive: static friction, current limit 10 A, "
            "T₀ = 20 N)\n\n" + step_markdown(steps),
            f"![steps]({steps_fig.name})" if steps_fig else "",
            "## Sensors: calibration as in Figs 14–15 (eq. 33; the rig's pulley μφ = 0.01 under the "
            "load-cell ones)\n\n" + calibration_table(seed_calibrations()),
            "## Fig. 18: the motor-current estimate (eq. 35) against the inline sensor through the "
            "HX711 (100 ms) and BLE (30 ms), current stepped 0 → 1.7 A → 0 (levels above 0.9 A, "
            "where the drum moves both ways)\n\n" + fig18_table(sweeps),
            f"![fig18]({sweeps_fig.name})" if sweeps_fig else "",
        ]
    )
    (out / "winch.md").write_text(text + "\n", encoding="utf-8")
    return text


@dataclass(frozen=True)
class StepResponse:
    """A reference step of ``step`` rad (``alpha_ref`` jumps, ``alpha_ref_dot`` stays 0) applied
    to a :class:`WinchDrive` at rest at its working point, and what it did: the traces;
    ``peak_time``, the first local maximum of α (s; ``None`` if α never turns back), and α there
    as a fraction of the step (``peak_fraction``); ``rise_time`` to 90 % of the step (s);
    ``overshoot`` (fraction of the step); ``settling_time`` (last exit from ±2 % of the step, s;
    ``None`` if still outside at the end); ``peak_tension`` (largest driven-cable tension, N);
    ``final_error`` (rad); and the linearisation's ``linear_peak_time`` ``π/ω_d`` (s) and its
    slowest time constant ``linear_slowest`` (s) (:func:`linearised_poles`)."""

    label: str
    step: float
    t: np.ndarray
    alpha: np.ndarray
    tension_a: np.ndarray
    tension_b: np.ndarray
    current: np.ndarray
    peak_time: float | None
    peak_fraction: float | None
    rise_time: float | None
    overshoot: float
    settling_time: float | None
    peak_tension: float
    final_error: float
    linear_peak_time: float | None
    linear_slowest: float | None


def _frictionless(w: Winch) -> Winch:
    """The same winch without its static friction."""
    v = w.values.copy()
    v[list(Winch.NAMES).index("static_friction")] = 0.0
    return Winch(v)


def _without_static_friction(drive: WinchDrive) -> WinchDrive:
    t0, i_max, eps, c = drive.settings
    return WinchDrive(
        _frictionless(drive.winch),
        setup=drive.setup,
        lpf=drive.lpf,
        pretension=t0,
        current_limit=i_max,
        friction_smoothing=eps,
        cable_damping=c,
        control=drive.control,
    )


@dataclass(frozen=True)
class Linearised:
    """Seed 003 eq. 26 (``setup="fixed"``) or eq. 27 (``"synchronized"``): the open loop
    ``PID·plant`` at ``K_p = 1`` as ``num``/``den`` (highest power first), its ``zeros`` and
    ``poles`` (complex), with or without the derivative's low-pass filter."""

    setup: str
    lpf: bool
    num: np.ndarray
    den: np.ndarray
    zeros: np.ndarray
    poles: np.ndarray


@checked
def linearise(w: Winch | None = None, setup: str = "fixed", *, lpf: bool = True) -> Linearised:
    """The winch's open-loop transfer function about its working point (seed 003 eqs 26–27);
    the core's (``Winch.open_loop``, ``Winch.zeros_and_poles``)."""
    w = instance(w, "w", Winch, optional=True) or Winch.seed003()
    instance(setup, "setup", str)
    instance(lpf, "lpf", bool)
    num, den = w.open_loop(setup, lpf)
    z, p = w.zeros_and_poles(setup, lpf)
    return Linearised(setup, lpf, np.asarray(num), np.asarray(den), _complex(z), _complex(p))


@checked
def root_locus(
    w: Winch | None = None, setup: str = "fixed", *, lpf: bool = True, kps: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """``(kps, poles)``: the closed-loop poles ``(K, n)`` (complex) at each gain ``K_p`` (A/rad;
    default 200 gains from 0.01 to 100, log-spaced)."""
    w = instance(w, "w", Winch, optional=True) or Winch.seed003()
    instance(setup, "setup", str)
    instance(lpf, "lpf", bool)
    gains = np.geomspace(0.01, 100.0, 200) if kps is None else float_array(kps, "kps", 1)
    poles = np.asarray(w.root_locus(setup, lpf, [float(k) for k in gains]))
    return gains, poles[..., 0] + 1j * poles[..., 1]


@checked
def linearised_poles(drive: WinchDrive) -> np.ndarray:
    """Closed-loop poles of the model linearised at its working point without static friction
    (the eigenvalues of ``∂f/∂x`` at rest; for Setup 1 these are eq. 26 closed by the PID, a
    tested identity; for Setup 2 they are the physical setup's, not eq. 27's lumped one),
    sorted by modulus. Without the LPF the unused filter state adds one pole at 0, left out."""
    instance(drive, "drive", WinchDrive)
    d = _without_static_friction(drive)
    ev = np.linalg.eigvals(d.jacobian(np.zeros(d.n_states), np.zeros(d.n_inputs)))
    if not drive.lpf:
        ev = np.delete(ev, int(np.argmin(np.abs(ev))))
    return ev[np.argsort(np.abs(ev), kind="stable")]


@checked
def step_response(
    drive: WinchDrive,
    step: float = 0.2,
    *,
    duration: float = 4.0,
    dt: float = 1e-3,
    substeps: int = 10,
    label: str = "",
) -> StepResponse:
    """Simulate a reference step of ``step`` rad for ``duration`` s (RK4, ``substeps`` per ``dt``)."""
    instance(drive, "drive", WinchDrive)
    step = real(step, "step", lo=-1e3, hi=1e3)
    if step == 0.0:
        raise ParameterError("step must be a non-zero reference step")
    duration = real(duration, "duration", lo=0.0, lo_open=True, hi=1e4)
    dt = real(dt, "dt", lo=1e-7, hi=1.0)
    substeps = count(substeps, "substeps", lo=1, hi=100_000)
    text(label, "label")
    if duration / dt > 1e7:
        raise ParameterError(f"duration / dt must be at most 1e7 samples, got {duration / dt:.3g}")
    n = round(duration / dt) + 1
    inputs = np.zeros((n, 2))
    inputs[1:, 0] = step
    run = simulate(drive, inputs, dt, substeps=substeps)
    t, alpha = run.t, run["alpha"]
    frac = alpha / step
    rising = np.diff(frac)
    turns = np.flatnonzero((rising[:-1] > 0) & (rising[1:] <= 0)) + 1
    peak = int(turns[0]) if turns.size else None
    reached = np.flatnonzero(frac >= 0.9)
    outside = np.flatnonzero(np.abs(frac - 1.0) > 0.02)
    if not outside.size:
        settle: float | None = 0.0
    elif outside[-1] == n - 1:
        settle = None
    else:
        settle = float(t[outside[-1] + 1])
    poles = linearised_poles(drive)
    pair = [p for p in poles if p.imag > 1e-9]
    damped = [p for p in poles if abs(p.imag) <= 1e-9 and p.real < 0]
    return StepResponse(
        label=label,
        step=step,
        t=t,
        alpha=alpha,
        tension_a=run["tension_a"],
        tension_b=run["tension_b"],
        current=run["current"],
        peak_time=None if peak is None else float(t[peak]),
        peak_fraction=None if peak is None else float(frac[peak]),
        rise_time=float(t[reached[0]]) if reached.size else None,
        overshoot=float(max(frac.max() - 1.0, 0.0)),
        settling_time=settle,
        peak_tension=float(run["tension_a"].max()),
        final_error=float(alpha[-1] - step),
        linear_peak_time=float(np.pi / pair[0].imag) if pair else None,
        linear_slowest=float(-1.0 / max(p.real for p in damped)) if damped else None,
    )


@checked
def step_cases(w: Winch | None = None) -> list[tuple[str, WinchDrive, float]]:
    """The steps of :func:`step_table`: the linear model's assumptions first (no static
    friction), then the seed's friction, the LPF left out, Setup 2 as built (the antagonist's
    drum following) and a step of a whole radian with the antagonist fixed."""
    w = instance(w, "w", Winch, optional=True) or Winch.seed003()
    frictionless = _frictionless(w)
    return [
        ("Setup 1, LPF, no static friction", WinchDrive(frictionless, setup="fixed"), 0.2),
        ("Setup 1, LPF, static friction", WinchDrive(w, setup="fixed"), 0.2),
        ("Setup 1, no LPF, static friction", WinchDrive(w, setup="fixed", lpf=False), 0.2),
        ("Setup 2, LPF, static friction", WinchDrive(w, setup="synchronized"), 0.2),
        ("Setup 1, LPF, static friction, 1 rad", WinchDrive(w, setup="fixed"), 1.0),
        ("Setup 1, LPF, static friction, 0.02 rad", WinchDrive(w, setup="fixed"), 0.02),
    ]


@checked
def step_table(w: Winch | None = None, *, duration: float = 4.0) -> list[StepResponse]:
    """Every case of :func:`step_cases` stepped."""
    return [step_response(d, s, duration=duration, label=name) for name, d, s in step_cases(w)]


@checked
def step_markdown(rows: list[StepResponse]) -> str:
    """The step responses as a Markdown table."""

    def ms(v: float | None) -> str:
        return "–" if v is None else f"{1e3 * v:.0f} ms"

    lines = [
        "| step | α step | first peak of α (linear π/ω_d) | α there | 90 % at (linear slowest τ) | "
        "overshoot | settled ±2 % | peak T_A | error at end |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        there = "–" if r.peak_fraction is None else f"{100 * r.peak_fraction:.0f} %"
        lines.append(
            f"| {r.label} | {r.step:g} rad | {ms(r.peak_time)} ({ms(r.linear_peak_time)}) | {there} | "
            f"{ms(r.rise_time)} ({ms(r.linear_slowest)}) | {100 * r.overshoot:.0f} % | "
            f"{ms(r.settling_time)} | "
            f"{r.peak_tension:.1f} N | {r.final_error:+.1e} rad |"
        )
    return "\n".join(lines)


@checked
def plot_steps(path: str | Path, rows: list[StepResponse]) -> Path | None:
    """α/step and T_A over time for every step."""
    from cablekit.plotting import pyplot_or_none, save_figure

    plt = pyplot_or_none()
    if plt is None:
        return None
    fig, (a, b) = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    for r in rows:
        a.plot(r.t, r.alpha / r.step, lw=1, label=r.label)
        b.plot(r.t, r.tension_a, lw=1, label=r.label)
    a.axhline(1.0, color="k", lw=0.5)
    a.set_ylabel("α / step")
    b.set_ylabel("T_A (N)")
    b.set_yscale("log")
    b.set_xlabel("t (s)")
    a.legend(fontsize=7)
    a.set_title("Seed 003's winch, nonlinear model: reference steps (T₀ = 20 N)")
    return save_figure(fig, path)
