//! Antagonistic cable-driven joint (one forceps jaw of seed 000, or a 1-DOF pulley board).
//!
//! A position-driven motor displacement `x_m` (m) pulls the **drive** cable and releases the
//! **return** cable, both wrapped on a joint pulley of radius `r`. Each cable is a
//! [`CableRun`](crate::cable::CableRun) with its own stiffness, damping, pretension and slack.
//!
//! ```text
//! s₁ = x_m − r·θ,        ṡ₁ = ẋ_m − r·θ̇          drive-cable stretch (m)
//! s₂ = r·θ − x_m,        ṡ₂ = r·θ̇ − ẋ_m          return-cable stretch (m)
//! T_j,k = max(0, T₀,k + F_k(s_k) + c_k·ṡ_k)        joint-side tensions (N)
//! J·θ̈ = r·(T_j,1 − T_j,2) − F_f(θ̇) − l_e·F_c      joint dynamics (seed 000 eq. 9)
//! ```
//!
//! **Contact** (optional) with an object at angle `θ_c` through a lever arm `l_e`: penetration
//! `p = l_e·(θ − θ_c)`, force `F_c = max(0, k_c·p + c_c·ṗ)` while `p > 0`, else 0 (N).
//!
//! **Motor-side tensions** (what the sensors at the motors of seed 000 measure) include the
//! capstan losses of the routing pulleys (total wrap `φ`, coefficient `μ`), with the cable
//! hauled in by the motor on the drive side when `ẋ_m > 0`:
//!
//! ```text
//! T_m,1 = T_j,1 · exp(+μφ·σ_ε(ẋ_m)),   T_m,2 = T_j,2 · exp(−μφ·σ_ε(ẋ_m))
//! ```
//!
//! so `F_M = F_T + F_f` of seed 000 eq. (4) with losses `F_f = T_m − T_j`. The routing friction
//! is lumped at the motor end: it changes the measured tensions, not the joint dynamics.
//!
//! **Optional hysteresis and creep** (both off by default):
//! * Dahl joint friction ([`Dahl`], seed 002 eq. 8): a friction torque state `z` (N·m) adds
//!   `−z` to the joint equation, `ż = σ₀·|1 − z/F_d·sgn θ̇|ⁿ·sgn(·)·θ̇`.
//! * Cable creep ([`Creep`]): one relaxation state `w_k` (N) per cable,
//!   `T_j,k = max(0, T₀,k + F_k(s_k) + c_k·ṡ_k − w_k)`, `ẇ_k = (κ·F_k(s_k) − w_k)/τ`.
//!
//! State `x = [θ, θ̇, (z), (w₁, w₂)]` (rad, rad/s, N·m, N, N — the bracketed states exist only
//! when the effect is on); input `u = [x_m, ẋ_m]` (m, m/s); outputs
//! `y = [T_m,1, T_m,2, T_j,1, T_j,2, θ, F_c]` (N, N, N, N, rad, N). Use first-order input hold
//! (`InputHold::Foh`) when `x_m` is a sampled position so that `x_m` and `ẋ_m` stay consistent
//! inside a sample interval.

use super::Model;
use crate::cable::{CableLaw, CableRun, Creep};
use crate::error::{check, Result};
use crate::friction::{smooth_sign, Dahl, StaticFriction};

/// Output names of an antagonistic joint (and of the forceps twin's jaw), in layout order.
pub const OUTPUT_NAMES: [&str; 6] = [
    "tension_motor_drive",
    "tension_motor_return",
    "tension_joint_drive",
    "tension_joint_return",
    "theta",
    "contact_force",
];

/// Contact with an object (jaw clamping, tissue) at a fixed angle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Joint angle where contact starts `θ_c` (rad); contact for `θ > θ_c`.
    pub angle: f64,
    /// Contact stiffness `k_c` (N/m), > 0.
    pub stiffness: f64,
    /// Contact damping `c_c` (N·s/m), ≥ 0 (no pull: force clamped at 0).
    pub damping: f64,
    /// Lever arm `l_e` from the joint axis to the contact point (m), > 0.
    pub lever_arm: f64,
}

