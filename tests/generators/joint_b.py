"""Blind benchmark "set B": an antagonistic single-joint cable drive with withheld effects.

(Kept in the test tree for the record: it was written by a session that was not shown the diagnosis
code, from the benchmark A README and file format only. Run from the repository root.)

Independent test-data generator.  Written from the physics literature only (friction, rope and
sensor models cited next to each form); it shares no code with the diagnosis tool under test.  The
only shared contract is the nominal plant and the file format of benchmark A:

    s1 = x_m - r*theta, s2 = -s1                 (drive / return cable stretch)
    T_i = max(0, T0 + k*s_i + c*ds_i/dt)         (joint-side tension)
    J*theta'' = r*(T1 - T2) - b*theta'           (joint)
    sensors: motor-side tensions (= T_i nominally) + N(0, 0.02 N); joint encoder quantised.

Integration: classical RK4 at 10 kHz (10 sub-steps per logged 1 kHz sample); the motor command is
the logged 1 kHz motor_pos, linearly interpolated, so the nominal re-simulated on the recorded
motor_pos sees exactly the generator's input.  Sensor and pulley-contact effects that do not feed
back into the motion are applied to the 10 kHz signals afterwards.

Usage:  python -m tests.generators.joint_b OUTDIR [--cases 1,4,9] [--seed S] [--workers 2]
"""

from __future__ import annotations

import argparse
import gzip
import io
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed

import numpy as np
from scipy import optimize, signal

FS = 1000  # logging rate [Hz]
SUB = 10  # RK4 sub-steps per logged sample (10 kHz integration)
DT = 1.0 / (FS * SUB)
N_SAMPLES = 20000  # 20 s per run, t = 0 ... 19.999 s (as benchmark A)
SIGMA_T = 0.02  # tension-sensor noise [N]
DEFAULT_SEED = 8000
CASE_IDS = tuple(range(1, 25))
G_TARGET = 3.0  # effect cases are scaled up until the nominal held-out gap exceeds this (>= 2 required)
HEADER = "t,motor_pos,tension_drive,tension_return,joint_pos"


# ----------------------------------------------------------------------------------------------
# Trajectories (1 kHz motor command at the capstan, metres)
# ----------------------------------------------------------------------------------------------
def _min_jerk(tau):
    """Flash & Hogan (1985) minimum-jerk profile on tau in [0, 1]."""
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)


class _Traj:
    """Sequential builder of a motor command sampled at 1 kHz."""

    def __init__(self, n):
        self.x = np.zeros(n)
        self.i = 0
        self.cur = 0.0

    def full(self):
        return self.i >= len(self.x)

    def _put(self, seg):
        m = min(len(seg), len(self.x) - self.i)
        self.x[self.i : self.i + m] = seg[:m]
        self.i += m
        if m:
            self.cur = float(seg[m - 1])

    def dwell(self, dur):
        self._put(np.full(max(1, round(dur * FS)), self.cur))

    def move(self, target, v_peak, min_dur=0.03):
        """Point-to-point min-jerk move; the peak speed of min-jerk is 1.875*D/T."""
        d = target - self.cur
        dur = max(1.875 * abs(d) / v_peak, min_dur)
        m = math.ceil(dur * FS)
        tau = np.minimum(np.arange(1, m + 1) / (dur * FS), 1.0)
        self._put(self.cur + d * _min_jerk(tau))

    def multisine(self, dur, amps, freqs, phases, ramp):
        """Sum of sines about the current position, raised-cosine fade in/out (returns to start)."""
        m = round(dur * FS)
        t = np.arange(1, m + 1) / FS
        w = np.ones(m)
        up = t < ramp
        w[up] = 0.5 * (1.0 - np.cos(np.pi * t[up] / ramp))
        dn = t > dur - ramp
        w[dn] = 0.5 * (1.0 - np.cos(np.pi * (dur - t[dn]) / ramp))
        s = sum(
            a * (np.sin(2 * np.pi * f * t + p) - math.sin(p))
            for a, f, p in zip(amps, freqs, phases, strict=True)
        )
        self._put(self.cur + w * s)


def _pick_target(rng, cur, xmax):
    while True:
        tgt = rng.uniform(-xmax, xmax)
        if abs(tgt - cur) >= 0.2 * xmax:
            return tgt


def _loguni(rng, lo, hi):
    return math.exp(rng.uniform(math.log(lo), math.log(hi)))


def _quantise_cmd(x):
    # 1 nm grid: the value written with %.9g parses back to exactly the simulated double
    return np.round(x * 1e9) / 1e9


def fit_trajectory(rng, r, f_n):
    """Fit run: min-jerk point-to-point sweeps at 5-80 mm/s peak with 0.3-1.2 s dwells.

    f_n is the nominal cable-joint resonance: moves last at least 3 of its periods so that the
    (lightly damped) mode is excited but the cables stay taut."""
    tr = _Traj(N_SAMPLES)
    xmax = 0.45 * r
    tr.dwell(rng.uniform(0.4, 0.8))
    while not tr.full():
        tr.move(_pick_target(rng, tr.cur, xmax), _loguni(rng, 0.005, 0.080), 3.0 / f_n)
        tr.dwell(rng.uniform(0.3, 1.2))
    return _quantise_cmd(tr.x)


def holdout_trajectory(rng, r, f_n):
    """Held-out run: faster sweeps (30-100 mm/s, short dwells, moves of >= 2.5 resonance periods)
    and a 3-5 tone 1-5 Hz multisine."""
    tr = _Traj(N_SAMPLES)
    xmax = 0.45 * r
    tr.dwell(rng.uniform(0.2, 0.5))
    t_ms = rng.uniform(7.0, 10.0)

    def sweeps(until):
        while tr.i < until and not tr.full():
            tr.move(_pick_target(rng, tr.cur, xmax), _loguni(rng, 0.030, 0.100), 2.5 / f_n)
            tr.dwell(rng.uniform(0.15, 0.6))

    def msine():
        n_t = int(rng.integers(3, 6))
        freqs = np.sort(rng.uniform(1.0, 5.0, n_t))
        phases = rng.uniform(0, 2 * np.pi, n_t)
        amps = rng.dirichlet(np.ones(n_t)) * rng.uniform(0.25, 0.36) * r
        tr.move(rng.uniform(-0.08, 0.08) * r, 0.03, 2.5 / f_n)
        tr.dwell(0.2)
        tr.multisine(t_ms, amps, freqs, phases, ramp=rng.uniform(0.4, 0.8))
        tr.dwell(0.3)

    if rng.integers(2) == 0:
        sweeps(N_SAMPLES - int((t_ms + 1.5) * FS))
        msine()
        sweeps(N_SAMPLES)
    else:
        msine()
        sweeps(N_SAMPLES)
    return _quantise_cmd(tr.x)


