//! A cable network: any mechanism of revolute or prismatic joints driven by cables routed over
//! pulleys and pulled by motors, described element by element (issue #39 §1).
//!
//! **Elements.** Bodies (each moved by one joint, its inertia about that joint's axis); joints
//! (revolute or prismatic, a parent body or the base, friction, a gravity load); pulleys (on a
//! joint's axis, turning with it — a joint pulley or an idler whose wrap changes with the joint —
//! or fixed to the base); cables (a routing: the ordered pulleys they pass, with the sense of
//! the wrap and its angle; a pretension, an elastic law, damping; the motor that hauls them in);
//! motors (torque- or position-driven, a capstan of radius `r_m` behind a gear ratio `N`).
//!
//! **Length map and coupling.** A contact `k` of cable `c` on a pulley of radius `r_k` on the
//! axis of joint `j_k`, with sense `s_k = ±1`, shortens the cable's path by `s_k·r_k·q_j`
//! (revolute; for a prismatic joint `r_k` is the metres of cable per metre of travel): with
//! `s_k = +1` the cable's tension turns the joint positively, and turning the joint positively
//! lets cable off towards it (slackening it unless its motor hauls in). So
//!
//! ```text
//! l(q) = l(0) − J·q,        J_cj = Σ_{k of c on joint j} s_k·r_k        (m × n, constant)
//! τ    = Jᵀ·T                                                           joint torques from tensions
//! ```
//!
//! `J` is the routing's moment-arm (coupling) matrix; `Jᵀ` is the structure matrix of tendon-
//! driven manipulators (Tsai & Lee 1989; Salisbury & Craig 1982). A network whose `J` has rank
//! below the number of joints cannot move every joint independently: refused.
//!
//! **Dynamics** (state `[q_j, q̇_j]` per joint, then `[q_m, q̇_m]` per torque-driven motor):
//!
//! ```text
//! ρ_m  = r_m / N_m                                 capstan metres per motor radian
//! e_c  = σ_c·ρ_m(c)·q_m(c) − (J·q)_c                cable elongation from pretension (m)
//! T_c  = max(0, T₀,c + F_c(e_c) + b_c·ė_c)          joint-side tension (crate::cable)
//! T_m,c = T_c·exp(μφ_c·σ_ε(v_h,c))                 driver-side tension: the routing's capstan
//!                                                  losses (μφ_c = Σ μ_k·φ_k), v_h,c the speed
//!                                                  at which the driver hauls the cable through
//!                                                  its friction contacts
//! I_j·q̈_j = (Jᵀ·T)_j + (J_dᵀ·(T_m − T))_j − F_f,j(q̇_j) − g_j(q_j) + τ_ext,j
//! I_m·q̈_m = τ_m − F_f,m(q̇_m) − ρ_m·Σ_{c on m} σ_c·T_m,c
//! ```
//!
//! **Friction along the routing.** A cable's elasticity sits on the joint side of its friction
//! contacts; the piece between its driver — the motor, or for a cable anchored on a driven
//! stage the contacts before the first one with friction (`J_d`, the driver's moment arms) —
//! and the friction contacts carries the driver-side tension `T_m`. So the capstan losses act in
//! the dynamics: a torque-driven motor, or the driven stage, pulls `T_m` where the joint feels
//! `T` (the Euler–Eytelwein ratio `e^{±μφ}` as the cable is hauled in or paid out). A diagnosis
//! may give a routing **pre-sliding** (a pulley's bristles, seed 002 eq. 8): the sign `σ_ε(v_h)`
//! becomes a state `ζ ∈ [−1, 1]`, `ζ̇ = (v_h − |v_h|·ζ)/x_d`, which slides to `±1` over `x_d` m
//! of hauled cable after each reversal (so the ratio ramps instead of jumping); its friction then
//! stays explicit in the diagnosis's replay.
//!
//! `σ_c = ±1` is the sense in which the motor hauls cable `c` in. A position-driven motor takes
//! `q_m`, `q̇_m` as inputs instead of states. The antagonistic joint of seed 000
//! ([`AntagonisticJoint`](crate::dynamics::AntagonisticJoint)) is one joint, one position motor
//! (`r_m = N = 1`: `q_m` is the displacement `x_m`) and two cables of senses `±1`; the coupled
//! transmission of seed 001 ([`CableTransmission`](crate::dynamics::CableTransmission)) is one
//! torque motor and one antagonistic pair per link, the distal pairs passing idlers on the
//! proximal axes (`r = C_ij·r_l,i`). Both are tested equal to the built-in models.
//!
//! **Not modelled** (said where it matters): inertial coupling between joints (each joint's
//! inertia is its body's, about its axis — as in the transmission model), friction contacts
//! between joint pulleys (a routing's friction is lumped before its first joint-side contact),
//! wrap angles that change with the configuration (the wrap is its value at `q = 0`).

use crate::cable::CableRun;
use crate::dynamics::{Gravity, JointKind, Model};
use crate::error::{check, CableError, Result};
use crate::friction::{smooth_sign, StaticFriction};

mod file;
#[cfg(test)]
mod tests;

/// Relative size of the smallest singular value of `J` below which the coupling is singular.
pub const SINGULAR_COUPLING: f64 = 1e-9;

/// Smoothing of a routing friction's sign when a network file gives none (m/s of cable): a
/// capstan's dry friction sticks — a regularisation as wide as an instrument's cable speeds
/// (mm/s) would turn the stick into a drag that grows with speed — so the default resolves the
/// stick to 1 µm/s. Explicit RK4 then needs the step advice's substeps where the routing acts
/// on a torque-driven motor or a driven stage; the diagnosis integrates it implicitly.
pub const DEFAULT_CAPSTAN_SMOOTHING: f64 = 1e-6;

/// Most iterations of the capstan's balance inside a motor's play.
const PLAY_ITER: usize = 60;

/// How a motor is driven.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Drive {
    /// A torque input `τ_m` (N·m) drives the motor's inertia (two states).
    Torque,
    /// The motor angle and rate are inputs (`q_m`, `q̇_m`): a stiff position servo.
    Position,
}

impl Drive {
    /// Parse `"torque"` / `"position"`.
    pub fn from_name(name: &str, field: &str) -> Result<Self> {
        match name {
            "torque" => Ok(Self::Torque),
            "position" => Ok(Self::Position),
            _ => Err(CableError::InvalidOption {
                name: field.to_owned(),
                value: name.to_owned(),
                allowed: "torque, position".into(),
            }),
        }
    }
}

/// A body: what one joint moves.
#[derive(Debug, Clone, PartialEq)]
pub struct BodySpec {
    /// Its name (unique).
    pub name: String,
    /// Inertia about its joint's axis (kg·m²; kg for a prismatic joint), > 0.
    pub inertia: f64,
}

/// A joint: moves `child` relative to `parent` (a body or `"base"`).
#[derive(Debug, Clone, PartialEq)]
pub struct JointSpec {
    /// Its name (unique).
    pub name: String,
    /// `"revolute"` or `"prismatic"`.
    pub kind: String,
    /// The body it is mounted on, or `"base"`.
    pub parent: String,
    /// The body it moves.
    pub child: String,
    /// Coulomb friction (N·m or N), viscous (N·m·s/rad or N·s/m), sign smoothing (rad/s or m/s).
    pub coulomb: f64,
    /// See `coulomb`.
    pub viscous: f64,
    /// See `coulomb`.
    pub smoothing: f64,
    /// Gravity load `A·cos(q + φ)` (revolute) or `A·cos φ` (prismatic).
    pub gravity: Gravity,
}

/// A pulley: on a joint's axis (turns with the joint) or fixed to the base (`joint` `None`).
#[derive(Debug, Clone, PartialEq)]
pub struct PulleySpec {
    /// Its name (unique).
    pub name: String,
    /// The joint on whose axis it turns, if any.
    pub joint: Option<String>,
    /// Radius (m), > 0; on a prismatic joint's axis, metres of cable per metre of travel.
    pub radius: f64,
}

/// One contact of a cable's routing.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactSpec {
    /// The pulley.
    pub pulley: String,
    /// Wrap angle (rad), ≥ 0.
    pub wrap: f64,
    /// +1: the cable's tension turns the pulley's joint positively (turning the joint positively
    /// shortens the cable's path, slackening it); −1 the other way.
    pub sense: f64,
    /// Capstan friction coefficient of the contact, ≥ 0.
    pub mu: f64,
}

/// A cable.
#[derive(Debug, Clone, PartialEq)]
pub struct CableSpec {
    /// Its name (unique).
    pub name: String,
    /// The ordered pulleys it passes, from the motor to its termination.
    pub routing: Vec<ContactSpec>,
    /// Elastic law, damping, pretension.
    pub run: CableRun,
    /// The motor that hauls it in; `None`: both ends are anchored (to the base or to a pulley
    /// it is wound on, a contact of sense −1 on a driven stage's pulley).
    pub motor: Option<String>,
    /// +1: the motor hauls it in when `q_m` increases; −1 the other way.
    pub motor_sense: f64,
    /// A position-driven motor that moves the cable's far end (its termination beyond the last
    /// contact: a parallel robot's platform, whose measured pose sets it); `None`: the end is
    /// anchored.
    pub end_motor: Option<String>,
    /// +1: the end motor stretches the cable when its angle increases; −1 the other way.
    pub end_sense: f64,
    /// The cable's free length (m) between its motor's capstan and its end with every motor at
    /// 0, when its motor winds it up (a winch): its elastic tension then scales as
    /// `length / (length − σ·ρ·q_m)` (a rod's `E·A/L` with `L` the free length); `None`: a
    /// fixed length (a tendon sliding over its pulleys).
    pub free_length: Option<f64>,
    /// Friction of the pulleys between its last contact and its far end (a parallel robot's
    /// guide and exit pulleys between the winch-side sensor and the platform; seed 002 eqs
    /// 7–8); `None`: none.
    pub path: Option<PathSpec>,
}

/// Where a path's exit-pulley wrap comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum ExitWrap {
    /// A fixed wrap (rad), in `[0, 2π]`.
    Fixed(f64),
    /// A measured signal of the network (rad; a parallel robot's exit wrap at its measured pose).
    Signal(String),
}

/// Friction on the path between a cable's last contact and its far end, seed 002's additive
/// law (see [`crate::cdpr::path`]): `T_path = T + μ·N·T·s + σ_v·v`, `N = 2·sin(θ_g/2) +
/// 2·sin(θ_e/2)`, `s` the sign of the cable's speed towards the motor `v` (Coulomb) or a Dahl
/// state over the hauled length; `T` the elastic piece's tension (its far end).
#[derive(Debug, Clone, PartialEq)]
pub struct PathSpec {
    /// Friction coefficient `μ`, ≥ 0.
    pub coefficient: f64,
    /// Viscous coefficient `σ_v` (N·s/m), ≥ 0.
    pub viscous: f64,
    /// Wrap of the guide pulleys `θ_g` (rad), in `[0, 2π]`.
    pub guide_wrap: f64,
    /// Wrap of the exit pulley `θ_e`.
    pub exit_wrap: ExitWrap,
    /// The law (Coulomb with its smoothing, or Dahl with its pre-sliding length and exponent).
    pub law: crate::cdpr::PathLaw,
}

