//! A digital twin of seed 000's two-forceps end-effector (§2.1, §3): each forceps a yaw jaw
//! driven through a pretensioned drive/return cable pair by a linear stepping motor, with the
//! tension losses of the cable–pulley routing, hysteretic joint friction, a grasped block with
//! compliant pads and the bench's sensors.
//!
//! **Jaw** ([`Jaw`], one per forceps). The jaw angle `θ` (rad) counts the closing rotation from
//! fully open (65° per jaw, a 130° opening); the forceps' opening angle is
//! `130° − θ_A − θ_B`. The motor displacement `x_m` (m) pulls the drive cable, which closes the
//! jaw, and pays out the return cable:
//!
//! ```text
//! s = x_m − r₂·θ,  ṡ = ẋ_m − r₂·θ̇                           cable stretch (m)
//! T_j,1 = max(0, T₀ + k·s + c·ṡ),  T_j,2 = max(0, T₀ − k·s − c·ṡ)   joint-side tensions (N)
//! J·θ̈ = r₂·(T_j,1 − T_j,2) − z − b·θ̇ − (τ_s0 + k_s·θ) − l_e·F_c     seed 000 eq. 9
//! ż = σ₀·(1 − z·sgn(θ̇)/τ_c)·θ̇                                    Dahl joint friction (N·m)
//! ```
//!
//! `τ_s0 + k_s·θ` is the jaw's elastic return torque (the bending of the electrode wires and
//! the cables around the small wrist pulleys; the `g(θ)` of seed 000 eq. 9): a conservative,
//! position-dependent load that a free-motion model can learn, unlike friction.
//!
//! The block's pad touches the jaw at `θ_c` through the force arm `l_e`: penetration
//! `p = l_e·(θ − θ_c)`, `F_c = max(0, k_c·p + c_c·ṗ)` while `p > 0`
//! ([`Contact`](crate::dynamics::Contact)). Seed 000's block meets both jaws at a 65° opening,
//! `θ_c = 32.5°`.
//!
//! **Tension losses** between the motor-side sensors and the jaw (seed 000 eq. 4,
//! `F_M = F_T + F_f`): capstan friction of the routing pulleys with a rate-independent
//! direction state `σ ∈ [−1, 1]` that follows the motor's travel (a cable at rest keeps the
//! friction it had, as a real capstan does), and viscous drag of the pulleys:
//!
//! ```text
//! dσ/dx_m = (1 − σ·sgn ẋ_m)/δ                                    reversal over a travel δ (m)
//! T_m,1 = T_j,1·exp(+μφ·σ) + c_p·ẋ_m,   T_m,2 = T_j,2·exp(−μφ·σ) − c_p·ẋ_m
//! ```
//!
//! **Motor** ([`Profile`]): moves and holds of a linear stepping motor with S-curve
//! acceleration and deceleration (raised-cosine velocity over `ramp`, seed 000: 0.02 s) at a
//! settable cruise speed; the position is the commanded one rounded to whole pulses (seed 000:
//! 0.00127 mm per pulse), the velocity the commanded one.
//!
//! **Sensors** ([`Noise`]): the four motor-side tensions with white noise (seed 000: 0–50 N
//! tension sensors) and the two pad forces measured by pressure sensors (FlexiForce A201) with
//! white noise; both sampled every `sample_time`.
//!
//! [`Twin::run`] integrates both jaws with RK4 at `substeps` steps per sample, the motor
//! profile evaluated at each RK4 stage. States per jaw `[θ, θ̇, z, σ]`.

use crate::dynamics::{Contact, Model};
use crate::error::{check, CableError, Result};
use crate::friction::{sign, Dahl};

/// Motor travel per pulse of seed 000's linear stepping motor (m): 0.00127 mm.
pub const PULSE: f64 = 1.27e-6;
/// Seed 000's S-curve acceleration and deceleration time (s).
pub const RAMP: f64 = 0.02;
/// Seed 000's free-motion cruise speeds (m/s): 0.5, 0.6, 0.7, 0.8 and 1.0 mm/s.
pub const SEED_SPEEDS: [f64; 5] = [0.5e-3, 0.6e-3, 0.7e-3, 0.8e-3, 1.0e-3];
/// Each jaw's range (rad): 0–65° (a 0–130° opening).
pub const JAW_RANGE: f64 = 65.0 * std::f64::consts::PI / 180.0;
/// Segments a profile may hold (every loop is bounded).
pub const MAX_SEGMENTS: usize = 100_000;
/// Samples a run may hold.
pub const MAX_SAMPLES: usize = 10_000_000;