# ----------------------------------------------------------------------------------------------
# True plant (mechanical part), RK4 at 10 kHz
# ----------------------------------------------------------------------------------------------
def _lin_law(T0, k, c):
    def tens(s, sd):
        t = T0 + k * s + c * sd
        return t if t > 0.0 else 0.0

    return tens


class Plant:
    """Equations of motion of one case (mech=None gives the nominal plant of the model file).

    rhs(xm, v, y) -> dy/dt, with xm, v the motor displacement and speed; it leaves the joint-side
    tensions of the evaluated point in self.aux.  post(y_old, y_new, xm, v) -> y is an optional
    projection after each step (hybrid stick/slip, bristle saturation).
    """

    def __init__(self, nom, mech=None):
        mech = mech or {}
        self.r, self.k, self.c, self.T0, self.b = nom["r"], nom["k"], nom["c"], nom["T0"], nom["b"]
        self.J = nom["J"] * (1.0 + mech.get("payload", 0.0))
        self.aux = [self.T0, self.T0]
        self.post = None
        self.i_thc = 0  # index of the cable-pulley angle in y (for the contact velocity)
        self.i_thl = 0  # index of the encoder (link) angle in y
        kind = mech.get("kind", "rigid")
        getattr(self, "_build_" + kind)(mech)

    # -- laws of the two cables for the stateless forms ------------------------------------------
    def _laws(self, mech):
        T0, k, c = self.T0, self.k, self.c
        lin = _lin_law(T0, k, c)
        law = mech.get("cable")
        if law is None:
            return lin, lin
        name = law[0]
        if name == "toe":
            # Toe region of a fibre rope / tendon (Fung, Biomechanics 1993, ch. 7; McKenna & Hearle,
            # Handbook of Fibre Rope Technology 2004): T = A*e^p below the transition elongation e_t,
            # linear with the rated stiffness k above; C1 at e_t.  Pretension T0 sits in the toe.
            _, Tt, p = law
            et = p * Tt / k
            A = Tt / et**p
            e0 = et * (T0 / Tt) ** (1.0 / p) if T0 < Tt else et + (T0 - Tt) / k

            def toe(s, sd):
                e = e0 + s
                te = 0.0 if e <= 0.0 else (A * e**p if e < et else Tt + k * (e - et))
                t = te + c * sd
                return t if t > 0.0 else 0.0

            return toe, toe
        if name == "bilinear":
            # Bilinear rope (Hearle et al.): slope k up to the knee elongation, k2 beyond it.
            _, sk, k2 = law
            e0 = T0 / k
            ek = e0 + sk

            def bil(s, sd):
                e = e0 + s
                te = 0.0 if e <= 0.0 else (k * e if e < ek else k * ek + k2 * (e - ek))
                t = te + c * sd
                return t if t > 0.0 else 0.0

            return bil, bil
        if name == "tdamp":
            # Rope internal damping growing with the load, Hunt & Crossley (1975) form:
            # T = Te + (c + lam*Te)*ds/dt, Te = T0 + k*s.
            lam = law[1]

            def td(s, sd):
                te = T0 + k * s
                t = te + (c + lam * (te if te > 0.0 else 0.0)) * sd
                return t if t > 0.0 else 0.0

            return td, td
        if name == "slack":
            # Drive terminal slipped by delta: the drive cable is delta longer (pretension lost).
            delta = law[1]

            def drive(s, sd):
                return lin(s - delta, sd)

            return drive, lin
        raise ValueError(name)

    def _static_theta(self, x0, t1, t2, extra=None):
        """Static equilibrium of the rigid joint at motor position x0 (at rest)."""
        r = self.r

        def g(th):
            tau = r * (t1(x0 - r * th, 0.0) - t2(r * th - x0, 0.0))
            return tau - (extra(th) if extra else 0.0)

        th_n = x0 / r
        if abs(g(th_n)) < 1e-12:
            return th_n
        return optimize.brentq(g, th_n - 0.3, th_n + 0.3, xtol=1e-14)

    # -- rigid joint, stateless cables, optional position-periodic ripple ------------------------
    def _build_rigid(self, mech):
        r, b, iJ, aux = self.r, self.b, 1.0 / self.J, self.aux
        t1, t2 = self._laws(mech)
        A, n_r, ph = mech.get("ripple", (0.0, 0, 0.0))
        sin = math.sin

        def rhs(xm, v, y):
            th = y[0]
            om = y[1]
            s = xm - r * th
            sd = v - r * om
            T1 = t1(s, sd)
            T2 = t2(-s, -sd)
            aux[0] = T1
            aux[1] = T2
            tau = r * (T1 - T2) - b * om
            if A:
                tau -= A * sin(n_r * th + ph)
            return [om, tau * iJ]

        ripple = (lambda th: A * sin(n_r * th + ph)) if A else None
        self.rhs = rhs
        self.y0 = lambda x0: [self._static_theta(x0, t1, t2, ripple), 0.0]

    # -- Burgers viscoelastic cables (creep) -------------------------------------------------------
    def _build_creep(self, mech):
        # Burgers model of a polymer rope (Findley, Lai & Onaran, Creep and Relaxation of Nonlinear
        # Viscoelastic Materials, 1976): Maxwell spring k (rated stiffness) in series with a
        # Kelvin-Voigt unit (k2, eta2) and a flow dashpot eta1; the nominal damper c acts on the
        # total stretch rate.  Cables freshly tensioned to T0 before each run (creep states zero).
        r, b, k, c, iJ, aux = self.r, self.b, self.k, self.c, 1.0 / self.J, self.aux
        k2, eta2, eta1 = mech["k2"], mech["eta2"], mech["eta1"]
        e0 = self.T0 / k

        def rhs(xm, v, y):
            th, om, a1, f1, a2, f2 = y
            s = xm - r * th
            sd = v - r * om
            T1 = k * (e0 + s - a1 - f1) + c * sd
            T1 = T1 if T1 > 0.0 else 0.0
            T2 = k * (e0 - s - a2 - f2) - c * sd
            T2 = T2 if T2 > 0.0 else 0.0
            aux[0] = T1
            aux[1] = T2
            return [
                om,
                (r * (T1 - T2) - b * om) * iJ,
                (T1 - k2 * a1) / eta2,
                T1 / eta1,
                (T2 - k2 * a2) / eta2,
                T2 / eta1,
            ]

        self.rhs = rhs
        self.y0 = lambda x0: [x0 / r, 0.0, 0.0, 0.0, 0.0, 0.0]

    # -- Coulomb friction with a saturating bristle (reset-integrator / elasto-plastic) ----------
    def _build_bristle(self, mech):
        # Haessig & Friedland (1991) reset-integrator model, cf. Dupont et al. (2002) elasto-plastic
        # model: bristle deflection z follows the joint until |z| = tau_c/sigma0, then stays; friction
        # = sigma0*z + sigma1*dz/dt, i.e. exactly tau_c while sliding, a stiff spring in presliding.
        r, b, iJ, aux = self.r, self.b, 1.0 / self.J, self.aux
        lin = _lin_law(self.T0, self.k, self.c)
        tc, s0, s1 = mech["tau_c"], mech["sigma0"], mech["sigma1"]
        zmax = tc / s0

        def rhs(xm, v, y):
            th, om, z = y
            s = xm - r * th
            sd = v - r * om
            T1 = lin(s, sd)
            T2 = lin(-s, -sd)
            aux[0] = T1
            aux[1] = T2
            zd = 0.0 if (z >= zmax and om > 0.0) or (z <= -zmax and om < 0.0) else om
            return [om, (r * (T1 - T2) - b * om - s0 * z - s1 * zd) * iJ, zd]

        def post(y_old, y, xm, v):
            z = y[2]
            if z > zmax:
                y[2] = zmax
            elif z < -zmax:
                y[2] = -zmax
            return y

        self.rhs = rhs
        self.post = post
        self.y0 = lambda x0: [x0 / r, 0.0, 0.0]

    # -- Stribeck friction with true stiction (Karnopp) --------------------------------------------
    def _build_karnopp(self, mech):
        # Karnopp (1985, ASME JDSMC 107:100): inside the band |w| < dv the friction balances the
        # applied torque up to the breakaway torque tau_s (the joint sticks); outside, the Tustin
        # (1947) exponential Stribeck curve tau_c + (tau_s - tau_c)*exp(-|w|/w_s) (Armstrong-
        # Helouvry, Dupont & Canudas de Wit 1994).  Stick is also entered when the velocity changes
        # sign within a step and the applied torque is below tau_s (discrete-time Karnopp).
        r, b, iJ, aux = self.r, self.b, 1.0 / self.J, self.aux
        lin = _lin_law(self.T0, self.k, self.c)
        tc, ts, ws, dv = mech["tau_c"], mech["tau_s"], mech["w_s"], mech["dv"]
        stuck = [True]
        exp = math.exp

        def rhs(xm, v, y):
            th = y[0]
            om = y[1]
            s = xm - r * th
            sd = v - r * om
            T1 = lin(s, sd)
            T2 = lin(-s, -sd)
            aux[0] = T1
            aux[1] = T2
            if stuck[0]:
                return [0.0, 0.0]
            ta = r * (T1 - T2) - b * om
            if -dv < om < dv:
                tf = ts if ta > ts else (-ts if ta < -ts else ta)
            else:
                mag = tc + (ts - tc) * exp(-abs(om) / ws)
                tf = mag if om > 0.0 else -mag
            return [om, (ta - tf) * iJ]

        def applied(th, xm, v):
            s = xm - r * th
            return r * (lin(s, v) - lin(-s, -v))

        def post(y_old, y, xm, v):
            if stuck[0]:
                if abs(applied(y[0], xm, v)) > ts:
                    stuck[0] = False
                return y
            w0, w1 = y_old[1], y[1]
            if (w0 * w1 < 0.0 or abs(w1) < dv) and abs(applied(y[0], xm, v)) <= ts:
                stuck[0] = True
                return [y[0], 0.0]
            return y

        def y0(x0):
            stuck[0] = True
            return [x0 / r, 0.0]

        self.rhs = rhs
        self.post = post
        self.y0 = y0

    # -- Backlash between joint pulley and link ---------------------------------------------------
    def _build_joint_backlash(self, mech):
        # Dead-zone with Kelvin-Voigt contact (Nordin & Gutman, Automatica 38 (2002) 1633, "Controlling
        # mechanical systems with backlash - a survey"), non-adhesive: contact torque never pulls.
        r, b, aux = self.r, self.b, self.aux
        lin = _lin_law(self.T0, self.k, self.c)
        h, alpha, kc, cc = mech["half_gap"], mech["alpha"], mech["k_contact"], mech["c_contact"]
        iJp, iJl = 1.0 / (alpha * self.J), 1.0 / ((1.0 - alpha) * self.J)

        def rhs(xm, v, y):
            tp, wp, tl, wl = y
            s = xm - r * tp
            sd = v - r * wp
            T1 = lin(s, sd)
            T2 = lin(-s, -sd)
            aux[0] = T1
            aux[1] = T2
            d = tp - tl
            if d > h:
                tq = kc * (d - h) + cc * (wp - wl)
                tq = tq if tq > 0.0 else 0.0
            elif d < -h:
                tq = kc * (d + h) + cc * (wp - wl)
                tq = tq if tq < 0.0 else 0.0
            else:
                tq = 0.0
            return [wp, (r * (T1 - T2) - tq) * iJp, wl, (tq - b * wl) * iJl]

        self.rhs = rhs
        self.i_thc, self.i_thl = 0, 2
        self.y0 = lambda x0: [x0 / r, 0.0, x0 / r, 0.0]

    # -- Backlash in the motor coupling (before the cables) -------------------------------------
    def _build_input_backlash(self, mech):
        # The capstan (linear-equivalent mass m_c) is driven by the motor hub through a play of
        # half-width h with Kelvin-Voigt contact; inside the play the capstan floats on the cables.
        r, b, iJ, aux = self.r, self.b, 1.0 / self.J, self.aux
        lin = _lin_law(self.T0, self.k, self.c)
        h, imc, kc, cc = mech["half_gap"], 1.0 / mech["m_c"], mech["k_contact"], mech["c_contact"]

        def rhs(xm, v, y):
            xc, vc, th, om = y
            s = xc - r * th
            sd = vc - r * om
            T1 = lin(s, sd)
            T2 = lin(-s, -sd)
            aux[0] = T1
            aux[1] = T2
            d = xm - xc
            if d > h:
                f = kc * (d - h) + cc * (v - vc)
                f = f if f > 0.0 else 0.0
            elif d < -h:
                f = kc * (d + h) + cc * (v - vc)
                f = f if f < 0.0 else 0.0
            else:
                f = 0.0
            return [vc, (f - (T1 - T2)) * imc, om, (r * (T1 - T2) - b * om) * iJ]

        self.rhs = rhs
        self.i_thc, self.i_thl = 2, 2
        self.y0 = lambda x0: [x0, 0.0, x0 / r, 0.0]


