//! The antagonistic joint as the diagnosis simulates it: the nominal joint plus effects located
//! by site (per cable, per cable–pulley contact, at the joint), with a simulation loop that
//! never lets a stateful effect make the replay diverge and that resolves non-smooth events.
//!
//! ```text
//! s₁ = x − r·θ,  s₂ = −s₁                       cable stretches (m), x the motor displacement
//! F_k(s) = law_k(s) + k_k·γ_k·s³                 elastic force (N), optional cubic hardening
//! T_j,k = max(0, T₀,k + F_k(s_k) + c_k·ṡ_k − w_k) joint-side tension (N)
//! ẇ_k = (κ_k·F_k(s_k) − w_k)/τ_k                  creep of the stretch-dependent part, or
//! ẇ_k = (κ_k·(T₀,k + F_k(s_k)) − w_k)/τ_k         creep of the whole tension ("whole")
//! J·θ̈ = r·(T_j,1 − T_j,2) − F_f(θ̇) − (μ_L·|r·(T_j,1 − T_j,2)|)·σ_ε(θ̇) − z − l_e·F_c + τ_ext
//! T_m,k = T_j,k·exp(±(μφ_k·σ(ẋ) + μφʰ_k·ζ_k))    motor-side tensions, + for the drive cable
//! F_m = T_m,1 − T_m,2 + F_cm·σ(ẋ) + b_m·ẋ + F_dm·ζ_m  force at the motor (drum/spindle friction)
//! ```
//!
//! **Hysteresis without stiffness.** A Dahl element is rate independent: over a monotone
//! displacement `u = |Δθ|` its state follows `dw/du = −wⁿ/θ_d` with `w = 1 − z·s/F`
//! (`s` the direction), which has the closed form
//! `w = w₀·e^{−u/θ_d}` (`n = 1`) or `w = max(0, w₀^{1−n} − (1−n)·u/θ_d)^{1/(1−n)}`.
//! The joint's Dahl torque is therefore carried as an anchor `(z_a, θ_a)` fixed over each RK4
//! substep, evaluated in closed form at every stage's `θ`, and re-anchored after the substep: no
//! `|θ̇|/θ_d` mode enters RK4, so no break-away angle, however small, can make it diverge. The
//! contact hysteresis `ζ_k ∈ [−1, 1]` (Dahl in the cable's sliding over the routing pulleys)
//! depends on the motor displacement alone and is computed exactly from it after the run.
//!
//! **Kinks.** A sample interval in which a cable slackens or re-tensions, the contact opens or
//! closes, or the joint reverses is integrated again with [`KINK_REFINE`] times the substeps, so
//! the `max(0, ·)` corners are resolved where they happen and nowhere else.
//!
//! **Stiff friction where it is stiff.** A smoothed dry friction `F·σ_ε(θ̇)` damps the joint at
//! the rate `F·σ_ε'(θ̇)/J`, which at `θ̇ = 0` is `F/(ε·J)` — a sharp friction law asks RK4 for
//! tens of substeps per sample — but falls as `(1 + (θ̇/ε)²)^{-3/2}` once the joint slides. The
//! substeps given to the simulation are those of the other modes; each interval adds what the
//! friction's local rate needs over the velocities it spans (start, and an Euler prediction of
//! the end, through zero if they differ in sign), checked against the velocity actually reached
//! (the interval is integrated again if it needed more), up to [`MAX_FRICTION_SUBSTEPS`]. A joint
//! near rest 7 % of the time costs ~2 substeps per sample instead of 16.
//!
//! **Sticks as the slow manifold.** Where the friction's mode is much faster than a substep —
//! the joint held in a stick by a sharp dry friction, its speed inside the sign's smoothing
//! band — the speed is slaved to the rest of the state (singular perturbation, Tikhonov): it is
//! the root of the joint's acceleration on the friction's rising branch,
//! `J·θ̈(θ, θ̇*, …) = 0`, solved at every RK4 stage by a secant iteration, and the remaining states
//! are integrated with the substeps of the other modes. The law is the same smoothed friction;
//! what is dropped is the fast transient, of time constant `J/F'(θ̇*)` below a seventh of the
//! substep. Within an interval whose friction needs four substeps or more, each step
//! near rest is slaved when the joint is on the manifold (within the smoothing band of its root)
//! or decelerating onto it within one of the friction's substeps (the arrival's extra travel
//! `(θ̇ − θ̇*)²/(2|θ̈|)` is kept), and is an RK4 step of the friction's substeps otherwise — the
//! slide into the stick and the break-away, where the root leaves the band or the mode slows.
//! A stick then costs one slaved step per sample instead of [`MAX_FRICTION_SUBSTEPS`] RK4 steps,
//! and a friction sharper than the cap is resolved instead of chattering through zero (45× and
//! 5× closer to a 512-substep replay for the Coulomb and stick-slipping Stribeck laws of the
//! tests).

use crate::cable::{CableLaw, CableRun};
use crate::dynamics::{AntagonisticJoint, Contact, Model};
use crate::error::{CableError, Result};
use crate::friction::{smooth_sign, StaticFriction};
use crate::integrate::Rk4;

/// Outputs of the diagnosis joint: `[T_m,1, T_m,2, T_j,1, T_j,2, θ, F_c, T_m,1 − T_m,2]`.
pub const JOINT_OUTPUTS: usize = 7;

/// Names of the diagnosis joint's outputs.
pub const JOINT_OUTPUT_NAMES: [&str; JOINT_OUTPUTS] = [
    "tension_motor_drive",
    "tension_motor_return",
    "tension_joint_drive",
    "tension_joint_return",
    "theta",
    "contact_force",
    "net_motor_force",
];

/// Factor by which a sample interval containing a kink is re-integrated with more substeps.
pub const KINK_REFINE: usize = 8;

/// RK4's stability limit on the negative real axis, `|h·λ|` (a damping mode).
const RK4_REAL_LIMIT: f64 = 2.785_293_563;
/// Safety factor on [`RK4_REAL_LIMIT`] for the friction's local damping rate.
const FRICTION_SAFETY: f64 = 0.8;
/// Most substeps per sample interval the friction's local rate may ask for (the diagnosis caps
/// its advised substeps at the same 16: a sharper friction chatters, boundedly, at rest rather
/// than making one trial fit cost a hundred others).
pub const MAX_FRICTION_SUBSTEPS: usize = 16;
/// Friction substeps from which an interval's joint speed is slaved when it can be (module
/// docs): the friction's rate is then at least ~9/dt, its transient at most a ninth of a sample.
const SLAVE_FROM: usize = 4;
/// Least `rate·h` (the friction mode's rate times the substep) at which a stage's speed may be
/// slaved: the dropped transient decays within a seventh of the substep.
const SLAVE_RATE_H: f64 = 7.0;
/// Secant iterations per stage before the slaved step gives up (the interval is then integrated
/// with its substeps).
const SLAVE_ITER: usize = 12;
/// Bit of [`JointPlant::regime`] that holds the joint's direction.
const DIRECTION: u8 = 1 << 3;

/// A rate-independent Dahl hysteresis with level `F`, break-away displacement `θ_d = F/σ₀` and
/// shape exponent `n`, advanced in closed form (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hysteresis {
    /// Saturation level `F` (N·m at the joint; a capstan exponent μφ in a contact).
    pub level: f64,
    /// Break-away displacement `θ_d` (rad at the joint; m of cable sliding in a contact), > 0.
    pub breakaway: f64,
    /// Shape exponent `n` > 0 (1: classic Dahl).
    pub exponent: f64,
}

impl Hysteresis {
    /// The normalised state `ζ = z/F ∈ [−1, 1]` after a displacement `delta` from `zeta0`.
    #[inline]
    pub fn advance(&self, zeta0: f64, delta: f64) -> f64 {
        if delta == 0.0 {
            return zeta0;
        }
        let s = delta.signum();
        let u = delta.abs() / self.breakaway;
        let w0 = (1.0 - zeta0 * s).clamp(0.0, 2.0);
        let w = if (self.exponent - 1.0).abs() < 1e-12 {
            w0 * (-u).exp()
        } else {
            let a = 1.0 - self.exponent;
            if w0 == 0.0 {
                0.0
            } else {
                let base = w0.powf(a) - a * u;
                if base <= 0.0 {
                    0.0
                } else {
                    base.powf(1.0 / a)
                }
            }
        };
        s * (1.0 - w)
    }
}