/// Number of parameters of a [`Jaw`].
pub const N_JAW: usize = 17;
/// Names of a jaw's parameters in [`Jaw::to_array`] order (SI units: m, kg·m², N/m, N·s/m, N,
/// N·m, N·m/rad, N·m·s/rad, N·m/rad, N·m, –, m, N·s/m, rad, N/m, N·s/m, m).
pub const JAW_NAMES: [&str; N_JAW] = [
    "r2",
    "inertia",
    "cable_stiffness",
    "cable_damping",
    "pretension",
    "joint_friction",
    "joint_friction_stiffness",
    "joint_viscous",
    "spring",
    "spring_preload",
    "capstan",
    "capstan_travel",
    "pulley_viscous",
    "contact_angle",
    "pad_stiffness",
    "pad_damping",
    "arm",
];

/// One piece of a motor program.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Segment {
    /// Move to `to` (m) at cruise speed `speed` (m/s, > 0) with S-curve ramps.
    Move {
        /// Target position (m).
        to: f64,
        /// Cruise speed (m/s).
        speed: f64,
    },
    /// Stand still for `duration` (s, ≥ 0).
    Hold {
        /// Duration (s).
        duration: f64,
    },
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Piece {
    start: f64,
    duration: f64,
    from: f64,
    distance: f64,
    speed: f64,
}

/// A motor program: positions and velocities of a linear stepping motor over time.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    start: f64,
    ramp: f64,
    pulse: f64,
    pieces: Vec<Piece>,
}

impl Profile {
    /// A program starting at `start` (m) that runs `segments` in order, with S-curve ramps of
    /// `ramp` s (> 0) and positions rounded to `pulse` m (> 0; 0 for none). A move too short
    /// to reach its speed within two ramps is slowed to cover its distance in `2·ramp`.
    pub fn new(start: f64, segments: &[Segment], ramp: f64, pulse: f64) -> Result<Self> {
        check::finite("start", start)?;
        check::positive("ramp", ramp)?;
        check::non_negative("pulse", pulse)?;
        if segments.len() > MAX_SEGMENTS {
            return Err(CableError::InvalidParameter {
                name: "segments".into(),
                value: segments.len() as f64,
                requirement: "at most 100000 segments (MAX_SEGMENTS)",
            });
        }
        let (mut t, mut x) = (0.0, start);
        let mut pieces = Vec::with_capacity(segments.len());
        for (i, seg) in segments.iter().enumerate() {
            let piece = match *seg {
                Segment::Move { to, speed } => {
                    check::finite(&format!("segments[{i}].to"), to)?;
                    let v = check::positive(&format!("segments[{i}].speed"), speed)?;
                    let d = to - x;
                    let v = v.min(d.abs() / ramp).max(f64::MIN_POSITIVE);
                    let duration = if d == 0.0 { 0.0 } else { d.abs() / v + ramp };
                    Piece {
                        start: t,
                        duration,
                        from: x,
                        distance: d,
                        speed: v,
                    }
                }
                Segment::Hold { duration } => {
                    check::non_negative(&format!("segments[{i}].duration"), duration)?;
                    Piece {
                        start: t,
                        duration,
                        from: x,
                        distance: 0.0,
                        speed: 0.0,
                    }
                }
            };
            t += piece.duration;
            x += piece.distance;
            if !t.is_finite() {
                return Err(CableError::InvalidParameter {
                    name: format!("segments[{i}]"),
                    value: t,
                    requirement: "a program whose total duration is finite",
                });
            }
            pieces.push(piece);
        }
        Ok(Self {
            start,
            ramp,
            pulse,
            pieces,
        })
    }

    /// Total duration (s).
    pub fn duration(&self) -> f64 {
        self.pieces.last().map_or(0.0, |p| p.start + p.duration)
    }

    /// Final position (m).
    pub fn end(&self) -> f64 {
        self.pieces
            .last()
            .map_or(self.start, |p| p.from + p.distance)
    }

    /// Commanded position and velocity `(x, ẋ)` at `t` (s), before pulse rounding; the start
    /// before 0 and the end after the program.
    pub fn commanded(&self, t: f64) -> (f64, f64) {
        let k = self.pieces.partition_point(|p| p.start <= t);
        let Some(p) = k.checked_sub(1).map(|k| self.pieces[k]) else {
            return (self.start, 0.0);
        };
        let tau = t - p.start;
        if tau >= p.duration || p.distance == 0.0 {
            return (
                p.from + if tau >= p.duration { p.distance } else { 0.0 },
                0.0,
            );
        }
        let dir = p.distance.signum();
        let (ta, v) = (self.ramp, p.speed);
        let ramp_at = |s: f64| {
            let w = std::f64::consts::PI / ta;
            (
                v * (s / 2.0 - (w * s).sin() / (2.0 * w)),
                v * (1.0 - (w * s).cos()) / 2.0,
            )
        };
        let (dx, dv) = if tau < ta {
            ramp_at(tau)
        } else if tau <= p.duration - ta {
            (v * ta / 2.0 + v * (tau - ta), v)
        } else {
            let (xr, vr) = ramp_at(p.duration - tau);
            (p.distance.abs() - xr, vr)
        };
        (p.from + dir * dx, dir * dv)
    }