def simulate(plant, x):
    """RK4 at 10 kHz on the 1 kHz command x (linear interpolation).  Returns 10 kHz arrays."""
    n = len(x)
    xl = x.tolist()
    vl = (np.append(np.diff(x), 0.0) * FS).tolist()
    f, post, aux = plant.rhs, plant.post, plant.aux
    ic, il = plant.i_thc, plant.i_thl
    y = plant.y0(xl[0])
    h = DT
    h2 = 0.5 * h
    h6 = h / 6.0
    m = n * SUB
    T1 = [0.0] * m
    T2 = [0.0] * m
    thc = [0.0] * m
    thl = [0.0] * m
    xm = [0.0] * m
    idx = 0
    for i in range(n):
        x0 = xl[i]
        v = vl[i]
        for j in range(SUB):
            xa = x0 + v * (j * h)
            xb = xa + v * h2
            xc = xa + v * h
            k1 = f(xa, v, y)
            T1[idx] = aux[0]
            T2[idx] = aux[1]
            thc[idx] = y[ic]
            thl[idx] = y[il]
            xm[idx] = xa
            idx += 1
            k2 = f(xb, v, [a + h2 * d for a, d in zip(y, k1, strict=True)])
            k3 = f(xb, v, [a + h2 * d for a, d in zip(y, k2, strict=True)])
            k4 = f(xc, v, [a + h * d for a, d in zip(y, k3, strict=True)])
            yn = [
                a + h6 * (p + 2.0 * q + 2.0 * s + u) for a, p, q, s, u in zip(y, k1, k2, k3, k4, strict=True)
            ]
            if post is not None:
                yn = post(y, yn, xc, v)
            y = yn
    return {
        "T1": np.array(T1),
        "T2": np.array(T2),
        "thc": np.array(thc),
        "thl": np.array(thl),
        "xm": np.array(xm),
    }