/// The Stribeck part of the joint's bristle state (LuGre): the level the state saturates at is
/// `g(θ̇) = F + ΔF·exp(−(θ̇/v_s)²)` instead of the constant `F`, with the bristle stiffness
/// `σ₀ = g(0)/θ_d` fixed (the pre-sliding displacement at speed is `g(θ̇)/σ₀`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BristleStribeck {
    /// Static minus Coulomb level `ΔF = F_s − F_c` (same unit as the level), ≥ 0.
    pub excess: f64,
    /// Stribeck velocity `v_s` (rad/s), > 0.
    pub velocity: f64,
}

impl BristleStribeck {
    /// `None` for a non-positive (or non-finite) velocity; a negative excess counts as 0.
    pub fn new(excess: f64, velocity: f64) -> Option<Self> {
        (velocity.is_finite() && velocity > 0.0 && excess.is_finite()).then_some(Self {
            excess: excess.max(0.0),
            velocity,
        })
    }
}

/// Viscous drag that is not linear in speed (lubricant shear thinning or thickening; the
/// `σ₂·|v|^{δ_v}` term of Armstrong-Hélouvry et al. 1994): with `u = v/v_r`,
/// `F = b·u·(u² + ε²)^{(n−1)/2}`, which is `b·|u|ⁿ·sgn(u)` beyond `|u| ≈ ε` (`b` is the drag at
/// the reference speed `v_r`, so the exponent changes the shape, not the level) and has the
/// finite slope `b·εⁿ⁻¹/v_r` at rest.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerDrag {
    /// Drag `b` at the reference speed (N·m), ≥ 0.
    pub coefficient: f64,
    /// Exponent `n` > 0 (1: linear viscous).
    pub exponent: f64,
    /// Reference speed `v_r` (rad/s), > 0.
    pub reference: f64,
}

impl PowerDrag {
    /// Smoothing `ε` of the law at rest, in units of the reference speed.
    pub const SMOOTHING: f64 = 0.02;

    /// The drag torque at speed `v`.
    #[inline]
    pub fn force(&self, v: f64) -> f64 {
        let u = v / self.reference;
        let e2 = Self::SMOOTHING * Self::SMOOTHING;
        self.coefficient * u * (u * u + e2).powf(0.5 * (self.exponent - 1.0))
    }
}

/// Creep of one cable: the relaxed fraction `κ`, time constant `τ`, and whether the whole
/// tension (pretension included) relaxes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CreepLaw {
    /// Relaxed fraction `κ` in `[0, 1)`.
    pub fraction: f64,
    /// Time constant `τ` (s), > 0.
    pub time_constant: f64,
    /// Relax the whole tension `T₀ + F(s)` (true) or only `F(s)`.
    pub whole: bool,
}

/// Friction on the motor side of the cables (the actuator's drum or input spindle, its bearings
/// and seals): the motor overcomes it, the cables never carry it, so it shows only in the force
/// measured at the motor (`net_motor_force`), driven by the motor's own motion.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MotorFriction {
    /// Coulomb level `F_cm` (N).
    pub coulomb: f64,
    /// Sign smoothing velocity (m/s).
    pub smoothing: f64,
    /// Viscous coefficient `b_m` (N·s/m).
    pub viscous: f64,
    /// Dahl hysteresis in the motor displacement (level N, break-away m).
    pub dahl: Option<Hysteresis>,
}

impl MotorFriction {
    fn is_active(&self) -> bool {
        self.coulomb != 0.0 || self.viscous != 0.0 || self.dahl.is_some()
    }
}

/// Play between the joint pulley, which the cables turn, and the link it drives (a keyed or
/// pinned hub with clearance, a worn clevis): the pulley carries `1 − f` of the inertia, the
/// link `f`; across the gap `±δ` nothing is transmitted, beyond it a contact of stiffness
/// `k_c = ratio·r²·(k₁ + k₂)` (a multiple of the cables' torsional stiffness) and damping at
/// 0.2 of its critical value. The joint encoder, the object contact and the external torque are
/// on the link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointPlay {
    /// Half-width `δ` of the clearance (rad), > 0.
    pub half_gap: f64,
    /// Share `f` of the joint inertia on the link side, in (0, 1).
    pub link_share: f64,
    /// Contact stiffness as a multiple of the cables' torsional stiffness at rest, > 0.
    pub stiffness_ratio: f64,
}

/// One cable of the diagnosis joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CablePart {
    /// Law, damping and pretension.
    pub run: CableRun,
    /// Cubic hardening `γ` (1/m²): `F(s) += k·γ·s³`.
    pub cubic: f64,
    /// Optional creep.
    pub creep: Option<CreepLaw>,
}

impl CablePart {
    #[inline]
    fn elastic(&self, s: f64) -> f64 {
        let f = self.run.law.elastic(s);
        if self.cubic == 0.0 {
            f
        } else {
            f + self.run.law.stiffness() * self.cubic * s * s * s
        }
    }

    /// Tangent stiffness at stretch `s` (N/m).
    fn slope(&self, s: f64) -> f64 {
        self.run.slope(s) + 3.0 * self.run.law.stiffness() * self.cubic * s * s
    }
}

/// The inputs at the start, middle and end of the step from fraction `a` to `b` of a sample
/// interval whose inputs go linearly from `ua` to `ub` (first-order hold).
#[inline]
fn hold_inputs(ua: &[f64], ub: &[f64], a: f64, b: f64) -> [[f64; 3]; 3] {
    let m = 0.5 * (a + b);
    let at = |f: f64| std::array::from_fn(|i| ua[i] + f * (ub[i] - ua[i]));
    [at(a), at(m), at(b)]
}

/// Scratch space of the slaved step ([`JointPlant::simulate_refined`]).
struct Slaved {
    stage: Vec<f64>,
    k: Vec<f64>,
    acc: Vec<f64>,
    /// The state the last slaved step ended at, with its derivative in `k` when `cached`.
    end: Vec<f64>,
    cached: bool,
    /// The last secant slope of the joint's acceleration in its speed (1/s; NaN: none yet).
    slope: f64,
}

impl Slaved {
    fn new(n: usize) -> Self {
        Self {
            stage: vec![0.0; n],
            k: vec![0.0; n],
            acc: vec![0.0; n],
            end: vec![0.0; n],
            cached: false,
            slope: f64::NAN,
        }
    }
}

/// The diagnosis joint: see the module docs.
#[derive(Debug, Clone, PartialEq)]
pub struct JointPlant {
    /// Joint pulley radius `r` (m).
    pub radius: f64,
    /// Joint inertia `J` (kg·m²).
    pub inertia: f64,
    /// Joint friction (Coulomb, Stribeck, viscous).
    pub friction: StaticFriction,
    /// Load-dependent dry friction `μ_L` (–): `μ_L·|r·(T_j,1 − T_j,2)|`, sign smoothed like
    /// `friction`.
    pub load_friction: f64,
    /// Drive and return cables.
    pub cables: [CablePart; 2],
    /// Capstan exponent `μφ` of each cable's routing contact (sign law).
    pub capstan: [f64; 2],
    /// Smoothing velocity of the capstan sign (m/s).
    pub capstan_smoothing: f64,
    /// Hysteresis of each cable's routing contact (level = capstan exponent, break-away in m).
    pub contact_hysteresis: [Option<Hysteresis>; 2],
    /// Dahl hysteresis at the joint (the bristle state of the sticking and LuGre friction forms).
    pub dahl: Option<Hysteresis>,
    /// The joint bristle's Stribeck level (LuGre form); `None`: the constant level of `dahl`.
    pub dahl_stribeck: Option<BristleStribeck>,
    /// Joint drag with a power law in speed (added to the nominal friction).
    pub power_drag: Option<PowerDrag>,
    /// Friction on the motor side of the cables.
    pub motor: MotorFriction,
    /// Optional contact with an object.
    pub contact: Option<Contact>,
    /// Optional play between the joint pulley and the link.
    pub play: Option<JointPlay>,
    dahl_at: Option<usize>,
    play_at: Option<usize>,
    creep_at: [Option<usize>; 2],
    n_states: usize,
}

