"""Independent simulator of cable-driven mechanisms, for testing diagnosis on foreign data.

This module is written from the literature only and deliberately shares no code with the rest of
the package: it imports the standard library, NumPy and SciPy, nothing else.  It builds three
plants (a two-stage instrument drive, a 3-joint tendon-driven finger, a 2-link coupled cable
transmission), writes their NOMINAL description in the public network file format, injects one
effect into the TRUE plant and records noisy measurements.  :func:`cases` returns the resulting
diagnosis cases.

Model (own formulation)
-----------------------
Coordinates are the joint angles, the rotor angles of torque-driven motors (both dynamic, with
inertia) and the capstan angles of position-driven motors (kinematic: the commanded, possibly
delayed, motor angle; with backlash a massless capstan free inside a dead zone).

Kinematics (structure matrix, Salisbury & Craig 1982; Tsai & Lee 1989).  Each cable ``c`` has a
stretch ``delta_c = sum_i D[c, i] x_i`` with ``D[c, motor] = motor_sense * R / G`` and
``D[c, joint] = sum sense * r`` over its contacts on pulleys of that joint; hauling in and winding
both increase the stretch.  The generalised force of a cable of tension ``T`` on coordinate ``i``
is ``-D[c, i] * T``.

Each cable has a *driver*: the motor that hauls it, or (cable anchored at both ends) the joint of
its first contact.  The elasticity of the cable is lumped beyond its last friction contact (the
joint side): ``T = T0 + law(delta) + c * d(delta)/dt`` clamped at zero (a cable cannot push).  The
short part between the driver and the friction contacts (fixed pulleys directly after the driver)
is taken rigid, so the cable slides over those contacts with the driver's haul-in speed ``u``.
Euler-Eytelwein (capstan) friction then gives the driver-side tension ``T * exp(mu*phi * sgn u)``
while sliding and anything in ``T * [exp(-mu*phi), exp(mu*phi)]`` while sticking (Kaneko et al.
1991).  On the driver coordinate this is exactly a force ``-a T cosh(mu*phi)`` plus a Coulomb
friction of load-dependent magnitude ``|a| T sinh(mu*phi)`` with a true stick phase, and it is
integrated as such.

Friction on dynamic coordinates: exactly switched Coulomb with a stick phase, viscous, and an
exponential-decay Stribeck term ``(Fs - Fc) exp(-|v|/vs)`` (break-away at ``Fs``), or a Dahl
model ``dz/dtheta = (sigma) (1 - z sgn(dtheta) / Fc)`` (integrated exactly along the path).  A
standard linear solid (spring ``(1-alpha) k`` in parallel with a Maxwell arm ``alpha k``, time
constant ``tau``) models creep.

Time stepping (fixed sub-step, 10 per sample): leapfrog, i.e. positions at the sub-step
instants and velocities at half steps; velocity-dependent forces use the velocity extrapolated
to the instant, viscous friction is trapezoidal, and Coulomb/Stribeck/capstan friction is exactly
switched: a sliding coordinate keeps its friction direction unless its velocity reaches zero
within the step, in which case the zero-crossing time is resolved and the remainder starts from
rest (stick while the other forces stay within the static bound; Moreau-type time stepping).
Held (zero-order-hold) motor torques are integrated exactly across sample instants.  The scheme
is second order (the tests check convergence and energy conservation).  Every run starts at rest
at the frictionless static equilibrium of the TRUE plant (creep relaxed, Dahl state zero).

Measurements: encoders quantised (2^12 counts/turn on joints, 2^14 on motors), tension cells with
white noise of 1 % of the nominal pretension, torque channels with white noise of 1.5 % of their
RMS.  ``load_m:<motor>`` is ``(R/G) * sum(motor_sense * T_motor)`` over the motor's cables, plus
the motor's own friction for a position-driven motor (the torque its current measures).

Inputs (columns ``u:<motor>``): a position-driven motor's commanded angle, a faded-in
multi-sine (with ``time_delay`` the motor follows it late; ``q_m`` is the motor's actual angle);
a torque-driven motor's commanded torque, from a joint-space PD with feed-forward running on the
TRUE plant at 1 kHz (zero-order hold; with ``time_delay`` the plant receives it late).  The
finger's PD takes its joint feedback from the motor encoders through the structure matrix
(collocated, as real tendon hands do), the transmission's from the link encoders.
"""

from __future__ import annotations

import json
import math
import tomllib
import zlib
from dataclasses import dataclass, field

import numpy as np
from scipy import signal
from scipy.interpolate import CubicSpline

DT = 1e-3
RUN_SECONDS = 3.0
RAMP_SECONDS = 0.4
JOINT_COUNTS = 2**12
MOTOR_COUNTS = 2**14
TENSION_NOISE = 0.01
TORQUE_NOISE = 0.015

LIBRARY_EFFECTS = (
    "coulomb_friction",
    "viscous_friction",
    "stribeck_friction",
    "inertia_error",
    "capstan_friction",
    "nonlinear_stiffness",
    "cable_damping",
    "slack",
    "sensor_gain_bias",
    "sensor_lag",
    "time_delay",
)
OUTSIDE_EFFECTS = ("dahl_hysteresis", "creep", "backlash")


@dataclass
class NetCase:
    """One diagnosis case: nominal network, recorded runs of the TRUE plant, and the truth."""

    name: str
    plant: str
    network_toml: str
    inputs: dict[str, str]
    outputs: dict[str, str]
    fit_runs: list[tuple[str, float, dict[str, np.ndarray]]]
    hold_runs: list[tuple[str, float, dict[str, np.ndarray]]]
    truth_effect: str | None
    truth_site: str | None
    in_library: bool
    size: str


@dataclass
class Effect:
    """One injected effect: canonical name, site, values, human description."""

    kind: str
    site: str
    values: dict = field(default_factory=dict)
    size: str = ""

    @property
    def in_library(self) -> bool:
        return self.kind in LIBRARY_EFFECTS


# --------------------------------------------------------------------------------------------
# network file format
# --------------------------------------------------------------------------------------------


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ValueError("non-finite value")
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v)} to TOML")


def to_toml(spec: dict) -> str:
    """Write a network spec (plain dicts and lists) in the network file format."""
    lines = []
    for key in ("name", "description", "capstan_smoothing"):
        lines.append(f"{key} = {_toml_value(spec[key])}")
    for table in ("bodies", "joints", "pulleys", "motors", "cables"):
        for item in spec.get(table, []):
            lines.append("")
            lines.append(f"[[{table}]]")
            lines.extend(f"{k} = {_toml_value(v)}" for k, v in item.items())
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------
# compiled network
# --------------------------------------------------------------------------------------------


@dataclass
class Network:
    spec: dict
    joints: list[str]
    tmotors: list[str]
    pmotors: list[str]
    cables: list[str]
    D: np.ndarray  # (n_cables, n_coords) stretch per coordinate
    driver: np.ndarray  # (n_cables,) coordinate index of each cable's driver
    a_drv: np.ndarray  # (n_cables,) D entry of the driver
    contacts: list[list[tuple[str, float]]]  # per cable: (pulley, wrap) of fixed friction-capable contacts
    inertia: np.ndarray  # (nd,)
    coulomb: np.ndarray
    viscous: np.ndarray
    pm_coulomb: np.ndarray  # (npm,)
    pm_viscous: np.ndarray
    stiffness: np.ndarray  # (nc,)
    damping: np.ndarray
    pretension: np.ndarray
    mphi: np.ndarray

    @property
    def nj(self) -> int:
        return len(self.joints)

    @property
    def nd(self) -> int:
        return len(self.joints) + len(self.tmotors)

    @property
    def ncoord(self) -> int:
        return self.nd + len(self.pmotors)

    @property
    def nc(self) -> int:
        return len(self.cables)

    def coord(self, name: str) -> int:
        names = self.joints + self.tmotors + self.pmotors
        return names.index(name)