/// A motor with its capstan.
#[derive(Debug, Clone, PartialEq)]
pub struct MotorSpec {
    /// Its name (unique).
    pub name: String,
    /// Torque or position driven.
    pub drive: Drive,
    /// Rotor inertia (kg·m²), > 0 for a torque-driven motor (unused when position driven).
    pub inertia: f64,
    /// Gear ratio `N` (motor rad per capstan rad), > 0.
    pub gear_ratio: f64,
    /// Capstan radius `r_m` (m), > 0.
    pub capstan_radius: f64,
    /// Motor friction.
    pub friction: StaticFriction,
}

/// A sensor: which output of the network a measured channel is.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorSpec {
    /// Its name (unique): the channel's name.
    pub name: String,
    /// `"encoder"` (a joint's or a motor's angle), `"tension"` (a cable's, `at` the motor or
    /// the joint), `"joint_torque"`, `"motor_current"` (the cable load on a motor, in N·m).
    pub kind: String,
    /// The joint, motor or cable it measures.
    pub target: String,
    /// For a tension: `"motor"` (after the routing's capstan losses) or `"joint"`.
    pub at: String,
}

/// A whole network, as a model file describes it.
#[derive(Debug, Clone, PartialEq)]
pub struct NetworkSpec {
    /// Bodies.
    pub bodies: Vec<BodySpec>,
    /// Joints.
    pub joints: Vec<JointSpec>,
    /// Pulleys.
    pub pulleys: Vec<PulleySpec>,
    /// Cables.
    pub cables: Vec<CableSpec>,
    /// Motors.
    pub motors: Vec<MotorSpec>,
    /// Sensors (may be empty: every output is then a channel).
    pub sensors: Vec<SensorSpec>,
    /// Smoothing of the sign of the cable's speed in the capstan losses (m/s of cable), > 0.
    pub capstan_smoothing: f64,
    /// Measured signals the network reads besides its motors (inputs after the motors'; e.g. a
    /// path's exit wrap at a parallel robot's measured pose).
    pub signals: Vec<String>,
}

/// Pre-sliding (Dahl) friction of a joint: a friction torque `z` that follows the joint's
/// displacement through `ż = σ₀·(q̇ − |q̇|·ζ)`, `ζ = clamp(z/F, −1, 1)`, `σ₀ = F/θ_d`, the
/// torque `z` (within `±F`): the joint turns elastically by about `θ_d` after each reversal
/// before the torque reaches its level `F` (Dahl 1968). Not read from a network file: the
/// diagnosis inserts it (issue #39 §2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Presliding {
    /// Level `F` (N·m, or N for a prismatic joint), ≥ 0.
    pub level: f64,
    /// Break-away displacement `θ_d` (rad or m), > 0.
    pub breakaway: f64,
}

impl Presliding {
    /// A Dahl element of level `level` and break-away `breakaway`.
    pub fn dahl(level: f64, breakaway: f64) -> Self {
        Self { level, breakaway }
    }

    /// The friction torque at state `z`, speed `v`, and the state's rate.
    #[inline]
    fn torque_and_rate(&self, z: f64, v: f64) -> (f64, f64) {
        if self.level <= 0.0 {
            return (0.0, 0.0);
        }
        let zeta = (z / self.level).clamp(-1.0, 1.0);
        (
            self.level * zeta,
            self.level / self.breakaway * (v - v.abs() * zeta),
        )
    }
}

/// Creep of a cable's tension: a relaxation `w` that the tension loses,
/// `T = T₀ + F(e) + b·ė − w`, `ẇ = (κ·(F(e) − F_r) − w)/τ` (`κ·(T₀ + F(e))` for the whole
/// tension) — a standard linear solid whose instantaneous law is the cable's, relaxing from the
/// reference `F_r`: the law at the run's first input, where the cable has been held (its creep
/// settled there) and the nominal's lengths were calibrated — a run that stays there keeps its
/// tension. The whole form's reference is 0 (the pretension freshly applied). `F_r` is a state of
/// zero rate after `w`'s, set by [`Network::rest_at`]. Inserted by the diagnosis.
///
/// The `stretch` form is the same solid written in the cable's stretch: a Kelvin–Voigt element
/// in series with the elastic one, its crept length `δ` (m) beyond the settled one,
/// `T = T₀ + F(e − δ) + b·ė`, `δ̇ = (κ·(e − e_r) − δ)/τ`, `e_r` the elongation at the first input.
/// On a cable of fixed length with a linear law the two are one model (`w = k·δ`); on a cable a
/// motor winds they differ: the tension form carries the crept strain with the cable (the loss
/// scales with `E·A/L` as the free length `L` changes), the stretch form keeps the crept length
/// in the free span (a lumped element, as a winch's cable model with one creep state has it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TensionCreep {
    /// Relaxed fraction `κ` in `[0, 1)`.
    pub fraction: f64,
    /// Time constant `τ` (s), > 0.
    pub time_constant: f64,
    /// Relax the pretension too.
    pub whole: bool,
    /// Creep of the stretch (a length `δ`), not of the tension.
    pub stretch: bool,
}

/// One joint of a built network.
#[derive(Debug, Clone, PartialEq)]
struct Joint {
    kind: JointKind,
    inv_inertia: f64,
    inertia: f64,
    friction: StaticFriction,
    gravity: Gravity,
    /// Pre-sliding friction and the index of its state.
    presliding: Option<(Presliding, usize)>,
}

/// One cable of a built network.
#[derive(Debug, Clone, PartialEq)]
struct Cable {
    run: CableRun,
    motor: Option<usize>,
    sense: f64,
    /// `Σ μ_k·φ_k` over its routing.
    capstan: f64,
    /// Moment arms of its contacts before the first one with friction (the driver's side, which
    /// carries the motor-side tension), length `n`; for an anchored cable without friction
    /// contacts, its first contact's (where friction added to its routing would act).
    driver_arms: Vec<f64>,
    /// Smoothing of the sign of its haul speed in its routing friction (m/s).
    smoothing: f64,
    /// Creep of its tension and the index of its state `w` (its reference `F_r` the next).
    creep: Option<(TensionCreep, usize)>,
    /// Its law's stiffness scaled by `s` about its reference stretch, and the index of the
    /// reference's state `F_r` (see [`Network::set_stiffness_scale`]).
    stiffness: Option<(f64, usize)>,
    /// Pre-sliding of its routing friction: the break-away sliding `x_d` (m of cable) and the
    /// index of its state `ζ` (module docs); `None`: the sign law.
    routing_dahl: Option<(f64, usize)>,
    /// The position-driven motor at its far end and the sense it stretches it.
    end: Option<(usize, f64)>,
    /// Free length at every motor's 0 when its motor winds it up (m).
    free_length: Option<f64>,
    /// Friction between its last contact and its far end.
    path: Option<Path>,
}

/// The exit wrap of a built path: its normal factor `2·sin(θ_e/2)`, or the input index of the
/// signal that gives `θ_e`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Exit {
    Fixed(f64),
    Input(usize),
}

/// A built path (see [`PathSpec`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Path {
    coefficient: f64,
    viscous: f64,
    /// `2·sin(θ_g/2)`.
    guide_normal: f64,
    exit: Exit,
    law: PathFrictionLaw,
}

/// A built path's law: Coulomb, or Dahl with the index of its state.
#[derive(Debug, Clone, Copy, PartialEq)]
enum PathFrictionLaw {
    Coulomb {
        smoothing: f64,
    },
    Dahl {
        presliding: f64,
        exponent: f64,
        state: usize,
    },
}

/// One motor of a built network.
#[derive(Debug, Clone, PartialEq)]
struct Motor {
    drive: Drive,
    rho: f64,
    inertia: f64,
    friction: StaticFriction,
    /// Index of its `q_m` in the state (torque) or the input (position).
    slot: usize,
    /// Index of its torque in the input (torque-driven; unused when position-driven).
    torque_input: usize,
    /// Half-width of the play between a position-driven motor and its capstan (rad of motor
    /// angle; 0: none).
    play: f64,
}

/// A tension tap between two contacts of a cable: `(cable, output name, Σ μφ of the contacts
/// between the tap and the cable's elastic piece)`.
type Tap = (usize, String, f64);

/// A sensor's name and the output it reads.
type SensorOutput = (String, usize);

/// A validated cable network; a [`Model`] (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Network {
    joints: Vec<Joint>,
    cables: Vec<Cable>,
    motors: Vec<Motor>,
    /// `J`, row-major `m × n`.
    arms: Vec<f64>,
    joint_names: Vec<String>,
    cable_names: Vec<String>,
    motor_names: Vec<String>,
    /// Per sensor: its name and the output it reads.
    sensors: Vec<(String, usize)>,
    /// Tension taps between contacts (outputs after `load_m`): `(cable, name, Σ μφ of the
    /// contacts between the tap and the cable's elastic piece)`.
    taps: Vec<Tap>,
    capstan_smoothing: f64,
    signal_names: Vec<String>,
    /// Index of the first signal in the input.
    signal_input: usize,
    n_states: usize,
    n_inputs: usize,
}

fn invalid(element: String, reason: impl Into<String>) -> CableError {
    CableError::Network {
        element,
        reason: reason.into(),
    }
}

/// Index of `name` among `names`, or a network error naming `element`.
fn lookup(names: &[&str], name: &str, element: &str, what: &str) -> Result<usize> {
    names
        .iter()
        .position(|n| *n == name)
        .ok_or_else(|| invalid(element.to_owned(), format!("no {what} named {name:?}")))
}

fn unique(kind: &str, names: &[&str]) -> Result<()> {
    for (i, n) in names.iter().enumerate() {
        if n.is_empty() {
            return Err(invalid(format!("{kind}[{i}]"), "has no name"));
        }
        if names[..i].contains(n) {
            return Err(invalid(format!("{kind} {n:?}"), "is named twice"));
        }
    }
    Ok(())
}