    /// Position rounded to whole pulses and commanded velocity `(x_m, ẋ_m)` at `t` (s).
    pub fn at(&self, t: f64) -> (f64, f64) {
        let (x, v) = self.commanded(t);
        if self.pulse > 0.0 {
            ((x / self.pulse).round() * self.pulse, v)
        } else {
            (x, v)
        }
    }
}

/// One forceps: a yaw jaw, its cable pair and losses, and its side of the block; see the
/// module docs for the equations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jaw {
    /// Effective drive radius `r₂` (m).
    pub r2: f64,
    /// Jaw inertia `J` about its axis (kg·m²).
    pub inertia: f64,
    /// Stiffness `k` of each cable between motor and jaw (N/m).
    pub cable_stiffness: f64,
    /// Damping `c` of each cable (N·s/m).
    pub cable_damping: f64,
    /// Pretension `T₀` of both cables (N).
    pub pretension: f64,
    /// Hysteretic (Dahl) joint friction: level `τ_c` (N·m) and rest stiffness `σ₀` (N·m/rad).
    pub joint_friction: Dahl,
    /// Viscous joint friction `b` (N·m·s/rad).
    pub joint_viscous: f64,
    /// Return stiffness of the jaw `k_s` (N·m/rad), ≥ 0.
    pub spring: f64,
    /// Return torque at fully open `τ_s0` (N·m), ≥ 0.
    pub spring_preload: f64,
    /// Capstan exponent `μφ` of the routing (friction coefficient × total wrap), ≥ 0.
    pub capstan: f64,
    /// Motor travel `δ` over which the capstan friction reverses (m), > 0.
    pub capstan_travel: f64,
    /// Viscous drag of the routing pulleys `c_p` (N·s/m), ≥ 0.
    pub pulley_viscous: f64,
    /// The block's pad on this jaw; `l_e` is its `lever_arm`, `θ_c` its `angle`.
    pub contact: Contact,
}

impl Jaw {
    /// Seed 000's forceps A (values the seed does not give are plausible choices, stated in
    /// docs/forceps.md and `instruments/seed000.toml`): `r₂ = 4 mm`, `l_eA = 12 mm`, a 0.45 mm
    /// steel rope (`k = 31.8 kN/m` per cable, 20 N·s/m), and pretension, capstan friction and
    /// return spring chosen so that closing at first contact the motor-side tensions are the
    /// seed's 14.8 / 6.8 N; joint friction 2 mN·m, a pad of 2 kN/m meeting the jaw at a 65°
    /// opening.
    pub fn seed_a() -> Self {
        Self {
            r2: 4e-3,
            inertia: 5e-6,
            cable_stiffness: 31.8e3,
            cable_damping: 20.0,
            pretension: 10.4,
            joint_friction: Dahl {
                sigma0: 2.0,
                coulomb: 2e-3,
                exponent: 1.0,
            },
            joint_viscous: 2e-3,
            spring: 0.0265,
            spring_preload: 5e-3,
            capstan: 0.12,
            capstan_travel: 50e-6,
            pulley_viscous: 300.0,
            contact: Contact {
                angle: 32.5f64.to_radians(),
                stiffness: 2e3,
                damping: 1.0,
                lever_arm: 12e-3,
            },
        }
    }

    /// Seed 000's forceps B: as A with a longer arm (`l_eB = 14 mm`), and pretension, losses
    /// and spring matched to the seed's 17.1 / 5.7 N at first contact.
    pub fn seed_b() -> Self {
        let mut j = Self::seed_a();
        j.pretension = 10.7;
        j.spring = 0.042;
        j.spring_preload = 6e-3;
        j.capstan = 0.15;
        j.capstan_travel = 60e-6;
        j.pulley_viscous = 250.0;
        j.joint_friction.coulomb = 2.5e-3;
        j.contact.lever_arm = 14e-3;
        j
    }

    /// The parameters in [`JAW_NAMES`] order.
    pub fn to_array(&self) -> [f64; N_JAW] {
        [
            self.r2,
            self.inertia,
            self.cable_stiffness,
            self.cable_damping,
            self.pretension,
            self.joint_friction.coulomb,
            self.joint_friction.sigma0,
            self.joint_viscous,
            self.spring,
            self.spring_preload,
            self.capstan,
            self.capstan_travel,
            self.pulley_viscous,
            self.contact.angle,
            self.contact.stiffness,
            self.contact.damping,
            self.contact.lever_arm,
        ]
    }