def compile_network(spec: dict) -> Network:
    """Structure matrix and nominal parameters of a network spec (see module docstring)."""
    bodies = {b["name"]: b for b in spec["bodies"]}
    pulleys = {p["name"]: p for p in spec.get("pulleys", [])}
    motors = {m["name"]: m for m in spec.get("motors", [])}
    joints = [j["name"] for j in spec["joints"]]
    tm = [m for m, d in motors.items() if d["drive"] == "torque"]
    pm = [m for m, d in motors.items() if d["drive"] == "position"]
    names = joints + tm + pm
    idx = {n: i for i, n in enumerate(names)}
    for j in spec["joints"]:
        if j.get("kind", "revolute") != "revolute" or j.get("gravity_amplitude", 0.0) != 0.0:
            raise ValueError("only revolute joints without gravity are simulated")
    cables = [c["name"] for c in spec["cables"]]
    nc = len(cables)
    D = np.zeros((nc, len(names)))
    driver = np.zeros(nc, dtype=int)
    a_drv = np.zeros(nc)
    mphi = np.zeros(nc)
    contacts: list[list[tuple[str, float]]] = []
    for ci, c in enumerate(spec["cables"]):
        routing = c["routing"]
        if "motor" in c:
            m = motors[c["motor"]]
            a = c.get("motor_sense", 1) * m["capstan_radius"] / m.get("gear_ratio", 1.0)
            driver[ci] = idx[c["motor"]]
            rest = routing
        else:
            first = routing[0]
            p = pulleys[first["pulley"]]
            if "joint" not in p:
                raise ValueError(f"cable {c['name']}: an anchored cable starts on a joint pulley")
            a = first.get("sense", 1) * p["radius"]
            driver[ci] = idx[p["joint"]]
            rest = routing[1:]
        a_drv[ci] = a
        D[ci, driver[ci]] += a
        fixed_run = True  # still in the run of fixed pulleys right after the driver
        cl = []
        for ct in rest:
            p = pulleys[ct["pulley"]]
            mu = float(ct.get("mu", 0.0))
            if "joint" in p:
                D[ci, idx[p["joint"]]] += ct.get("sense", 1) * p["radius"]
                fixed_run = False
                if mu != 0.0:
                    raise ValueError(f"cable {c['name']}: friction only on fixed pulleys")
            else:
                if fixed_run:
                    cl.append((ct["pulley"], float(ct["wrap"])))
                elif mu != 0.0:
                    raise ValueError(f"cable {c['name']}: friction contact after a joint pulley")
                mphi[ci] += mu * float(ct["wrap"])
        contacts.append(cl)
    inertia = [bodies[j["child"]]["inertia"] for j in spec["joints"]]
    inertia += [motors[m]["inertia"] for m in tm]
    coulomb = [j.get("coulomb", 0.0) for j in spec["joints"]] + [motors[m].get("coulomb", 0.0) for m in tm]
    viscous = [j.get("viscous", 0.0) for j in spec["joints"]] + [motors[m].get("viscous", 0.0) for m in tm]
    for c in spec["cables"]:
        if c.get("law", "linear") != "linear":
            raise ValueError("nominal cables are linear")
    return Network(
        spec=spec,
        joints=joints,
        tmotors=tm,
        pmotors=pm,
        cables=cables,
        D=D,
        driver=driver,
        a_drv=a_drv,
        contacts=contacts,
        inertia=np.array(inertia, float),
        coulomb=np.array(coulomb, float),
        viscous=np.array(viscous, float),
        pm_coulomb=np.array([motors[m].get("coulomb", 0.0) for m in pm], float),
        pm_viscous=np.array([motors[m].get("viscous", 0.0) for m in pm], float),
        stiffness=np.array([c["stiffness"] for c in spec["cables"]], float),
        damping=np.array([c.get("damping", 0.0) for c in spec["cables"]], float),
        pretension=np.array([c.get("pretension", 0.0) for c in spec["cables"]], float),
        mphi=mphi,
    )


# --------------------------------------------------------------------------------------------
# per-member parameters (nominal + one effect)
# --------------------------------------------------------------------------------------------


def member_params(net: Network, effect: Effect | None) -> dict[str, np.ndarray]:
    """Parameters of the TRUE plant: nominal values with ``effect`` applied."""
    p = {
        "inertia": net.inertia.copy(),
        "coulomb": net.coulomb.copy(),
        "viscous": net.viscous.copy(),
        "strib_extra": np.zeros(net.nd),
        "strib_v": np.ones(net.nd),
        "dahl_fc": np.zeros(net.nd),
        "dahl_rate": np.zeros(net.nd),
        "stiffness": net.stiffness.copy(),
        "damping": net.damping.copy(),
        "pretension": net.pretension.copy(),
        "mphi": net.mphi.copy(),
        "beta": np.zeros(net.nc),
        "creep_alpha": np.zeros(net.nc),
        "creep_tau": np.ones(net.nc),
        "pm_coulomb": net.pm_coulomb.copy(),
        "pm_viscous": net.pm_viscous.copy(),
        "backlash": np.zeros(len(net.pmotors)),
        "delay": np.zeros(()),
    }
    if effect is None:
        return p
    kind, site, val = effect.kind, effect.site, effect.values
    group, _, name = site.partition(".")
    if group in ("joint", "motor"):
        if group == "motor" and name in net.pmotors:
            k = net.pmotors.index(name)
            if kind == "coulomb_friction":
                p["pm_coulomb"][k] = val["coulomb"]
            elif kind == "viscous_friction":
                p["pm_viscous"][k] = val["viscous"]
            elif kind == "backlash":
                p["backlash"][k] = val["half_gap"]
            else:
                raise ValueError(f"{kind} at {site}")
            return p
        i = net.coord(name)
        if kind == "coulomb_friction":
            p["coulomb"][i] = val["coulomb"]
        elif kind == "viscous_friction":
            p["viscous"][i] = val["viscous"]
        elif kind == "stribeck_friction":
            p["strib_extra"][i] = val["static"] - p["coulomb"][i]
            p["strib_v"][i] = val["v_stribeck"]
        elif kind == "inertia_error":
            p["inertia"][i] *= val["factor"]
        elif kind == "dahl_hysteresis":
            p["dahl_fc"][i] = p["coulomb"][i]
            p["dahl_rate"][i] = val["sigma"] / p["coulomb"][i]
            p["coulomb"][i] = 0.0
        else:
            raise ValueError(f"{kind} at {site}")
    elif group in ("cable", "routing"):
        c = net.cables.index(name)
        if kind == "capstan_friction":
            wraps = dict(net.contacts[c])
            p["mphi"][c] += val["mu"] * wraps[val["pulley"]]
        elif kind == "nonlinear_stiffness":
            p["beta"][c] = val["beta"]
        elif kind == "cable_damping":
            p["damping"][c] = val["damping"]
        elif kind == "slack":
            p["pretension"][c] = val["pretension"]
        elif kind == "creep":
            p["creep_alpha"][c] = val["alpha"]
            p["creep_tau"][c] = val["tau"]
        else:
            raise ValueError(f"{kind} at {site}")
    elif group == "input":
        if kind != "time_delay":
            raise ValueError(f"{kind} at {site}")
        p["delay"] = np.array(val["delay"])
    elif group != "sensor":
        raise ValueError(f"unknown site {site}")
    return p