impl From<&AntagonisticJoint> for JointPlant {
    fn from(j: &AntagonisticJoint) -> Self {
        let creep = j.creep.map(|c| CreepLaw {
            fraction: c.fraction,
            time_constant: c.time_constant,
            whole: false,
        });
        let part = |run: CableRun| CablePart {
            run,
            cubic: 0.0,
            creep,
        };
        let mu_phi = j.capstan_mu * j.capstan_wrap;
        let mut p = JointPlant {
            radius: j.radius,
            inertia: j.inertia,
            friction: j.friction,
            load_friction: 0.0,
            cables: [part(j.drive), part(j.ret)],
            capstan: [mu_phi, mu_phi],
            capstan_smoothing: j.capstan_smoothing,
            contact_hysteresis: [None, None],
            dahl: j.dahl.map(|d| Hysteresis {
                level: d.coulomb,
                breakaway: d.coulomb / d.sigma0,
                exponent: d.exponent,
            }),
            dahl_stribeck: None,
            power_drag: None,
            motor: MotorFriction::default(),
            contact: j.contact,
            play: None,
            dahl_at: None,
            play_at: None,
            creep_at: [None, None],
            n_states: 2,
        };
        p.layout();
        p
    }
}

impl JointPlant {
    /// Recompute the state layout after effects were switched on or off:
    /// `[θ, θ̇, (z_a, θ_a), (w₁), (w₂), (θ_l, θ̇_l)]` (`θ` is the pulley's angle when there is
    /// play, `θ_l` the link's).
    pub fn layout(&mut self) {
        let mut n = 2;
        self.dahl_at = self.dahl.map(|_| {
            n += 2;
            2
        });
        for k in 0..2 {
            self.creep_at[k] = self.cables[k].creep.map(|_| {
                n += 1;
                n - 1
            });
        }
        self.play_at = self.play.map(|_| {
            n += 2;
            n - 2
        });
        self.n_states = n;
    }

    /// Inertias of the pulley and of the link (the link's is 0 without play).
    #[inline]
    fn inertias(&self) -> (f64, f64) {
        match self.play {
            Some(p) => (
                self.inertia * (1.0 - p.link_share),
                self.inertia * p.link_share,
            ),
            None => (self.inertia, 0.0),
        }
    }

    /// Torque the pulley passes to the link across the play at state `x` (0 without play), and
    /// whether the contact is engaged (−1, 0, +1).
    #[inline]
    fn play_torque(&self, x: &[f64]) -> (f64, i8) {
        let (Some(p), Some(i)) = (self.play, self.play_at) else {
            return (0.0, 0);
        };
        let e = x[0] - x[i];
        let (jp, jl) = self.inertias();
        let kc = p.stiffness_ratio
            * self.radius
            * self.radius
            * (self.cables[0].run.law.stiffness() + self.cables[1].run.law.stiffness());
        let cc = 0.4 * (kc * jp * jl / (jp + jl)).sqrt();
        let de = x[1] - x[i + 1];
        if e > p.half_gap {
            (kc * (e - p.half_gap) + cc * de, 1)
        } else if e < -p.half_gap {
            (kc * (e + p.half_gap) + cc * de, -1)
        } else {
            (0.0, 0)
        }
    }

    /// The measured joint angle and rate: the link's when there is play.
    #[inline]
    fn link(&self, x: &[f64]) -> (f64, f64) {
        match self.play_at {
            Some(i) => (x[i], x[i + 1]),
            None => (x[0], x[1]),
        }
    }

    /// Initial state at rest at joint angle `theta0` (hysteresis and creep states at zero).
    pub fn rest(&self, theta0: f64) -> Vec<f64> {
        let mut x = vec![0.0; self.n_states];
        x[0] = theta0;
        if let Some(k) = self.dahl_at {
            x[k + 1] = theta0;
        }
        if let Some(k) = self.play_at {
            x[k] = theta0;
        }
        x
    }

    /// Joint-side tensions before the `max(0, ·)` clamp.
    #[inline]
    fn raw_tensions(&self, x: &[f64], u: &[f64]) -> [f64; 2] {
        let s1 = u[0] - self.radius * x[0];
        let sd1 = u[1] - self.radius * x[1];
        let mut t = [0.0; 2];
        for (k, (s, sd)) in [(s1, sd1), (-s1, -sd1)].into_iter().enumerate() {
            let c = &self.cables[k];
            let w = self.creep_at[k].map_or(0.0, |i| x[i]);
            t[k] = c.run.pretension + c.elastic(s) + c.run.damping * sd - w;
        }
        t
    }

    /// The joint's Dahl torque at angle `theta` from the substep's anchor in `x`.
    #[inline]
    fn dahl_torque(&self, x: &[f64], theta: f64) -> f64 {
        match (self.dahl, self.dahl_at) {
            (Some(h), Some(k)) => match self.dahl_stribeck {
                None => h.level * h.advance(x[k], theta - x[k + 1]),
                Some(b) => self.bristle(h, b, x[1], x[k], theta - x[k + 1]),
            },
            _ => 0.0,
        }
    }

    /// LuGre bristle torque after a displacement `delta` from the anchor `zeta_a` (the state in
    /// units of the static level `F + ΔF`) at joint speed `v`: a Dahl element with the level
    /// `g(v)` and the break-away displacement `θ_d·g(v)/(F + ΔF)` (constant bristle stiffness).
    #[inline]
    fn bristle(&self, h: Hysteresis, b: BristleStribeck, v: f64, zeta_a: f64, delta: f64) -> f64 {
        let fs = h.level + b.excess;
        let r = v / b.velocity;
        let g = h.level + b.excess * (-r * r).exp();
        if g.is_nan() || g <= 0.0 {
            return 0.0;
        }
        let at = Hysteresis {
            level: g,
            breakaway: h.breakaway * g / fs,
            exponent: 1.0,
        };
        g * at.advance(zeta_a * fs / g, delta)
    }

    /// Re-anchor the Dahl state at the current angle (after each substep).
    #[inline]
    fn reanchor(&self, x: &mut [f64]) {
        if let (Some(h), Some(k)) = (self.dahl, self.dahl_at) {
            x[k] = match self.dahl_stribeck {
                None => h.advance(x[k], x[0] - x[k + 1]),
                Some(b) => self.bristle(h, b, x[1], x[k], x[0] - x[k + 1]) / (h.level + b.excess),
            };
            x[k + 1] = x[0];
        }
    }

    /// Whether the joint has a dry (sign-smoothed) friction whose stiffness depends on speed.
    fn has_dry_friction(&self) -> bool {
        self.friction.coulomb > 0.0
            || self.friction.static_level > 0.0
            || self.load_friction != 0.0
            || self.power_drag.is_some()
    }

    /// Joint friction torque at velocity `v` with transmitted torque magnitude `load`.
    #[inline]
    fn friction_torque(&self, v: f64, load: f64) -> f64 {
        let mut f = self.friction.force(v);
        if self.load_friction != 0.0 {
            f += self.load_friction * load * smooth_sign(v, self.friction.smoothing);
        }
        if let Some(d) = self.power_drag {
            f += d.force(v);
        }
        f
    }

    /// Speed band in which the joint's dry friction is stiff: the sign's smoothing `ε`, or the
    /// power drag's if it is narrower (rad/s).
    fn friction_band(&self) -> f64 {
        self.power_drag.map_or(self.friction.smoothing, |d| {
            (PowerDrag::SMOOTHING * d.reference).min(self.friction.smoothing)
        })
    }