    /// A validated jaw from [`JAW_NAMES`] order; `prefix` names it in errors.
    pub fn from_array(v: &[f64], prefix: &str) -> Result<Self> {
        check::len(&format!("{prefix} parameters"), v, N_JAW)?;
        let jaw = Self {
            r2: v[0],
            inertia: v[1],
            cable_stiffness: v[2],
            cable_damping: v[3],
            pretension: v[4],
            joint_friction: Dahl {
                coulomb: v[5],
                sigma0: v[6],
                exponent: 1.0,
            },
            joint_viscous: v[7],
            spring: v[8],
            spring_preload: v[9],
            capstan: v[10],
            capstan_travel: v[11],
            pulley_viscous: v[12],
            contact: Contact {
                angle: v[13],
                stiffness: v[14],
                damping: v[15],
                lever_arm: v[16],
            },
        };
        jaw.validate(prefix)?;
        Ok(jaw)
    }

    /// Every parameter finite and in range (names prefixed by `prefix`).
    pub fn validate(&self, prefix: &str) -> Result<()> {
        let p = |n: &str| format!("{prefix}.{n}");
        check::positive(&p("r2"), self.r2)?;
        check::positive(&p("inertia"), self.inertia)?;
        check::positive(&p("cable_stiffness"), self.cable_stiffness)?;
        check::non_negative(&p("cable_damping"), self.cable_damping)?;
        check::non_negative(&p("pretension"), self.pretension)?;
        check::positive(&p("joint_friction.sigma0"), self.joint_friction.sigma0)?;
        check::positive(&p("joint_friction.coulomb"), self.joint_friction.coulomb)?;
        check::positive(&p("joint_friction.exponent"), self.joint_friction.exponent)?;
        check::non_negative(&p("joint_viscous"), self.joint_viscous)?;
        check::non_negative(&p("spring"), self.spring)?;
        check::non_negative(&p("spring_preload"), self.spring_preload)?;
        check::at_most(
            &p("capstan"),
            self.capstan,
            20.0,
            "finite, in [0, 20]: μ·φ of the routing (e^20 is a tension ratio of 5·10⁸)",
        )?;
        check::positive(&p("capstan_travel"), self.capstan_travel)?;
        check::non_negative(&p("pulley_viscous"), self.pulley_viscous)?;
        Contact::new(
            self.contact.angle,
            self.contact.stiffness,
            self.contact.damping,
            self.contact.lever_arm,
        )
        .map_err(|e| match e {
            CableError::InvalidParameter {
                name,
                value,
                requirement,
            } => CableError::InvalidParameter {
                name: p(&name),
                value,
                requirement,
            },
            e => e,
        })?;
        Ok(())
    }

    /// Motor position that holds the jaw at `theta` (rad) in free motion, friction aside:
    /// `r₂·θ` plus the cable stretch under the spring's torque, `(τ_s0 + k_s·θ)/(2k·r₂)`.
    pub fn motor_at(&self, theta: f64) -> f64 {
        let spring = self.spring_preload + self.spring * theta;
        self.r2 * theta + spring / (2.0 * self.cable_stiffness * self.r2)
    }

    /// Jaw angle at rest in free motion for motor position `x_m`, friction aside (the
    /// inverse of [`Jaw::motor_at`]).
    pub fn rest_angle(&self, x_m: f64) -> f64 {
        let k = 2.0 * self.cable_stiffness * self.r2;
        (k * x_m - self.spring_preload) / (k * self.r2 + self.spring)
    }

    /// Motor travel beyond first contact that presses the pad with `force` (N) at rest,
    /// friction aside: the jaw turns into the pad (`k_c·l_e²`) while the cable pair (`2k·r₂²`)
    /// stretches under the pad's and the spring's added torque.
    pub fn travel_for(&self, force: f64) -> f64 {
        let l = self.contact.lever_arm;
        let pad = self.contact.stiffness * l * l;
        let turn = force * l / pad;
        let cables = 2.0 * self.cable_stiffness * self.r2 * self.r2;
        self.r2 * turn * (1.0 + (pad + self.spring) / cables)
    }

    #[inline]
    fn joint_tensions(&self, x: &[f64], u: &[f64]) -> (f64, f64) {
        let s = u[0] - self.r2 * x[0];
        let sd = u[1] - self.r2 * x[1];
        let f = self.cable_stiffness * s + self.cable_damping * sd;
        (
            (self.pretension + f).max(0.0),
            (self.pretension - f).max(0.0),
        )
    }

    #[inline]
    fn derivative_with(&self, x: &[f64], u: &[f64], block: bool, dx: &mut [f64]) {
        let (t1, t2) = self.joint_tensions(x, u);
        let fc = if block {
            self.contact.force(x[0], x[1])
        } else {
            0.0
        };
        let torque = self.r2 * (t1 - t2)
            - x[2]
            - self.joint_viscous * x[1]
            - (self.spring_preload + self.spring * x[0])
            - self.contact.lever_arm * fc;
        dx[0] = x[1];
        dx[1] = torque / self.inertia;
        dx[2] = self.joint_friction.rate(x[2], x[1]);
        dx[3] = u[1] * (1.0 - x[3] * sign(u[1])) / self.capstan_travel;
    }