impl Contact {
    /// Validated constructor.
    pub fn new(angle: f64, stiffness: f64, damping: f64, lever_arm: f64) -> Result<Self> {
        Ok(Self {
            angle: check::finite("contact.angle", angle)?,
            stiffness: check::positive("contact.stiffness", stiffness)?,
            damping: check::non_negative("contact.damping", damping)?,
            lever_arm: check::positive("contact.lever_arm", lever_arm)?,
        })
    }

    /// Contact force (N) at joint angle `theta` and rate `omega`.
    #[inline]
    pub fn force(&self, theta: f64, omega: f64) -> f64 {
        let p = self.lever_arm * (theta - self.angle);
        if p > 0.0 {
            (self.stiffness * p + self.damping * self.lever_arm * omega).max(0.0)
        } else {
            0.0
        }
    }
}

/// The antagonistic joint; see the module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AntagonisticJoint {
    /// Joint pulley radius `r` (m).
    pub radius: f64,
    /// Drive cable (pulled by positive `x_m`).
    pub drive: CableRun,
    /// Return cable (released by positive `x_m`).
    pub ret: CableRun,
    /// Joint inertia `J` (kg·m²).
    pub inertia: f64,
    /// Joint friction (viscous `b`, Coulomb `F_c`, optional Stribeck), N·m.
    pub friction: StaticFriction,
    /// Capstan friction coefficient `μ` of the routing pulleys, ≥ 0.
    pub capstan_mu: f64,
    /// Total wrap angle `φ` of the routing pulleys (rad), ≥ 0.
    pub capstan_wrap: f64,
    /// Smoothing velocity of the capstan sign (m/s), > 0.
    pub capstan_smoothing: f64,
    /// Optional contact.
    pub contact: Option<Contact>,
    /// Optional Dahl (hysteretic) joint friction, in addition to `friction`.
    pub dahl: Option<Dahl>,
    /// Optional creep of both cables.
    pub creep: Option<Creep>,
}

impl AntagonisticJoint {
    /// Validated constructor.
    pub fn new(
        radius: f64,
        drive: CableRun,
        ret: CableRun,
        inertia: f64,
        friction: StaticFriction,
        capstan_mu: f64,
        capstan_wrap: f64,
        capstan_smoothing: f64,
        contact: Option<Contact>,
    ) -> Result<Self> {
        drive.validate("drive")?;
        ret.validate("return")?;
        friction.validate("friction")?;
        Ok(Self {
            radius: check::positive("radius", radius)?,
            drive,
            ret,
            inertia: check::positive("inertia", inertia)?,
            friction,
            capstan_mu: check::non_negative("capstan_mu", capstan_mu)?,
            capstan_wrap: check::non_negative("capstan_wrap", capstan_wrap)?,
            capstan_smoothing: check::positive("capstan_smoothing", capstan_smoothing)?,
            contact,
            dahl: None,
            creep: None,
        })
    }

    /// The same joint with Dahl joint friction (validated).
    pub fn with_dahl(mut self, dahl: Option<Dahl>) -> Result<Self> {
        if let Some(d) = dahl {
            Dahl::new(d.sigma0, d.coulomb, d.exponent)?;
        }
        self.dahl = dahl;
        Ok(self)
    }

    /// The same joint with cable creep (validated).
    pub fn with_creep(mut self, creep: Option<Creep>) -> Result<Self> {
        if let Some(c) = creep {
            Creep::new(c.fraction, c.time_constant)?;
        }
        self.creep = creep;
        Ok(self)
    }

    /// Index of the Dahl state, if any.
    fn dahl_index(&self) -> Option<usize> {
        self.dahl.map(|_| 2)
    }

    /// Index of the first creep state, if any.
    fn creep_index(&self) -> Option<usize> {
        self.creep.map(|_| 2 + usize::from(self.dahl.is_some()))
    }