impl Network {
    /// Validate and build; every defect is a [`CableError::Network`] naming the element (a
    /// cable over no pulley, an unknown pulley or motor, a negative wrap angle, a body no chain
    /// of joints connects to the base, a joint no cable moves, a singular coupling) or a
    /// parameter error naming the field.
    pub fn new(spec: &NetworkSpec) -> Result<Self> {
        let body_names: Vec<&str> = spec.bodies.iter().map(|b| b.name.as_str()).collect();
        let joint_names: Vec<&str> = spec.joints.iter().map(|j| j.name.as_str()).collect();
        let pulley_names: Vec<&str> = spec.pulleys.iter().map(|p| p.name.as_str()).collect();
        let motor_names: Vec<&str> = spec.motors.iter().map(|m| m.name.as_str()).collect();
        let cable_names: Vec<&str> = spec.cables.iter().map(|c| c.name.as_str()).collect();
        for (kind, names) in [
            ("body", &body_names),
            ("joint", &joint_names),
            ("pulley", &pulley_names),
            ("motor", &motor_names),
            ("cable", &cable_names),
        ] {
            unique(kind, names)?;
        }
        // (no joint is a network of drives alone: cables between motors, as a parallel robot's
        // winches and the platform's measured attachment points)
        if spec.cables.is_empty() {
            return Err(invalid(
                "cables".into(),
                "a network needs at least one cable",
            ));
        }
        if body_names.contains(&"base") {
            return Err(invalid(
                "body \"base\"".into(),
                "\"base\" is the ground, not a body",
            ));
        }
        check::positive("capstan_smoothing", spec.capstan_smoothing)?;
        let signal_names: Vec<&str> = spec.signals.iter().map(String::as_str).collect();
        unique("signal", &signal_names)?;
        let joints = Self::joints(spec, &body_names)?;
        let (motors, mut n_states, n_inputs) = Self::motors(spec)?;
        let n = joints.len();
        // the signals sit between the motors' inputs and the joints' loads
        let signal_input = n_inputs - n;
        let n_inputs = n_inputs + signal_names.len();
        let mut arms = vec![0.0; spec.cables.len() * n];
        let mut cables = Vec::with_capacity(spec.cables.len());
        for (c, cs) in spec.cables.iter().enumerate() {
            let el = format!("cable {:?}", cs.name);
            if cs.routing.is_empty() {
                return Err(invalid(el, "passes over no pulley"));
            }
            cs.run.validate(&format!("cable {:?}", cs.name))?;
            let motor = cs
                .motor
                .as_ref()
                .map(|m| lookup(&motor_names, m, &el, "motor"))
                .transpose()?;
            let sense = Self::sense(cs.motor_sense, &format!("{el}.motor_sense"))?;
            let end = match &cs.end_motor {
                None => None,
                Some(name) => {
                    let i = lookup(&motor_names, name, &el, "motor")?;
                    if motor == Some(i) {
                        return Err(invalid(
                            format!("{el}.end_motor"),
                            format!("motor {name:?} already hauls the cable at its other end"),
                        ));
                    }
                    if spec.motors[i].drive != Drive::Position {
                        return Err(invalid(
                            format!("{el}.end_motor"),
                            format!("motor {name:?} must be position-driven to move a cable's end"),
                        ));
                    }
                    Some((i, Self::sense(cs.end_sense, &format!("{el}.end_sense"))?))
                }
            };
            if let Some(l) = cs.free_length {
                check::positive(&format!("{el}.free_length"), l)?;
            }
            let mut capstan = 0.0;
            let mut driver_arms = vec![0.0; n];
            for (k, ct) in cs.routing.iter().enumerate() {
                let ctx = format!("{el}.routing[{k}]");
                let p = lookup(&pulley_names, &ct.pulley, &ctx, "pulley")?;
                if !(ct.wrap.is_finite() && ct.wrap >= 0.0) {
                    return Err(invalid(
                        format!("{ctx} (pulley {:?})", ct.pulley),
                        format!("wrap angle must be finite and >= 0 rad, got {}", ct.wrap),
                    ));
                }
                check::non_negative(&format!("{ctx}.mu"), ct.mu)?;
                let s = Self::sense(ct.sense, &format!("{ctx}.sense"))?;
                capstan += ct.mu * ct.wrap;
                let pulley = &spec.pulleys[p];
                check::positive(&format!("pulley {:?}.radius", pulley.name), pulley.radius)?;
                if let Some(j) = &pulley.joint {
                    let j = lookup(
                        &joint_names,
                        j,
                        &format!("pulley {:?}", pulley.name),
                        "joint",
                    )?;
                    arms[c * n + j] += s * pulley.radius;
                    if capstan == 0.0 {
                        driver_arms[j] += s * pulley.radius;
                    }
                }
            }
            if capstan == 0.0 {
                // no friction contact: the driver is the motor, or an anchored cable's first
                // contact's joint
                driver_arms.iter_mut().for_each(|a| *a = 0.0);
                if motor.is_none() {
                    let first = &cs.routing[0];
                    let p = lookup(&pulley_names, &first.pulley, &el, "pulley")?;
                    if let Some(j) = &spec.pulleys[p].joint {
                        let j = lookup(&joint_names, j, &el, "joint")?;
                        driver_arms[j] = first.sense * spec.pulleys[p].radius;
                    }
                }
            }
            let path = match &cs.path {
                None => None,
                Some(ps) => Some(Self::path(
                    ps,
                    &el,
                    &signal_names,
                    signal_input,
                    &mut n_states,
                    arms[c * n..(c + 1) * n].iter().any(|a| *a != 0.0),
                )?),
            };
            cables.push(Cable {
                run: cs.run,
                motor,
                sense,
                capstan,
                driver_arms,
                smoothing: spec.capstan_smoothing,
                creep: None,
                stiffness: None,
                routing_dahl: None,
                end,
                free_length: cs.free_length,
                path,
            });
        }
        for (i, name) in motor_names.iter().enumerate() {
            if !cables
                .iter()
                .any(|c| c.motor == Some(i) || c.end.is_some_and(|(e, _)| e == i))
            {
                return Err(invalid(format!("motor {name:?}"), "hauls no cable"));
            }
        }
        for p in &spec.pulleys {
            if let Some(j) = &p.joint {
                lookup(&joint_names, j, &format!("pulley {:?}", p.name), "joint")?;
            }
        }
        Self::controllable(&arms, spec.cables.len(), &joint_names)?;
        let (sensors, taps) = Self::sensors(spec, &joint_names, &motor_names, &cable_names)?;
        Ok(Self {
            sensors,
            taps,
            joints,
            cables,
            motors,
            arms,
            joint_names: joint_names.iter().map(|s| (*s).to_owned()).collect(),
            cable_names: cable_names.iter().map(|s| (*s).to_owned()).collect(),
            motor_names: motor_names.iter().map(|s| (*s).to_owned()).collect(),
            capstan_smoothing: spec.capstan_smoothing,
            signal_names: signal_names.iter().map(|s| (*s).to_owned()).collect(),
            signal_input,
            n_states,
            n_inputs,
        })
    }

    /// Build and check cable `el`'s path; a Dahl law takes the next state.
    fn path(
        ps: &PathSpec,
        el: &str,
        signals: &[&str],
        signal_input: usize,
        n_states: &mut usize,
        turns_a_joint: bool,
    ) -> Result<Path> {
        use crate::cdpr::PathLaw;
        let el = format!("{el}.path");
        if turns_a_joint {
            return Err(invalid(
                el,
                "a path's friction is for a cable whose routing turns no joint (a parallel \
                 robot's drive: winch, pulleys, platform)",
            ));
        }
        check::non_negative(&format!("{el}.coefficient"), ps.coefficient)?;
        check::non_negative(&format!("{el}.viscous"), ps.viscous)?;
        let wrap = |name: &str, w: f64| -> Result<f64> {
            if w.is_finite() && (0.0..=std::f64::consts::TAU).contains(&w) {
                Ok(w)
            } else {
                Err(invalid(
                    format!("{el}.{name}"),
                    format!("must be a wrap angle in [0, 2π] rad, got {w}"),
                ))
            }
        };
        let guide = wrap("guide_wrap", ps.guide_wrap)?;
        let exit = match &ps.exit_wrap {
            ExitWrap::Fixed(w) => Exit::Fixed(2.0 * (0.5 * wrap("exit_wrap", *w)?).sin()),
            ExitWrap::Signal(name) => {
                Exit::Input(signal_input + lookup(signals, name, &el, "signal")?)
            }
        };
        let law = match ps.law {
            PathLaw::Coulomb { smoothing } => {
                check::positive(&format!("{el}.smoothing"), smoothing)?;
                PathFrictionLaw::Coulomb { smoothing }
            }
            PathLaw::Dahl {
                presliding,
                exponent,
            } => {
                check::positive(&format!("{el}.presliding"), presliding)?;
                check::positive(&format!("{el}.exponent"), exponent)?;
                *n_states += 1;
                PathFrictionLaw::Dahl {
                    presliding,
                    exponent,
                    state: *n_states - 1,
                }
            }
        };
        Ok(Path {
            coefficient: ps.coefficient,
            viscous: ps.viscous,
            guide_normal: 2.0 * (0.5 * guide).sin(),
            exit,
            law,
        })
    }

    /// Each sensor's output index (layout of [`Model::output`]).
    fn sensors(
        spec: &NetworkSpec,
        joints: &[&str],
        motors: &[&str],
        cables: &[&str],
    ) -> Result<(Vec<SensorOutput>, Vec<Tap>)> {
        let names: Vec<&str> = spec.sensors.iter().map(|s| s.name.as_str()).collect();
        unique("sensor", &names)?;
        let (n, p, m) = (joints.len(), motors.len(), cables.len());
        let mut out = Vec::with_capacity(spec.sensors.len());
        let mut taps: Vec<Tap> = Vec::new();
        for s in &spec.sensors {
            let el = format!("sensor {:?}", s.name);
            let find = |names: &[&str], what: &str| lookup(names, &s.target, &el, what);
            let index = match (s.kind.as_str(), s.at.as_str()) {
                ("encoder", _) => find(joints, "joint").or_else(|_| Ok::<_, CableError>(n + find(motors, "joint or motor")?))?,
                ("tension", "joint") => n + p + find(cables, "cable")?,
                ("tension", "motor") => n + p + m + find(cables, "cable")?,
                // between two contacts: the tension beyond the contact on pulley `at` (its
                // side towards the cable's end)
                ("tension", at) => {
                    let c = find(cables, "cable")?;
                    let routing = &spec.cables[c].routing;
                    let Some(k) = routing.iter().position(|ct| ct.pulley == at) else {
                        return Err(invalid(
                            el,
                            format!(
                                "at must be \"motor\", \"joint\" or a pulley of cable {:?}'s \
                                 routing, got {at:?}",
                                s.target
                            ),
                        ));
                    };
                    let beyond: f64 = routing[k + 1..].iter().map(|ct| ct.mu * ct.wrap).sum();
                    let name = format!("T@{at}:{}", s.target);
                    let t = taps.iter().position(|(_, nm, _)| *nm == name).unwrap_or_else(|| {
                        taps.push((c, name, beyond));
                        taps.len() - 1
                    });
                    2 * n + 2 * p + 2 * m + t
                }
                ("joint_torque", _) => n + p + 2 * m + find(joints, "joint")?,
                ("motor_current", _) => 2 * n + p + 2 * m + find(motors, "motor")?,
                (kind, _) => {
                    return Err(invalid(
                        el,
                        format!(
                            "kind must be encoder, tension, joint_torque or motor_current, got {kind:?}"
                        ),
                    ))
                }
            };
            out.push((s.name.clone(), index));
        }
        Ok((out, taps))
    }

    /// The sensors: each channel's name and the output it reads.
    pub fn sensor_outputs(&self) -> &[(String, usize)] {
        &self.sensors
    }

    fn sense(v: f64, name: &str) -> Result<f64> {
        #[allow(clippy::float_cmp)]
        if v == 1.0 || v == -1.0 {
            Ok(v)
        } else {
            Err(CableError::InvalidParameter {
                name: name.to_owned(),
                value: v,
                requirement: "+1 or -1",
            })
        }
    }

