//! Seed 003's winch as a nonlinear model (§3.2, eqs 11–20): the PID position loop with the
//! derivative's low-pass filter and the servo amplifier's current limit, the DC motor, gearbox
//! and drum with viscous and static (Coulomb) friction, and the elastic driven cable to the
//! end-effector (EE) mass held by an antagonistic cable. Its linearisation is
//! [`crate::cdpr::winch`] (eq. 26).
//!
//! ```text
//! e = α_ref − α,   ė = α̇_ref − α̇
//! PID + LPF (eq. 13):  i_cmd = K_p·(e + D + z/t_i),  Ḋ = ω_c·(t_d·ė − D),  ż = e
//! PID (eq. 12):        i_cmd = K_p·(e + t_d·ė + z/t_i)                (D stays 0)
//! i_a = clamp(i_cmd, ±I_max); ż = 0 while saturated and e pushes further (conditional
//! integration, anti-windup)
//! J_l·α̈ = k_φ·r_gb·i_a − B_l·α̇ − τ_st·σ_ε(α̇) − r·T_A                       (eqs 16–19)
//! m_E·ẍ_E = T_B − T_A
//! T_A = max(0, T₀ + K_A·(x_E + r·α) + c·(ẋ_E + r·α̇))                     (eq. 20)
//! T_B = max(0, T₀ − K_B·(x_E + s·r·α) − c·(ẋ_E + s·r·α̇))
//!     s = 0: antagonist fixed (Setup 1);  s = 1: its drum turns with −α (Setup 2)
//! ```
//!
//! `x_E` is measured from the working point where both cables hold the pretension `T₀` at
//! `α = 0` (the seed's `ε_A`, `ε_B` of eq. 20 folded into `T₀`); positive `α` and `i_a` tension
//! the driven cable. At rest there ([`Model::rest_state`], the default initial state) the
//! integral holds the current `i₀ = r·T₀/(k_φ·r_gb)` that carries the pretension: the seed's
//! "increments over `I_fr`" start from this equilibrium. `σ_ε(v) = v/√(v² + ε²)` smooths the sign of eq. 18. Cables cannot push.
//! The seed's cables are undamped (`c = 0`, its default here): the EE's cable mode then decays
//! only through the drum's viscous friction, over minutes.
//!
//! **Setup 2.** Here the antagonist's drum follows `−α` exactly and carries only its own cable:
//! the driven drum feels `K_A`. The seed's eq. 27 instead lumps both cables on one drum
//! (`K_A ← K_A + K_B`, `K_B ← 0`); that is this model's Setup 1 with those stiffnesses.
//!
//! **Current control** ([`Control::Current`], the seed's Fig. 18 experiment): the amplifier
//! follows a current reference `u = [i_ref]` (A, within `±I_max`) and the PID is bypassed (`z`
//! and `D` stay put).
//!
//! State `x = [α, α̇, x_E, ẋ_E, z, D]` (rad, rad/s, m, m/s, rad·s, rad); input
//! `u = [α_ref, α̇_ref]` (rad, rad/s) under position control; outputs `y = [α, T_A, T_B, x_E, i_a, T̂]` (rad, N, N, m,
//! A, N) with the motor-current tension estimate `T̂ = k_φ·r_gb·i_a/r` (eqs 34–35).

use super::Model;
use crate::cdpr::winch::{Setup, Winch};
use crate::error::{check, Result};
use crate::friction::smooth_sign;

/// State names of a [`WinchDrive`], in layout order.
pub const WINCH_STATE_NAMES: [&str; 6] = [
    "alpha",
    "alpha_dot",
    "x_ee",
    "x_ee_dot",
    "error_integral",
    "derivative_filtered",
];
/// Input names of a [`WinchDrive`].
pub const WINCH_INPUT_NAMES: [&str; 2] = ["alpha_ref", "alpha_ref_dot"];
/// Input name of a [`WinchDrive`] under [`Control::Current`].
pub const WINCH_CURRENT_INPUT: &str = "current_ref";

/// What the servo amplifier follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Control {
    /// The PID position loop sets the current (the seed's §3).
    #[default]
    Position,
    /// A current reference, the PID bypassed (the seed's Fig. 18 experiment).
    Current,
}

impl Control {
    /// From its name (`"position"`, `"current"`).
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "position" => Ok(Self::Position),
            "current" => Ok(Self::Current),
            other => Err(crate::error::CableError::InvalidOption {
                name: "control".into(),
                value: other.into(),
                allowed: "position, current".into(),
            }),
        }
    }

    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Position => "position",
            Self::Current => "current",
        }
    }
}
/// Output names of a [`WinchDrive`].
pub const WINCH_OUTPUT_NAMES: [&str; 6] = [
    "alpha",
    "tension_a",
    "tension_b",
    "x_ee",
    "current",
    "tension_from_current",
];