def stack_params(plist: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    return {k: np.stack([p[k] for p in plist]) for k in plist[0]}


# --------------------------------------------------------------------------------------------
# excitation
# --------------------------------------------------------------------------------------------


def _window(t: np.ndarray, ramp: float):
    """Raised-cosine fade-in over ``ramp`` seconds: value, first and second derivative."""
    a = math.pi / ramp
    tc = np.clip(t, 0.0, ramp)
    on = (t > 0.0) & (t < ramp)
    w = 0.5 * (1 - np.cos(a * tc))
    w1 = np.where(on, 0.5 * a * np.sin(a * tc), 0.0)
    w2 = np.where(on, 0.5 * a * a * np.cos(a * tc), 0.0)
    return w, w1, w2


def multisine(t, amps: np.ndarray, omegas: np.ndarray, ramp: float = RAMP_SECONDS):
    """Faded-in sum of zero-phase sines and its first two derivatives (sums the last axis).

    ``t`` is a scalar or an array broadcast against ``amps.shape[:-1]`` from the left (one
    time per batch member)."""
    t = np.asarray(t, float)
    tt = t.reshape(t.shape + (1,) * (amps.ndim - t.ndim))
    w, w1, w2 = _window(tt[..., 0], ramp)
    s = np.sin(omegas * tt)
    c = np.cos(omegas * tt)
    f = (amps * s).sum(-1)
    f1 = (amps * omegas * c).sum(-1)
    f2 = -(amps * omegas**2 * s).sum(-1)
    return w * f, w1 * f + w * f1, w2 * f + 2 * w1 * f1 + w * f2


@dataclass
class PD:
    """Joint-space PD with feed-forward on the true plant, mapped to motor torques."""

    amps: np.ndarray  # (B, nj, ns) reference multi-sine per joint
    omegas: np.ndarray  # (B, nj, ns)
    kp: np.ndarray  # (nj,)
    kd: np.ndarray  # (nj,)
    ff_inertia: np.ndarray  # (nj,) believed inertia for the feed-forward
    ff_viscous: np.ndarray  # (nj,)
    t_hold: np.ndarray  # (nc,) held tensions (pretension)
    kdm: np.ndarray  # (ntm,) collocated motor damping
    ff_motor: np.ndarray  # (ntm,) believed rotor inertia for the feed-forward
    collocated: bool = False  # joint feedback from the motor encoders (rigid-cable estimate)


def _pd_maps(net: Network):
    DJ = net.D[:, : net.nj]  # (nc, nj)
    DM = net.D[:, net.nj : net.nd]  # (nc, ntm)
    to_tension = -np.linalg.pinv(DJ.T)  # (nc, nj): dT = to_tension @ tau_joint
    M = np.zeros((len(net.tmotors), net.nc))
    for c in range(net.nc):
        k = net.driver[c] - net.nj
        if 0 <= k < len(net.tmotors):
            M[k, c] = net.a_drv[c]
    motor_rate = -np.linalg.pinv(DM) @ DJ  # (ntm, nj): motor velocity at constant stretch
    joint_from_motor = -np.linalg.pinv(DJ) @ DM  # (nj, ntm): joint angles at constant stretch
    return to_tension, M, motor_rate, joint_from_motor


def pd_command(net: Network, pd: PD, t: float, x: np.ndarray, v: np.ndarray, maps=None):
    """Motor torques (B, ntm) of the PD at time t for states x, v (B, ncoord)."""
    to_tension, M, motor_rate, joint_from_motor = _pd_maps(net) if maps is None else maps
    nj = net.nj
    qr, vr, ar = multisine(t, pd.amps, pd.omegas)
    if pd.collocated:
        q = x[:, nj : net.nd] @ joint_from_motor.T
        w = v[:, nj : net.nd] @ joint_from_motor.T
    else:
        q, w = x[:, :nj], v[:, :nj]
    tau = pd.ff_inertia * ar + pd.ff_viscous * vr + pd.kp * (qr - q) + pd.kd * (vr - w)
    tens = pd.t_hold + tau @ to_tension.T
    vm_ref = vr @ motor_rate.T
    am_ref = ar @ motor_rate.T
    return tens @ M.T + pd.kdm * (vm_ref - v[:, nj : net.nd]) + pd.ff_motor * am_ref


# --------------------------------------------------------------------------------------------
# simulation core
# --------------------------------------------------------------------------------------------


def _tension(P, delta, ddelta, e, relaxed=False):
    k = P["stiffness"]
    beta = P["beta"]
    if np.any(beta):
        safe = np.where(beta > 0, beta, 1.0)
        g = np.where(beta > 0, k * np.expm1(np.clip(safe * delta, -50, 50)) / safe, k * delta)
    else:
        g = k * delta
    alpha = P["creep_alpha"]
    if relaxed:
        tel = P["pretension"] + (1 - alpha) * g
    else:
        tel = P["pretension"] + (1 - alpha) * g + alpha * k * (delta - e) + P["damping"] * ddelta
    return np.maximum(tel, 0.0)


def _equilibrium(net: Network, P: dict, torque0) -> np.ndarray:
    """Frictionless static equilibrium (creep relaxed) by batched Newton with pseudo-inverse.

    ``torque0(x)`` gives the motor torques (B, ntm) applied at rest in state x.  Position motors
    sit at angle 0; a capstan with backlash is free (zero net cable torque)."""
    B = P["inertia"].shape[0]
    n = net.ncoord
    nd = net.nd
    free_cap = P["backlash"] > 0  # (B, npm)

    def residual(x):
        delta = x @ net.D.T
        T = _tension(P, delta, 0.0, delta, relaxed=True)
        F = -T @ net.D
        if net.tmotors:
            F[:, net.nj : nd] += torque0(x)
        if net.pmotors:
            F[:, nd:] = np.where(free_cap, F[:, nd:], x[:, nd:])
        return F

    x = np.zeros((B, n))
    scale = np.maximum(np.abs(net.D).max(0) * net.pretension.max(), 1e-9)
    for _ in range(50):
        r = residual(x)
        if np.all(np.abs(r) < 1e-11 * scale):
            break
        J = np.empty((B, n, n))
        h = 1e-7
        for i in range(n):
            xp = x.copy()
            xp[:, i] += h
            J[:, :, i] = (residual(xp) - r) / h
        x = x - np.einsum("bij,bj->bi", np.linalg.pinv(J, rcond=1e-10), r)
    return x


def simulate(
    net: Network,
    P: dict[str, np.ndarray],
    n_samples: int,
    *,
    pm_input=None,
    pd: PD | None = None,
    replay: np.ndarray | None = None,
    n_sub: int = 10,
    dt_out: float = DT,
    x0: np.ndarray | None = None,
    v0: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Integrate a batch of B members (leading axis of every parameter array).

    Position motors follow ``pm_input(t - delay)`` -> (angle, rate), each (B, npm).  Torque
    motors get the PD's commands (``pd``, delayed by ``delay``) or the recorded torques
    ``replay`` (B, n_samples, ntm); both are held over each sample interval.  Starts at rest
    at the frictionless equilibrium unless ``x0`` is given.  Returns arrays over samples."""
    B = P["inertia"].shape[0]
    nj, nd, nc, n = net.nj, net.nd, net.nc, net.ncoord
    npm, ntm = len(net.pmotors), len(net.tmotors)
    dt = dt_out / n_sub
    delay = np.broadcast_to(P["delay"], (B,))
    delay_steps = np.rint(delay / dt_out).astype(int)
    rows = np.arange(B)

    maps = _pd_maps(net) if pd is not None else None

    def torque_at(k, x, v):
        if replay is not None:
            return replay[:, k]
        if pd is not None:
            return pd_command(net, pd, k * dt_out, x, v, maps)
        return np.zeros((B, ntm))

    if x0 is None:
        x = _equilibrium(net, P, lambda xx: torque_at(0, xx, np.zeros_like(xx)))
    else:
        x = x0.copy()
    v = np.zeros((B, n)) if v0 is None else v0.copy()
    Dt = net.D.T.copy()
    drv = net.driver
    Ddr = np.zeros_like(net.D)
    Ddr[np.arange(nc), drv] = net.a_drv
    Dnd = net.D - Ddr
    Sabs = np.abs(Ddr)
    cosh = np.cosh(P["mphi"])
    sinh = np.sinh(P["mphi"])
    has_cap = bool(np.any(P["mphi"]))
    inertia = P["inertia"]
    coulomb = P["coulomb"]
    strib = P["strib_extra"]
    has_strib = bool(np.any(strib))
    strib_v = P["strib_v"]
    half_visc = 0.5 * dt * P["viscous"]  # trapezoidal (Crank-Nicolson) viscous friction
    denom = inertia + half_visc
    keep = inertia - half_visc
    has_dahl = bool(np.any(P["dahl_fc"]))
    dahl_fc, dahl_rate = P["dahl_fc"], P["dahl_rate"]
    z = np.zeros((B, nd))
    has_creep = bool(np.any(P["creep_alpha"]))
    creep_keep = np.exp(-dt / P["creep_tau"])
    e = x @ Dt  # relaxed Maxwell arm at the start
    backlash = P["backlash"]
    has_bl = bool(np.any(backlash))
    # backlash capstan: cables driven by each position motor
    cap_rows = [np.flatnonzero(drv == nd + k) for k in range(npm)]

    out_x = np.empty((B, n_samples, n))
    out_v = np.empty((B, n_samples, n))
    out_T = np.empty((B, n_samples, nc))
    out_TA = np.empty((B, n_samples, nc))
    out_u = np.zeros((B, n_samples, ntm))
    out_qm = np.zeros((B, n_samples, npm))
    out_qmd = np.zeros((B, n_samples, npm))
    out_cmd = np.zeros((B, n_samples, npm))
    u_full = np.zeros((B, nd))
    u_kick = u_full
    u_prev = None
    # leapfrog: vh holds v(t - dt/2), vh_prev v(t - 3dt/2); v(t) is extrapolated from them
    # (at t = 0 vh holds v(0) itself and the first kick is half a step)
    vh = v[:, :nd].copy()
    vh_prev = vh.copy()

    for k in range(n_samples):
        tk = k * dt_out
        for s in range(n_sub):
            t = tk + s * dt
            if npm:
                qm, qmd = pm_input(t - delay)
                if has_bl:
                    xc, vc = _backlash_capstan(net, P, x, v, qm, qmd, cap_rows, dt)
                    x[:, nd:], v[:, nd:] = xc, vc
                else:
                    x[:, nd:], v[:, nd:] = qm, qmd
            v[:, :nd] = np.where(vh == 0.0, 0.0, 1.5 * vh - 0.5 * vh_prev)
            delta = x @ Dt
            ddelta = v @ Dt
            T = _tension(P, delta, ddelta, e)
            if s == 0:
                if ntm:
                    cmd = torque_at(k, x, v)
                    out_u[:, k] = cmd
                    if pd is not None and np.any(delay_steps):
                        u_full[:, nj:] = out_u[rows, np.maximum(k - delay_steps, 0)]
                    else:
                        u_full[:, nj:] = cmd
                    # the kick at a sample instant spans half a sub-step of each held value
                    u_kick = u_full.copy()
                    if k > 0:
                        u_kick[:, nj:] = 0.5 * (u_kick[:, nj:] + u_prev)
                    u_prev = u_full[:, nj:].copy()
                if npm:
                    out_cmd[:, k] = pm_input(np.full(B, tk))[0]
                    out_qm[:, k] = qm
                    out_qmd[:, k] = qmd
                out_x[:, k] = x
                out_v[:, k] = v
                out_T[:, k] = T
                if has_cap:
                    out_TA[:, k] = T * np.exp(P["mphi"] * np.sign(v[:, drv] * net.a_drv))
                else:
                    out_TA[:, k] = T
            if has_cap:
                F = -(T @ Dnd) - (T * cosh) @ Ddr
                bound = coulomb + ((T * sinh) @ Sabs)[:, :nd]
            else:
                F = -(T @ net.D)
                bound = coulomb
            Fd = F[:, :nd] + (u_kick if s == 0 and ntm else u_full)
            if has_dahl:
                Fd = Fd - z
            if k == 0 and s == 0:  # start: half a kick from v(0) to v(dt/2)
                hv = 0.5 * half_visc
                vnew = _friction_kick(
                    vh,
                    Fd,
                    0.5 * dt,
                    inertia,
                    inertia - hv,
                    inertia + hv,
                    hv,
                    bound,
                    strib,
                    strib_v,
                    has_strib,
                )
                vh = np.where(vh == 0.0, 0.0, 2.0 * vh - vnew)  # ~v(-dt/2), for the extrapolation
            else:
                vnew = _friction_kick(
                    vh, Fd, dt, inertia, keep, denom, half_visc, bound, strib, strib_v, has_strib
                )
            if has_dahl:
                dth = vnew * dt
                zt = dahl_fc * np.sign(dth)
                z = zt + (z - zt) * np.exp(-dahl_rate * np.abs(dth))
            if has_creep:
                mid = delta + 0.5 * dt * ddelta
                e = mid + (e - mid) * creep_keep
            vh_prev = vh
            vh = vnew
            x[:, :nd] += dt * vnew
    return {
        "x": out_x,
        "v": out_v,
        "T": out_T,
        "T_A": out_TA,
        "u": out_u,
        "qm_pm": out_qm,
        "qmd_pm": out_qmd,
        "cmd_pm": out_cmd,
    }


def _friction_kick(vh, F, dt, inertia, keep, denom, half_visc, bound, strib, strib_v, has_strib):
    """Velocity kick over one sub-step with exactly switched Coulomb/Stribeck friction.

    Sliding coordinates keep their friction direction unless the velocity reaches zero inside
    the step; then the zero-crossing time is resolved and the rest of the step starts from rest:
    stick if the other forces stay within the static bound, else slide the other way.  Resting
    coordinates break away only when the static bound is exceeded (Moreau time stepping)."""
    s0 = np.sign(vh)
    if has_strib:
        kin = bound + strib * np.exp(-np.abs(vh) / strib_v)
        static = bound + strib
    else:
        kin = static = bound
    acc = F - s0 * kin
    v_slide = (keep * vh + dt * acc) / denom
    crossing = (s0 != 0.0) & (np.sign(v_slide) != s0)
    # from rest (at the step start or after a zero crossing at time tau)
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = np.where(crossing, np.clip(inertia * np.abs(vh) / np.abs(acc), 0.0, dt), 0.0)
    rest = dt - tau
    moving = np.abs(F) > static
    v_rest = np.where(moving, (F - np.sign(F) * static) * rest / (inertia + half_visc * rest / dt), 0.0)
    return np.where((s0 != 0.0) & ~crossing, v_slide, v_rest)


def _backlash_capstan(net, P, x, v, qm, qmd, cap_rows, dt):
    """Massless capstan inside a dead zone of half-width ``backlash`` around the motor angle.

    Inside the gap the capstan sits where the (linear, damped) cable torques balance, solved
    implicitly for the step; at an edge it is carried by the motor."""
    nd = net.nd
    xc = np.empty_like(qm)
    vc = np.empty_like(qm)
    for k, rows in enumerate(cap_rows):
        col = nd + k
        a = net.D[rows, col]  # (m,)
        xold = x[:, col]
        rest = x @ net.D[rows].T - xold[:, None] * a  # stretch from other coordinates
        rrate = v @ net.D[rows].T - v[:, col][:, None] * a
        kk = P["stiffness"][:, rows]
        cc = P["damping"][:, rows]
        t0 = P["pretension"][:, rows]
        num = (a * (-t0 - kk * rest - cc * rrate + cc * a * xold[:, None] / dt)).sum(-1)
        den = (a * a * (kk + cc / dt)).sum(-1)
        free = num / den
        lo = qm[:, k] - P["backlash"][:, k]
        hi = qm[:, k] + P["backlash"][:, k]
        new = np.clip(free, lo, hi)
        inside = (free > lo) & (free < hi)
        xc[:, k] = new
        vc[:, k] = np.where(inside, (new - xold) / dt, qmd[:, k])
    return xc, vc


# --------------------------------------------------------------------------------------------
# measurements
# --------------------------------------------------------------------------------------------


def channels(net: Network, P: dict, sim: dict, b: int, names) -> dict[str, np.ndarray]:
    """Clean (noise-free, undistorted) output channels of batch member ``b``."""
    nd = net.nd
    drv = net.driver
    Ddr = np.zeros_like(net.D)
    Ddr[np.arange(net.nc), drv] = net.a_drv
    Dnd = net.D - Ddr
    out = {}
    for name in names:
        kind, _, el = name.partition(":")
        if kind == "q":
            out[name] = sim["x"][b, :, net.coord(el)]
        elif kind == "q_m":
            if el in net.pmotors:
                out[name] = sim["qm_pm"][b, :, net.pmotors.index(el)]
            else:
                out[name] = sim["x"][b, :, net.coord(el)]
        elif kind == "T":
            out[name] = sim["T"][b, :, net.cables.index(el)]
        elif kind == "T_motor":
            out[name] = sim["T_A"][b, :, net.cables.index(el)]
        elif kind == "tau":
            j = net.coord(el)
            out[name] = -(sim["T"][b] @ Dnd[:, j]) - (sim["T_A"][b] @ Ddr[:, j])
        elif kind == "load_m":
            i = net.coord(el)
            load = sim["T_A"][b] @ Ddr[:, i]
            if el in net.pmotors:
                k = i - nd
                w = sim["qmd_pm"][b, :, k]
                load = load + P["pm_coulomb"][b, k] * np.sign(w) + P["pm_viscous"][b, k] * w
            out[name] = load
        else:
            raise ValueError(f"unknown output {name}")
    return out


def first_order_lag(u: np.ndarray, tau: float, h: float = DT) -> np.ndarray:
    """Exact response of ``tau y' = u - y`` to the piecewise-linear interpolant of samples ``u``,
    starting in steady state."""
    a = math.exp(-h / tau)
    c1 = (1 - a) - (tau - a * (h + tau)) / h
    b = [c1, (1 - a) - c1]
    zi = signal.lfilter_zi(b, [1.0, -a]) * u[0]
    return signal.lfilter(b, [1.0, -a], u, zi=zi)[0]


def noise_sigma(name: str, net: Network, clean: np.ndarray) -> float:
    """Standard deviation of the measurement error of channel ``name``."""
    kind, _, el = name.partition(":")
    if kind == "q":
        return 2 * math.pi / JOINT_COUNTS / math.sqrt(12)
    if kind == "q_m":
        return 2 * math.pi / MOTOR_COUNTS / math.sqrt(12)
    if kind in ("T", "T_motor"):
        return TENSION_NOISE * float(net.pretension[net.cables.index(el)])
    return TORQUE_NOISE * float(np.sqrt(np.mean(clean**2)))


def measure(net: Network, clean: dict, effect: Effect | None, rng) -> dict[str, np.ndarray]:
    """Sensor effect, then quantisation / noise (``rng=None``: no noise, no quantisation)."""
    out = {}
    for name, y in clean.items():
        if effect is not None and effect.site == f"sensor.{name}":
            if effect.kind == "sensor_gain_bias":
                y = effect.values["gain"] * y + effect.values["bias"]
            elif effect.kind == "sensor_lag":
                y = first_order_lag(y, effect.values["tau"])
            else:
                raise ValueError(f"{effect.kind} at {effect.site}")
        if rng is not None:
            kind = name.partition(":")[0]
            if kind in ("q", "q_m"):
                step = 2 * math.pi / (JOINT_COUNTS if kind == "q" else MOTOR_COUNTS)
                y = np.round(y / step) * step
            else:
                y = y + rng.normal(0.0, noise_sigma(name, net, clean[name]), y.shape)
        out[name] = np.asarray(y, float)
    return out


# --------------------------------------------------------------------------------------------
# plants
# --------------------------------------------------------------------------------------------

PI = math.pi
HZ = 2 * math.pi


def _joint(name, child, coulomb, viscous):
    return {
        "name": name,
        "child": child,
        "parent": "base",
        "kind": "revolute",
        "coulomb": coulomb,
        "viscous": viscous,
        "smoothing": 1e-3,
        "gravity_amplitude": 0.0,
        "gravity_offset": 0.0,
    }


def _contact(pulley, wrap, sense=1, mu=0.0):
    return {"pulley": pulley, "wrap": wrap, "sense": sense, "mu": mu}


def _cable(name, routing, stiffness, damping, pretension, motor=None, motor_sense=1):
    c = {"name": name, "routing": routing}
    if motor is not None:
        c["motor"] = motor
        c["motor_sense"] = motor_sense
    c.update(law="linear", stiffness=stiffness, damping=damping, pretension=pretension)
    return c


def two_stage_spec() -> dict:
    jaw = dict(stiffness=3e4, damping=10.0, pretension=10.0)
    cpl = dict(stiffness=1e4, damping=2.0, pretension=5.0)
    return {
        "name": "two_stage",
        "description": "position-servoed motor -> compliant coupling -> spindle capstan -> "
        "wrist idler -> jaw (independent simulator)",
        "capstan_smoothing": 1e-3,
        "bodies": [
            {"name": "spindle_body", "inertia": 2e-6},
            {"name": "jaw_body", "inertia": 1e-7},
        ],
        "joints": [
            _joint("spindle", "spindle_body", 2e-3, 1e-4),
            _joint("jaw", "jaw_body", 1e-3, 1e-5),
        ],
        "pulleys": [
            {"name": "spindle_in", "radius": 0.005, "joint": "spindle"},
            {"name": "spindle_capstan", "radius": 0.004, "joint": "spindle"},
            {"name": "wrist_idler", "radius": 0.0015},
            {"name": "jaw_pulley", "radius": 0.0025, "joint": "jaw"},
        ],
        "motors": [
            {
                "name": "drive",
                "drive": "position",
                "capstan_radius": 0.005,
                "gear_ratio": 1.0,
                "coulomb": 0.0,
                "viscous": 0.0,
                "smoothing": 0.1,
            }
        ],
        "cables": [
            _cable("coupling_a", [_contact("spindle_in", PI, -1)], **cpl, motor="drive"),
            _cable("coupling_b", [_contact("spindle_in", PI, 1)], **cpl, motor="drive", motor_sense=-1),
            _cable(
                "jaw_drive",
                [
                    _contact("spindle_capstan", PI, -1),
                    _contact("wrist_idler", 2.0, 1, 0.1),
                    _contact("jaw_pulley", PI, 1),
                ],
                **jaw,
            ),
            _cable(
                "jaw_return",
                [
                    _contact("spindle_capstan", PI, 1),
                    _contact("wrist_idler", 2.0, 1, 0.1),
                    _contact("jaw_pulley", PI, -1),
                ],
                **jaw,
            ),
        ],
    }


def _torque_motor(name, radius, gear, inertia, viscous):
    return {
        "name": name,
        "drive": "torque",
        "capstan_radius": radius,
        "gear_ratio": gear,
        "inertia": inertia,
        "coulomb": 0.0,
        "viscous": viscous,
        "smoothing": 0.1,
    }


def finger_spec() -> dict:
    ten = dict(stiffness=2e4, damping=5.0)
    flex = [("mcp_flex", -1), ("pip_flex", -1), ("dip_flex", -1)]
    cables = []
    for i in range(3):
        routing = [_contact(f"palm_{i + 1}", 0.8)]
        routing += [_contact(p, PI / 2, s) for p, s in flex[: i + 1]]
        cables.append(_cable(f"t{i + 1}", routing, **ten, pretension=10.0, motor=f"m{i + 1}"))
    routing = [_contact("palm_4", 0.8)]
    routing += [_contact(p, PI / 2, 1) for p in ("mcp_ext", "pip_ext", "dip_ext")]
    cables.append(_cable("t4", routing, **ten, pretension=15.0, motor="m4"))
    pulleys = [{"name": f"palm_{i}", "radius": 0.005} for i in range(1, 5)]
    for name, r, j in (
        ("mcp_flex", 0.004, "mcp"),
        ("mcp_ext", 0.008, "mcp"),
        ("pip_flex", 0.006, "pip"),
        ("pip_ext", 0.008, "pip"),
        ("dip_flex", 0.006, "dip"),
        ("dip_ext", 0.004, "dip"),
    ):
        pulleys.append({"name": name, "radius": r, "joint": j})
    return {
        "name": "finger",
        "description": "planar 3-joint finger, 4 tendons (3 flexors + common extensor), "
        "torque-driven motors (independent simulator)",
        "capstan_smoothing": 1e-3,
        "bodies": [
            {"name": "proximal", "inertia": 3e-5},
            {"name": "middle", "inertia": 2e-5},
            {"name": "distal", "inertia": 1e-5},
        ],
        "joints": [
            _joint("mcp", "proximal", 1e-3, 1e-4),
            _joint("pip", "middle", 1e-3, 1e-4),
            _joint("dip", "distal", 1e-3, 1e-4),
        ],
        "pulleys": pulleys,
        "motors": [_torque_motor(f"m{i}", 0.005, 1.0, 1e-5, 2e-5) for i in range(1, 5)],
        "cables": cables,
    }


def transmission2_spec() -> dict:
    cab = dict(stiffness=2e4, damping=10.0, pretension=20.0)
    return {
        "name": "transmission2",
        "description": "Raven-II-like 2-link coupled cable transmission: elbow cables pass "
        "idlers on the shoulder axis (independent simulator)",
        "capstan_smoothing": 1e-3,
        "bodies": [
            {"name": "upper_arm", "inertia": 1e-2},
            {"name": "forearm", "inertia": 4e-3},
        ],
        "joints": [
            _joint("shoulder", "upper_arm", 1e-2, 5e-3),
            _joint("elbow", "forearm", 5e-3, 2e-3),
        ],
        "pulleys": [
            {"name": "idler_s", "radius": 0.005},
            {"name": "idler_e", "radius": 0.005},
            {"name": "sh_pulley", "radius": 0.02, "joint": "shoulder"},
            {"name": "sh_idler", "radius": 0.01, "joint": "shoulder"},
            {"name": "el_pulley", "radius": 0.015, "joint": "elbow"},
        ],
        "motors": [
            _torque_motor("m_shoulder", 0.008, 12.0, 5e-6, 1e-5),
            _torque_motor("m_elbow", 0.008, 12.0, 3e-6, 1e-5),
        ],
        "cables": [
            _cable(
                "sh_a",
                [_contact("idler_s", 1.2), _contact("sh_pulley", PI, -1)],
                **cab,
                motor="m_shoulder",
            ),
            _cable(
                "sh_b",
                [_contact("idler_s", 1.2), _contact("sh_pulley", PI, 1)],
                **cab,
                motor="m_shoulder",
                motor_sense=-1,
            ),
            _cable(
                "el_a",
                [
                    _contact("idler_e", 1.2),
                    _contact("sh_idler", PI / 2, 1),
                    _contact("el_pulley", PI, -1),
                ],
                **cab,
                motor="m_elbow",
            ),
            _cable(
                "el_b",
                [
                    _contact("idler_e", 1.2),
                    _contact("sh_idler", PI / 2, -1),
                    _contact("el_pulley", PI, 1),
                ],
                **cab,
                motor="m_elbow",
                motor_sense=-1,
            ),
        ],
    }


@dataclass
class PlantSetup:
    spec: dict
    outputs: list[str]
    runs: list[tuple[str, np.ndarray, np.ndarray]]  # (name, amps (m, ns), omegas (m, ns))
    n_sub: int
    pd_gains: dict | None  # kp, kd, kdm (per joint / per motor)
    effects: list[tuple[str, Effect | None]]
    quick: tuple[str, ...]


def _runs(design) -> list[tuple[str, np.ndarray, np.ndarray]]:
    out = []
    for name, amps, freqs in design:
        out.append((name, np.array(amps, float), HZ * np.array(freqs, float)))
    return out


def two_stage_setup() -> PlantSetup:
    runs = _runs(
        [
            ("fit_a", [[0.15, 0.10, 0.05]], [[0.7, 1.9, 3.3]]),
            ("fit_b", [[0.20, 0.08, 0.05]], [[0.5, 1.3, 2.7]]),
            ("hold", [[0.12, 0.10, 0.04]], [[0.9, 2.3, 4.1]]),
        ]
    )
    E = Effect
    effects = [
        (
            "coulomb_friction_joint.spindle",
            E("coulomb_friction", "joint.spindle", {"coulomb": 4e-3}, "F_c = 4 mN·m (2x nominal 2 mN·m)"),
        ),
        (
            "viscous_friction_joint.spindle",
            E("viscous_friction", "joint.spindle", {"viscous": 1e-3}, "b = 1e-3 N·m·s/rad (10x nominal)"),
        ),
        (
            "stribeck_friction_joint.spindle",
            E(
                "stribeck_friction",
                "joint.spindle",
                {"static": 6e-3, "v_stribeck": 0.1},
                "F_s = 6 mN·m (F_c 2 mN·m), v_s = 0.1 rad/s, exp(-|v|/v_s)",
            ),
        ),
        (
            "capstan_friction_routing.jaw_drive",
            E(
                "capstan_friction",
                "routing.jaw_drive",
                {"pulley": "wrist_idler", "mu": 0.05},
                "mu at wrist_idler 0.10 -> 0.15 (wrap 2 rad)",
            ),
        ),
        (
            "slack_cable.jaw_return",
            E("slack", "cable.jaw_return", {"pretension": 4.0}, "T0 = 4 N (nominal 10 N)"),
        ),
        (
            "cable_damping_cable.coupling_a",
            E("cable_damping", "cable.coupling_a", {"damping": 100.0}, "c = 100 N·s/m (nominal 2)"),
        ),
        (
            "coulomb_friction_motor.drive",
            E("coulomb_friction", "motor.drive", {"coulomb": 3e-3}, "motor F_c = 3 mN·m (nominal 0)"),
        ),
        ("time_delay_input", E("time_delay", "input", {"delay": 0.008}, "delay = 8 ms")),
        (
            "sensor_gain_bias_sensor.load_m:drive",
            E(
                "sensor_gain_bias",
                "sensor.load_m:drive",
                {"gain": 1.15, "bias": 2e-3},
                "gain 1.15, bias 2 mN·m",
            ),
        ),
        (
            "sensor_lag_sensor.load_m:drive",
            E("sensor_lag", "sensor.load_m:drive", {"tau": 0.01}, "first-order lag 10 ms"),
        ),
        (
            "backlash_motor.drive",
            E("backlash", "motor.drive", {"half_gap": 0.01}, "dead zone ±10 mrad between motor and capstan"),
        ),
        (
            "dahl_hysteresis_joint.spindle",
            E(
                "dahl_hysteresis",
                "joint.spindle",
                {"sigma": 0.05},
                "Dahl, F_c 2 mN·m, sigma = 0.05 N·m/rad (replaces Coulomb)",
            ),
        ),
        ("control_1", None),
        ("control_2", None),
    ]
    return PlantSetup(
        spec=two_stage_spec(),
        outputs=["q_m:drive", "q:spindle", "load_m:drive", "q:jaw"],
        runs=runs,
        n_sub=10,
        pd_gains=None,
        effects=effects,
        quick=(
            "coulomb_friction_joint.spindle",
            "backlash_motor.drive",
            "sensor_gain_bias_sensor.load_m:drive",
        ),
    )


def finger_setup() -> PlantSetup:
    runs = _runs(
        [
            ("fit_a", [[0.12, 0.06], [0.10, 0.06], [0.10, 0.05]], [[0.8, 2.1], [1.1, 2.9], [1.5, 3.7]]),
            ("fit_b", [[0.10, 0.08], [0.12, 0.05], [0.08, 0.06]], [[0.6, 1.7], [0.9, 2.5], [1.3, 3.1]]),
            ("hold", [[0.14, 0.05], [0.09, 0.07], [0.11, 0.05]], [[1.0, 2.6], [0.7, 3.3], [1.9, 4.3]]),
        ]
    )
    E = Effect
    effects = [
        (
            "coulomb_friction_joint.pip",
            E("coulomb_friction", "joint.pip", {"coulomb": 2e-3}, "F_c = 2 mN·m (2x nominal)"),
        ),
        (
            "viscous_friction_joint.mcp",
            E("viscous_friction", "joint.mcp", {"viscous": 1e-3}, "b = 1e-3 N·m·s/rad (10x nominal)"),
        ),
        (
            "stribeck_friction_joint.dip",
            E(
                "stribeck_friction",
                "joint.dip",
                {"static": 3e-3, "v_stribeck": 0.05},
                "F_s = 3 mN·m (F_c 1 mN·m), v_s = 0.05 rad/s",
            ),
        ),
        (
            "inertia_error_joint.mcp",
            E("inertia_error", "joint.mcp", {"factor": 2.0}, "I = 6e-5 kg·m² (2x nominal)"),
        ),
        (
            "capstan_friction_routing.t2",
            E(
                "capstan_friction",
                "routing.t2",
                {"pulley": "palm_2", "mu": 0.03},
                "mu = 0.03 at palm_2 (wrap 0.8 rad; nominal 0)",
            ),
        ),
        (
            "cable_damping_cable.t1",
            E("cable_damping", "cable.t1", {"damping": 50.0}, "c = 50 N·s/m (nominal 5)"),
        ),
        ("slack_cable.t3", E("slack", "cable.t3", {"pretension": 3.0}, "T0 = 3 N (nominal 10 N)")),
        (
            "coulomb_friction_motor.m2",
            E("coulomb_friction", "motor.m2", {"coulomb": 1e-3}, "motor F_c = 1 mN·m (nominal 0)"),
        ),
        (
            "viscous_friction_motor.m1",
            E("viscous_friction", "motor.m1", {"viscous": 5e-4}, "motor b = 5e-4 N·m·s/rad (nominal 2e-5)"),
        ),
        (
            "sensor_gain_bias_sensor.T:t2",
            E("sensor_gain_bias", "sensor.T:t2", {"gain": 1.1, "bias": 0.5}, "gain 1.1, bias 0.5 N"),
        ),
        ("time_delay_input", E("time_delay", "input", {"delay": 0.003}, "delay = 3 ms")),
        (
            "dahl_hysteresis_joint.pip",
            E(
                "dahl_hysteresis",
                "joint.pip",
                {"sigma": 0.05},
                "Dahl, F_c 1 mN·m, sigma = 0.05 N·m/rad (replaces Coulomb)",
            ),
        ),
        (
            "creep_cable.t1",
            E(
                "creep",
                "cable.t1",
                {"alpha": 0.5, "tau": 0.3},
                "SLS: 50 % of k in a Maxwell arm, tau = 0.3 s",
            ),
        ),
        ("control_1", None),
        ("control_2", None),
    ]
    return PlantSetup(
        spec=finger_spec(),
        outputs=["q:mcp", "q:pip", "q:dip"]
        + [f"q_m:m{i}" for i in range(1, 5)]
        + [f"T:t{i}" for i in range(1, 5)],
        runs=runs,
        n_sub=10,
        pd_gains={
            "kp": np.array([0.08, 0.06, 0.03]),
            "kd": np.array([1.5e-3, 1e-3, 5e-4]),
            "kdm": np.zeros(4),
            "collocated": True,
        },
        effects=effects,
        quick=("capstan_friction_routing.t2", "coulomb_friction_motor.m2", "control_1"),
    )


def transmission2_setup() -> PlantSetup:
    runs = _runs(
        [
            ("fit_a", [[0.15, 0.08], [0.15, 0.08]], [[0.6, 1.7], [0.9, 2.3]]),
            ("fit_b", [[0.12, 0.10], [0.18, 0.06]], [[0.8, 2.0], [0.5, 1.9]]),
            ("hold", [[0.18, 0.06], [0.12, 0.09]], [[0.7, 2.4], [1.1, 2.8]]),
        ]
    )
    E = Effect
    effects = [
        (
            "coulomb_friction_joint.shoulder",
            E("coulomb_friction", "joint.shoulder", {"coulomb": 2e-2}, "F_c = 20 mN·m (2x nominal)"),
        ),
        (
            "stribeck_friction_joint.elbow",
            E(
                "stribeck_friction",
                "joint.elbow",
                {"static": 1.5e-2, "v_stribeck": 0.05},
                "F_s = 15 mN·m (F_c 5), v_s = 0.05 rad/s",
            ),
        ),
        (
            "inertia_error_joint.elbow",
            E("inertia_error", "joint.elbow", {"factor": 1.25}, "I = 5e-3 kg·m² (1.25x nominal)"),
        ),
        (
            "viscous_friction_motor.m_elbow",
            E(
                "viscous_friction",
                "motor.m_elbow",
                {"viscous": 4e-5},
                "motor b = 4e-5 N·m·s/rad (4x nominal 1e-5)",
            ),
        ),
        (
            "capstan_friction_routing.el_a",
            E(
                "capstan_friction",
                "routing.el_a",
                {"pulley": "idler_e", "mu": 0.03},
                "mu = 0.03 at idler_e (wrap 1.2 rad; nominal 0)",
            ),
        ),
        (
            "nonlinear_stiffness_cable.sh_a",
            E(
                "nonlinear_stiffness",
                "cable.sh_a",
                {"beta": 1500.0},
                "T = T0 + k/beta (exp(beta δ) - 1), beta = 1500 1/m",
            ),
        ),
        ("slack_cable.el_b", E("slack", "cable.el_b", {"pretension": 8.0}, "T0 = 8 N (nominal 20 N)")),
        (
            "sensor_gain_bias_sensor.T:el_a",
            E("sensor_gain_bias", "sensor.T:el_a", {"gain": 0.9, "bias": -1.0}, "gain 0.9, bias -1 N"),
        ),
        ("time_delay_input", E("time_delay", "input", {"delay": 0.005}, "delay = 5 ms")),
        (
            "sensor_lag_sensor.T:sh_b",
            E("sensor_lag", "sensor.T:sh_b", {"tau": 0.02}, "first-order lag 20 ms"),
        ),
        (
            "creep_cable.sh_b",
            E(
                "creep",
                "cable.sh_b",
                {"alpha": 0.3, "tau": 0.2},
                "SLS: 30 % of k in a Maxwell arm, tau = 0.2 s",
            ),
        ),
        ("control_1", None),
        ("control_2", None),
    ]
    return PlantSetup(
        spec=transmission2_spec(),
        outputs=["q_m:m_shoulder", "q_m:m_elbow", "q:shoulder", "q:elbow"]
        + [f"T:{c}" for c in ("sh_a", "sh_b", "el_a", "el_b")],
        runs=runs,
        n_sub=10,
        pd_gains={
            "kp": np.array([4.0, 1.5]),
            "kd": np.array([0.15, 0.05]),
            "kdm": np.array([1e-4, 5e-5]),
        },
        effects=effects,
        quick=("nonlinear_stiffness_cable.sh_a", "time_delay_input"),
    )


SETUPS = {
    "two_stage": two_stage_setup,
    "finger": finger_setup,
    "transmission2": transmission2_setup,
}


# --------------------------------------------------------------------------------------------
# case generation
# --------------------------------------------------------------------------------------------


def make_pd(net: Network, setup: PlantSetup, amps, omegas) -> PD:
    return PD(
        amps=amps,
        omegas=omegas,
        kp=setup.pd_gains["kp"],
        kd=setup.pd_gains["kd"],
        ff_inertia=net.inertia[: net.nj],
        ff_viscous=net.viscous[: net.nj],
        t_hold=net.pretension,
        kdm=setup.pd_gains["kdm"],
        ff_motor=net.inertia[net.nj :],
        collocated=setup.pd_gains.get("collocated", False),
    )


def run_plant(
    setup: PlantSetup,
    effects: list[Effect | None],
    n_samples: int,
    *,
    n_sub: int | None = None,
):
    """Simulate every (effect, run) pair of a plant in one batch; returns (net, P, sim, members)."""
    net = compile_network(setup.spec)
    members = [(ci, ri) for ci in range(len(effects)) for ri in range(len(setup.runs))]
    P = stack_params([member_params(net, effects[ci]) for ci, _ in members])
    amps = np.stack([setup.runs[ri][1] for _, ri in members])
    omegas = np.stack([setup.runs[ri][2] for _, ri in members])
    n_sub = setup.n_sub if n_sub is None else n_sub
    if net.pmotors:

        def pm_input(t):
            q, qd, _ = multisine(t, amps, omegas)
            return q, qd

        sim = simulate(net, P, n_samples, pm_input=pm_input, n_sub=n_sub)
    else:
        sim = simulate(net, P, n_samples, pd=make_pd(net, setup, amps, omegas), n_sub=n_sub)
    return net, P, sim, members


def _plant_cases(
    plant: str, seed: int, quick: bool, n_samples: int, names: frozenset[str] | None = None
) -> list[NetCase]:
    setup = SETUPS[plant]()
    chosen = [
        (n, e)
        for n, e in setup.effects
        if (not quick or n in setup.quick) and (names is None or f"{plant}_{n}" in names)
    ]
    if not chosen:
        return []
    net, P, sim, members = run_plant(setup, [e for _, e in chosen], n_samples)
    toml = to_toml(setup.spec)
    t = np.arange(n_samples) * DT
    motors = net.tmotors + net.pmotors
    inputs = {m: f"u:{m}" for m in motors}
    out = []
    for ci, (cname, effect) in enumerate(chosen):
        fit, hold = [], []
        for b, (mci, ri) in enumerate(members):
            if mci != ci:
                continue
            clean = channels(net, P, sim, b, setup.outputs)
            rng = np.random.default_rng([seed, zlib.crc32(f"{plant}_{cname}".encode()), ri])
            cols = {"t": t.copy()}
            for m in motors:
                if m in net.pmotors:
                    cols[inputs[m]] = sim["cmd_pm"][b, :, net.pmotors.index(m)].copy()
                else:
                    cols[inputs[m]] = sim["u"][b, :, net.tmotors.index(m)].copy()
            cols.update(measure(net, clean, effect, rng))
            run_name = setup.runs[ri][0]
            (hold if run_name == "hold" else fit).append((run_name, DT, cols))
        out.append(
            NetCase(
                name=f"{plant}_{cname}",
                plant=plant,
                network_toml=toml,
                inputs=inputs,
                outputs={o: o for o in setup.outputs},
                fit_runs=fit,
                hold_runs=hold,
                truth_effect=None if effect is None else effect.kind,
                truth_site=None if effect is None else effect.site,
                in_library=True if effect is None else effect.in_library,
                size="none (control)" if effect is None else effect.size,
            )
        )
    return out


def cases(seed: int = 0, quick: bool = False, names: frozenset[str] | None = None) -> list[NetCase]:
    """All diagnosis cases (``quick``: a representative subset of 8; ``names``: only these
    ``<plant>_<case>``, simulated alone — each case's noise is drawn from its own name)."""
    n_samples = round(RUN_SECONDS / DT)
    out = []
    for plant in SETUPS:
        out.extend(_plant_cases(plant, seed, quick, n_samples, names))
    return out


# --------------------------------------------------------------------------------------------
# nominal replay (for checks): the nominal plant driven open loop by a case's recorded inputs
# --------------------------------------------------------------------------------------------


def replay_nominal(
    network_toml: str,
    inputs: dict[str, str],
    outputs: dict[str, str],
    runs: list[tuple[str, float, dict[str, np.ndarray]]],
    n_sub: int = 10,
) -> list[dict[str, np.ndarray]]:
    """Clean outputs of the NOMINAL plant (parsed from ``network_toml``) replaying the recorded
    inputs of ``runs`` open loop: position commands through a cubic spline, motor torques held
    over each sample.  All runs are simulated as one batch (they must have equal length)."""
    spec = tomllib.loads(network_toml)
    net = compile_network(spec)
    B = len(runs)
    n = len(runs[0][2]["t"])
    dt_out = runs[0][1]
    P = stack_params([member_params(net, None)] * B)
    kw = {}
    if net.pmotors:
        t = runs[0][2]["t"]
        q = np.stack([np.stack([r[2][inputs[m]] for m in net.pmotors], -1) for r in runs])  # (B, n, npm)
        spl = CubicSpline(t, q, axis=1)
        dspl = spl.derivative()

        def pm_input(tt):
            return spl(tt[0]), dspl(tt[0])

        kw["pm_input"] = pm_input
    if net.tmotors:
        kw["replay"] = np.stack([np.stack([r[2][inputs[m]] for m in net.tmotors], -1) for r in runs])
    sim = simulate(net, P, n, n_sub=n_sub, dt_out=dt_out, **kw)
    return [channels(net, P, sim, b, list(outputs)) for b in range(B)]


def deviations(case_list: list[NetCase], which: str = "hold") -> list[dict[str, float]]:
    """Per case and output: max over its runs of RMS(measured - nominal replay) / noise sigma.

    Runs of cases sharing a network are replayed as one batch."""
    res: list[dict[str, float]] = [{} for _ in case_list]
    groups: dict[str, list[int]] = {}
    for i, c in enumerate(case_list):
        groups.setdefault(c.network_toml, []).append(i)
    for toml_text, idx in groups.items():
        net = compile_network(tomllib.loads(toml_text))
        jobs = [
            (i, r)
            for i in idx
            for r in (case_list[i].hold_runs if which == "hold" else case_list[i].fit_runs)
        ]
        first = case_list[idx[0]]
        nominal = replay_nominal(toml_text, first.inputs, first.outputs, [r for _, r in jobs])
        for (i, (_, _, cols)), nom in zip(jobs, nominal, strict=True):
            for name, col in case_list[i].outputs.items():
                sig = noise_sigma(name, net, nom[name])
                d = float(np.sqrt(np.mean((cols[col] - nom[name]) ** 2)) / sig)
                res[i][name] = max(res[i].get(name, 0.0), d)
    return res