    /// The joints, with every body moved by exactly one joint and connected to the base.
    fn joints(spec: &NetworkSpec, body_names: &[&str]) -> Result<Vec<Joint>> {
        let mut mover: Vec<Option<usize>> = vec![None; body_names.len()];
        let mut joints = Vec::with_capacity(spec.joints.len());
        for (j, js) in spec.joints.iter().enumerate() {
            let el = format!("joint {:?}", js.name);
            let child = lookup(body_names, &js.child, &el, "body")?;
            if js.parent != "base" {
                lookup(body_names, &js.parent, &el, "body")?;
            }
            if js.parent == js.child {
                return Err(invalid(el, "moves the body it is mounted on"));
            }
            if let Some(other) = mover[child] {
                return Err(invalid(
                    format!("body {:?}", js.child),
                    format!(
                        "is moved by two joints ({:?} and {:?})",
                        spec.joints[other].name, js.name
                    ),
                ));
            }
            mover[child] = Some(j);
            let kind = JointKind::from_name(&js.kind, &format!("{el}.kind"))?;
            let friction =
                StaticFriction::coulomb_viscous(&el, js.coulomb, js.viscous, js.smoothing)?;
            check::finite(&format!("{el}.gravity_amplitude"), js.gravity.amplitude)?;
            check::finite(&format!("{el}.gravity_offset"), js.gravity.offset)?;
            let inertia = spec.bodies[child].inertia;
            check::positive(&format!("body {:?}.inertia", js.child), inertia)?;
            joints.push(Joint {
                kind,
                inv_inertia: 1.0 / inertia,
                inertia,
                friction,
                gravity: js.gravity,
                presliding: None,
            });
        }
        // every body reaches the base through the joints that move it (no cycle, no orphan)
        for (b, name) in body_names.iter().enumerate() {
            let (mut at, mut steps) = (b, 0);
            loop {
                let Some(j) = mover[at] else {
                    return Err(invalid(
                        format!("body {name:?}"),
                        "is disconnected: no joint moves it",
                    ));
                };
                let parent = &spec.joints[j].parent;
                if parent == "base" {
                    break;
                }
                at = body_names.iter().position(|n| n == parent).unwrap_or(at);
                steps += 1;
                if steps > body_names.len() {
                    return Err(invalid(
                        format!("body {name:?}"),
                        "is on a loop of joints that never reaches the base",
                    ));
                }
            }
        }
        Ok(joints)
    }

    fn motors(spec: &NetworkSpec) -> Result<(Vec<Motor>, usize, usize)> {
        let n = spec.joints.len();
        let (mut n_states, mut n_inputs) = (2 * n, 0);
        let mut motors = Vec::with_capacity(spec.motors.len());
        for ms in &spec.motors {
            let el = format!("motor {:?}", ms.name);
            check::positive(&format!("{el}.gear_ratio"), ms.gear_ratio)?;
            check::positive(&format!("{el}.capstan_radius"), ms.capstan_radius)?;
            ms.friction.validate(&el)?;
            let slot = match ms.drive {
                Drive::Torque => {
                    check::positive(&format!("{el}.inertia"), ms.inertia)?;
                    n_states += 2;
                    n_states - 2
                }
                Drive::Position => {
                    n_inputs += 2;
                    n_inputs - 2
                }
            };
            motors.push(Motor {
                drive: ms.drive,
                rho: ms.capstan_radius / ms.gear_ratio,
                inertia: ms.inertia,
                friction: ms.friction,
                slot,
                torque_input: 0,
                play: 0.0,
            });
        }
        // inputs: the position motors' [q_m, q̇_m], one torque per torque motor, the joint loads
        for m in motors.iter_mut().filter(|m| m.drive == Drive::Torque) {
            m.torque_input = n_inputs;
            n_inputs += 1;
        }
        Ok((motors, n_states, n_inputs + n))
    }

    /// Refuse a coupling that cannot move every joint independently (rank of `J` below `n`).
    fn controllable(arms: &[f64], m: usize, joint_names: &[&str]) -> Result<()> {
        let n = joint_names.len();
        if n == 0 {
            return Ok(());
        }
        for (j, name) in joint_names.iter().enumerate() {
            #[allow(clippy::float_cmp)]
            if (0..m).all(|c| arms[c * n + j] == 0.0) {
                return Err(invalid(
                    format!("joint {name:?}"),
                    "no cable passes a pulley on its axis: nothing moves it",
                ));
            }
        }
        if m < n {
            return Err(invalid(
                "cables".into(),
                format!("{m} cables cannot move {n} joints independently"),
            ));
        }
        let a = nalgebra::DMatrix::from_row_slice(m, n, arms);
        let svd = a.svd(false, true);
        let s = &svd.singular_values;
        let (smax, smin) = (s.max(), s.min());
        if smin <= SINGULAR_COUPLING * smax {
            let v = svd.v_t.as_ref().map(|vt| {
                let k = s.imin();
                vt.row(k).iter().map(|x| x.abs()).collect::<Vec<_>>()
            });
            let j = v.map_or(0, |v| {
                v.iter()
                    .enumerate()
                    .max_by(|a, b| a.1.total_cmp(b.1))
                    .map_or(0, |(j, _)| j)
            });
            return Err(invalid(
                format!("joint {:?}", joint_names[j]),
                format!(
                    "the coupling matrix is singular (smallest singular value {smin:.3e} of \
                     {smax:.3e}): no combination of cable tensions moves this joint on its own"
                ),
            ));
        }
        Ok(())
    }

    /// Number of joints `n`.
    pub fn n_joints(&self) -> usize {
        self.joints.len()
    }
    /// Number of cables `m`.
    pub fn n_cables(&self) -> usize {
        self.cables.len()
    }
    /// Number of motors.
    pub fn n_motors(&self) -> usize {
        self.motors.len()
    }
    /// The output index of motor `i`'s load `load_m:<motor>` (the layout of `output`).
    pub fn load_output(&self, i: usize) -> usize {
        2 * self.n_joints() + self.n_motors() + 2 * self.n_cables() + i
    }
    /// Joint names, in order.
    pub fn joint_names(&self) -> &[String] {
        &self.joint_names
    }
    /// Cable names, in order.
    pub fn cable_names(&self) -> &[String] {
        &self.cable_names
    }
    /// Motor names, in order.
    pub fn motor_names(&self) -> &[String] {
        &self.motor_names
    }

    /// The moment-arm (coupling) matrix `J = −∂l/∂q`, row-major `m × n`.
    pub fn moment_arms(&self) -> &[f64] {
        &self.arms
    }

    /// Change of every cable's path length from `q = 0`: `l(q) − l(0) = −J·q` (m).
    pub fn length_change(&self, q: &[f64]) -> Result<Vec<f64>> {
        let n = self.n_joints();
        check::len("q", q, n)?;
        check::all_finite("q", q, n)?;
        let out: Vec<f64> = self.arms.chunks_exact(n).map(|row| -dot(row, q)).collect();
        check::result_finite("length_change", &out, 1, "the joint values are too large")?;
        Ok(out)
    }

    /// Joint torques (N·m or N) of cable tensions `t` (N): `τ = Jᵀ·T`.
    pub fn joint_torques(&self, tensions: &[f64]) -> Result<Vec<f64>> {
        let (m, n) = (self.n_cables(), self.n_joints());
        check::len("tensions", tensions, m)?;
        check::all_finite("tensions", tensions, m)?;
        let mut tau = vec![0.0; n];
        for (row, t) in self.arms.chunks_exact(n).zip(tensions) {
            for (o, a) in tau.iter_mut().zip(row) {
                *o += a * t;
            }
        }
        check::result_finite("joint_torques", &tau, 1, "the tensions are too large")?;
        Ok(tau)
    }