# ----------------------------------------------------------------------------------------------
# Pulley-contact effects on the motor-side tensions (no feedback on the motion)
# ----------------------------------------------------------------------------------------------
def _maxwell_slip(p, T, kap, wfrac, mu):
    """Generalised Maxwell-slip (Lampaert, Al-Bender & Swevers 2003; Al-Bender et al. IEEE TAC 2005).

    N spring-slider elements of stiffness kap_i; element i slips at w_i*mu*T (Coulomb slider
    proportional to the local cable tension, as a capstan contact).  Returns the summed force.
    """
    dp = np.diff(p, prepend=p[0]).tolist()
    Tl = T.tolist()
    n = len(kap)
    d = [0.0] * n
    out = [0.0] * len(dp)
    for m_, dx in enumerate(dp):
        tm = Tl[m_] * mu
        tot = 0.0
        for i in range(n):
            lim = wfrac[i] * tm / kap[i]
            di = d[i] + dx
            if di > lim:
                di = lim
            elif di < -lim:
                di = -lim
            d[i] = di
            tot += kap[i] * di
        out[m_] = tot
    return np.array(out)


def _creep_direction(p, ell):
    """Direction state of the capstan friction with a micro-slip (belt-creep) length ell.

    Belt-creep theory (Johnson, Contact Mechanics 1985, ch. 8; Swift 1928): after a reversal
    the slip zone must sweep the wrap before the full exp(mu*phi) ratio holds; approximated by an
    exponential approach in sliding distance: d(sig) = (sign(dx) - sig)*|dx|/ell.
    """
    dp = np.diff(p, prepend=p[0]).tolist()
    out = [0.0] * len(dp)
    sig = 0.0
    ex = math.exp
    for m_, dx in enumerate(dp):
        if dx > 0.0:
            sig = 1.0 + (sig - 1.0) * ex(-dx / ell)
        elif dx < 0.0:
            sig = -1.0 + (sig + 1.0) * ex(dx / ell)
        out[m_] = sig
    return np.array(out)


def _contact(cfg, sim, r):
    T1, T2 = sim["T1"], sim["T2"]
    if not cfg:
        return T1, T2
    # drive-cable displacement toward the motor at the contact (return cable: the opposite)
    p = cfg.get("lam", 1.0) * sim["xm"] + (1.0 - cfg.get("lam", 1.0)) * r * sim["thc"]
    kind = cfg["kind"]
    if kind == "maxwell":
        a = cfg
        return (
            T1 + _maxwell_slip(p, T1, a["kap"], a["w"], a["mu"]),
            T2 + _maxwell_slip(-p, T2, a["kap"], a["w"], a["mu"]),
        )
    if kind == "capstan_creep":  # Euler-Eytelwein on the drive routing only
        return T1 * np.exp(cfg["mu_phi"] * _creep_direction(p, cfg["ell"])), T2
    if kind == "capstan_reg":  # Euler-Eytelwein on both, algebraic sign regularisation
        v = np.diff(p, prepend=p[0]) / DT
        sg = v / np.sqrt(v * v + cfg["v_eps"] ** 2)
        return T1 * np.exp(cfg["mu_phi_drive"] * sg), T2 * np.exp(-cfg["mu_phi_return"] * sg)
    raise ValueError(kind)