/// Seed 003's winch, cable, EE and controller as a nonlinear model; see the module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WinchDrive {
    /// Motor, gearbox, drum, cables, EE mass and PID gains (SI, see [`Winch`]).
    pub winch: Winch,
    /// Which of seed 003's setups (Fig. 6).
    pub setup: Setup,
    /// The derivative term through the low-pass filter (eq. 13) or not (eq. 12).
    pub lpf: bool,
    /// Tension of both cables at the working point `T₀` (N), ≥ 0.
    pub pretension: f64,
    /// Servo amplifier's current limit `I_max` (A), > 0.
    pub current_limit: f64,
    /// Smoothing velocity `ε` of the static friction's sign (rad/s), > 0.
    pub friction_smoothing: f64,
    /// Damping of each cable `c` (N·s/m), ≥ 0; the seed has none.
    pub cable_damping: f64,
    /// What the amplifier follows (position loop by default).
    pub control: Control,
}

impl WinchDrive {
    /// Validated constructor.
    pub fn new(
        winch: Winch,
        setup: Setup,
        lpf: bool,
        pretension: f64,
        current_limit: f64,
        friction_smoothing: f64,
        cable_damping: f64,
    ) -> Result<Self> {
        let w = Self {
            winch,
            setup,
            lpf,
            pretension,
            current_limit,
            friction_smoothing,
            cable_damping,
            control: Control::Position,
        };
        w.validate()?;
        Ok(w)
    }

    /// Seed 003's winch ([`Winch::seed003`]) in Setup 1 with the LPF; choices the seed does not
    /// print: `T₀ = 20 N`, `I_max = 10 A` (the ESCON 70/10's continuous current), `ε = 0.01
    /// rad/s`.
    pub fn seed003() -> Self {
        Self {
            winch: Winch::seed003(),
            setup: Setup::AntagonistFixed,
            lpf: true,
            pretension: 20.0,
            current_limit: 10.0,
            friction_smoothing: 0.01,
            cable_damping: 0.0,
            control: Control::Position,
        }
    }

    /// The same winch under `control`.
    pub fn with_control(self, control: Control) -> Self {
        Self { control, ..self }
    }

    /// Every parameter finite and in range.
    pub fn validate(&self) -> Result<()> {
        self.winch.validate()?;
        check::non_negative("pretension", self.pretension)?;
        check::positive("current_limit", self.current_limit)?;
        check::positive("friction_smoothing", self.friction_smoothing)?;
        check::non_negative("cable_damping", self.cable_damping)?;
        Ok(())
    }

    /// Cable tensions `(T_A, T_B)` (N) at the state `x`.
    #[inline]
    pub fn tensions(&self, x: &[f64]) -> (f64, f64) {
        let w = &self.winch;
        let r = w.drum_radius;
        let s = match self.setup {
            Setup::AntagonistFixed => 0.0,
            Setup::Synchronized => 1.0,
        };
        let c = self.cable_damping;
        let stretch_a = w.stiffness_a * (x[2] + r * x[0]) + c * (x[3] + r * x[1]);
        let stretch_b = w.stiffness_b * (x[2] + s * r * x[0]) + c * (x[3] + s * r * x[1]);
        (
            (self.pretension + stretch_a).max(0.0),
            (self.pretension - stretch_b).max(0.0),
        )
    }

    /// The controller's command and the current after the limit `(i_cmd, i_a)` (A).
    #[inline]
    pub fn current(&self, x: &[f64], u: &[f64]) -> (f64, f64) {
        let w = &self.winch;
        if self.control == Control::Current {
            return (u[0], u[0].clamp(-self.current_limit, self.current_limit));
        }
        let e = u[0] - x[0];
        let derivative = if self.lpf { x[5] } else { w.td * (u[1] - x[1]) };
        let cmd = w.kp * (e + derivative + x[4] / w.ti);
        (cmd, cmd.clamp(-self.current_limit, self.current_limit))
    }

    /// The drum angle `α` (rad) at which the working point's tension `T₀` rises to `tension` in
    /// the driven cable with the EE held still: `(T − T₀)/(K_A·r)`.
    pub fn angle_for_tension(&self, tension: f64) -> f64 {
        (tension - self.pretension) / (self.winch.stiffness_a * self.winch.drum_radius)
    }
}