    /// **Tension closure** (tendon controllability, Tsai 1999 ch. 10): the cable tensions
    /// `T ≥ 0`, `Σ T = 1`, that put no torque on any joint (`Jᵀ·T = 0`) with the largest
    /// smallest share `s = min T`, by a linear program (clarabel; `T` is not bounded below, so
    /// the program is feasible whenever a torque-free distribution exists). With `s > 0` every
    /// cable can be pretensioned without moving the mechanism, and — `J` having rank `n` — every
    /// joint torque is reachable with all cables taut; with `s ≤ 0` a torque-free state needs a
    /// cable to push (`T` then has a negative share). Returns `(s, T)`.
    pub fn tension_closure(&self) -> Result<(f64, Vec<f64>)> {
        use clarabel::algebra::CscMatrix;
        use clarabel::solver::{
            DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus,
            SupportedConeT::{NonnegativeConeT, ZeroConeT},
        };
        let (m, n) = (self.n_cables(), self.n_joints());
        // z = [T₁…T_m, s]; rows: Jᵀ·T = 0 (n), Σ T = 1 (1), s − T_i ≤ 0 (m)
        let (mut colptr, mut rowval, mut nzval) = (vec![0], Vec::new(), Vec::new());
        for c in 0..m {
            for j in 0..n {
                rowval.push(j);
                nzval.push(self.arms[c * n + j]);
            }
            rowval.extend([n, n + 1 + c]);
            nzval.extend([1.0, -1.0]);
            colptr.push(rowval.len());
        }
        rowval.extend(n + 1..n + 1 + m);
        nzval.extend(std::iter::repeat_n(1.0, m));
        colptr.push(rowval.len());
        let a = CscMatrix::new(n + 1 + m, m + 1, colptr, rowval, nzval);
        let p = CscMatrix::zeros((m + 1, m + 1));
        let mut q = vec![0.0; m + 1];
        q[m] = -1.0;
        let mut b = vec![0.0; n + 1 + m];
        b[n] = 1.0;
        let cones = [ZeroConeT(n + 1), NonnegativeConeT(m)];
        let fail = |_: String| CableError::NotConverged {
            what: "tension_closure".into(),
            limit: 200,
            hint: "the linear program of the tension closure did not solve (clarabel)",
        };
        let settings = DefaultSettingsBuilder::default()
            .verbose(false)
            .max_iter(200)
            .build()
            .map_err(|e| fail(e.to_string()))?;
        let mut solver = DefaultSolver::new(&p, &q, &a, &b, &cones, settings)
            .map_err(|e| fail(e.to_string()))?;
        solver.solve();
        match solver.solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {}
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
                return Err(CableError::Network {
                    element: "cables".into(),
                    reason: "have no torque-free tensions of positive total: the mechanism \
                             cannot be pretensioned"
                        .into(),
                })
            }
            other => return Err(fail(format!("{other:?}"))),
        }
        let x = &solver.solution.x;
        Ok((x[m], x[..m].to_vec()))
    }

    /// Motor angle of motor `i` and its rate, from the state or the input.
    #[inline]
    fn motor_at(&self, i: usize, x: &[f64], u: &[f64]) -> (f64, f64) {
        let m = &self.motors[i];
        match m.drive {
            Drive::Torque => (x[m.slot], x[m.slot + 1]),
            Drive::Position => (u[m.slot], u[m.slot + 1]),
        }
    }

    /// Angle and rate of motor `i`'s capstan: the motor's, or, across a play of half-width
    /// `δ` (a position-driven motor's gearhead or coupling), the angle within `q_m ± δ` where
    /// the motor's cables balance (`Σ σ_c·T_c = 0`, the capstan massless; damping and routing
    /// friction left out of the balance), held at the nearer end when they do not balance in
    /// it. Inside the play its rate follows the joints through the cables' tangent stiffnesses.
    fn capstan_at(&self, i: usize, x: &[f64], u: &[f64]) -> (f64, f64) {
        let (qm, wm) = self.motor_at(i, x, u);
        let mo = &self.motors[i];
        if mo.play <= 0.0 {
            return (qm, wm);
        }
        let n = self.n_joints();
        let rho = mo.rho;
        // per cable of the motor: its sense and its joint-side shortening J·q
        // on the stack up to eight cables (no allocation per derivative), on the heap beyond
        let mut stack = [(0usize, 0.0, 0.0); 8];
        let mut heap = Vec::new();
        let mut k = 0;
        for (c, cable) in self.cables.iter().enumerate() {
            if cable.motor == Some(i) {
                let row = &self.arms[c * n..(c + 1) * n];
                let p: f64 = row
                    .iter()
                    .enumerate()
                    .map(|(j, a)| a * x[2 * j])
                    .sum::<f64>()
                    - self.end_of(c, u).0;
                if k < stack.len() {
                    stack[k] = (c, cable.sense, p);
                } else {
                    if heap.is_empty() {
                        heap.extend_from_slice(&stack);
                    }
                    heap.push((c, cable.sense, p));
                }
                k += 1;
            }
        }
        let cables: &[(usize, f64, f64)] = if heap.is_empty() { &stack[..k] } else { &heap };
        let balance = |qc: f64| -> (f64, f64) {
            let (mut g, mut dg) = (0.0, 0.0);
            for &(c, s, p) in cables {
                let run = &self.cables[c].run;
                let e = s * rho * qc - p;
                let t = (run.pretension + self.elastic_of(c, e, x)) * self.length_scale(c, qc)
                    - self.creep_of(c, x);
                if t > 0.0 {
                    g += s * t;
                    dg += rho * self.slope_of(c, e, x);
                }
            }
            (g, dg)
        };
        let (lo, hi) = (qm - mo.play, qm + mo.play);
        if balance(lo).0 >= 0.0 {
            return (lo, wm);
        }
        if balance(hi).0 <= 0.0 {
            return (hi, wm);
        }
        let (mut a, mut b) = (lo, hi);
        let mut q = 0.5 * (a + b);
        for _ in 0..PLAY_ITER {
            let (g, dg) = balance(q);
            if g < 0.0 {
                a = q;
            } else {
                b = q;
            }
            let mut next = if dg > 0.0 { q - g / dg } else { f64::NAN };
            if !(next > a && next < b) {
                next = 0.5 * (a + b);
            }
            let done = (next - q).abs() <= 1e-14 * (1.0 + q.abs()) || b - a <= 1e-14;
            q = next;
            if done {
                break;
            }
        }
        // its rate: d/dt Σ σ_c·T_c = 0 with the tangent stiffnesses
        let (mut num, mut den) = (0.0, 0.0);
        for &(c, s, p) in cables {
            let run = &self.cables[c].run;
            let e = s * rho * q - p;
            if (run.pretension + self.elastic_of(c, e, x)) * self.length_scale(c, q)
                - self.creep_of(c, x)
                > 0.0
            {
                let kc = self.slope_of(c, e, x);
                let row = &self.arms[c * n..(c + 1) * n];
                let dp: f64 = row.iter().enumerate().map(|(j, a)| a * x[2 * j + 1]).sum();
                num += s * kc * dp;
                den += rho * kc;
            }
        }
        (q, if den > 0.0 { num / den } else { wm })
    }

    /// Creep relaxation `w` of cable `c`'s tension at state `x` (0 without creep, or with its
    /// stretch form).
    #[inline]
    fn creep_of(&self, c: usize, x: &[f64]) -> f64 {
        match self.cables[c].creep {
            Some((cr, k)) if !cr.stretch => x[k],
            _ => 0.0,
        }
    }

    /// Crept length `δ` of cable `c` at state `x` (its creep's stretch form; 0 otherwise): the
    /// law acts on `e − δ`.
    #[inline]
    fn crept_of(&self, c: usize, x: &[f64]) -> f64 {
        match self.cables[c].creep {
            Some((cr, k)) if cr.stretch => x[k],
            _ => 0.0,
        }
    }

    /// Whether cable `c`'s motor winds it (its free length changes with the motor's angle).
    pub fn is_wound(&self, c: usize) -> bool {
        self.cables[c].free_length.is_some() && self.cables[c].motor.is_some()
    }

    /// The elastic part of cable `c`'s law at elongation `e`, state `x`: `F(e)`, or
    /// `F_r + s·(F(e) − F_r)` with a stiffness scaled about its reference; of `e − δ` with a
    /// creep of the stretch.
    #[inline]
    fn elastic_of(&self, c: usize, e: f64, x: &[f64]) -> f64 {
        let f = self.cables[c].run.law.elastic(e - self.crept_of(c, x));
        match self.cables[c].stiffness {
            None => f,
            Some((s, k)) => x[k] + s * (f - x[k]),
        }
    }

    /// The slope of [`Self::elastic_of`] in `e`.
    #[inline]
    fn slope_of(&self, c: usize, e: f64, x: &[f64]) -> f64 {
        let k = self.cables[c].run.law.slope(e - self.crept_of(c, x));
        self.cables[c].stiffness.map_or(k, |(s, _)| s * k)
    }

    /// Joint-side tension of cable `c` at elongation `e`, rate `de`: its law (scaled by
    /// [`Self::length_scale`] `f`) less its creep.
    #[inline]
    fn tension_of(&self, c: usize, e: f64, de: f64, x: &[f64], f: f64) -> f64 {
        let cable = &self.cables[c];
        let run = &cable.run;
        #[allow(clippy::float_cmp)] // exactly 1 for a cable of fixed length
        if f == 1.0 && cable.creep.is_none() && cable.stiffness.is_none() {
            return run.tension(e, de);
        }
        ((run.pretension + self.elastic_of(c, e, x)) * f + run.damping * de - self.creep_of(c, x))
            .max(0.0)
    }

    /// `length / (length − σ·ρ·q_m)` of a cable its motor winds up at capstan angle `qc` (its
    /// elastic tension's factor: a rod's `E·A/L` with `L` its free length), 1 otherwise; the
    /// free length is kept above 1 % of `length`.
    #[inline]
    fn length_scale(&self, c: usize, qc: f64) -> f64 {
        let cable = &self.cables[c];
        match (cable.free_length, cable.motor) {
            (Some(l), Some(i)) => {
                let wound = cable.sense * self.motors[i].rho * qc;
                l / (l - wound).max(0.01 * l)
            }
            _ => 1.0,
        }
    }

    /// [`Self::length_scale`] of cable `c` at state `x`, input `u`.
    #[inline]
    fn length_scale_at(&self, c: usize, x: &[f64], u: &[f64]) -> f64 {
        match (self.cables[c].free_length, self.cables[c].motor) {
            (Some(_), Some(i)) => self.length_scale(c, self.capstan_at(i, x, u).0),
            _ => 1.0,
        }
    }

    /// Elongation and its rate of cable `c`.
    #[inline]
    fn elongation(&self, c: usize, x: &[f64], u: &[f64]) -> (f64, f64) {
        let n = self.n_joints();
        let cable = &self.cables[c];
        let (mut e, mut de) = match cable.motor {
            Some(i) => {
                let (qm, wm) = self.capstan_at(i, x, u);
                let rho = self.motors[i].rho;
                (cable.sense * rho * qm, cable.sense * rho * wm)
            }
            None => (0.0, 0.0),
        };
        let row = &self.arms[c * n..(c + 1) * n];
        for (j, a) in row.iter().enumerate() {
            e -= a * x[2 * j];
            de -= a * x[2 * j + 1];
        }
        let (pe, pde) = self.end_of(c, u);
        (e + pe, de + pde)
    }

    /// The stretch (m) its end motor gives cable `c`, and its rate (0 with an anchored end).
    #[inline]
    fn end_of(&self, c: usize, u: &[f64]) -> (f64, f64) {
        match self.cables[c].end {
            Some((i, s)) => {
                let m = &self.motors[i];
                (s * m.rho * u[m.slot], s * m.rho * u[m.slot + 1])
            }
            None => (0.0, 0.0),
        }
    }

    /// The speed `v_h` at which cable `c` is hauled through its friction contacts — by its
    /// motor (`σ·ρ·q̇_m`) and by the contacts before them on a driven stage's pulley.
    #[inline]
    fn haul_speed(&self, c: usize, x: &[f64], u: &[f64]) -> f64 {
        let cable = &self.cables[c];
        let mut haul = match cable.motor {
            Some(i) => self.capstan_at(i, x, u).1 * self.motors[i].rho * cable.sense,
            None => 0.0,
        };
        for (j, a) in cable.driver_arms.iter().enumerate() {
            haul -= a * x[2 * j + 1];
        }
        haul
    }

    /// Joint-side and motor-side tension of cable `c` (N): the routing's capstan losses
    /// `T_m = T·exp(Σμφ·σ_ε(v_h))` follow the haul speed `v_h` ([`Self::haul_speed`]), or with
    /// pre-sliding at the routing `T_m = T·exp(Σμφ·ζ)`, `ζ` its state.
    #[inline]
    fn cable_tensions(&self, c: usize, x: &[f64], u: &[f64]) -> (f64, f64) {
        let (t, tm, _) = self.cable_tensions_and_sign(c, x, u);
        (t, tm)
    }

    /// [`Self::cable_tensions`] and the sign its routing friction acts with (0 without one).
    #[inline]
    fn cable_tensions_and_sign(&self, c: usize, x: &[f64], u: &[f64]) -> (f64, f64, f64) {
        let (t, _, tm, sign) = self.cable_tensions_full(c, x, u);
        (t, tm, sign)
    }

    /// Cable `c`'s tensions: its elastic piece's `T`, beyond its path's friction `T_path` (=
    /// `T` without a path), at its motor `T_m = T_path·exp(Σμφ·s)`, and the routing's sign `s`.
    #[inline]
    fn cable_tensions_full(&self, c: usize, x: &[f64], u: &[f64]) -> (f64, f64, f64, f64) {
        let (e, de) = self.elongation(c, x, u);
        let cable = &self.cables[c];
        let t = self.tension_of(c, e, de, x, self.length_scale_at(c, x, u));
        let tp = match &cable.path {
            Some(p) => self.path_tension(c, p, t, x, u),
            None => t,
        };
        let has_taps = self.taps.iter().any(|(k, _, b)| *k == c && *b > 0.0);
        if cable.capstan == 0.0 && !has_taps {
            return (t, tp, tp, 0.0);
        }
        let sign = match cable.routing_dahl {
            Some((_, k)) => x[k].clamp(-1.0, 1.0),
            None => smooth_sign(self.haul_speed(c, x, u), cable.smoothing),
        };
        (t, tp, tp * (cable.capstan * sign).exp(), sign)
    }

    /// The speed (m/s) at which cable `c` slides over its path towards its motor: its far end's
    /// (`−σ_e·ρ_e·u̇_e`, the end motor paying it out), or its haul speed with an anchored end.
    #[inline]
    fn path_speed(&self, c: usize, x: &[f64], u: &[f64]) -> f64 {
        match self.cables[c].end {
            Some((i, s)) => {
                let m = &self.motors[i];
                -s * m.rho * u[m.slot + 1]
            }
            None => self.haul_speed(c, x, u),
        }
    }

    /// The tension on the motor's side of cable `c`'s path `p` (seed 002 eqs 7–8, kept ≥ 0):
    /// `T + μ·N·T·s + σ_v·v` at the elastic piece's tension `T`.
    #[inline]
    fn path_tension(&self, c: usize, p: &Path, t: f64, x: &[f64], u: &[f64]) -> f64 {
        let exit = match p.exit {
            Exit::Fixed(n) => n,
            Exit::Input(i) => 2.0 * (0.5 * u[i]).sin().max(0.0),
        };
        let v = self.path_speed(c, x, u);
        let s = match p.law {
            PathFrictionLaw::Dahl { state, .. } => x[state].clamp(-1.0, 1.0),
            PathFrictionLaw::Coulomb { smoothing } => smooth_sign(v, smoothing),
        };
        (t + p.coefficient * (p.guide_normal + exit) * t * s + p.viscous * v).max(0.0)
    }

    /// Joint-side tension of every cable (N) at state `x`, input `u`.
    pub fn tensions(&self, x: &[f64], u: &[f64], out: &mut [f64]) {
        for (c, o) in out.iter_mut().enumerate() {
            let (e, de) = self.elongation(c, x, u);
            *o = self.tension_of(c, e, de, x, self.length_scale_at(c, x, u));
        }
    }

    /// Total mechanical energy (J) at `x` (inputs `u` for position-driven motors): kinetic of
    /// the joints and torque-driven motors, elastic of every cable while taut (pretension work
    /// included), gravity. Conserved by the exact flow without friction, damping or slack — and
    /// without a winch-wound free length, whose cable's elastic energy is taken at the stiffness
    /// of its full free length (its tension's `length/L` factor is left out here).
    pub fn energy(&self, x: &[f64], u: &[f64]) -> f64 {
        let mut e = 0.0;
        for (j, joint) in self.joints.iter().enumerate() {
            e += 0.5 * joint.inertia * x[2 * j + 1].powi(2)
                + joint.gravity.potential(joint.kind, x[2 * j]);
        }
        for m in &self.motors {
            if m.drive == Drive::Torque {
                e += 0.5 * m.inertia * x[m.slot + 1].powi(2);
            }
        }
        for (c, cable) in self.cables.iter().enumerate() {
            let (s, _) = self.elongation(c, x, u);
            e += cable.run.pretension * s
                + match cable.stiffness {
                    None => cable.run.law.energy(s),
                    Some((k, i)) => x[i] * s + k * (cable.run.law.energy(s) - x[i] * s),
                };
        }
        e
    }

    /// Index of the first external joint load input.
    fn load_input(&self) -> usize {
        self.n_inputs - self.n_joints()
    }

    /// The measured signals it reads (inputs after the motors').
    pub fn signal_names(&self) -> &[String] {
        &self.signal_names
    }

    /// Index of the first signal in the input.
    pub fn signal_input(&self) -> usize {
        self.signal_input
    }

    /// Whether motor `i` is torque-driven (it has states, inertia and friction in the
    /// dynamics) rather than position-driven.
    pub fn motor_is_torque_driven(&self, i: usize) -> bool {
        self.motors[i].drive == Drive::Torque
    }

    /// Capstan metres of cable per motor radian `ρ = r_m/N` of motor `i`.
    pub fn motor_rho(&self, i: usize) -> f64 {
        self.motors[i].rho
    }

    /// The motor that hauls cable `c`, if any.
    pub fn cable_motor(&self, c: usize) -> Option<usize> {
        self.cables[c].motor
    }

    /// The cable run (law, damping, pretension) of cable `c`.
    pub fn cable_run(&self, c: usize) -> &CableRun {
        &self.cables[c].run
    }

    /// Friction of joint `j`.
    pub fn joint_friction(&self, j: usize) -> &StaticFriction {
        &self.joints[j].friction
    }

    /// Inertia of joint `j` (its body's, about its axis).
    pub fn joint_inertia(&self, j: usize) -> f64 {
        self.joints[j].inertia
    }

    /// For a torque-driven motor `i`: the index of its angle in the state (its rate follows),
    /// its rotor inertia and its friction; `None` for a position-driven one.
    pub fn motor_dynamics(&self, i: usize) -> Option<(usize, f64, &StaticFriction)> {
        let m = &self.motors[i];
        (m.drive == Drive::Torque).then_some((m.slot, m.inertia, &m.friction))
    }

    /// Smoothing of the sign of cable `c`'s haul speed in its routing friction (m/s).
    pub fn cable_smoothing(&self, c: usize) -> f64 {
        self.cables[c].smoothing
    }

    /// The file's smoothing of the routing friction's sign (m/s of cable).
    pub fn capstan_smoothing(&self) -> f64 {
        self.capstan_smoothing
    }

    /// The routing friction of cable `c` (`Σ μ_k·φ_k`).
    pub fn cable_capstan(&self, c: usize) -> f64 {
        self.cables[c].capstan
    }

    /// The one coordinate whose dynamics the routing friction of cable `c` acts on, when there
    /// is one: `(index of its speed in the state, arm)` such that the cable's driver-side tension
    /// `T_m` pulls that coordinate with `arm·T_m` and the cable is hauled through its friction
    /// contacts at `−arm·v`. A torque-driven motor (`arm = −σ·ρ`), or the single joint of an
    /// anchored cable's driver-side contacts; `None` for a position-driven motor (the friction
    /// shows in its load only), a cable without friction, or driver-side contacts on several
    /// joints.
    pub fn cable_driver(&self, c: usize) -> Option<(usize, f64)> {
        if self.cables[c].capstan == 0.0 || self.cables[c].routing_dahl.is_some() {
            return None;
        }
        self.routing_driver(c)
    }

    /// The coordinate friction on cable `c`'s routing would act on ([`Self::cable_driver`]),
    /// whether or not it has any.
    pub fn routing_driver(&self, c: usize) -> Option<(usize, f64)> {
        let cable = &self.cables[c];
        match cable.motor.map(|i| &self.motors[i]) {
            Some(m) if m.drive == Drive::Torque => {
                if cable.driver_arms.iter().any(|a| *a != 0.0) {
                    return None;
                }
                Some((m.slot + 1, -m.rho * cable.sense))
            }
            Some(_) => None,
            None => {
                let mut on = cable
                    .driver_arms
                    .iter()
                    .enumerate()
                    .filter(|(_, a)| **a != 0.0);
                match (on.next(), on.next()) {
                    (Some((j, a)), None) => Some((2 * j + 1, *a)),
                    _ => None,
                }
            }
        }
    }

    /// The same network without the friction of its joints and torque-driven motors, and
    /// without the routing friction of every cable with a [`Self::cable_driver`] (the
    /// position-driven motors' friction, which acts in their outputs only, is kept, and so are
    /// the joints' pre-sliding states, creep and play): the smooth part of the dynamics, for
    /// integrators that treat the friction on its own.
    pub fn frictionless(&self) -> Self {
        let mut out = self.clone();
        for j in &mut out.joints {
            j.friction = StaticFriction::NONE;
        }
        for m in out.motors.iter_mut().filter(|m| m.drive == Drive::Torque) {
            m.friction = StaticFriction::NONE;
        }
        for c in 0..out.cables.len() {
            if self.cable_driver(c).is_some() {
                out.cables[c].capstan = 0.0;
            }
        }
        out
    }

    /// The diagnosis' access to the elements (issue #39 §2): effects inserted at a joint, a
    /// cable, a cable's routing or a motor change these values of a copy of the nominal.
    pub(crate) fn joint_friction_mut(&mut self, j: usize) -> &mut StaticFriction {
        &mut self.joints[j].friction
    }

    /// Scale joint `j`'s inertia by `f` (> 0; a non-positive factor is floored at 1e-3).
    pub(crate) fn scale_joint_inertia(&mut self, j: usize, f: f64) {
        let joint = &mut self.joints[j];
        joint.inertia *= f.max(1e-3);
        joint.inv_inertia = 1.0 / joint.inertia;
    }

    /// Cable `c`'s run, mutable.
    pub(crate) fn cable_run_mut(&mut self, c: usize) -> &mut CableRun {
        &mut self.cables[c].run
    }

    /// Add `a` to cable `c`'s routing friction `Σ μ_k·φ_k` (kept ≥ 0) and set the smoothing of
    /// its sign (m/s, > 0).
    pub(crate) fn set_routing_friction(&mut self, c: usize, a: f64, smoothing: f64) {
        let cable = &mut self.cables[c];
        cable.capstan = (cable.capstan + a).max(0.0);
        cable.smoothing = smoothing;
    }

    /// Give cable `c`'s routing friction pre-sliding: add `a` to its `Σ μ_k·φ_k` (kept ≥ 0) and
    /// replace the sign of its haul speed by a Dahl state `ζ` that slides to `±1` over `x_d` m of
    /// cable (`ζ̇ = (v_h − |v_h|·ζ)/x_d`; a pulley's bristles, seed 002 eq. 8), with a state.
    pub(crate) fn set_routing_dahl(&mut self, c: usize, a: f64, breakaway: f64) {
        let slot = self.state_slot(self.cables[c].routing_dahl.map(|(_, k)| k));
        let cable = &mut self.cables[c];
        cable.capstan = (cable.capstan + a).max(0.0);
        cable.routing_dahl = Some((breakaway.max(f64::MIN_POSITIVE), slot));
    }

    /// Give joint `j` a pre-sliding (Dahl) friction (replacing any it had), with a state.
    pub(crate) fn set_presliding(&mut self, j: usize, p: Presliding) {
        let slot = self.state_slot(self.joints[j].presliding.map(|(_, k)| k));
        self.joints[j].presliding = Some((p, slot));
    }

    /// The index of an element's state: the one it has, or a new one at the end.
    fn state_slot(&mut self, existing: Option<usize>) -> usize {
        existing.unwrap_or_else(|| {
            self.n_states += 1;
            self.n_states - 1
        })
    }

    /// Scale cable `c`'s stiffness by `s` (> 0; floored at 1e-3) about its reference stretch,
    /// replacing any scale it had, with a state: `F_r + s·(F(e) − F_r)`, `F_r` its law at the
    /// run's first input ([`Self::rest_at`], as creep's reference) — a cable whose length was
    /// calibrated where it was held keeps that tension there, and only its slope changes (a
    /// scale about zero stretch would move the tension it was set to). Where the rest leaves the
    /// cable at its pretension (`F_r = 0`), the plain scaled law.
    pub(crate) fn set_stiffness_scale(&mut self, c: usize, s: f64) {
        let slot = self.state_slot(self.cables[c].stiffness.map(|(_, k)| k));
        self.cables[c].stiffness = Some((s.max(1e-3), slot));
    }

    /// Give cable `c` a creep of its tension (replacing any it had), with a state.
    pub(crate) fn set_creep(&mut self, c: usize, cr: TensionCreep) {
        let slot = self.cables[c].creep.map_or_else(
            || {
                self.n_states += 2;
                self.n_states - 2
            },
            |(_, k)| k,
        );
        self.cables[c].creep = Some((cr, slot));
    }

    /// Set the play between position-driven motor `i` and its capstan (half-width, rad of
    /// motor angle, ≥ 0; ignored for a torque-driven motor).
    pub(crate) fn set_play(&mut self, i: usize, half_width: f64) {
        if self.motors[i].drive == Drive::Position {
            self.motors[i].play = half_width.max(0.0);
        }
    }

    /// Motor `i`'s friction, mutable.
    pub(crate) fn motor_friction_mut(&mut self, i: usize) -> &mut StaticFriction {
        &mut self.motors[i].friction
    }

    /// Scale torque-driven motor `i`'s rotor inertia by `f` (floored at 1e-3).
    pub(crate) fn scale_motor_inertia(&mut self, i: usize, f: f64) {
        self.motors[i].inertia *= f.max(1e-3);
    }

    /// The state at rest for the first input `u0` (`[q_m, q̇_m]` of each position motor, the
    /// torques, the loads): every speed zero, every torque-driven motor at 0, and the joints in
    /// static equilibrium under that input — the cables' tensions, gravity and the external
    /// torques balanced (Newton's method from the angles that leave every cable at its
    /// pretension, `J·q = e₀`, `e₀` the position motors' hauls `σ·ρ·q_m`, in the least-squares
    /// sense; those angles when the iteration finds no smaller imbalance, or when a motor has
    /// play, across which the capstan floats and any angle in the play rests). A pair whose
    /// pretensions differ, a sagging joint or a held load starts where it rests rather than
    /// ringing from the kinematic angles. A cable's creep takes its reference there
    /// (`F_r = F(e₀)`, see [`TensionCreep`]; 0 for the whole form).
    pub fn rest_at(&self, u0: &[f64]) -> Vec<f64> {
        let x = self.with_references(self.joints_at_rest(u0), u0);
        // across a motor's play the capstan floats: joints and capstan then rest anywhere in
        // the play, and the kinematic angles are kept (no rest is better defined)
        if u0.len() < self.n_inputs
            || self.n_joints() == 0
            || self.motors.iter().any(|m| m.play > 0.0)
        {
            return x;
        }
        self.balanced(x, u0)
    }

    /// `x` with the states that take their reference at rest (a cable's stiffness law there, its
    /// creep's reference) set for its joints and the input `u0`.
    fn with_references(&self, mut x: Vec<f64>, u0: &[f64]) -> Vec<f64> {
        if u0.len() < self.n_inputs {
            return x;
        }
        // the stiffness' references first: the creep's is the law there, scaled or not
        for (c, cable) in self.cables.iter().enumerate() {
            if let Some((_, k)) = cable.stiffness {
                let (e, _) = self.elongation(c, &x, u0);
                let r = cable.run.law.elastic(e);
                x[k] = if r.is_finite() { r } else { 0.0 };
            }
        }
        for (c, cable) in self.cables.iter().enumerate() {
            if let Some((cr, k)) = cable.creep {
                if !cr.whole {
                    let (e, _) = self.elongation(c, &x, u0);
                    // the stretch form's reference is the elongation, the tension's its law
                    let r = if cr.stretch {
                        e
                    } else {
                        self.elastic_of(c, e, &x) * self.length_scale_at(c, &x, u0)
                    };
                    x[k + 1] = if r.is_finite() { r } else { 0.0 };
                }
            }
        }
        x
    }

    /// The net torque on each joint at state `x` (at rest) under input `u0`.
    fn joint_imbalance(&self, x: &[f64], u0: &[f64], dx: &mut [f64]) -> Vec<f64> {
        self.derivative(x, u0, dx);
        self.joints
            .iter()
            .enumerate()
            .map(|(j, joint)| dx[2 * j + 1] / joint.inv_inertia)
            .collect()
    }

    /// [`Self::rest_at`]'s equilibrium: damped Newton steps on the joint angles (a
    /// finite-difference Jacobian of the net joint torques, solved by SVD so that a joint no
    /// cable holds takes no step), each kept only when it lowers the imbalance; at most
    /// [`REST_ITERATIONS`] steps.
    fn balanced(&self, x0: Vec<f64>, u0: &[f64]) -> Vec<f64> {
        let n = self.n_joints();
        let mut dx = vec![0.0; self.n_states];
        let norm = |g: &[f64]| g.iter().map(|v| v * v).sum::<f64>().sqrt();
        let mut x = x0;
        let mut g = self.joint_imbalance(&x, u0, &mut dx);
        let mut size = norm(&g);
        // the torque a cable at its pretension puts on its joints: the scale of "balanced"
        let scale = self
            .cables
            .iter()
            .enumerate()
            .map(|(c, cable)| {
                let arm = self.arms[c * n..(c + 1) * n]
                    .iter()
                    .map(|a| a.abs())
                    .sum::<f64>();
                arm * cable.run.pretension.abs()
            })
            .sum::<f64>()
            .max(f64::MIN_POSITIVE);
        for _ in 0..REST_ITERATIONS {
            if !size.is_finite() || size <= 1e-10 * scale {
                break;
            }
            let h = 1e-7;
            let mut jac = nalgebra::DMatrix::zeros(n, n);
            for i in 0..n {
                let mut xi = x.clone();
                xi[2 * i] += h;
                let xi = self.with_references(xi, u0);
                let gi = self.joint_imbalance(&xi, u0, &mut dx);
                for j in 0..n {
                    jac[(j, i)] = (gi[j] - g[j]) / h;
                }
            }
            let rhs = nalgebra::DVector::from_fn(n, |j, _| -g[j]);
            let Ok(step) = jac.svd(true, true).solve(&rhs, 1e-12) else {
                break;
            };
            if step.iter().any(|v| !v.is_finite()) {
                break;
            }
            // halve the step until the imbalance falls
            let mut t = 1.0;
            let mut taken = false;
            for _ in 0..30 {
                let mut xt = x.clone();
                for j in 0..n {
                    xt[2 * j] += t * step[j];
                }
                let xt = self.with_references(xt, u0);
                let gt = self.joint_imbalance(&xt, u0, &mut dx);
                let st = norm(&gt);
                if st.is_finite() && st < size {
                    (x, g, size, taken) = (xt, gt, st, true);
                    break;
                }
                t *= 0.5;
            }
            if !taken {
                break;
            }
        }
        x
    }

    /// [`Self::rest_at`]'s joints (every other state 0).
    fn joints_at_rest(&self, u0: &[f64]) -> Vec<f64> {
        let (n, m) = (self.n_joints(), self.n_cables());
        let mut x = vec![0.0; self.n_states];
        if u0.len() < self.n_inputs || n == 0 {
            return x;
        }
        let b = nalgebra::DVector::from_fn(m, |c, _| {
            let cable = &self.cables[c];
            let end = self.end_of(c, u0).0;
            match cable.motor.map(|i| &self.motors[i]) {
                Some(mo) if mo.drive == Drive::Position => cable.sense * mo.rho * u0[mo.slot] + end,
                _ => end,
            }
        });
        if b.iter().all(|v| *v == 0.0) {
            return x;
        }
        let a = nalgebra::DMatrix::from_row_slice(m, n, &self.arms);
        if let Ok(q) = a.svd(true, true).solve(&b, 1e-12) {
            for j in 0..n {
                if q[j].is_finite() {
                    x[2 * j] = q[j];
                }
            }
        }
        x
    }
}