# ----------------------------------------------------------------------------------------------
# Sensors
# ----------------------------------------------------------------------------------------------
def _lag2(sig, fn, zeta):
    """Underdamped 2nd-order force sensor wn^2/(s^2 + 2 zeta wn s + wn^2) (Doebelin, Measurement
    Systems, ch. 3), ZOH-discretised at 10 kHz, started at steady state."""
    wn = 2 * np.pi * fn
    bd, ad, _ = signal.cont2discrete(([wn**2], [1.0, 2 * zeta * wn, wn**2]), DT, method="zoh")
    bd = np.ravel(bd)
    return signal.lfilter(bd, ad, sig, zi=signal.lfilter_zi(bd, ad) * sig[0])[0]


def _delay(sig, d):
    t = np.arange(len(sig)) * DT
    return np.interp(t - d, t, sig, left=sig[0])


def _hx711(sig, period, jitter, phase, rng):
    """Integrating sigma-delta converter (HX711 datasheet, Avia Semiconductor: 10/80 SPS): each
    output word is the mean of the input over its conversion window, held until the next word;
    conversion periods jitter (RC oscillator)."""
    n = len(sig)
    ends = []
    t = phase
    while t < n * DT:
        ends.append(t)
        t += period * (1.0 + jitter * rng.standard_normal())
    idx = np.clip(np.round(np.array(ends) / DT).astype(int), 1, n)
    starts = np.concatenate([[max(idx[0] - round(period / DT), 0)], idx[:-1]])
    csum = np.concatenate([[0.0], np.cumsum(sig)])
    means = (csum[idx] - csum[starts]) / np.maximum(idx - starts, 1)
    k = np.searchsorted(idx, np.arange(n), side="right") - 1
    return np.where(k >= 0, means[np.maximum(k, 0)], sig[0])


def _measure(spec, sim, nom, q, rngs, run):
    """Motor-side tensions and encoder through the case's sensor chain, at 1 kHz."""
    sens = spec.get("sensor", {})
    Tm1, Tm2 = _contact(spec.get("contact"), sim, nom["r"])
    th = sim["thl"]
    noise = rngs["noise"][run].normal(0.0, SIGMA_T, (2, N_SAMPLES))
    if "lag2" in sens:
        fn, ze = sens["lag2"]
        Tm1, Tm2 = _lag2(Tm1, fn, ze), _lag2(Tm2, fn, ze)
    if "delay_T" in sens:
        Tm1, Tm2 = _delay(Tm1, sens["delay_T"]), _delay(Tm2, sens["delay_T"])
    if "delay_th" in sens:
        th = _delay(th, sens["delay_th"])
    if "hx711" in sens:
        per, jit, ph1, ph2 = sens["hx711"]
        rj = rngs["aux"][run]
        Tm1, Tm2 = _hx711(Tm1, per, jit, ph1, rj), _hx711(Tm2, per, jit, ph2, rj)
    y1, y2, th = Tm1[::SUB].copy(), Tm2[::SUB].copy(), th[::SUB].copy()
    if "sh" in sens:
        # plain sample-and-hold every P ms; the converter noise is part of the held sample
        per = sens["sh"]
        si = np.arange(0, N_SAMPLES, per)
        k = np.searchsorted(si, np.arange(N_SAMPLES), side="right") - 1
        y1 = (y1[si] + noise[0, : len(si)])[k]
        y2 = (y2[si] + noise[1, : len(si)])[k]
    else:
        if "gainbias_ret" in sens:
            g, bias = sens["gainbias_ret"]
            y2 = g * y2 + bias
        if "drift_drive" in sens:
            y1 = sens["drift_drive"][run]["gain"] * y1 + sens["drift_drive"][run]["bias"]
        y1 = y1 + noise[0]
        y2 = y2 + noise[1]
    th_q = np.round(th / q) * q  # encoder quantisation (Widrow & Kollar, Quantization Noise 2008)
    return y1, y2, th_q


# ----------------------------------------------------------------------------------------------
# Cases
# ----------------------------------------------------------------------------------------------
def _draw_nominal(rng):
    return {
        "r": rng.uniform(0.008, 0.015),
        "J": rng.uniform(1e-4, 4e-4),
        "b": rng.uniform(1e-4, 5e-4),
        "k": rng.uniform(10e3, 25e3),
        "c": rng.uniform(2.0, 6.0),
        "T0": rng.uniform(15.0, 30.0),
    }


def _u(rng, lo, hi):
    return float(rng.uniform(lo, hi))


def _joint_backlash(rng, nom, sc):
    alpha = _u(rng, 0.2, 0.4)
    fc, zc = _u(rng, 150.0, 300.0), _u(rng, 0.1, 0.3)
    mu = alpha * (1 - alpha) * nom["J"]  # reduced inertia of the contact pair
    kc = mu * (2 * np.pi * fc) ** 2
    mech = {
        "kind": "joint_backlash",
        "half_gap": _u(rng, 2e-3, 6e-3) * sc,
        "alpha": alpha,
        "k_contact": kc,
        "c_contact": 2 * zc * math.sqrt(kc * mu),
    }
    return mech, {k: mech[k] for k in ("half_gap", "alpha", "k_contact", "c_contact")}


def _payload(rng, sc):
    return _u(rng, 0.3, 0.6) * sc