    #[inline]
    fn output_with(&self, x: &[f64], u: &[f64], block: bool, y: &mut [f64]) {
        let (t1, t2) = self.joint_tensions(x, u);
        let e = (self.capstan * x[3]).exp();
        let drag = self.pulley_viscous * u[1];
        y[0] = t1 * e + drag;
        y[1] = t2 / e - drag;
        y[2] = t1;
        y[3] = t2;
        y[4] = x[0];
        y[5] = if block {
            self.contact.force(x[0], x[1])
        } else {
            0.0
        };
    }
}

/// The jaw as a [`Model`] with its block (states `[θ, θ̇, z, σ]`, inputs `[x_m, ẋ_m]`, outputs
/// `[T_m,1, T_m,2, T_j,1, T_j,2, θ, F_c]`), for `simulate`, the filters and the diagnosis.
impl Model for Jaw {
    fn n_states(&self) -> usize {
        4
    }
    fn n_inputs(&self) -> usize {
        2
    }
    fn n_outputs(&self) -> usize {
        6
    }
    fn derivative(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
        self.derivative_with(x, u, true, dx);
    }
    fn output(&self, x: &[f64], u: &[f64], y: &mut [f64]) {
        self.output_with(x, u, true, y);
    }
    fn state_names(&self) -> Vec<String> {
        ["theta", "dtheta", "joint_friction", "capstan_direction"]
            .map(String::from)
            .to_vec()
    }
    fn input_names(&self) -> Vec<String> {
        ["x_m", "dx_m"].map(String::from).to_vec()
    }
    fn output_names(&self) -> Vec<String> {
        crate::dynamics::ANTAGONISTIC_OUTPUTS
            .map(String::from)
            .to_vec()
    }
}

/// Sensor noise of the bench (standard deviations) and the generator's seed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Noise {
    /// Each motor-side tension sensor (N).
    pub tension: f64,
    /// Each pad pressure sensor (N).
    pub pressure: f64,
    /// Seed of the deterministic noise generator.
    pub seed: u64,
}

impl Noise {
    /// No noise.
    pub const NONE: Noise = Noise {
        tension: 0.0,
        pressure: 0.0,
        seed: 0,
    };
}

/// The two-forceps end-effector and its bench.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Twin {
    /// Forceps A.
    pub a: Jaw,
    /// Forceps B.
    pub b: Jaw,
    /// Sensor noise.
    pub noise: Noise,
    /// Sampling period of the sensors (s).
    pub sample_time: f64,
    /// RK4 steps per sample.
    pub substeps: usize,
}

/// A run of the twin, row-major, one row per sample.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinRun {
    /// Samples `T`.
    pub len: usize,
    /// `(T,)` sample times (s).
    pub time: Vec<f64>,
    /// `(T, 4)` motor motion `[x_a, v_a, x_b, v_b]` (m, m/s), the network's inputs.
    pub motors: Vec<f64>,
    /// `(T, 4)` measured motor-side tensions `F_M = [F_A¹, F_A², F_B¹, F_B²]` (N), noisy.
    pub measured: Vec<f64>,
    /// `(T, 4)` the same tensions without noise (N).
    pub tensions: Vec<f64>,
    /// `(T, 4)` joint-side tensions `F_T` (N).
    pub joint_tensions: Vec<f64>,
    /// `(T, 2)` pad forces as the pressure sensors read them `[F_ext^A, F_ext^B]` (N), noisy.
    pub external: Vec<f64>,
    /// `(T, 2)` true pad forces (N).
    pub external_true: Vec<f64>,
    /// `(T, 2)` jaw angles `[θ_A, θ_B]` (rad).
    pub angles: Vec<f64>,
}

/// SplitMix64 with Box–Muller: reproducible Gaussian noise without a dependency.
struct Gauss {
    state: u64,
    spare: Option<f64>,
}

impl Gauss {
    fn new(seed: u64) -> Self {
        Self {
            state: seed ^ 0x9E37_79B9_7F4A_7C15,
            spare: None,
        }
    }
    fn uniform(&mut self) -> f64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn next(&mut self) -> f64 {
        if let Some(s) = self.spare.take() {
            return s;
        }
        let (u1, u2) = (self.uniform(), self.uniform());
        let r = (-2.0 * u1.ln()).sqrt();
        let a = std::f64::consts::TAU * u2;
        self.spare = Some(r * a.sin());
        r * a.cos()
    }
}

impl Twin {
    /// Seed 000's end-effector ([`Jaw::seed_a`], [`Jaw::seed_b`]) sampled at 100 Hz with
    /// 100 RK4 steps per sample, 0.08 N tension-sensor noise (0.16 % of the 50 N range) and
    /// 0.01 N pressure-sensor noise.
    pub fn seed() -> Self {
        Self {
            a: Jaw::seed_a(),
            b: Jaw::seed_b(),
            noise: Noise {
                tension: 0.08,
                pressure: 0.01,
                seed: 0,
            },
            sample_time: 0.01,
            substeps: 100,
        }
    }