impl NetworkSpec {
    /// The antagonistic joint as a network: one joint `"joint"` moving body `"link"`, its
    /// pulley, a fixed idler carrying the routing's capstan wrap, a position-driven motor
    /// (`r_m = N = 1`, so `q_m` is the displacement `x_m`) and the cables `"drive"` and
    /// `"return"`. Contact, Dahl and creep (states the network does not have) are refused.
    pub fn from_joint(joint: &crate::dynamics::AntagonisticJoint) -> Result<Self> {
        if joint.contact.is_some() || joint.dahl.is_some() || joint.creep.is_some() {
            return Err(invalid(
                "antagonistic joint".into(),
                "has a contact, a Dahl or a creep state, which a network does not model",
            ));
        }
        let contact = |pulley: &str, sense: f64, wrap: f64, mu: f64| ContactSpec {
            pulley: pulley.into(),
            wrap,
            sense,
            mu,
        };
        let cable = |name: &str, run: CableRun, sense: f64| CableSpec {
            name: name.into(),
            routing: vec![
                contact("routing", sense, joint.capstan_wrap, joint.capstan_mu),
                contact("joint_pulley", sense, std::f64::consts::PI, 0.0),
            ],
            run,
            motor: Some("motor".into()),
            motor_sense: sense,
            end_motor: None,
            end_sense: 1.0,
            free_length: None,
            path: None,
        };
        Ok(Self {
            bodies: vec![BodySpec {
                name: "link".into(),
                inertia: joint.inertia,
            }],
            joints: vec![JointSpec {
                name: "joint".into(),
                kind: "revolute".into(),
                parent: "base".into(),
                child: "link".into(),
                coulomb: joint.friction.coulomb,
                viscous: joint.friction.viscous,
                smoothing: joint.friction.smoothing,
                gravity: Gravity::NONE,
            }],
            pulleys: vec![
                PulleySpec {
                    name: "joint_pulley".into(),
                    joint: Some("joint".into()),
                    radius: joint.radius,
                },
                PulleySpec {
                    name: "routing".into(),
                    joint: None,
                    radius: joint.radius,
                },
            ],
            cables: vec![
                cable("drive", joint.drive, 1.0),
                cable("return", joint.ret, -1.0),
            ],
            sensors: Vec::new(),
            motors: vec![MotorSpec {
                name: "motor".into(),
                drive: Drive::Position,
                inertia: 0.0,
                gear_ratio: 1.0,
                capstan_radius: 1.0,
                friction: StaticFriction::NONE,
            }],
            capstan_smoothing: joint.capstan_smoothing,
            signals: Vec::new(),
        })
    }