def _spec(cid, rng, nom, sc):
    """Effect specification of case cid.  sc >= 1 scales the effect's magnitude (visibility)."""
    k, T0, J = nom["k"], nom["T0"], nom["J"]
    if cid == 1:
        f = _payload(rng, sc)
        return {
            "mech": {"payload": f},
            "effects": {"inertia_error": {"factor": 1 + f, "J_true": J * (1 + f)}},
            "site": "joint",
            "form": "payload on the link: J_true = J*(1+f)",
        }
    if cid == 2:
        mech, p = _joint_backlash(rng, nom, sc)
        return {
            "mech": mech,
            "effects": {"backlash": p},
            "site": "joint",
            "form": "dead zone pulley<->link, Kelvin-Voigt non-adhesive contact; encoder on link; "
            "pulley carries alpha*J",
        }
    if cid == 3:
        mc, fc, zc = _u(rng, 0.02, 0.05), _u(rng, 300.0, 500.0), 0.2
        kc = mc * (2 * np.pi * fc) ** 2
        mech = {
            "kind": "input_backlash",
            "half_gap": _u(rng, 20e-6, 60e-6) * sc,
            "m_c": mc,
            "k_contact": kc,
            "c_contact": 2 * zc * math.sqrt(kc * mc),
        }
        return {
            "mech": mech,
            "effects": {"backlash": {kk: mech[kk] for kk in mech if kk != "kind"}},
            "site": "input",
            "form": "play between motor hub and capstan (mass m_c) with Kelvin-Voigt "
            "contact; capstan floats on the cables inside the play",
        }
    if cid in (4, 19):
        fn, ze = _u(rng, 15.0, 40.0) / sc, _u(rng, 0.15, 0.4)
        lag = {"f_n": fn, "zeta": ze}
        if cid == 4:
            return {
                "sensor": {"lag2": (fn, ze)},
                "effects": {"sensor_lag": lag},
                "site": "sensors.force",
                "form": "underdamped 2nd-order force sensor wn^2/(s^2+2 zeta wn s+wn^2) on both cells",
            }
        mech, p = _joint_backlash(rng, nom, sc)
        return {
            "mech": mech,
            "sensor": {"lag2": (fn, ze)},
            "effects": {"backlash": p, "sensor_lag": lag},
            "site": ["joint", "sensors.force"],
            "form": ["dead zone pulley<->link with contact stiffness", "underdamped 2nd-order force sensor"],
        }
    if cid == 5:
        per, jit = _u(rng, 0.06, 0.12) * sc, _u(rng, 0.005, 0.02)
        ph = (_u(rng, 0, per), _u(rng, 0, per))
        return {
            "sensor": {"hx711": (per, jit, *ph)},
            "effects": {
                "sensor_sampling": {
                    "period": per,
                    "jitter_rel": jit,
                    "phase_drive": ph[0],
                    "phase_return": ph[1],
                }
            },
            "site": "sensors.force",
            "form": "integrating converter: mean over each conversion window, "
            "held; jittered clock; noise after the hold",
        }
    if cid == 6:
        per = int(min(rng.integers(20, 41) * sc, 200))
        return {
            "sensor": {"sh": per},
            "effects": {"sensor_sampling": {"period": per / 1000.0}},
            "site": "sensors.force",
            "form": "sample-and-hold; noise in the held sample (before the hold)",
        }
    if cid == 7:
        nom["T0"] = T0 = _u(rng, 15.0, 18.0)  # low pretension for this case (drawn here, in the nominal)
        Tt, p = T0 * _u(rng, 1.3, 1.8) * sc, _u(rng, 1.6, 2.4)
        return {
            "mech": {"cable": ("toe", Tt, p)},
            "effects": {
                "nonlinear_stiffness": {
                    "T_transition": Tt,
                    "exponent": p,
                    "k_at_T0": k * (T0 / Tt) ** ((p - 1) / p),
                }
            },
            "site": "cable.both",
            "form": "toe region: T = A*e^p below T_transition, slope k above (C1)",
        }
    if cid == 8:
        sk, k2 = _u(rng, 20e-6, 50e-6), k * (1 + _u(rng, 0.6, 1.4) * sc)
        return {
            "mech": {"cable": ("bilinear", sk, k2)},
            "effects": {"nonlinear_stiffness": {"knee_stretch": sk, "k_above": k2}},
            "site": "cable.both",
            "form": "bilinear rope: slope k below knee stretch, k_above beyond",
        }
    if cid == 9:
        tc = _u(rng, 0.003, 0.008) * sc
        ts, ws = tc * _u(rng, 1.5, 2.5), _u(rng, 2e-3, 10e-3)
        mech = {"kind": "karnopp", "tau_c": tc, "tau_s": ts, "w_s": ws, "dv": 1e-4}
        return {
            "mech": mech,
            "effects": {"stribeck_friction": {kk: mech[kk] for kk in mech if kk != "kind"}},
            "site": "joint",
            "form": "Karnopp stick band + Tustin exponential Stribeck curve",
        }
    if cid == 10:
        tc = _u(rng, 0.003, 0.010) * sc
        s0 = tc / _u(rng, 1e-4, 3e-4)
        mech = {"kind": "bristle", "tau_c": tc, "sigma0": s0, "sigma1": 2 * 0.5 * math.sqrt(s0 * J)}
        return {
            "mech": mech,
            "effects": {"coulomb_friction": {kk: mech[kk] for kk in mech if kk != "kind"}},
            "site": "joint",
            "form": "Coulomb with saturating bristle (reset integrator, Haessig-Friedland)",
        }
    if cid == 11:
        mu, lam = _u(rng, 0.02, 0.05) * sc, _u(rng, 0.6, 0.9)
        ell = np.array([5e-6, 20e-6, 60e-6, 200e-6]) * rng.uniform(0.7, 1.5, 4)
        w = rng.dirichlet(np.full(4, 2.0))
        kap = w * mu * T0 / ell  # presliding length ell_i at the pretension
        return {
            "contact": {"kind": "maxwell", "mu": mu, "w": w.tolist(), "kap": kap.tolist(), "lam": lam},
            "effects": {
                "dahl_hysteresis": {
                    "mu": mu,
                    "weights": w.tolist(),
                    "stiffness": kap.tolist(),
                    "contact_position": lam,
                }
            },
            "site": "contact.both",
            "form": "4-element Maxwell-slip per cable, slip forces w_i*mu*T, added to motor-side tension",
        }
    if cid == 12:
        mp, ell, lam = _u(rng, 0.03, 0.08) * sc, _u(rng, 5e-5, 3e-4), _u(rng, 0.7, 1.0)
        return {
            "contact": {"kind": "capstan_creep", "mu_phi": mp, "ell": ell, "lam": lam},
            "effects": {"capstan_friction": {"mu_phi": mp, "creep_length": ell, "contact_position": lam}},
            "site": "contact.drive",
            "form": "T_motor = T*exp(mu_phi*sig), sig relaxes to sign(dx) "
            "over sliding distance ell (belt creep); drive only",
        }
    if cid == 13:
        k2, tau2, loss = k * _u(rng, 4.0, 8.0) / sc, _u(rng, 1.0, 4.0), _u(rng, 0.03, 0.08) * sc
        mech = {"kind": "creep", "k2": k2, "eta2": k2 * tau2, "eta1": 20.0 * k / loss}
        return {
            "mech": mech,
            "effects": {"creep": {kk: mech[kk] for kk in mech if kk != "kind"}},
            "site": "cable.both",
            "form": "Burgers rope (Maxwell spring k + Kelvin-Voigt k2,eta2 + flow "
            "eta1), fresh pretension each run",
        }
    if cid == 14:
        frac = min(_u(rng, 0.7, 0.95) * sc, 1.6)
        delta = frac * T0 / k
        return {
            "mech": {"cable": ("slack", delta)},
            "effects": {"slack": {"slip": delta, "fraction_of_pretension_stretch": frac}},
            "site": "cable.drive",
            "form": "drive terminal slipped by delta (drive cable longer)",
        }
    if cid == 15:
        d = _u(rng, 0.010, 0.040) * sc
        return {
            "sensor": {"delay_T": d},
            "effects": {"time_delay": {"delay": d}},
            "site": "sensors.force",
            "form": "tension channels delayed (bus), encoder not",
        }
    if cid == 16:
        d = _u(rng, 0.005, 0.020) * sc
        return {
            "sensor": {"delay_th": d},
            "effects": {"time_delay": {"delay": d}},
            "site": "sensor.theta",
            "form": "encoder delayed, tensions not",
        }
    if cid == 17:
        g = 1.0 - _u(rng, 0.05, 0.10) * sc
        bias = _u(rng, 0.2, 0.6) * (1 if rng.integers(2) else -1) * sc
        return {
            "sensor": {"gainbias_ret": (g, bias)},
            "effects": {"sensor_gain_bias": {"gain": g, "bias": bias}},
            "site": "sensor.tension_motor_return",
            "form": "return cell y = gain*T + bias",
        }
    if cid == 18:
        lam = _u(rng, 2.0, 4.0) * nom["c"] / T0 * sc
        return {
            "mech": {"cable": ("tdamp", lam)},
            "effects": {"cable_damping": {"lambda": lam, "extra_c_at_T0": lam * T0}},
            "site": "cable.both",
            "form": "load-proportional damping T = Te + (c + lambda*Te)*ds/dt",
        }
    if cid == 20:
        f = _payload(rng, sc)
        md, mr, ve = _u(rng, 0.03, 0.08) * sc, _u(rng, 0.03, 0.08) * sc, _u(rng, 5e-4, 2e-3)
        return {
            "mech": {"payload": f},
            "contact": {"kind": "capstan_reg", "mu_phi_drive": md, "mu_phi_return": mr, "v_eps": ve},
            "effects": {
                "inertia_error": {"factor": 1 + f, "J_true": J * (1 + f)},
                "capstan_friction": {"mu_phi_drive": md, "mu_phi_return": mr, "v_eps": ve},
            },
            "site": ["joint", "contact.both"],
            "form": ["payload J*(1+f)", "T_motor = T*exp(+-mu_phi*v/sqrt(v^2+v_eps^2)), own wrap per cable"],
        }
    if cid == 21:
        A, n_r, ph = _u(rng, 0.002, 0.006) * sc, int(rng.integers(6, 13)), _u(rng, 0, 2 * np.pi)
        return {
            "mech": {"ripple": (A, n_r, ph)},
            "in_library": False,
            "effects": {"none_of_library": {"amplitude": A, "periods_per_rev": n_r, "phase": ph}},
            "description": "position-periodic (cogging-like / pulley-eccentricity) torque ripple "
            "tau = -A*sin(n*theta + phi) on the joint",
            "site": "joint",
            "form": "torque ripple A*sin(n*theta+phi)",
        }
    if cid == 22:
        dg = _u(rng, 0.02, 0.05) * (1 if rng.integers(2) else -1) * sc
        tau_th, s_rw = _u(rng, 20.0, 60.0), _u(rng, 0.01, 0.03) * sc
        steps = rng.normal(0.0, s_rw * math.sqrt(1.0 / FS), 2 * N_SAMPLES)
        bias = np.cumsum(steps)
        t = np.arange(2 * N_SAMPLES) / FS  # the hold-out session follows the fit session
        gain = 1.0 + dg * (1.0 - np.exp(-t / tau_th))
        dr = [
            {"gain": gain[:N_SAMPLES], "bias": bias[:N_SAMPLES]},
            {"gain": gain[N_SAMPLES:], "bias": bias[N_SAMPLES:]},
        ]
        return {
            "sensor": {"drift_drive": dr},
            "in_library": False,
            "effects": {
                "none_of_library": {"gain_drift_total": dg, "tau_thermal": tau_th, "bias_random_walk": s_rw}
            },
            "description": "thermal drift of the drive load cell: gain 1 + dg*(1 - exp(-t/tau)) over the "
            "fit then hold-out sessions, plus a random-walk bias (N/sqrt(s))",
            "site": "sensor.tension_motor_drive",
            "form": "time-varying gain + random-walk bias",
        }
    if cid in (23, 24):
        return {"effects": {}, "site": None, "form": None}
    raise ValueError(f"unknown case {cid}")