    /// The joint speed on the slow manifold at the state `x` (its `x[1]` is overwritten) and
    /// inputs `u`: the root of the joint's acceleration in its speed on a falling (stable)
    /// branch, by secant steps from `guess` and the last slope in `slope`, within twenty bands
    /// of rest, where the mode is fast against the substep `h` (`rate·h` ≥ [`SLAVE_RATE_H`]).
    /// `dx` then holds the derivative at the root. `None`: no such root (the joint slides, or
    /// the friction is not stiff there).
    #[allow(clippy::too_many_arguments)]
    fn slaved_speed(
        &self,
        x: &mut [f64],
        u: &[f64],
        dx: &mut [f64],
        guess: f64,
        slope: &mut f64,
        band: f64,
        h: f64,
    ) -> Option<f64> {
        let limit = 20.0 * band;
        let tol = 1e-9 * band;
        let accel = |v: f64, x: &mut [f64], dx: &mut [f64]| {
            x[1] = v;
            self.derivative(x, u, dx);
            dx[1]
        };
        let mut v0 = guess.clamp(-limit, limit);
        let mut a0 = accel(v0, x, dx);
        let mut m = *slope;
        if m.is_nan() || m >= 0.0 {
            let dv = 1e-3 * band;
            m = (accel(v0 + dv, x, dx) - a0) / dv;
        }
        for _ in 0..SLAVE_ITER {
            if !(m < 0.0 && m.is_finite() && a0.is_finite()) {
                return None;
            }
            let step = -a0 / m;
            let v1 = v0 + step;
            if v1.is_nan() || v1.abs() > limit {
                return None;
            }
            let a1 = accel(v1, x, dx);
            if step.abs() <= tol {
                if -m * h < SLAVE_RATE_H {
                    return None;
                }
                *slope = m;
                return Some(v1);
            }
            m = (a1 - a0) / (v1 - v0);
            (v0, a0) = (v1, a1);
        }
        None
    }

    /// One RK4 step of size `h` (inputs `u0`, `um`, `u1` at its start, middle and end) with the
    /// joint speed slaved to the slow manifold (module docs). `false`, with `x` untouched, where
    /// the step does not start on the manifold — the joint is neither within the band of it nor
    /// decelerating onto it within `h_arrive` — or a stage leaves it (break-away).
    #[allow(clippy::too_many_arguments)]
    fn slaved_step(
        &self,
        sw: &mut Slaved,
        x: &mut [f64],
        u0: &[f64],
        um: &[f64],
        u1: &[f64],
        h: f64,
        h_arrive: f64,
        band: f64,
    ) -> bool {
        let ns = x.len();
        // k1: the derivative on the manifold at x (kept from the last slaved step if x is still
        // where that step left it)
        let mut theta = x[0];
        let v = if sw.cached && sw.end[..] == x[..] {
            x[1]
        } else {
            // the joint's own acceleration, and the manifold's speed
            self.derivative(x, u0, &mut sw.k);
            let a = sw.k[1];
            sw.stage.copy_from_slice(x);
            let guess = x[1];
            let Some(v) =
                self.slaved_speed(&mut sw.stage, u0, &mut sw.k, guess, &mut sw.slope, band, h)
            else {
                return false;
            };
            // on the manifold already, or arriving within a fast step: the joint decelerates
            // towards it, and the arrival's extra travel (x₁ − v*)²/(2|a|) is kept
            let gap = x[1] - v;
            if gap.abs() > band {
                if !(gap * a < 0.0 && gap.abs() <= a.abs() * h_arrive) {
                    return false;
                }
                theta += gap * gap.abs() / (2.0 * a.abs());
                sw.stage[0] = theta;
                let Some(v) =
                    self.slaved_speed(&mut sw.stage, u0, &mut sw.k, v, &mut sw.slope, band, h)
                else {
                    return false;
                };
                v
            } else {
                v
            }
        };
        sw.acc.copy_from_slice(&sw.k);
        let x0 = |i: usize| if i == 0 { theta } else { x[i] };
        for (stage_u, w, weight) in [(um, 0.5, 2.0), (um, 0.5, 2.0), (u1, 1.0, 1.0)] {
            for i in 0..ns {
                sw.stage[i] = x0(i) + w * h * sw.k[i];
            }
            if self
                .slaved_speed(&mut sw.stage, stage_u, &mut sw.k, v, &mut sw.slope, band, h)
                .is_none()
            {
                sw.cached = false;
                return false;
            }
            for i in 0..ns {
                sw.acc[i] += weight * sw.k[i];
            }
        }
        for i in 0..ns {
            sw.end[i] = x0(i) + h / 6.0 * sw.acc[i];
        }
        sw.end[1] = sw.stage[1];
        self.reanchor(&mut sw.end);
        sw.stage.copy_from_slice(&sw.end);
        let guess = sw.end[1];
        let Some(v1) =
            self.slaved_speed(&mut sw.stage, u1, &mut sw.k, guess, &mut sw.slope, band, h)
        else {
            sw.cached = false;
            return false;
        };
        sw.end[1] = v1;
        x.copy_from_slice(&sw.end);
        sw.cached = true;
        true
    }

    /// Advance one sample interval `dt` by RK4 steps of `dt/n`, or — with `slave`, where the
    /// joint is on the slow manifold of a stiff friction — by slaved steps of `dt/n_slow`
    /// (module docs); inputs go linearly from `ua` to `ub`. At most `n + n_slow` steps.
    #[allow(clippy::too_many_arguments)]
    fn advance_mixed(
        &self,
        ws: &mut Rk4,
        sw: &mut Slaved,
        x: &mut [f64],
        ua: &[f64],
        ub: &[f64],
        dt: f64,
        n: usize,
        n_slow: usize,
        slave: bool,
    ) {
        if !slave {
            sw.cached = false;
            self.advance(ws, x, ua, ub, dt, n);
            return;
        }
        let band = self.friction_band();
        let (h_fast, h_slow) = (1.0 / n as f64, 1.0 / n_slow as f64);
        // time as a fraction of the interval
        let mut a = 0.0;
        for _ in 0..n + n_slow {
            if a >= 1.0 - 1e-12 {
                break;
            }
            let near_rest = x[1].abs() <= 20.0 * band;
            for fast in [false, true] {
                if !fast && !near_rest {
                    continue;
                }
                let b = (a + if fast { h_fast } else { h_slow }).min(1.0);
                let [u0, um, u1] = hold_inputs(ua, ub, a, b);
                let h = (b - a) * dt;
                if fast {
                    sw.cached = false;
                    ws.step_with(self, x, &u0, &um, &u1, h);
                    self.reanchor(x);
                } else if !self.slaved_step(sw, x, &u0, &um, &u1, h, h_fast * dt, band) {
                    continue;
                }
                a = b;
                break;
            }
        }
    }

    /// RK4 substeps of a sample interval `dt` that the friction's local damping rate needs over
    /// velocities from `v0` to `v1` (through zero when their signs differ; the rate is largest
    /// at rest and falls with speed), at transmitted torque `load`.
    fn friction_substeps(&self, v0: f64, v1: f64, load: f64, dt: f64) -> usize {
        if !self.has_dry_friction() {
            return 1;
        }
        let v = if v0 * v1 <= 0.0 {
            0.0
        } else {
            v0.abs().min(v1.abs())
        };
        let h = 0.05 * self.friction_band();
        let slope =
            (self.friction_torque(v + h, load) - self.friction_torque(v - h, load)) / (2.0 * h);
        let rate = slope.max(0.0) / self.inertias().0;
        let n = (dt * rate / (RK4_REAL_LIMIT * FRICTION_SAFETY)).ceil();
        if n.is_finite() && n >= 1.0 {
            (n as usize).min(MAX_FRICTION_SUBSTEPS)
        } else {
            1
        }
    }

    /// Magnitude of the torque the cables transmit at state `x`.
    fn transmitted(&self, x: &[f64], u: &[f64]) -> f64 {
        let raw = self.raw_tensions(x, u);
        (self.radius * (raw[0].max(0.0) - raw[1].max(0.0))).abs()
    }

    /// Non-smooth regime of a state: slack of each cable, contact, direction of the joint.
    fn regime(&self, x: &[f64], u: &[f64]) -> u8 {
        let t = self.raw_tensions(x, u);
        let theta = self.link(x).0;
        let contact = self
            .contact
            .is_some_and(|c| c.lever_arm * (theta - c.angle) > 0.0);
        let engaged = self.play_torque(x).1;
        u8::from(t[0] <= 0.0)
            | u8::from(t[1] <= 0.0) << 1
            | u8::from(contact) << 2
            | u8::from(x[1] > 0.0) << 3
            | u8::from(engaged > 0) << 4
            | u8::from(engaged < 0) << 5
    }