    /// The coupled transmission as a network: per link `i` a torque motor `motor{i}`, a joint
    /// `joint{i}` moving body `link{i}` with its pulley, and the pair `drive{i}` / `return{i}`
    /// passing an idler on every proximal axis `j` it couples into (radius `|C_ij|·r_l,i`).
    pub fn from_transmission(tx: &crate::dynamics::CableTransmission) -> Result<Self> {
        let n = tx.n_links();
        let coupling = tx.coupling();
        let mut spec = Self {
            bodies: Vec::new(),
            joints: Vec::new(),
            pulleys: Vec::new(),
            cables: Vec::new(),
            motors: Vec::new(),
            sensors: Vec::new(),
            capstan_smoothing: 1e-3,
            signals: Vec::new(),
        };
        for (i, l) in tx.links().iter().enumerate() {
            let k = i + 1;
            spec.bodies.push(BodySpec {
                name: format!("link{k}"),
                inertia: l.link_inertia,
            });
            #[allow(clippy::float_cmp)] // exact: coulomb_viscous sets one level to the other
            if l.link_friction.static_level != l.link_friction.coulomb {
                return Err(invalid(
                    format!("link {k}"),
                    "has a Stribeck friction, which a network joint does not model",
                ));
            }
            spec.joints.push(JointSpec {
                name: format!("joint{k}"),
                kind: l.kind.name().into(),
                parent: if i == 0 {
                    "base".into()
                } else {
                    format!("link{i}")
                },
                child: format!("link{k}"),
                coulomb: l.link_friction.coulomb,
                viscous: l.link_friction.viscous,
                smoothing: l.link_friction.smoothing,
                gravity: l.gravity,
            });
            spec.pulleys.push(PulleySpec {
                name: format!("pulley{k}"),
                joint: Some(format!("joint{k}")),
                radius: l.joint_radius,
            });
            spec.motors.push(MotorSpec {
                name: format!("motor{k}"),
                drive: Drive::Torque,
                inertia: l.motor_inertia,
                gear_ratio: l.gear_ratio,
                capstan_radius: l.capstan_radius,
                friction: l.motor_friction,
            });
            let mut routing = Vec::new();
            for j in 0..i {
                let c = coupling[i * n + j];
                #[allow(clippy::float_cmp)] // exact zero: no routing over that axis
                if c != 0.0 {
                    let name = format!("idler{k}_{}", j + 1);
                    spec.pulleys.push(PulleySpec {
                        name: name.clone(),
                        joint: Some(format!("joint{}", j + 1)),
                        radius: c.abs() * l.joint_radius,
                    });
                    routing.push((name, c.signum()));
                }
            }
            routing.push((format!("pulley{k}"), 1.0));
            for (name, side) in [("drive", 1.0), ("return", -1.0)] {
                spec.cables.push(CableSpec {
                    name: format!("{name}{k}"),
                    routing: routing
                        .iter()
                        .map(|(p, s)| ContactSpec {
                            pulley: p.clone(),
                            wrap: std::f64::consts::FRAC_PI_2,
                            sense: s * side,
                            mu: 0.0,
                        })
                        .collect(),
                    run: l.cable.run,
                    motor: Some(format!("motor{k}")),
                    motor_sense: side,
                    end_motor: None,
                    end_sense: 1.0,
                    free_length: None,
                    path: None,
                });
            }
        }
        Ok(spec)
    }
}

