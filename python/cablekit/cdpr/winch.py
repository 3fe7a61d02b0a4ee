"""Seed 003's winch actuator linearised (§3.2–3.3, issue #23): the open-loop zeros and poles of
its Table 5 recomputed from its own Tables 1–4 and Appendices A–B, where the printed values
disagree with those equations (with the arithmetic), the root locus over ``K_p`` and the
dominant pair's damped frequency and peak time ``t_p = π/ω_d`` (eq. 30).

``cablekit cdpr winch --out DIR`` writes the table, the notes and the root-locus plot.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cablekit._cablekit import Winch

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


def with_modulus(w: Winch, youngs_modulus: float) -> Winch:
    """The same winch with both cables' stiffness scaled to another Young's modulus."""
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

    def label(self) -> str:
        setup = "Setup 1 (antagonist fixed)" if self.setup == "fixed" else "Setup 2 (synchronized)"
        return f"{setup}, E = {self.modulus_gpa:g} GPa, {'with' if self.lpf else 'without'} LPF"


def _complex(a: np.ndarray) -> np.ndarray:
    z = a[:, 0] + 1j * a[:, 1]
    return z[np.argsort(np.abs(z), kind="stable")]


def table5(w: Winch | None = None) -> list[Column]:
    """The six columns of seed 003 Table 5 recomputed."""
    w = w or Winch.seed003()
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


def inconsistencies(w: Winch | None = None) -> list[str]:
    """Where seed 003's printed values disagree with its own equations, with the arithmetic."""
    w = w or Winch.seed003()
    v = dict(zip(Winch.NAMES, w.values, strict=True))
    j_l, b_l = w.load
    ea_l = 48.9e9 * 1.89e-6 / 6.0
    td, ti, wc = v["td"], v["ti"], v["cutoff"]
    lpf = np.roots([ti * ti + td * ti * wc, wc * ti + 1.0, wc])
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
        f"PID zeros with the LPF (eq. 13, Table 4: t_i = {ti} s, t_d = {td} s, ω_c = {wc:g} rad/s): "
        f"({ti * ti + td * ti * wc:.4f}) s² + ({wc * ti + 1:.1f}) s + {wc:g} = 0 has roots "
        f"{lpf[0]:.2f} and {lpf[1]:.2f}; Table 5 prints −28.17 and −2.13. Without the LPF "
        f"(eq. 12): {td * ti:.5f} s² + {ti} s + 1 = 0 gives {plain[0]:.2f} and {plain[1]:.2f} "
        "(printed −33.17, −2.13: the rounding of t_d = K_d/K_p = 0.17/6 = 0.02833).",
        "The real part of Setup 1's slow pair and Setup 2's real pole follow from "
        f"J_l = {j_l:.6f} kg·m² and B_l = {b_l:.6f} N·m·s/rad (eq. 17 with Tables 1–3): "
        f"−B_l/(2J_l) = {slow1:.3f} and −B_l/(J_l + m_E r²) = {slow2:.3f}; Table 5 prints −1.84 "
        "and −3.66, 2–3 % less damping than its own Tables give.",
    ]


def plot_root_locus(path: str | Path, w: Winch | None = None) -> Path | None:
    """Closed-loop poles over ``K_p`` from 0.01 to 100 for the six columns, ``K_p = 6`` marked."""
    from cablekit.plotting import pyplot_or_none

    plt = pyplot_or_none()
    if plt is None:
        return None
    w = w or Winch.seed003()
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
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def report(out: str | Path, plots: bool = True) -> str:
    """Table 5 ours vs the seed's, the inconsistencies, the root locus; returns the markdown."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cols = table5()
    fig = plot_root_locus(out / "winch_root_locus.png") if plots else None
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
        ]
    )
    (out / "winch.md").write_text(text + "\n", encoding="utf-8")
    return text