    /// An EndoWrist-like forceps jaw (seed 000): 0.45 mm steel rope of 0.5 m
    /// (`E·A ≈ 15.9 kN` with a rope modulus of 100 GPa, so `k ≈ 31.8 kN/m`), 2.5 mm pulley
    /// (8 mm wrist), 10 N pretension (sensor range 0–50 N), `μ = 0.05` over `2π` of routing wrap,
    /// and a contact at 0.3 rad through a 10 mm lever arm with 2 kN/m. Illustrative values.
    pub fn forceps_example() -> Self {
        let cable = CableRun {
            law: CableLaw::Linear { stiffness: 31.8e3 },
            damping: 20.0,
            pretension: 10.0,
        };
        AntagonisticJoint {
            radius: 2.5e-3,
            drive: cable,
            ret: cable,
            inertia: 1e-6,
            friction: StaticFriction {
                coulomb: 2e-3,
                static_level: 2e-3,
                stribeck_velocity: 1.0,
                stribeck_exponent: 2.0,
                viscous: 1e-4,
                smoothing: 0.05,
            },
            capstan_mu: 0.05,
            capstan_wrap: std::f64::consts::TAU,
            capstan_smoothing: 1e-3,
            contact: Some(Contact {
                angle: 0.3,
                stiffness: 2e3,
                damping: 1.0,
                lever_arm: 10e-3,
            }),
            dahl: None,
            creep: None,
        }
    }

    /// Drive-cable stretch and rate `(s₁, ṡ₁)`; the return cable sees `(−s₁, −ṡ₁)`.
    #[inline]
    fn stretch(&self, x: &[f64], u: &[f64]) -> (f64, f64) {
        (u[0] - self.radius * x[0], u[1] - self.radius * x[1])
    }

    /// Joint-side tensions `(T_j,1, T_j,2)`.
    #[inline]
    fn joint_tensions(&self, x: &[f64], u: &[f64]) -> (f64, f64) {
        let (s1, sd1) = self.stretch(x, u);
        let (w1, w2) = self.creep_index().map_or((0.0, 0.0), |k| (x[k], x[k + 1]));
        (
            self.drive.relaxed_tension(s1, sd1, w1),
            self.ret.relaxed_tension(-s1, -sd1, w2),
        )
    }

    #[inline]
    fn contact_force(&self, x: &[f64]) -> f64 {
        self.contact.map_or(0.0, |c| c.force(x[0], x[1]))
    }
}

impl Model for AntagonisticJoint {
    fn n_states(&self) -> usize {
        2 + usize::from(self.dahl.is_some()) + 2 * usize::from(self.creep.is_some())
    }
    fn n_inputs(&self) -> usize {
        2
    }
    fn n_outputs(&self) -> usize {
        6
    }

    fn derivative(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
        let (t1, t2) = self.joint_tensions(x, u);
        let lever = self.contact.map_or(0.0, |c| c.lever_arm);
        let mut torque =
            self.radius * (t1 - t2) - self.friction.force(x[1]) - lever * self.contact_force(x);
        if let (Some(d), Some(k)) = (self.dahl, self.dahl_index()) {
            torque -= x[k];
            dx[k] = d.rate(x[k], x[1]);
        }
        if let (Some(c), Some(k)) = (self.creep, self.creep_index()) {
            let (s1, _) = self.stretch(x, u);
            dx[k] = c.rate(x[k], self.drive.law.elastic(s1));
            dx[k + 1] = c.rate(x[k + 1], self.ret.law.elastic(-s1));
        }
        dx[0] = x[1];
        dx[1] = torque / self.inertia;
    }

    fn output(&self, x: &[f64], u: &[f64], y: &mut [f64]) {
        let (t1, t2) = self.joint_tensions(x, u);
        let a = self.capstan_mu * self.capstan_wrap * smooth_sign(u[1], self.capstan_smoothing);
        y[0] = t1 * a.exp();
        y[1] = t2 * (-a).exp();
        y[2] = t1;
        y[3] = t2;
        y[4] = x[0];
        y[5] = self.contact_force(x);
    }