#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The most Newton steps [`Network::rest_at`] takes towards the joints' equilibrium.
pub const REST_ITERATIONS: usize = 50;

impl Model for Network {
    fn n_states(&self) -> usize {
        self.n_states
    }
    fn n_inputs(&self) -> usize {
        self.n_inputs
    }
    fn n_outputs(&self) -> usize {
        2 * self.n_joints() + 2 * self.n_motors() + 2 * self.n_cables() + self.taps.len()
    }

    fn derivative(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
        let n = self.n_joints();
        let load = self.load_input();
        for (j, joint) in self.joints.iter().enumerate() {
            let v = x[2 * j + 1];
            dx[2 * j] = v;
            dx[2 * j + 1] =
                -joint.friction.force(v) - joint.gravity.load(joint.kind, x[2 * j]) + u[load + j];
            if let Some((p, k)) = joint.presliding {
                let (torque, rate) = p.torque_and_rate(x[k], v);
                dx[2 * j + 1] -= torque;
                dx[k] = rate;
            }
        }
        for (c, cable) in self.cables.iter().enumerate() {
            if let Some((cr, k)) = cable.creep {
                let (e, _) = self.elongation(c, x, u);
                let target = if cr.stretch {
                    e
                } else {
                    let mut t = self.elastic_of(c, e, x);
                    if cr.whole {
                        t += cable.run.pretension;
                    }
                    t * self.length_scale_at(c, x, u)
                };
                dx[k] = (cr.fraction * (target - x[k + 1]) - x[k]) / cr.time_constant;
                dx[k + 1] = 0.0;
            }
            if let Some((_, k)) = cable.stiffness {
                dx[k] = 0.0;
            }
            if let Some((x_d, k)) = cable.routing_dahl {
                let v = self.haul_speed(c, x, u);
                dx[k] = (v - v.abs() * x[k].clamp(-1.0, 1.0)) / x_d;
            }
            if let Some(Path {
                law:
                    PathFrictionLaw::Dahl {
                        presliding,
                        exponent,
                        state: k,
                    },
                ..
            }) = cable.path
            {
                // dz/ds = |1 − z·sgn ṡ|ⁿ·sgn(1 − z·sgn ṡ)/x_c over the hauled length s
                let v = self.path_speed(c, x, u);
                let g = 1.0 - x[k].clamp(-1.0, 1.0) * v.signum();
                dx[k] = if v == 0.0 {
                    0.0
                } else {
                    v * g.abs().powf(exponent) * g.signum() / presliding
                };
            }
        }
        for m in &self.motors {
            if m.drive == Drive::Torque {
                dx[m.slot] = x[m.slot + 1];
                dx[m.slot + 1] = -m.friction.force(x[m.slot + 1]);
            }
        }
        for (c, cable) in self.cables.iter().enumerate() {
            let (t, tm) = self.cable_tensions(c, x, u);
            for (j, a) in self.arms[c * n..(c + 1) * n].iter().enumerate() {
                dx[2 * j + 1] += a * t;
            }
            #[allow(clippy::float_cmp)] // equal exactly when the cable has no routing friction
            if tm != t {
                for (j, a) in cable.driver_arms.iter().enumerate() {
                    dx[2 * j + 1] += a * (tm - t);
                }
            }
            if let Some(m) = cable.motor.map(|i| &self.motors[i]) {
                if m.drive == Drive::Torque {
                    dx[m.slot + 1] -= m.rho * cable.sense * tm;
                }
            }
        }
        for (j, joint) in self.joints.iter().enumerate() {
            dx[2 * j + 1] *= joint.inv_inertia;
        }
        for m in &self.motors {
            if m.drive == Drive::Torque {
                dx[m.slot + 1] = (dx[m.slot + 1] + u[m.torque_input]) / m.inertia;
            }
        }
    }

    /// `y = [q_j…, q_m…, T_c (joint side)…, T_m,c (motor side)…, τ_j…, load_m…]`, the
    /// motor's cable load `ρ_m·Σ σ_c·T_m,c` (N·m) being what its current measures — plus, for a
    /// position-driven motor, its own friction `F_f,m(q̇_m)`, which its servo's current also
    /// overcomes (a torque-driven motor's friction is in its dynamics).
    fn output(&self, x: &[f64], u: &[f64], y: &mut [f64]) {
        let (n, p, m) = (self.n_joints(), self.n_motors(), self.n_cables());
        for j in 0..n {
            y[j] = x[2 * j];
            y[n + p + 2 * m + j] = 0.0;
        }
        for i in 0..p {
            y[n + i] = self.motor_at(i, x, u).0;
            y[2 * n + p + 2 * m + i] = 0.0;
        }
        let mut signs = [(0.0, 0.0); 16];
        for (c, cable) in self.cables.iter().enumerate() {
            let (t, tp, tm, sign) = self.cable_tensions_full(c, x, u);
            if c < signs.len() {
                signs[c] = (sign, tp);
            }
            y[n + p + c] = t;
            y[n + p + m + c] = tm;
            if let Some(i) = cable.motor {
                y[2 * n + p + 2 * m + i] += self.motors[i].rho * cable.sense * tm;
            }
            for (j, arm) in self.arms[c * n..(c + 1) * n].iter().enumerate() {
                y[n + p + 2 * m + j] += arm * t + cable.driver_arms[j] * (tm - t);
            }
        }
        // a position-driven motor's current also overcomes its own friction
        for (i, mo) in self.motors.iter().enumerate() {
            if mo.drive == Drive::Position {
                y[2 * n + p + 2 * m + i] += mo.friction.force(u[mo.slot + 1]);
            }
        }
        // a tension between contacts: the tension beyond the path (the joint-side tension
        // without one) through the friction beyond it
        for (k, &(c, _, beyond)) in self.taps.iter().enumerate() {
            let (sign, tp) = if c < signs.len() {
                signs[c]
            } else {
                let (_, tp, _, sign) = self.cable_tensions_full(c, x, u);
                (sign, tp)
            };
            y[2 * n + 2 * p + 2 * m + k] = tp * (beyond * sign).exp();
        }
    }

    fn state_names(&self) -> Vec<String> {
        let mut out = vec![String::new(); self.n_states];
        for (j, name) in self.joint_names.iter().enumerate() {
            out[2 * j] = format!("q:{name}");
            out[2 * j + 1] = format!("dq:{name}");
            if let Some((_, k)) = self.joints[j].presliding {
                out[k] = format!("z:{name}");
            }
        }
        for (m, name) in self.motors.iter().zip(&self.motor_names) {
            if m.drive == Drive::Torque {
                out[m.slot] = format!("q_m:{name}");
                out[m.slot + 1] = format!("dq_m:{name}");
            }
        }
        for (c, name) in self.cables.iter().zip(&self.cable_names) {
            if let Some((cr, k)) = c.creep {
                let (w, r) = if cr.stretch {
                    ("crept", "crept_ref")
                } else {
                    ("creep", "creep_ref")
                };
                out[k] = format!("{w}:{name}");
                out[k + 1] = format!("{r}:{name}");
            }
            if let Some((_, k)) = c.stiffness {
                out[k] = format!("stiffness_ref:{name}");
            }
            if let Some((_, k)) = c.routing_dahl {
                out[k] = format!("z_routing:{name}");
            }
            if let Some(Path {
                law: PathFrictionLaw::Dahl { state: k, .. },
                ..
            }) = c.path
            {
                out[k] = format!("z_path:{name}");
            }
        }
        out
    }

    fn input_names(&self) -> Vec<String> {
        let mut out = Vec::with_capacity(self.n_inputs);
        for (m, name) in self.motors.iter().zip(&self.motor_names) {
            if m.drive == Drive::Position {
                out.push(format!("q_m:{name}"));
                out.push(format!("dq_m:{name}"));
            }
        }
        for (m, name) in self.motors.iter().zip(&self.motor_names) {
            if m.drive == Drive::Torque {
                out.push(format!("tau_m:{name}"));
            }
        }
        out.extend(self.signal_names.iter().map(|s| format!("signal:{s}")));
        out.extend(self.joint_names.iter().map(|j| format!("tau_ext:{j}")));
        out
    }

    fn output_names(&self) -> Vec<String> {
        let mut out: Vec<String> = self.joint_names.iter().map(|j| format!("q:{j}")).collect();
        out.extend(self.motor_names.iter().map(|m| format!("q_m:{m}")));
        out.extend(self.cable_names.iter().map(|c| format!("T:{c}")));
        out.extend(self.cable_names.iter().map(|c| format!("T_motor:{c}")));
        out.extend(self.joint_names.iter().map(|j| format!("tau:{j}")));
        out.extend(self.motor_names.iter().map(|m| format!("load_m:{m}")));
        out.extend(self.taps.iter().map(|(_, name, _)| name.clone()));
        out
    }
}