impl Model for WinchDrive {
    fn n_states(&self) -> usize {
        6
    }
    fn n_inputs(&self) -> usize {
        match self.control {
            Control::Position => 2,
            Control::Current => 1,
        }
    }
    fn n_outputs(&self) -> usize {
        6
    }

    fn derivative(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
        let w = &self.winch;
        let (alpha, omega, v_ee) = (x[0], x[1], x[3]);
        let (t_a, t_b) = self.tensions(x);
        let (cmd, i) = self.current(x, u);
        let e = u[0] - alpha;
        let torque = w.torque_constant * w.gear_ratio * i
            - w.load_viscous() * omega
            - w.static_friction * smooth_sign(omega, self.friction_smoothing)
            - w.drum_radius * t_a;
        dx[0] = omega;
        dx[1] = torque / w.load_inertia();
        dx[2] = v_ee;
        dx[3] = (t_b - t_a) / w.ee_mass;
        if self.control == Control::Current {
            dx[4] = 0.0;
            dx[5] = 0.0;
            return;
        }
        // conditional integration: hold the integral while saturated and `e` pushes further
        let winding = cmd.abs() > self.current_limit && w.kp * e * cmd > 0.0;
        dx[4] = if winding { 0.0 } else { e };
        dx[5] = if self.lpf {
            w.cutoff * (w.td * (u[1] - omega) - x[5])
        } else {
            0.0
        };
    }

    fn output(&self, x: &[f64], u: &[f64], y: &mut [f64]) {
        let w = &self.winch;
        let (t_a, t_b) = self.tensions(x);
        let (_, i) = self.current(x, u);
        y[0] = x[0];
        y[1] = t_a;
        y[2] = t_b;
        y[3] = x[2];
        y[4] = i;
        y[5] = w.torque_constant * w.gear_ratio * i / w.drum_radius;
    }

    /// The working point at rest: `α = 0`, `x_E = 0`, the integral holding `i₀` (within the
    /// current limit; zero when `K_p = 0`, which has no such equilibrium, and under current
    /// control, where the held current is the input's).
    fn rest_state(&self) -> Vec<f64> {
        let w = &self.winch;
        let hold = (w.drum_radius * self.pretension / (w.torque_constant * w.gear_ratio))
            .min(self.current_limit);
        let z = if w.kp.abs() > 0.0 && self.control == Control::Position {
            hold * w.ti / w.kp
        } else {
            0.0
        };
        vec![0.0, 0.0, 0.0, 0.0, z, 0.0]
    }