# ----------------------------------------------------------------------------------------------
# One case: simulate, measure, gap, write
# ----------------------------------------------------------------------------------------------
def _rngs(case_seed):
    ss = np.random.SeedSequence(case_seed).spawn(6)
    g = [np.random.default_rng(s) for s in ss]
    return {"nominal": g[0], "params": g[1], "traj": g[2], "noise": (g[3], g[4]), "aux": (g[5], g[5])}


def _gap(meas, nom_sim, q):
    y1, y2, th = meas
    g = [
        float(np.mean((y1 - nom_sim["T1"][::SUB]) ** 2) / SIGMA_T**2),
        float(np.mean((y2 - nom_sim["T2"][::SUB]) ** 2) / SIGMA_T**2),
        float(np.mean((th - nom_sim["thl"][::SUB]) ** 2) / (q * q / 12.0)),
    ]
    return float(np.mean(g)), g


def _write_csv_gz(path, x, meas):
    t = np.arange(N_SAMPLES) / FS
    buf = io.StringIO()
    buf.write(HEADER + "\n")
    np.savetxt(buf, np.column_stack([t, x, *meas]), fmt="%.9g", delimiter=",")
    with open(path, "wb") as fh, gzip.GzipFile(filename="", mode="wb", fileobj=fh, mtime=0) as gz:
        gz.write(buf.getvalue().encode())