    /// Every parameter in range.
    pub fn validate(&self) -> Result<()> {
        self.a.validate("a")?;
        self.b.validate("b")?;
        // noise standard deviations whose samples stay numbers (a Gaussian draw reaches ~6σ)
        for (name, v) in [
            ("noise.tension", self.noise.tension),
            ("noise.pressure", self.noise.pressure),
        ] {
            check::at_most(name, v, 1e300, "finite, in [0, 1e300]")?;
        }
        check::positive("sample_time", self.sample_time)?;
        check::substeps("substeps", self.substeps)?;
        Ok(())
    }

    /// Runs the motor programs `a` and `b` (sampled from 0 to the longer one's end, the
    /// shorter holding its last position) with the block in place (`block`) or removed (free
    /// motion). Errors: parameters out of range, more than [`MAX_SAMPLES`] samples, or a
    /// state that leaves the floating-point range (`Diverged`: fewer substeps than the stiffest
    /// mode needs).
    ///
    /// Both jaws start at rest in free motion where the motors' first positions hold them
    /// ([`Jaw::rest_angle`]), friction and capstan states at 0.
    pub fn run(&self, a: &Profile, b: &Profile, block: bool) -> Result<TwinRun> {
        self.validate()?;
        let duration = a.duration().max(b.duration());
        let n = (duration / self.sample_time).floor() + 1.0;
        if n > MAX_SAMPLES as f64 {
            return Err(CableError::InvalidParameter {
                name: "samples".into(),
                value: n,
                requirement: "at most 10000000 samples (MAX_SAMPLES): a shorter program or a longer sample_time",
            });
        }
        let n = n as usize;
        let jaws = [(&self.a, a), (&self.b, b)];
        let mut run = TwinRun {
            len: n,
            time: Vec::with_capacity(n),
            motors: Vec::with_capacity(4 * n),
            measured: Vec::with_capacity(4 * n),
            tensions: Vec::with_capacity(4 * n),
            joint_tensions: Vec::with_capacity(4 * n),
            external: Vec::with_capacity(2 * n),
            external_true: Vec::with_capacity(2 * n),
            angles: Vec::with_capacity(2 * n),
        };
        let mut states = jaws.map(|(j, p)| [j.rest_angle(p.at(0.0).0), 0.0, 0.0, 0.0]);
        let mut rows = [[0.0; 6]; 2];
        let h = self.sample_time / self.substeps as f64;
        let mut gauss = Gauss::new(self.noise.seed);
        for k in 0..n {
            let t = k as f64 * self.sample_time;
            if k > 0 {
                for s in 0..self.substeps {
                    let t0 = t - self.sample_time + s as f64 * h;
                    for ((jaw, prof), x) in jaws.iter().zip(states.iter_mut()) {
                        rk4(jaw, prof, block, x, t0, h);
                    }
                }
                if states.iter().flatten().any(|v| !v.is_finite()) {
                    return Err(CableError::Diverged { step: k, time_s: t });
                }
            }
            run.time.push(t);
            for (((jaw, prof), x), y) in jaws.iter().zip(&states).zip(rows.iter_mut()) {
                let (xm, vm) = prof.at(t);
                jaw.output_with(x, &[xm, vm], block, y);
                run.motors.extend([xm, vm]);
            }
            for y in &rows {
                run.tensions.extend([y[0], y[1]]);
                run.measured.extend([
                    y[0] + self.noise.tension * gauss.next(),
                    y[1] + self.noise.tension * gauss.next(),
                ]);
                run.joint_tensions.extend([y[2], y[3]]);
                run.angles.push(y[4]);
                run.external_true.push(y[5]);
                run.external.push(y[5] + self.noise.pressure * gauss.next());
            }
        }
        Ok(run)
    }
}

impl Twin {
    /// Seed 000's free-motion experiment (§3.1): both jaws close over their whole range and
    /// open again at each of `speeds` (m/s; [`SEED_SPEEDS`]), pausing `pause` s at each end,
    /// with the block removed.
    pub fn free_motion(&self, speeds: &[f64], pause: f64) -> Result<TwinRun> {
        let p = |j: &Jaw| Profile::new(0.0, &free_motion_program(j, speeds, pause), RAMP, PULSE);
        self.run(&p(&self.a)?, &p(&self.b)?, false)
    }

    /// Seed 000's clamping experiments (§3.3) on the block, both jaws alike: from a 120°
    /// opening, `steps = 1` closes continuously to `peak` N and holds `dwell` s (Fig. 7);
    /// `steps > 1` closes to first contact and loads in `steps` equal increments held `dwell` s
    /// each (Figs 8–9; the seed uses 5). See [`clamp_program`].
    pub fn clamp(&self, speed: f64, peak: f64, steps: usize, dwell: f64) -> Result<TwinRun> {
        check::non_negative("peak", peak)?;
        check::non_negative("dwell", dwell)?;
        if steps > 1000 {
            return Err(CableError::InvalidParameter {
                name: "steps".into(),
                value: steps as f64,
                requirement: "at most 1000 load increments",
            });
        }
        let p = |j: &Jaw| {
            Profile::new(
                0.0,
                &clamp_program(j, speed, peak, steps, dwell),
                RAMP,
                PULSE,
            )
        };
        self.run(&p(&self.a)?, &p(&self.b)?, true)
    }
}