    /// Simulate the plant on inputs `(T, 3)` row-major `[x, ẋ, τ_ext]` (first-order hold) from
    /// `x0` with `substeps` RK4 steps per sample interval `dt` (intervals with a kink get
    /// [`KINK_REFINE`] times more); returns the outputs `(T, 7)`.
    ///
    /// Errors: [`CableError::Diverged`] at the first non-finite sample.
    pub fn simulate(&self, u: &[f64], x0: &[f64], dt: f64, substeps: usize) -> Result<Vec<f64>> {
        self.simulate_refined(u, x0, dt, substeps, KINK_REFINE)
    }

    /// [`JointPlant::simulate`] with `refine` times the substeps in intervals with a kink (1: no
    /// refinement: plain RK4 with `substeps` everywhere, also through stiff friction).
    pub fn simulate_refined(
        &self,
        u: &[f64],
        x0: &[f64],
        dt: f64,
        substeps: usize,
        refine: usize,
    ) -> Result<Vec<f64>> {
        let t_len = u.len() / 3;
        let mut out = vec![0.0; t_len * JOINT_OUTPUTS];
        let mut ws = Rk4::new(self.n_states, 3);
        let mut x = x0.to_vec();
        let mut saved = x.clone();
        let mut dx = vec![0.0; self.n_states];
        let local = refine > 1 && self.has_dry_friction();
        let mut sw = Slaved::new(self.n_states);
        for k in 0..t_len {
            let u_k = &u[3 * k..3 * k + 3];
            if k > 0 {
                let u_prev = &u[3 * (k - 1)..3 * k];
                saved.copy_from_slice(&x);
                let before = self.regime(&x, u_prev);
                let (v0, load) = (
                    x[1],
                    if local {
                        self.transmitted(&x, u_prev)
                    } else {
                        0.0
                    },
                );
                let n = if local {
                    self.derivative(&x, u_prev, &mut dx);
                    // twice the Euler prediction: a joint sliding into a stick decelerates
                    // harder as it slows (the friction rises towards its static level)
                    substeps.max(self.friction_substeps(v0, v0 + 2.0 * dt * dx[1], load, dt))
                } else {
                    substeps
                };
                // where the friction is stiff past SLAVE_FROM, sticks go on the slow manifold
                let slave = |m: usize| local && m >= SLAVE_FROM && m > substeps;
                self.advance_mixed(
                    &mut ws,
                    &mut sw,
                    &mut x,
                    u_prev,
                    u_k,
                    dt,
                    n,
                    substeps,
                    slave(n),
                );
                let need = if local {
                    n.max(self.friction_substeps(v0, x[1], load, dt))
                } else {
                    n
                };
                // a reversal in a stiff friction's interval is its own corner, resolved by the
                // friction's substeps or on the manifold, not refined again
                let mask = if slave(n) { !DIRECTION } else { u8::MAX };
                let redo = if refine > 1 && self.regime(&x, u_k) & mask != before & mask {
                    // a kink: `refine` times the substeps of the other modes, or what the friction
                    // needs if that is finer (a friction past its cap chatters through zero at
                    // every sample of a stick: refining its need again would cost 8× for nothing)
                    Some((need.max(substeps * refine), substeps * refine))
                } else {
                    (need > n).then_some((need, substeps))
                };
                if let Some((m, slow)) = redo {
                    x.copy_from_slice(&saved);
                    let (a, b) = (u_prev, u_k);
                    self.advance_mixed(&mut ws, &mut sw, &mut x, a, b, dt, m, slow, slave(m));
                }
            }
            let y = &mut out[k * JOINT_OUTPUTS..(k + 1) * JOINT_OUTPUTS];
            self.output(&x, u_k, y);
            if !x.iter().chain(y.iter()).all(|v| v.is_finite()) {
                return Err(CableError::Diverged {
                    step: k,
                    time_s: k as f64 * dt,
                });
            }
        }
        self.apply_contact_hysteresis(u, &mut out);
        Ok(out)
    }

    fn advance(&self, ws: &mut Rk4, x: &mut [f64], ua: &[f64], ub: &[f64], dt: f64, n: usize) {
        let h = dt / n as f64;
        for j in 0..n {
            let (a, b) = (j as f64 / n as f64, (j + 1) as f64 / n as f64);
            let [u0, um, u1] = hold_inputs(ua, ub, a, b);
            ws.step_with(self, x, &u0, &um, &u1, h);
            self.reanchor(x);
        }
    }

    /// Multiply the motor-side tensions by `exp(±μφʰ·ζ)` of each contact's hysteresis, driven by
    /// the motor displacement (the cable's sliding over the routing pulleys), and add the motor
    /// side's friction to the force at the motor.
    fn apply_contact_hysteresis(&self, u: &[f64], out: &mut [f64]) {
        for (k, h) in self.contact_hysteresis.iter().enumerate() {
            let Some(h) = h else { continue };
            let sign = if k == 0 { 1.0 } else { -1.0 };
            let mut zeta = 0.0;
            let mut prev = u[0];
            for (t, row) in out.chunks_exact_mut(JOINT_OUTPUTS).enumerate() {
                let xm = u[3 * t];
                zeta = h.advance(zeta, xm - prev);
                prev = xm;
                row[k] *= (sign * h.level * zeta).exp();
            }
        }
        for row in out.chunks_exact_mut(JOINT_OUTPUTS) {
            row[6] = row[0] - row[1];
        }
        let mf = self.motor;
        if mf.is_active() {
            let mut zeta = 0.0;
            let mut prev = u[0];
            for (t, row) in out.chunks_exact_mut(JOINT_OUTPUTS).enumerate() {
                let (xm, v) = (u[3 * t], u[3 * t + 1]);
                let mut f = mf.viscous * v;
                if mf.coulomb != 0.0 {
                    f += mf.coulomb * smooth_sign(v, mf.smoothing);
                }
                if let Some(h) = mf.dahl {
                    zeta = h.advance(zeta, xm - prev);
                    prev = xm;
                    f += h.level * zeta;
                }
                row[6] += f;
            }
        }
    }

    /// Torsional stiffness of the cables at rest plus the joint Dahl's initial stiffness
    /// (N·m/rad), and the largest rate of a first-order state (1/s): for step advice.
    pub fn stiffest(&self) -> (f64, f64) {
        let r2 = self.radius * self.radius;
        let mut kt = r2 * (self.cables[0].slope(0.0) + self.cables[1].slope(0.0));
        if let Some(h) = self.dahl {
            let excess = self.dahl_stribeck.map_or(0.0, |b| b.excess);
            kt += (h.level + excess) / h.breakaway;
        }
        if let Some(c) = self.contact {
            kt += c.stiffness * c.lever_arm * c.lever_arm;
        }
        if let Some(p) = self.play {
            // the contact across the play acts on the lighter of the two inertias: as a
            // stiffness on the whole joint, scaled up by J / min(J_p, J_l)
            let kc = p.stiffness_ratio
                * r2
                * (self.cables[0].run.law.stiffness() + self.cables[1].run.law.stiffness());
            kt += kc / p.link_share.min(1.0 - p.link_share).max(1e-3);
        }
        let mut rate: f64 = 0.0;
        for c in &self.cables {
            if let Some(cr) = c.creep {
                rate = rate.max(1.0 / cr.time_constant);
            }
        }
        (kt, rate)
    }
}

impl Model for JointPlant {
    fn n_states(&self) -> usize {
        self.n_states
    }
    fn n_inputs(&self) -> usize {
        3
    }
    fn n_outputs(&self) -> usize {
        JOINT_OUTPUTS
    }