    fn state_names(&self) -> Vec<String> {
        WINCH_STATE_NAMES.iter().map(|s| (*s).to_owned()).collect()
    }
    fn input_names(&self) -> Vec<String> {
        match self.control {
            Control::Position => WINCH_INPUT_NAMES.iter().map(|s| (*s).to_owned()).collect(),
            Control::Current => vec![WINCH_CURRENT_INPUT.to_owned()],
        }
    }
    fn output_names(&self) -> Vec<String> {
        WINCH_OUTPUT_NAMES.iter().map(|s| (*s).to_owned()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrate::{jacobian_rows, rk4_interval};
    use nalgebra::DMatrix;

    /// Eigenvalues of the model's Jacobian at rest, sorted by (re, im).
    fn eigenvalues(model: &WinchDrive) -> Vec<(f64, f64)> {
        let rows = jacobian_rows(model, &[0.0; 6], &[0.0; 2]).unwrap();
        let j = DMatrix::from_row_slice(6, 6, &rows);
        let mut ev: Vec<(f64, f64)> = j
            .complex_eigenvalues()
            .iter()
            .map(|c| (c.re, c.im))
            .collect();
        ev.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        ev
    }

    fn sorted(mut v: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
        v.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        v
    }

    /// Without static friction and away from the current limit, the model's small-signal
    /// dynamics are eq. 26 closed by the PID: the Jacobian's eigenvalues are the closed-loop
    /// poles of the linear analysis (both PIDs, three gains; Setup 2 as the seed lumps it is
    /// Setup 1 with `K_A + K_B`, `K_B = 0`).
    #[test]
    fn linearised_model_has_the_closed_loop_poles_of_eq_26() {
        for lpf in [true, false] {
            for kp in [2.0, 6.0, 15.0] {
                for lumped in [false, true] {
                    let mut w = Winch::seed003();
                    w.static_friction = 0.0;
                    w.kp = kp;
                    let setup = if lumped {
                        Setup::Synchronized
                    } else {
                        Setup::AntagonistFixed
                    };
                    let want = sorted(w.closed_loop_poles(setup, lpf, kp).unwrap());
                    if lumped {
                        w.stiffness_a += w.stiffness_b;
                        w.stiffness_b = 0.0;
                    }
                    let model =
                        WinchDrive::new(w, Setup::AntagonistFixed, lpf, 20.0, 10.0, 0.01, 0.0)
                            .unwrap();
                    let mut got = eigenvalues(&model);
                    if !lpf {
                        // D is unused without the LPF: one extra eigenvalue at 0
                        let k = got
                            .iter()
                            .position(|p| p.0.abs() < 1e-6 && p.1.abs() < 1e-6)
                            .unwrap();
                        got.remove(k);
                    }
                    assert_eq!(got.len(), want.len());
                    for (g, p) in got.iter().zip(&want) {
                        let scale = 1.0 + p.0.hypot(p.1);
                        assert!(
                            (g.0 - p.0).abs() < 1e-4 * scale && (g.1 - p.1).abs() < 1e-4 * scale,
                            "lpf {lpf} kp {kp} lumped {lumped}: {got:?} vs {want:?}"
                        );
                    }
                }
            }
        }
    }

    /// Physical Setup 2: the EE follows the drum (`x_E → −r·α`) so the driven drum feels
    /// `K_A·m_E·s²/(m_E·s² + K_A + K_B)`: at low frequency no stiffness at all. A held angle
    /// then costs no tension, where Setup 1 stretches both cables. (Damped cables, so that
    /// the EE's cable mode settles.)
    #[test]
    fn synchronized_antagonist_lets_the_ee_follow_the_drum() {
        let mut fixed = WinchDrive::seed003();
        fixed.winch.static_friction = 0.0;
        fixed.cable_damping = 50.0;
        let sync = WinchDrive {
            setup: Setup::Synchronized,
            ..fixed
        };
        let target = 0.02; // rad: 0.5 mm of cable
                           // a smoothstep over 1 s: the undamped cable mode is barely excited
        let reference = |t: f64| {
            let s = t.min(1.0);
            [
                target * s * s * (3.0 - 2.0 * s),
                target * 6.0 * s * (1.0 - s),
            ]
        };
        let (mut a, mut b) = (fixed.rest_state(), sync.rest_state());
        for k in 0..10_000 {
            let (u0, u1) = (reference(k as f64 * 1e-3), reference((k + 1) as f64 * 1e-3));
            a = rk4_interval(&fixed, &a, &u0, &u1, 1e-3, 20).unwrap();
            b = rk4_interval(&sync, &b, &u0, &u1, 1e-3, 20).unwrap();
        }
        let r = fixed.winch.drum_radius;
        for x in [&a, &b] {
            // (the integral's slow closed-loop pole, about -0.5/s, is still closing the gap)
            assert!((x[0] - target).abs() < 0.02 * target, "{x:?}");
        }
        // Setup 1: the EE settles between the two springs, T_A = T_B above T₀
        let ka = fixed.winch.stiffness_a;
        let kb = fixed.winch.stiffness_b;
        let x_e = -ka * r * a[0] / (ka + kb);
        assert!((a[2] - x_e).abs() < 1e-3 * x_e.abs(), "{} vs {x_e}", a[2]);
        let (ta, tb) = fixed.tensions(&a);
        assert!((ta - tb).abs() < 1e-3 && ta > 20.0 + 3.0, "{ta} {tb}");
        // Setup 2: the EE moves with the cable, both tensions stay at T₀
        assert!(
            (b[2] + r * b[0]).abs() < 1e-3 * r * target,
            "{} vs {}",
            b[2],
            -r * b[0]
        );
        let (ta, tb) = sync.tensions(&b);
        assert!(
            (ta - 20.0).abs() < 0.05 && (tb - 20.0).abs() < 0.05,
            "{ta} {tb}"
        );
    }

    /// The current limit holds, the integral stops winding up while it does, and the motor
    /// current's tension estimate equals the cable tension at a static hold without friction
    /// and is off by `τ_st/r` with it (the seed's Fig. 18 point).
    #[test]
    fn current_limit_anti_windup_and_the_current_tension_estimate() {
        let m = WinchDrive::seed003();
        let big = 5.0; // rad: far beyond what 10 A moves at once
        let rest = m.rest_state();
        let mut x = rest.clone();
        let (mut peak, mut y) = (0.0_f64, [0.0; 6]);
        for _ in 0..200 {
            x = rk4_interval(&m, &x, &[big, 0.0], &[big, 0.0], 1e-3, 20).unwrap();
            m.output(&x, &[big, 0.0], &mut y);
            peak = peak.max(y[4].abs());
        }
        assert!((peak - m.current_limit).abs() < 1e-12, "{peak}");
        // saturated all along with e > 0: the integral never grew
        assert_eq!(x[4].to_bits(), rest[4].to_bits());
        // a static hold: the integral carries the tension; without friction T̂ = T_A
        let mut still = m;
        still.winch.static_friction = 0.0;
        let target = still.angle_for_tension(40.0) * 2.0; // Setup 1 shares the stretch
        let mut x = still.rest_state();
        for _ in 0..6000 {
            x = rk4_interval(&still, &x, &[target, 0.0], &[target, 0.0], 1e-3, 20).unwrap();
        }
        still.output(&x, &[target, 0.0], &mut y);
        assert!((y[1] - 40.0).abs() < 0.05, "{y:?}");
        assert!((y[5] - y[1]).abs() < 1e-3 * y[1], "{y:?}");
    }

    /// Under current control with a sharp static friction, a slow current ramp up and back
    /// down leaves the tension `(k_φ·r_gb·i ∓ τ_st)/r`: the motor-current estimate reads high
    /// by `τ_st/r` while loading and low by as much while unloading (the seed's Fig. 18).
    #[test]
    fn current_control_shows_the_static_friction_hysteresis_of_the_current_estimate() {
        let mut m = WinchDrive::seed003().with_control(Control::Current);
        m.friction_smoothing = 1e-4;
        m.cable_damping = 20.0;
        let w = m.winch;
        let band = w.static_friction / w.drum_radius;
        let mut x = vec![0.0; 6];
        let mut y = [0.0; 6];
        // ramps (2 s each, then 0.5 s held): 0 → 1.3 A loading, 1.3 → 0.9 A unloading; the
        // estimate is then off by the whole band either way
        let mut level = 0.0;
        for (target, loading) in [(1.3, true), (0.9, false)] {
            for k in 0..2500 {
                // (a smoothstep: the drum stops without momentum to carry it into the band)
                let at = |k: usize| {
                    let s = (k as f64 / 2000.0).min(1.0);
                    level + (target - level) * s * s * (3.0 - 2.0 * s)
                };
                x = rk4_interval(&m, &x, &[at(k)], &[at(k + 1)], 1e-3, 100).unwrap();
            }
            level = target;
            m.output(&x, &[target], &mut y);
            let want = if loading { y[5] - band } else { y[5] + band };
            assert!(
                (y[1] - want).abs() < 0.05 * band,
                "{target} {loading}: {y:?} band {band}"
            );
        }
        let mut dx = [0.0; 6];
        m.derivative(&x, &[0.9], &mut dx);
        assert!(dx[4].abs() < 1e-300 && dx[5].abs() < 1e-300);
        assert_eq!(m.input_names(), vec!["current_ref".to_owned()]);
    }

    /// The rest state is an equilibrium: the integral's current carries the pretension.
    #[test]
    fn rest_state_is_the_working_point_equilibrium() {
        for setup in [Setup::AntagonistFixed, Setup::Synchronized] {
            let m = WinchDrive {
                setup,
                ..WinchDrive::seed003()
            };
            let x = m.rest_state();
            let mut dx = [0.0; 6];
            m.derivative(&x, &[0.0, 0.0], &mut dx);
            assert!(dx.iter().all(|v| v.abs() < 1e-12), "{dx:?}");
            let mut y = [0.0; 6];
            m.output(&x, &[0.0, 0.0], &mut y);
            assert!(
                (y[1] - 20.0).abs() < 1e-12 && (y[5] - 20.0).abs() < 1e-9,
                "{y:?}"
            );
        }
    }

    #[test]
    fn bad_parameters_are_typed_errors() {
        let w = Winch::seed003();
        for (t0, imax, eps) in [
            (-1.0, 10.0, 0.01),
            (20.0, 0.0, 0.01),
            (20.0, 10.0, f64::NAN),
            (f64::INFINITY, 10.0, 0.01),
        ] {
            assert!(WinchDrive::new(w, Setup::AntagonistFixed, true, t0, imax, eps, 0.0).is_err());
        }
        let mut bad = w;
        bad.ee_mass = -0.1;
        assert!(WinchDrive::new(bad, Setup::AntagonistFixed, true, 20.0, 10.0, 0.01, 0.0).is_err());
        assert!(WinchDrive::new(w, Setup::AntagonistFixed, true, 20.0, 10.0, 0.01, -1.0).is_err());
    }
}