    fn state_names(&self) -> Vec<String> {
        let mut names = vec!["theta".to_owned(), "dtheta".to_owned()];
        if self.dahl.is_some() {
            names.push("dahl_torque".into());
        }
        if self.creep.is_some() {
            names.extend(["creep_drive".into(), "creep_return".into()]);
        }
        names
    }
    fn input_names(&self) -> Vec<String> {
        vec!["x_m".into(), "dx_m".into()]
    }
    fn output_names(&self) -> Vec<String> {
        OUTPUT_NAMES.map(String::from).to_vec()
    }
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // exact zeros are the claims under test (slack, no contact)
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn static_equilibrium_tensions_are_pretension_plus_minus_k_stretch() {
        let mut j = AntagonisticJoint::forceps_example();
        j.contact = None;
        j.friction = StaticFriction::NONE;
        // at equilibrium r·(T1 − T2) = 0 → θ = x_m / r for identical cables
        let x = [0.1, 0.0];
        let u = [0.1 * j.radius + 1e-5, 0.0];
        let mut y = [0.0; 6];
        j.output(&x, &u, &mut y);
        assert_relative_eq!(y[2], 10.0 + 31.8e3 * 1e-5, max_relative = 1e-12);
        assert_relative_eq!(y[3], 10.0 - 31.8e3 * 1e-5, max_relative = 1e-12);
    }

    #[test]
    fn contact_pushes_back_only_when_penetrating() {
        let c = Contact::new(0.3, 2e3, 1.0, 0.01).unwrap();
        assert_eq!(c.force(0.29, 1.0), 0.0);
        assert_relative_eq!(c.force(0.31, 0.0), 2e3 * 0.01 * 0.01, max_relative = 1e-12);
        assert_eq!(c.force(0.3001, -100.0), 0.0);
    }

    #[test]
    fn creep_relaxes_a_held_stretch_by_its_fraction() {
        let mut j = AntagonisticJoint::forceps_example();
        j.contact = None;
        let j = j.with_creep(Some(Creep::new(0.3, 0.5).unwrap())).unwrap();
        assert_eq!(j.n_states(), 4);
        // joint held (huge inertia), motor pulled by 0.1 mm: drive tension relaxes to
        // T0 + 0.7·k·s with time constant 0.5 s (10 s = 20 τ)
        let mut held = j;
        held.inertia = 1e12;
        let u = [1e-4, 0.0];
        let opts =
            crate::integrate::SimOptions::new(1e-3, 1, crate::integrate::InputHold::Zoh).unwrap();
        let u = [u[0], u[1]].repeat(10_000);
        let tr = crate::integrate::simulate(&held, &u, &[0.0; 4], &opts).unwrap();
        let last = &tr.outputs[tr.outputs.len() - 6..];
        assert_relative_eq!(last[2], 10.0 + 0.7 * 31.8e3 * 1e-4, max_relative = 1e-6);
        assert_relative_eq!(last[3], 10.0 - 0.7 * 31.8e3 * 1e-4, max_relative = 1e-6);
        assert!(Creep::new(1.0, 0.5).is_err());
        assert!(Creep::new(0.2, 0.0).is_err());
    }

    #[test]
    fn dahl_torque_saturates_and_opposes_motion() {
        let mut j = AntagonisticJoint::forceps_example();
        j.contact = None;
        let j = j
            .with_dahl(Some(Dahl::new(5.0, 1e-3, 1.0).unwrap()))
            .unwrap();
        assert_eq!(j.n_states(), 3);
        let mut dx = [0.0; 3];
        // moving forward with z at the Coulomb level: no further growth
        j.derivative(&[0.0, 1.0, 1e-3], &[0.0, 0.0], &mut dx);
        assert_eq!(dx[2], 0.0);
        // z opposes motion: with zero cable torque the acceleration is −(friction + z)/J
        j.derivative(&[0.0, 0.0, 1e-3], &[0.0, 0.0], &mut dx);
        assert_relative_eq!(dx[1], -1e-3 / j.inertia, max_relative = 1e-12);
        assert!(j
            .with_dahl(Some(Dahl {
                sigma0: -1.0,
                coulomb: 1.0,
                exponent: 1.0
            }))
            .is_err());
    }
}