    fn derivative(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
        let raw = self.raw_tensions(x, u);
        let (t1, t2) = (raw[0].max(0.0), raw[1].max(0.0));
        let transmitted = self.radius * (t1 - t2);
        let lever = self.contact.map_or(0.0, |c| c.lever_arm);
        let (th_l, w_l) = self.link(x);
        let contact = self.contact.map_or(0.0, |c| c.force(th_l, w_l));
        // the object contact and the external torque act on the link: on the pulley itself
        // without play, across the play otherwise
        let (on_link, passed) = (u[2] - lever * contact, self.play_torque(x).0);
        let mut torque = transmitted - self.friction.force(x[1]);
        if let Some(i) = self.play_at {
            torque -= passed;
            dx[i] = x[i + 1];
            dx[i + 1] = (passed + on_link) / self.inertias().1;
        } else {
            torque += on_link;
        }
        if self.load_friction != 0.0 {
            torque -=
                self.load_friction * transmitted.abs() * smooth_sign(x[1], self.friction.smoothing);
        }
        if let Some(d) = self.power_drag {
            torque -= d.force(x[1]);
        }
        torque -= self.dahl_torque(x, x[0]);
        if let Some(k) = self.dahl_at {
            dx[k] = 0.0;
            dx[k + 1] = 0.0;
        }
        let s1 = u[0] - self.radius * x[0];
        for (k, s) in [s1, -s1].into_iter().enumerate() {
            if let (Some(c), Some(i)) = (self.cables[k].creep, self.creep_at[k]) {
                let mut target = self.cables[k].elastic(s);
                if c.whole {
                    target += self.cables[k].run.pretension;
                }
                dx[i] = (c.fraction * target - x[i]) / c.time_constant;
            }
        }
        dx[0] = x[1];
        dx[1] = torque / self.inertias().0;
    }

    fn output(&self, x: &[f64], u: &[f64], y: &mut [f64]) {
        let raw = self.raw_tensions(x, u);
        let (t1, t2) = (raw[0].max(0.0), raw[1].max(0.0));
        let sg = smooth_sign(u[1], self.capstan_smoothing);
        y[0] = t1 * (self.capstan[0] * sg).exp();
        y[1] = t2 * (-self.capstan[1] * sg).exp();
        y[2] = t1;
        y[3] = t2;
        let (th_l, w_l) = self.link(x);
        y[4] = th_l;
        y[5] = self.contact.map_or(0.0, |c| c.force(th_l, w_l));
        y[6] = y[0] - y[1];
    }

    fn state_names(&self) -> Vec<String> {
        let mut v = vec!["theta".to_owned(), "dtheta".to_owned()];
        if self.dahl.is_some() {
            v.extend(["dahl_anchor".into(), "dahl_anchor_angle".into()]);
        }
        for (k, name) in ["creep_drive", "creep_return"].iter().enumerate() {
            if self.cables[k].creep.is_some() {
                v.push((*name).into());
            }
        }
        if self.play.is_some() {
            v.extend(["link_angle".into(), "link_rate".into()]);
        }
        v
    }
    fn input_names(&self) -> Vec<String> {
        vec!["x_m".into(), "dx_m".into(), "tau_ext".into()]
    }
    fn output_names(&self) -> Vec<String> {
        JOINT_OUTPUT_NAMES.iter().map(|s| s.to_string()).collect()
    }
}