def _model_toml(nom):
    return (
        'model = "antagonistic_joint"\n\n[parameters]\n'
        f"radius = {nom['r']!r}\nstiffness = {nom['k']!r}\ninertia = {nom['J']!r}\n"
        f"damping = {nom['c']!r}\npretension = {nom['T0']!r}\nviscous = {nom['b']!r}\ncoulomb = 0.0\n\n"
        '[inputs]\nx_m = "motor_pos"\n\n[outputs]\ntension_motor_drive = "tension_drive"\n'
        'tension_motor_return = "tension_return"\ntheta = "joint_pos"\n'
    )


def _jsonable(o):
    if isinstance(o, dict):
        return {k: _jsonable(v) for k, v in o.items()}
    if isinstance(o, list | tuple):
        return [_jsonable(v) for v in o]
    if isinstance(o, np.floating | np.integer):
        return o.item()
    return o


def build_case(cid, seed=DEFAULT_SEED):
    """Simulate case cid; returns (truth, {run: (x, meas)}) without writing anything."""
    case_seed = seed + cid
    sc = 1.0
    for _attempt in range(5):
        rngs = _rngs(case_seed)  # identical draws on every attempt; only the scale changes
        nom = _draw_nominal(rngs["nominal"])
        cpr = int(rngs["nominal"].choice([4096, 5000, 8000, 8192, 10000, 12800, 16384]))
        q = 2 * np.pi / cpr
        spec = _spec(cid, rngs["params"], nom, sc)
        f_n = math.sqrt(2 * nom["k"] * nom["r"] ** 2 / nom["J"]) / (2 * np.pi)
        xs = {
            "fit": fit_trajectory(rngs["traj"], nom["r"], f_n),
            "holdout": holdout_trajectory(rngs["traj"], nom["r"], f_n),
        }
        plant = Plant(nom, spec.get("mech"))
        runs, gaps = {}, {}
        for ri, run in enumerate(("fit", "holdout")):
            sim = simulate(plant, xs[run])
            meas = _measure(spec, sim, nom, q, rngs, ri)
            runs[run] = (xs[run], meas)
            nom_sim = sim if "mech" not in spec else simulate(Plant(nom), xs[run])
            gaps[run] = _gap(meas, nom_sim, q)
        if cid in (23, 24) or gaps["holdout"][0] >= G_TARGET:
            break
        sc *= 2.0
    truth = {
        "case": f"case{cid:02d}",
        "effects": spec["effects"],
        "nominal": {kk: nom[kk] for kk in ("r", "J", "b", "k", "c", "T0")},
        "seed": case_seed,
        "site": spec["site"],
        "form": spec["form"],
        "in_library": spec.get("in_library", True),
        "nominal_gap_holdout": gaps["holdout"][0],
        "nominal_gap_holdout_channels": dict(
            zip(("tension_drive", "tension_return", "joint_pos"), gaps["holdout"][1], strict=True)
        ),
        "effect_scale": sc,
        "encoder_counts_per_turn": cpr,
        "noise": {"tension_sigma": SIGMA_T, "encoder": "quantised, no other noise"},
    }
    if "description" in spec:
        truth["description"] = spec["description"]
    truth["nominal_gap_fit"] = gaps["fit"][0]
    return _jsonable(truth), runs, nom


def write_case(outdir, cid, seed=DEFAULT_SEED):
    t0 = time.perf_counter()
    truth, runs, nom = build_case(cid, seed)
    d = os.path.join(outdir, f"case{cid:02d}")
    os.makedirs(d, exist_ok=True)
    for run, (x, meas) in runs.items():
        _write_csv_gz(os.path.join(d, f"{run}.csv.gz"), x, meas)
    with open(os.path.join(d, "model.toml"), "w") as fh:
        fh.write(_model_toml(nom))
    with open(os.path.join(d, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=2)
        fh.write("\n")
    return truth, time.perf_counter() - t0


def _label(truth):
    if not truth["effects"]:
        return "control"
    site = truth["site"] if isinstance(truth["site"], list) else [truth["site"]]
    return " + ".join(f"{e}@{s}" for e, s in zip(truth["effects"], site, strict=True))


def generate(outdir, cases=None, seed=DEFAULT_SEED, workers=2, verbose=True):
    """Write the cases (default: all) under outdir; return their truths, ordered by case id."""
    cases = list(CASE_IDS if cases is None else cases)
    bad = [c for c in cases if c not in CASE_IDS]
    if bad:
        raise ValueError(f"unknown case ids {bad}; valid: 1..24")
    os.makedirs(outdir, exist_ok=True)
    t0 = time.perf_counter()
    truths = {}

    def report(tr, dt):
        truths[int(tr["case"][4:])] = tr
        if verbose:
            print(
                f"{tr['case']}  {_label(tr):58s} G_holdout={tr['nominal_gap_holdout']:10.2f}  ({dt:.1f} s)",
                flush=True,
            )

    if workers > 1 and len(cases) > 1:
        with ProcessPoolExecutor(max_workers=workers) as ex:
            futs = [ex.submit(write_case, outdir, c, seed) for c in cases]
            for fu in as_completed(futs):
                report(*fu.result())
    else:
        for c in cases:
            report(*write_case(outdir, c, seed))
    out = [truths[c] for c in sorted(truths)]
    if verbose:
        print(f"\n{'case':7s}{'effect@site':62s}{'scale':>6s}{'G_hold':>10s}  per channel (Td, Tr, theta)")
        for tr in out:
            ch = tr["nominal_gap_holdout_channels"]
            print(
                f"{tr['case']:7s}{_label(tr):62s}{tr['effect_scale']:6.0f}{tr['nominal_gap_holdout']:10.2f}  "
                f"({ch['tension_drive']:.2f}, {ch['tension_return']:.2f}, {ch['joint_pos']:.2f})"
            )
        print(f"generated {len(out)} cases in {time.perf_counter() - t0:.1f} s")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(
        prog="python -m tests.generators.joint_b", description=__doc__.splitlines()[0]
    )
    ap.add_argument("outdir")
    ap.add_argument("--cases", default=None, help="comma-separated case ids (1..24); default all")
    ap.add_argument("--seed", type=int, default=DEFAULT_SEED)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    cases = None if a.cases is None else [int(s) for s in a.cases.split(",") if s.strip()]
    if cases is not None and not set(cases) <= set(CASE_IDS):
        ap.error(f"unknown case ids {sorted(set(cases) - set(CASE_IDS))}; valid ids are 1..24")
    generate(a.outdir, cases, seed=a.seed, workers=a.workers)
    return 0


if __name__ == "__main__":
    sys.exit(main())