/// One classic RK4 step of a jaw from `t0` over `h`, the motor program evaluated per stage.
fn rk4(jaw: &Jaw, prof: &Profile, block: bool, x: &mut [f64; 4], t0: f64, h: f64) {
    let (mut k1, mut k2, mut k3, mut k4) = ([0.0; 4], [0.0; 4], [0.0; 4], [0.0; 4]);
    let at = |t: f64| {
        let (p, v) = prof.at(t);
        [p, v]
    };
    let (u0, um, u1) = (at(t0), at(t0 + 0.5 * h), at(t0 + h));
    let stage = |base: &[f64; 4], k: &[f64; 4], f: f64| {
        std::array::from_fn::<f64, 4, _>(|i| base[i] + f * k[i])
    };
    jaw.derivative_with(x, &u0, block, &mut k1);
    jaw.derivative_with(&stage(x, &k1, 0.5 * h), &um, block, &mut k2);
    jaw.derivative_with(&stage(x, &k2, 0.5 * h), &um, block, &mut k3);
    jaw.derivative_with(&stage(x, &k3, h), &u1, block, &mut k4);
    for i in 0..4 {
        x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
}

/// Seed 000's free-motion program for one jaw (§3.1): from fully open, close over the whole
/// range (0–65°) and open again at each speed in `speeds` (m/s), with a `pause` (s) at each end.
pub fn free_motion_program(jaw: &Jaw, speeds: &[f64], pause: f64) -> Vec<Segment> {
    let far = jaw.motor_at(JAW_RANGE);
    speeds
        .iter()
        .flat_map(|&speed| {
            [
                Segment::Move { to: far, speed },
                Segment::Hold { duration: pause },
                Segment::Move { to: 0.0, speed },
                Segment::Hold { duration: pause },
            ]
        })
        .collect()
}

/// The clamping programs of seed 000 §3.3 for one jaw, from fully open: close to a 120°
/// opening (`θ = 5°`, [`clamp_start`]) and pause 0.5 s, then
///
/// * Continuous clamping (Fig. 7), `steps = 1`: close at `speed` through first contact to the
///   travel that presses `peak` N, hold `dwell` s (the constant-loading region), open back.
/// * Stair loading (Figs 8–9), `steps = 5`: close to first contact, then `steps` equal
///   increments up to `peak` N, each held `dwell` s, then open back.
pub fn clamp_program(jaw: &Jaw, speed: f64, peak: f64, steps: usize, dwell: f64) -> Vec<Segment> {
    let start = clamp_start(jaw);
    let touch = jaw.motor_at(jaw.contact.angle);
    // arrive at the start by closing from fully open, as an instrument does: the friction
    // states are then those of a real approach, not an arbitrary initial condition
    let mut segs = vec![
        Segment::Move { to: start, speed },
        Segment::Hold { duration: 0.5 },
    ];
    if steps <= 1 {
        segs.push(Segment::Move {
            to: touch + jaw.travel_for(peak),
            speed,
        });
        segs.push(Segment::Hold { duration: dwell });
    } else {
        segs.push(Segment::Move { to: touch, speed });
        segs.push(Segment::Hold {
            duration: dwell / 2.0,
        });
        for i in 1..=steps {
            let f = peak * i as f64 / steps as f64;
            segs.push(Segment::Move {
                to: touch + jaw.travel_for(f),
                speed,
            });
            segs.push(Segment::Hold { duration: dwell });
        }
    }
    segs.push(Segment::Move { to: start, speed });
    segs.push(Segment::Hold { duration: 0.5 });
    segs
}

/// Motor position of a jaw at a 120° opening (`θ = 5°`), where the clamping programs start.
pub fn clamp_start(jaw: &Jaw) -> f64 {
    jaw.motor_at(5f64.to_radians())
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // exact positions of a program's ends are the claims under test
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn a_move_covers_its_distance_with_s_curve_ramps() {
        let p = Profile::new(
            1e-3,
            &[Segment::Move {
                to: 3e-3,
                speed: 1e-3,
            }],
            0.02,
            0.0,
        )
        .unwrap();
        assert_relative_eq!(p.duration(), 2.0 + 0.02, max_relative = 1e-12);
        assert_eq!(p.commanded(0.0), (1e-3, 0.0));
        assert_relative_eq!(p.commanded(p.duration()).0, 3e-3, max_relative = 1e-12);
        assert_relative_eq!(p.commanded(1.0).1, 1e-3, max_relative = 1e-12);
        // ramp midpoint: half speed; velocity is the derivative of position
        assert_relative_eq!(p.commanded(0.01).1, 0.5e-3, max_relative = 1e-12);
        for t in [0.005, 0.015, 0.5, 2.005, 2.015] {
            let d = 1e-7;
            let fd = (p.commanded(t + d).0 - p.commanded(t - d).0) / (2.0 * d);
            assert_relative_eq!(fd, p.commanded(t).1, max_relative = 1e-5, epsilon = 1e-9);
        }
    }

    #[test]
    fn positions_are_whole_pulses_and_short_moves_slow_down() {
        let p = Profile::new(
            0.0,
            &[Segment::Move {
                to: 1e-5,
                speed: 1e-3,
            }],
            0.02,
            PULSE,
        )
        .unwrap();
        assert_relative_eq!(p.duration(), 0.04, max_relative = 1e-12);
        for k in 0..40 {
            let x = p.at(k as f64 * 1e-3).0 / PULSE;
            assert!((x - x.round()).abs() < 1e-9);
        }
        assert!(Profile::new(
            0.0,
            &[Segment::Move {
                to: 1.0,
                speed: 0.0
            }],
            0.02,
            0.0
        )
        .is_err());
        assert!(Profile::new(0.0, &[Segment::Hold { duration: f64::NAN }], 0.02, 0.0).is_err());
    }

    #[test]
    fn a_capstan_or_noise_past_the_floating_point_range_is_refused() {
        let mut twin = Twin::seed();
        twin.a.capstan = 1e300;
        let err = twin.validate().unwrap_err();
        assert!(err.to_string().contains("a.capstan"), "{err}");
        let mut twin = Twin::seed();
        twin.noise.tension = 1e308;
        let err = twin.validate().unwrap_err();
        assert!(err.to_string().contains("noise.tension"), "{err}");
        let mut twin = Twin::seed();
        twin.a.capstan = 20.0;
        twin.validate().unwrap();
    }

    #[test]
    fn free_motion_without_block_has_no_external_force_and_capstan_orders_tensions() {
        let mut twin = Twin::seed();
        twin.noise = Noise::NONE;
        let prog = free_motion_program(&twin.a, &[1e-3], 0.2);
        let pa = Profile::new(0.0, &prog, RAMP, PULSE).unwrap();
        let pb = Profile::new(
            0.0,
            &free_motion_program(&twin.b, &[1e-3], 0.2),
            RAMP,
            PULSE,
        )
        .unwrap();
        let run = twin.run(&pa, &pb, false).unwrap();
        assert!(run.external_true.iter().all(|&f| f == 0.0));
        // closing (v > 0): the motor pulls the drive cable over the pulleys, F_A¹ > F_A²
        let k = run.time.iter().position(|&t| t > 1.0).unwrap();
        assert!(run.motors[4 * k + 1] > 0.0);
        assert!(run.tensions[4 * k] > run.tensions[4 * k + 1] + 2.0);
        // the jaw follows the motor less the drive cable's stretch (quasi-static: within 0.5 %)
        let (jt, a) = (&run.joint_tensions[4 * k..4 * k + 2], &twin.a);
        let stretch = (jt[0] - jt[1]) / (2.0 * a.cable_stiffness);
        let th = run.angles[2 * k];
        assert_relative_eq!(
            th,
            (run.motors[4 * k] - stretch) / a.r2,
            max_relative = 5e-3
        );
    }

    #[test]
    fn rest_angle_inverts_motor_at() {
        let j = Jaw::seed_b();
        for th in [0.0, 0.3, 1.1] {
            assert_relative_eq!(j.rest_angle(j.motor_at(th)), th, epsilon = 1e-12);
        }
    }

    #[test]
    fn a_held_clamp_presses_the_pad_with_the_programmed_force() {
        let mut twin = Twin::seed();
        twin.noise = Noise::NONE;
        let run = twin.clamp(1e-3, 1.5, 1, 2.0).unwrap();
        let peak = run
            .external_true
            .chunks(2)
            .map(|r| r[0])
            .fold(0.0, f64::max);
        // friction holds part of the load: within the joint friction's share of the force
        let slack = twin.a.joint_friction.coulomb / twin.a.contact.lever_arm;
        assert!((peak - 1.5).abs() < slack + 0.05, "peak {peak}");
        // torque balance at hold: r2·(T_j1 − T_j2) − spring = l_e·F_c + z (|z| ≤ τ_c)
        let k = run
            .external_true
            .chunks(2)
            .position(|r| r[0] == peak)
            .unwrap();
        let jt = &run.joint_tensions[4 * k..4 * k + 2];
        let a = &twin.a;
        let lhs = a.r2 * (jt[0] - jt[1]) - (a.spring_preload + a.spring * run.angles[2 * k]);
        assert!((lhs - a.contact.lever_arm * peak).abs() <= a.joint_friction.coulomb * 1.01);
    }
}