/// The cable law of a nominal run with an exponential stiffening of `beta` (1/m) applied.
pub(crate) fn exponential(run: &CableRun, beta: f64) -> CableLaw {
    if beta == 0.0 {
        run.law
    } else {
        CableLaw::Exponential {
            stiffness: run.law.stiffness(),
            length_scale: 1.0 / beta,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::friction::Dahl;
    use crate::integrate::{simulate, InputHold, SimOptions};
    use approx::assert_relative_eq;

    fn inputs(t_len: usize, dt: f64, amp: f64) -> Vec<f64> {
        let x: Vec<f64> = (0..t_len)
            .map(|k| {
                let t = k as f64 * dt;
                amp * (2.0 * std::f64::consts::PI * 1.3 * t).sin()
                    + 0.3 * amp * (2.0 * std::f64::consts::PI * 4.1 * t).sin()
            })
            .collect();
        let mut v = vec![0.0; t_len];
        crate::identify::signal::velocity(&x, dt, &mut v);
        (0..t_len).flat_map(|k| [x[k], v[k], 0.0]).collect()
    }

    #[test]
    fn joint_play_offsets_the_link_by_the_clearance_under_a_load() {
        // a constant external torque on the link presses it against one side of the clearance:
        // at rest the link sits δ + τ/k_c beyond the pulley, the cables carry the same torque
        let mut j = AntagonisticJoint::forceps_example();
        j.contact = None;
        let nominal = JointPlant::from(&j);
        let mut p = nominal.clone();
        let (delta, ratio) = (4e-3, 20.0);
        p.play = Some(JointPlay {
            half_gap: delta,
            link_share: 0.6,
            stiffness_ratio: ratio,
        });
        p.layout();
        assert_eq!(p.n_states(), 4);
        let (dt, t_len, tau) = (1e-3, 3000, 2e-3);
        let u: Vec<f64> = (0..t_len).flat_map(|_| [0.0, 0.0, tau]).collect();
        let settle = |plant: &JointPlant| {
            let y = plant.simulate(&u, &plant.rest(0.0), dt, 8).unwrap();
            let last = &y[(t_len - 1) * JOINT_OUTPUTS..];
            (last[4], last[2] - last[3])
        };
        let (theta_nom, net_nom) = settle(&nominal);
        let (theta_play, net_play) = settle(&p);
        let r2 = p.radius * p.radius;
        let kc = ratio * r2 * (p.cables[0].run.law.stiffness() + p.cables[1].run.law.stiffness());
        let want = delta + tau / kc;
        assert!(
            ((theta_play - theta_nom) - want).abs() < 0.02 * want,
            "link offset {} vs {want}",
            theta_play - theta_nom
        );
        assert_relative_eq!(net_play, net_nom, max_relative = 2e-2); // still ringing a little
                                                                     // without a load, rest is an equilibrium of the pulley, the cables and the link
        let still: Vec<f64> = (0..500).flat_map(|_| [0.0, 0.0, 0.0]).collect();
        let y = p.simulate(&still, &p.rest(0.0), dt, 4).unwrap();
        assert!(y[499 * JOINT_OUTPUTS + 4].abs() < 1e-15);
    }

    #[test]
    fn nominal_plant_reproduces_the_antagonistic_joint() {
        // without the kink refinement the plant is the joint's RK4 up to the summation order
        // of the torque (the refinement re-integrates the joint's reversals)
        let mut j = AntagonisticJoint::forceps_example();
        j.contact = None;
        let p = JointPlant::from(&j);
        let (dt, t_len) = (1e-3, 2000);
        let u = inputs(t_len, dt, 2e-4);
        let u2: Vec<f64> = u.chunks(3).flat_map(|r| [r[0], r[1]]).collect();
        let x0 = [0.0, 0.0];
        let opts = SimOptions::new(dt, 4, InputHold::Foh).unwrap();
        let want = simulate(&j, &u2, &x0, &opts).unwrap();
        let got = p.simulate_refined(&u, &x0, dt, 4, 1).unwrap();
        for k in 0..t_len {
            for c in 0..6 {
                assert_relative_eq!(
                    got[k * 7 + c],
                    want.outputs[k * 6 + c],
                    max_relative = 1e-9,
                    epsilon = 1e-12
                );
            }
        }
    }

    #[test]
    fn closed_form_hysteresis_matches_the_dahl_ode() {
        // integrate dζ/dθ of seed 002 eq. 8 finely and compare with the closed form
        for n in [0.6, 1.0, 1.5, 2.5] {
            let h = Hysteresis {
                level: 1.0,
                breakaway: 0.01,
                exponent: n,
            };
            let d = Dahl::new(1.0 / 0.01, 1.0, n).unwrap();
            for (z0, delta) in [(0.0, 0.02), (0.9, -0.015), (-0.5, 0.004), (1.0, -0.05)] {
                let steps = 200_000;
                let dth = delta / steps as f64;
                let mut z: f64 = z0;
                for _ in 0..steps {
                    z += d.rate(z, dth.signum()) * dth.abs();
                }
                assert_relative_eq!(h.advance(z0, delta), z, epsilon = 2e-4);
            }
        }
    }

    #[test]
    fn a_tiny_breakaway_angle_never_diverges_and_tends_to_coulomb() {
        let mut j = AntagonisticJoint::forceps_example();
        j.contact = None;
        j.friction = StaticFriction::NONE;
        let mut p = JointPlant::from(&j);
        let (dt, t_len) = (1e-3, 3000);
        let u = inputs(t_len, dt, 3e-3);
        let f = 2e-3;
        p.dahl = Some(Hysteresis {
            level: f,
            breakaway: 1e-9,
            exponent: 1.0,
        });
        p.layout();
        // substeps for the cables only: RK4 of the Dahl ODE would need |θ̇|/θ_d·h < 2.8
        let y = p.simulate(&u, &p.rest(0.0), dt, 2).unwrap();
        assert!(y.iter().all(|v| v.is_finite()));
        // while sliding, the hysteresis torque is the Coulomb level
        let mut x = p.rest(0.0);
        x[2] = 0.3;
        x[3] = 0.0;
        assert_relative_eq!(p.dahl_torque(&x, 1e-6), f, max_relative = 1e-12);
        assert_relative_eq!(p.dahl_torque(&x, -1e-6), -f, max_relative = 1e-12);
    }

    #[test]
    fn a_lugre_bristle_slides_on_the_stribeck_curve_and_holds_the_static_level() {
        let mut j = AntagonisticJoint::forceps_example();
        j.contact = None;
        j.friction = StaticFriction::NONE;
        let mut p = JointPlant::from(&j);
        let (fc, df, vs, th) = (2e-3, 3e-3, 0.05, 1e-4);
        p.dahl = Some(Hysteresis {
            level: fc,
            breakaway: th,
            exponent: 1.0,
        });
        p.dahl_stribeck = BristleStribeck::new(df, vs);
        p.layout();
        // sliding far at speed v: the level of the Stribeck curve, either way
        for v in [0.0, 0.02, 0.05, 0.2, -0.03] {
            let mut x = p.rest(0.0);
            x[1] = v;
            let g = fc + df * (-(v / vs) * (v / vs)).exp();
            let s = if v < 0.0 { -1.0 } else { 1.0 };
            assert_relative_eq!(p.dahl_torque(&x, s * 1.0), s * g, max_relative = 1e-9);
        }
        // at rest the bristle is a spring of stiffness F_s/θ_d: a deflection of θ_d/100 holds
        // about F_s/100, more than the Coulomb level's share
        let x = p.rest(0.0);
        let small = p.dahl_torque(&x, th / 100.0);
        assert_relative_eq!(small, (fc + df) / 100.0, max_relative = 1e-2);
        // without the Stribeck excess it is the Dahl element of the same level
        let mut d = p.clone();
        d.dahl_stribeck = BristleStribeck::new(0.0, vs);
        let mut q = p.clone();
        q.dahl_stribeck = None;
        let mut x = p.rest(0.0);
        x[1] = 0.01;
        x[2] = 0.4;
        for delta in [-3e-4, 1e-5, 2e-4] {
            assert_relative_eq!(
                d.dahl_torque(&x, delta),
                q.dahl_torque(&x, delta),
                max_relative = 1e-12
            );
        }
        // and a replay with it stays finite
        let (dt, t_len) = (1e-3, 2000);
        let u = inputs(t_len, dt, 3e-3);
        let y = p.simulate(&u, &p.rest(0.0), dt, 4).unwrap();
        assert!(y.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn power_drag_is_a_power_of_speed_away_from_rest_and_linear_for_n_one() {
        let d = PowerDrag {
            coefficient: 0.2,
            exponent: 0.5,
            reference: 2.0,
        };
        // b·|v/v_r|ⁿ·sgn(v) once |v| ≫ ε·v_r, odd, finite slope b·εⁿ⁻¹/v_r at rest
        for v in [1.0, 4.0, -3.0] {
            let want = 0.2 * (v / 2.0_f64).abs().powf(0.5) * v.signum();
            assert_relative_eq!(d.force(v), want, max_relative = 2e-3);
        }
        let h = 1e-9;
        let slope = (d.force(h) - d.force(-h)) / (2.0 * h);
        assert_relative_eq!(
            slope,
            0.2 * PowerDrag::SMOOTHING.powf(-0.5) / 2.0,
            max_relative = 1e-6
        );
        let lin = PowerDrag { exponent: 1.0, ..d };
        assert_relative_eq!(lin.force(0.7), 0.2 * 0.7 / 2.0, max_relative = 1e-12);
        // on the joint it adds to the friction torque and asks for substeps where it is stiff
        let mut j = AntagonisticJoint::forceps_example();
        j.contact = None;
        j.friction = StaticFriction::NONE;
        let mut p = JointPlant::from(&j);
        assert_eq!(p.friction_substeps(0.0, 0.0, 0.0, 1e-3), 1);
        p.power_drag = Some(PowerDrag {
            coefficient: 10.0,
            exponent: 0.3,
            reference: 1.0,
        });
        assert_relative_eq!(
            p.friction_torque(1.0, 0.0),
            d.force(0.0) + 10.0,
            max_relative = 1e-3
        );
        assert!(p.friction_substeps(0.0, 0.0, 0.0, 1e-3) > 1);
    }

    #[test]
    fn whole_tension_creep_relaxes_the_pretension_at_rest() {
        let mut j = AntagonisticJoint::forceps_example();
        j.contact = None;
        let mut p = JointPlant::from(&j);
        for c in &mut p.cables {
            c.creep = Some(CreepLaw {
                fraction: 0.3,
                time_constant: 0.5,
                whole: true,
            });
        }
        p.layout();
        let t_len = 10_000;
        let u = vec![0.0; 3 * t_len];
        let y = p.simulate(&u, &p.rest(0.0), 1e-3, 1).unwrap();
        let last = &y[(t_len - 1) * 7..];
        assert_relative_eq!(last[2], 0.7 * 10.0, max_relative = 1e-6);
        assert_relative_eq!(last[3], 0.7 * 10.0, max_relative = 1e-6);
        // the stretch-only creep leaves the pretension alone
        for c in &mut p.cables {
            c.creep.as_mut().unwrap().whole = false;
        }
        let y = p.simulate(&u, &p.rest(0.0), 1e-3, 1).unwrap();
        assert_relative_eq!(y[(t_len - 1) * 7 + 2], 10.0, max_relative = 1e-9);
    }

    #[test]
    fn contact_hysteresis_tends_to_the_capstan_sign_law() {
        let mut j = AntagonisticJoint::forceps_example();
        j.contact = None;
        j.capstan_mu = 0.0;
        let (dt, t_len) = (1e-3, 2000);
        let u = inputs(t_len, dt, 2e-4);
        let mut sharp = JointPlant::from(&j);
        sharp.capstan = [0.2, 0.0];
        sharp.capstan_smoothing = 1e-9;
        let mut hyst = JointPlant::from(&j);
        hyst.contact_hysteresis[0] = Some(Hysteresis {
            level: 0.2,
            breakaway: 1e-12,
            exponent: 1.0,
        });
        let a = sharp.simulate(&u, &[0.0, 0.0], dt, 2).unwrap();
        let b = hyst.simulate(&u, &[0.0, 0.0], dt, 2).unwrap();
        let mut same = 0;
        for k in 1..t_len {
            // equal wherever the motor moves (the sign law is 0 at rest, the state holds)
            if u[3 * k + 1].abs() > 1e-6 && (u[3 * k] - u[3 * k - 3]) * u[3 * k + 1] > 0.0 {
                assert_relative_eq!(a[k * 7], b[k * 7], max_relative = 1e-7);
                same += 1;
            }
            // the return cable is untouched
            assert_relative_eq!(b[k * 7 + 1], b[k * 7 + 3], max_relative = 1e-12);
        }
        assert!(same > t_len / 2);
    }

    #[test]
    fn motor_side_friction_shows_only_in_the_force_at_the_motor() {
        let mut j = AntagonisticJoint::forceps_example();
        j.contact = None;
        let (dt, t_len) = (1e-3, 2000);
        let u = inputs(t_len, dt, 2e-4);
        let nominal = JointPlant::from(&j);
        let mut p = JointPlant::from(&j);
        p.motor = MotorFriction {
            coulomb: 0.5,
            smoothing: 1e-9,
            viscous: 30.0,
            dahl: Some(Hysteresis {
                level: 0.2,
                breakaway: 1e-12,
                exponent: 1.0,
            }),
        };
        let a = nominal.simulate(&u, &[0.0, 0.0], dt, 2).unwrap();
        let b = p.simulate(&u, &[0.0, 0.0], dt, 2).unwrap();
        let mut moving = 0;
        for k in 1..t_len {
            // every output but the force at the motor is the nominal's: the cables never carry it
            for i in 0..6 {
                assert_eq!(a[k * 7 + i].to_bits(), b[k * 7 + i].to_bits());
            }
            let v = u[3 * k + 1];
            if v.abs() > 1e-4 && (u[3 * k] - u[3 * k - 3]) * v > 0.0 {
                // a sharp Dahl is the sign law: (0.5 + 0.2)·sign(v) + 30·v
                let expect = 0.7 * v.signum() + 30.0 * v;
                assert_relative_eq!(b[k * 7 + 6] - a[k * 7 + 6], expect, max_relative = 1e-6);
                moving += 1;
            }
        }
        assert!(moving > t_len / 2);
    }

    #[test]
    fn slack_kinks_are_refined() {
        // closing hard on the object slackens the return cable: the refined coarse replay is
        // much closer to a 64-substep reference than the plain one
        let mut j = AntagonisticJoint::forceps_example();
        // no dry friction: its stick stiffness would need the advised substeps, not the kinks
        j.friction = StaticFriction::coulomb_viscous("f", 0.0, 1e-4, 0.05).unwrap();
        j.drive.pretension = 2.0;
        j.ret.pretension = 2.0;
        let p = JointPlant::from(&j);
        let (dt, t_len) = (1e-3, 3000);
        let u = inputs(t_len, dt, 2e-3);
        let fine = p.simulate(&u, &[0.0, 0.0], dt, 64).unwrap();
        let slack = fine.chunks(7).filter(|r| r[3] == 0.0).count();
        assert!(slack > 100, "{slack}");
        let err = |refine| {
            let coarse = p.simulate_refined(&u, &[0.0, 0.0], dt, 4, refine).unwrap();
            fine.iter()
                .zip(&coarse)
                .step_by(7)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max)
        };
        let (plain, refined) = (err(1), err(KINK_REFINE));
        assert!(refined < 0.25 * plain, "{refined} vs {plain}");
    }

    #[test]
    fn sticks_beyond_the_substep_cap_are_integrated_on_the_slow_manifold() {
        // sharp frictions whose sticks need 50-150 substeps (F_s/(ε·J) = 3-4e5 /s), past the
        // cap of 16: at one substep per sample the slaved sticks follow a plain RK4 replay at 512
        // substeps everywhere, where the capped substeps chatter through every stick. Coulomb
        // sticks and slides; the Stribeck law (static level 1.5× the Coulomb level) stick-slips,
        // whose slip times are sensitive to everything before them
        let (dt, t_len) = (1e-3, 3000);
        let u = inputs(t_len, dt, 2e-4);
        let x0 = [0.0, 0.0];
        for (friction, bound, gain) in [
            (
                StaticFriction::coulomb_viscous("f", 2e-3, 0.0, 0.005),
                1e-3,
                20.0,
            ),
            (
                StaticFriction::stribeck("f", 2e-3, 3e-3, 0.5, 2.0, 0.0, 0.01),
                0.03,
                3.0,
            ),
        ] {
            let mut j = AntagonisticJoint::forceps_example();
            j.contact = None;
            j.friction = friction.unwrap();
            let p = JointPlant::from(&j);
            assert_eq!(
                p.friction_substeps(0.0, 0.0, 0.0, dt),
                MAX_FRICTION_SUBSTEPS
            );
            let fine = p.simulate_refined(&u, &x0, dt, 512, 1).unwrap();
            let slaved = p.simulate_refined(&u, &x0, dt, 1, KINK_REFINE).unwrap();
            let capped = p
                .simulate_refined(&u, &x0, dt, MAX_FRICTION_SUBSTEPS, 1)
                .unwrap();
            let channel = |y: &[f64], c: usize| -> Vec<f64> {
                y.iter().skip(c).step_by(7).copied().collect()
            };
            let theta = channel(&fine, 4);
            // the joint sticks: its angle stands nearly still for much of the run
            let steps: Vec<f64> = theta.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
            let fastest = steps.iter().fold(0.0, |m: f64, s| m.max(*s));
            let still = steps.iter().filter(|s| **s < 0.02 * fastest).count();
            assert!(still > t_len / 10, "{still} samples at rest");
            for c in [0, 4] {
                let want = channel(&fine, c);
                let range = want.iter().fold(f64::MIN, |m, x| m.max(*x))
                    - want.iter().fold(f64::MAX, |m, x| m.min(*x));
                let err = |y: &[f64]| {
                    channel(y, c)
                        .iter()
                        .zip(&want)
                        .map(|(a, b)| (a - b).abs())
                        .fold(0.0, f64::max)
                        / range
                };
                let (e_slaved, e_capped) = (err(&slaved), err(&capped));
                assert!(
                    e_slaved < bound,
                    "channel {c}: {e_slaved} (capped {e_capped})"
                );
                assert!(
                    e_capped > gain * e_slaved,
                    "channel {c}: {e_capped} vs {e_slaved}"
                );
            }
        }
    }

    #[test]
    fn sharp_friction_gets_its_substeps_where_the_joint_sticks() {
        // a sharp Coulomb friction (F/(ε·J) = 2e4 /s) needs ~9 substeps at rest and one when
        // sliding: given one substep, the interval-by-interval choice stays stable and close to
        // a fine replay, where one substep everywhere does not
        let mut j = AntagonisticJoint::forceps_example();
        j.contact = None;
        j.friction = StaticFriction::coulomb_viscous("f", 2e-3, 0.0, 0.1).unwrap();
        let p = JointPlant::from(&j);
        let (dt, t_len) = (1e-3, 4000);
        let at_rest = p.friction_substeps(0.0, 0.0, 0.0, dt);
        assert!((4..MAX_FRICTION_SUBSTEPS).contains(&at_rest), "{at_rest}");
        // the rate falls as (1 + (v/ε)²)^(-3/2): ten ε of speed needs one substep
        assert_eq!(p.friction_substeps(1.0, 1.0, 0.0, dt), 1);
        assert_eq!(p.friction_substeps(1.0, -1.0, 0.0, dt), at_rest);
        let u = inputs(t_len, dt, 2e-4);
        let x0 = [0.0, 0.0];
        let fine = p
            .simulate_refined(&u, &x0, dt, 8 * at_rest, KINK_REFINE)
            .unwrap();
        let uniform = p
            .simulate_refined(&u, &x0, dt, at_rest, KINK_REFINE)
            .unwrap();
        let local = p.simulate_refined(&u, &x0, dt, 1, KINK_REFINE).unwrap();
        let err = |y: &[f64], c: usize| {
            y.iter()
                .zip(&fine)
                .skip(c)
                .step_by(7)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max)
        };
        let range = |c: usize| {
            let v: Vec<f64> = fine.iter().skip(c).step_by(7).copied().collect();
            v.iter().fold(f64::MIN, |m, x| m.max(*x)) - v.iter().fold(f64::MAX, |m, x| m.min(*x))
        };
        let plain = p.simulate_refined(&u, &x0, dt, 1, 1).unwrap();
        assert!(local.iter().all(|v| v.is_finite()));
        for c in [0, 4] {
            // within 2e-4 of the channel's range of a replay at 8× the substeps at rest; one
            // substep everywhere chatters through the sticks (7 % of the tension range here)
            let (e_local, e_uniform, e_plain) = (err(&local, c), err(&uniform, c), err(&plain, c));
            assert!(
                e_local < 2e-4 * range(c),
                "channel {c}: {e_local} (uniform {e_uniform})"
            );
            assert!(
                e_plain > 100.0 * e_local,
                "channel {c}: plain {e_plain} vs {e_local}"
            );
        }
    }
}
