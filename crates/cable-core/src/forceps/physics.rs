//! A physics-informed clamping-force estimator (issue #22 §2): the JTDO with the free-motion
//! network replaced by the tension losses of the cable–pulley routing, a handful of
//! interpretable parameters per forceps identified from **one** calibration run.
//!
//! Per forceps, from the motor motion `(x_m, ẋ_m)` and the two motor-side tensions
//! `(T_m,1, T_m,2)` only:
//!
//! ```text
//! σ_c ← sgn(Δx)·(1 − (1 − σ_c·sgn Δx)·e^{−|Δx|/δ_c})       capstan direction (exact for a step Δx)
//! σ_j ← the same with δ_j                                    joint-friction direction
//! T̂_j,1 = (T_m,1 − c_p·ẋ_m)·e^{−μφ·σ_c},  T̂_j,2 = (T_m,2 + c_p·ẋ_m)·e^{+μφ·σ_c}
//! θ̂ = (x_m − ½·c·(T̂_j,1 − T̂_j,2)) / r₂                           jaw angle, cable stretch removed
//! τ̂_ext = r₂·(T̂_j,1 − T̂_j,2) − τ_c·σ_j − b·ẋ_m/r₂ − k_s·θ̂ − τ₀   seed 000 eq. 9, inertia neglected
//! F̂_ext = τ̂_ext / l_e,   F̂_CF = ½(|F̂_ext^A| + |F̂_ext^B|)      eqs 16–17
//! ```
//!
//! The direction states are rate-independent (they move with the motor's travel, not with
//! time), so a held cable keeps the friction it had — the hysteresis of a capstan and of a
//! stuck joint. Pretension does not appear: the estimator works on the measured tensions, so
//! an instrument whose cables are tighter needs no parameter for it; the cable compliance
//! enters only through the jaw angle under load.
//!
//! Identifiability: on a free-motion run (no external force) the tension load hardly changes,
//! so the capstan exponent and the joint friction level are nearly interchangeable, and the
//! compliance is not seen at all; a calibration run with known forces (the seed's calibration
//! group, pressure sensors on the block) separates them. Both are measured in
//! `cablekit forceps experiments`.
//!
//! Parameters ([`Losses`]): capstan exponent `μφ`, its reversal travel `δ_c` (m), pulley drag
//! `c_p` (N·s/m), joint friction `τ_c` (N·m) with reversal travel `δ_j` (m, of the motor),
//! joint viscous friction `b` (N·m·s/rad), the jaw's return stiffness `k_s` (N·m/rad) and
//! torque `τ₀` at fully open (N·m; with the sensor zeros), and the compliance `c` of one cable
//! between sensor and jaw (m/N).
//! [`PhysicsObserver::calibrate`] fits them per forceps by bounded Levenberg–Marquardt on a
//! run with known external forces (zeros for a free-motion run).

use super::{Clamp, ClampLog, Geometry};
use crate::error::{check, CableError, Result};
use crate::identify::{least_squares, LmOptions};

/// Number of loss parameters per forceps.
pub const N_LOSSES: usize = 9;
/// Names of the loss parameters in [`Losses::to_array`] order (units in [`Losses`]).
pub const LOSS_NAMES: [&str; N_LOSSES] = [
    "capstan",
    "capstan_travel",
    "pulley_viscous",
    "joint_coulomb",
    "joint_travel",
    "joint_viscous",
    "spring",
    "preload",
    "compliance",
];
const LOWER: [f64; N_LOSSES] = [0.0, 1e-7, 0.0, 0.0, 1e-7, 0.0, -1.0, -1.0, 0.0];
const UPPER: [f64; N_LOSSES] = [3.0, 1e-2, 1e5, 1.0, 1e-2, 10.0, 1.0, 1.0, 1e-3];
const SCALE: [f64; N_LOSSES] = [0.3, 5e-5, 100.0, 2e-3, 5e-5, 1e-3, 1e-2, 1e-3, 3e-5];

/// Tension-loss parameters of one forceps; see the module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Losses {
    /// Capstan exponent `μφ` (friction coefficient × wrap), in `[0, 3]`.
    pub capstan: f64,
    /// Motor travel `δ_c` over which the capstan friction reverses (m), in `[1e-7, 1e-2]`.
    pub capstan_travel: f64,
    /// Pulley drag `c_p` (N·s/m), in `[0, 1e5]`.
    pub pulley_viscous: f64,
    /// Joint friction level `τ_c` (N·m), in `[0, 1]`.
    pub joint_coulomb: f64,
    /// Motor travel `δ_j` over which the joint friction reverses (m), in `[1e-7, 1e-2]`.
    pub joint_travel: f64,
    /// Joint viscous friction `b` (N·m·s/rad), in `[0, 10]`.
    pub joint_viscous: f64,
    /// Return stiffness of the jaw `k_s` (N·m/rad), in `[−1, 1]`.
    pub spring: f64,
    /// Return torque at fully open `τ₀`, sensor zeros included (N·m), in `[−1, 1]`.
    pub preload: f64,
    /// Compliance `c = 1/k` of one cable between sensor and jaw (m/N), in `[0, 1e-3]`.
    pub compliance: f64,
}

impl Losses {
    /// A neutral starting point for a calibration: moderate capstan friction, reversal over
    /// 50 µm, no drag, 1 mN·m joint friction, no spring, the compliance of 0.5 m of a 0.45 mm
    /// steel rope (1/30 kN/m).
    pub const START: Losses = Losses {
        capstan: 0.2,
        capstan_travel: 50e-6,
        pulley_viscous: 0.0,
        joint_coulomb: 1e-3,
        joint_travel: 50e-6,
        joint_viscous: 0.0,
        spring: 0.0,
        preload: 0.0,
        compliance: 1.0 / 30e3,
    };

    /// The parameters in [`LOSS_NAMES`] order.
    pub fn to_array(&self) -> [f64; N_LOSSES] {
        [
            self.capstan,
            self.capstan_travel,
            self.pulley_viscous,
            self.joint_coulomb,
            self.joint_travel,
            self.joint_viscous,
            self.spring,
            self.preload,
            self.compliance,
        ]
    }

    /// Checked parameters from [`LOSS_NAMES`] order; `prefix` names them in errors.
    pub fn from_array(v: &[f64], prefix: &str) -> Result<Self> {
        check::len(&format!("{prefix} losses"), v, N_LOSSES)?;
        for (i, &x) in v.iter().enumerate() {
            let name = format!("{prefix}.{}", LOSS_NAMES[i]);
            check::finite(&name, x)?;
            if x < LOWER[i] || x > UPPER[i] {
                return Err(CableError::InvalidParameter {
                    name,
                    value: x,
                    requirement: "within the documented range of the loss parameter (see Losses)",
                });
            }
        }
        Ok(Self {
            capstan: v[0],
            capstan_travel: v[1],
            pulley_viscous: v[2],
            joint_coulomb: v[3],
            joint_travel: v[4],
            joint_viscous: v[5],
            spring: v[6],
            preload: v[7],
            compliance: v[8],
        })
    }
}

/// Rate-independent direction state after a motor step `dx` with reversal travel `travel`
/// (the exact solution of `dσ/dx = (1 − σ·sgn dx)/travel` over the step).
#[inline]
pub(crate) fn direction(state: f64, dx: f64, travel: f64) -> f64 {
    if dx == 0.0 {
        return state;
    }
    let s = dx.signum();
    s * (1.0 - (1.0 - state * s) * (-dx.abs() / travel).exp())
}

/// The per-forceps estimator: parameters, lever geometry and its two direction states.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Side {
    losses: Losses,
    r2: f64,
    arm: f64,
    capstan_state: f64,
    joint_state: f64,
    last_x: Option<f64>,
}

impl Side {
    /// `(τ̂_ext, [loss₁, loss₂])` for one sample; updates the direction states.
    #[inline]
    fn step(&mut self, x: f64, v: f64, t1: f64, t2: f64) -> (f64, [f64; 2]) {
        let p = &self.losses;
        let dx = self.last_x.map_or(0.0, |last| x - last);
        self.last_x = Some(x);
        self.capstan_state = direction(self.capstan_state, dx, p.capstan_travel);
        self.joint_state = direction(self.joint_state, dx, p.joint_travel);
        let e = (p.capstan * self.capstan_state).exp();
        let drag = p.pulley_viscous * v;
        let (j1, j2) = ((t1 - drag) / e, (t2 + drag) * e);
        let theta = (x - 0.5 * p.compliance * (j1 - j2)) / self.r2;
        let tau = self.r2 * (j1 - j2)
            - p.joint_coulomb * self.joint_state
            - p.joint_viscous * v / self.r2
            - p.spring * theta
            - p.preload;
        (tau, [t1 - j1, t2 - j2])
    }

    fn reset(&mut self) {
        self.capstan_state = 0.0;
        self.joint_state = 0.0;
        self.last_x = None;
    }
}

/// The physics-informed clamping-force estimator of a two-forceps end-effector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhysicsObserver {
    sides: [Side; 2],
    geometry: Geometry,
    threshold: f64,
}

/// What a calibration of one forceps found.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// Fitted parameters.
    pub losses: Losses,
    /// RMS external-force error on the calibration run before the fit, at the start (N).
    pub rmse_start: f64,
    /// ... and after it (N).
    pub rmse: f64,
    /// Levenberg–Marquardt iterations.
    pub iterations: usize,
    /// Whether a tolerance (not the iteration cap) stopped the fit.
    pub converged: bool,
}

impl PhysicsObserver {
    /// An estimator for `geometry` with the loss parameters of forceps A and B, flagging
    /// contact above `threshold` (N).
    pub fn new(geometry: Geometry, losses: [Losses; 2], threshold: f64) -> Result<Self> {
        super::Jtdo::new(geometry, threshold, [0.0, 0.0])?;
        for (l, name) in losses.iter().zip(["a", "b"]) {
            Losses::from_array(&l.to_array(), name)?;
        }
        let side = |losses: Losses, arm: f64| Side {
            losses,
            r2: geometry.r2,
            arm,
            capstan_state: 0.0,
            joint_state: 0.0,
            last_x: None,
        };
        Ok(Self {
            sides: [
                side(losses[0], geometry.arm_a),
                side(losses[1], geometry.arm_b),
            ],
            geometry,
            threshold,
        })
    }

    /// The geometry.
    pub fn geometry(&self) -> Geometry {
        self.geometry
    }

    /// The collision threshold (N).
    pub fn threshold(&self) -> f64 {
        self.threshold
    }

    /// The loss parameters of A and B.
    pub fn losses(&self) -> [Losses; 2] {
        [self.sides[0].losses, self.sides[1].losses]
    }

    /// Forget the direction states (a new run starts).
    pub fn reset(&mut self) {
        self.sides.iter_mut().for_each(Side::reset);
    }

    /// One sample: motor motion `[x_a, v_a, x_b, v_b]` (m, m/s) and measured tensions
    /// `[F_A¹, F_A², F_B¹, F_B²]` (N). `disturbance` holds the estimated tension losses
    /// `F_f = F_M − F̂_T` (seed 000 eq. 4) and `torque` the external joint torques.
    pub fn step(&mut self, motors: &[f64; 4], measured: &[f64; 4]) -> Result<Clamp> {
        check::all_finite("motors", motors, 4)?;
        check::all_finite("measured", measured, 4)?;
        let c = self.step_unchecked(motors, measured);
        check::result_finite("clamping estimate", &c.external, 2, OVERFLOW)?;
        Ok(c)
    }

    #[inline]
    fn step_unchecked(&mut self, motors: &[f64; 4], measured: &[f64; 4]) -> Clamp {
        let mut c = Clamp {
            disturbance: [0.0; 4],
            torque: [0.0; 2],
            external: [0.0; 2],
            clamping: 0.0,
            contact: [false; 2],
        };
        for (k, side) in self.sides.iter_mut().enumerate() {
            let (tau, loss) = side.step(
                motors[2 * k],
                motors[2 * k + 1],
                measured[2 * k],
                measured[2 * k + 1],
            );
            c.disturbance[2 * k] = loss[0];
            c.disturbance[2 * k + 1] = loss[1];
            c.torque[k] = tau;
            c.external[k] = tau / side.arm;
            c.contact[k] = c.external[k].abs() > self.threshold;
        }
        c.clamping = 0.5 * (c.external[0].abs() + c.external[1].abs());
        c
    }

    /// A whole run `(T, 4)` each, from reset direction states (this estimator is unchanged).
    pub fn estimate_log(&self, motors: &[f64], measured: &[f64]) -> Result<ClampLog> {
        let t = rows_of(motors, measured)?;
        let mut me = *self;
        me.reset();
        let mut log = ClampLog {
            len: t,
            disturbance: Vec::with_capacity(4 * t),
            torque: Vec::with_capacity(2 * t),
            external: Vec::with_capacity(2 * t),
            clamping: Vec::with_capacity(t),
            contact: Vec::with_capacity(2 * t),
        };
        for (m, f) in motors.chunks_exact(4).zip(measured.chunks_exact(4)) {
            let c = me.step_unchecked(&[m[0], m[1], m[2], m[3]], &[f[0], f[1], f[2], f[3]]);
            log.disturbance.extend(c.disturbance);
            log.torque.extend(c.torque);
            log.external.extend(c.external);
            log.clamping.push(c.clamping);
            log.contact.extend(c.contact);
        }
        check::result_finite("external force", &log.external, 2, OVERFLOW)?;
        Ok(log)
    }

    /// Fits the loss parameters of each forceps to one calibration run — motor motion and
    /// measured tensions `(T, 4)`, the known external forces `(T, 2)` (zeros for free motion)
    /// — starting from `start` (e.g. another instrument's fit, or [`Losses::START`]).
    pub fn calibrate(
        geometry: Geometry,
        threshold: f64,
        start: [Losses; 2],
        motors: &[f64],
        measured: &[f64],
        external: &[f64],
    ) -> Result<(Self, [Calibration; 2])> {
        let t = rows_of(motors, measured)?;
        if t < 2 * N_LOSSES || external.len() != 2 * t {
            return Err(CableError::Shape {
                what: "calibration run".into(),
                expected: format!(
                    "({t}, 2) external forces and at least {} samples",
                    2 * N_LOSSES
                ),
                got: format!("{} values over {t} samples", external.len()),
            });
        }
        check::all_finite("external", external, 2)?;
        let base = Self::new(geometry, start, threshold)?;
        let opts = LmOptions {
            max_iter: 200,
            ftol: 1e-10,
            xtol: 1e-10,
            ..LmOptions::default()
        };
        let fit = |k: usize| -> Result<Calibration> {
            let template = base.sides[k];
            let residuals = |p: &[f64], r: &mut [f64]| -> Result<()> {
                let mut side = template;
                side.losses = Losses::from_array(p, "calibration")?;
                for (i, (m, f)) in motors
                    .chunks_exact(4)
                    .zip(measured.chunks_exact(4))
                    .enumerate()
                {
                    let (tau, _) = side.step(m[2 * k], m[2 * k + 1], f[2 * k], f[2 * k + 1]);
                    r[i] = tau / side.arm - external[2 * i + k];
                }
                Ok(())
            };
            let x0 = template.losses.to_array();
            let rep = least_squares(residuals, &x0, &LOWER, &UPPER, &SCALE, t, &opts)?;
            let rms = |cost: f64| (2.0 * cost / t as f64).sqrt();
            Ok(Calibration {
                losses: Losses::from_array(&rep.params, "calibration")?,
                rmse_start: rms(rep.initial_cost),
                rmse: rms(rep.cost),
                iterations: rep.iterations,
                converged: rep.converged,
            })
        };
        let (ca, cb) = (fit(0)?, fit(1)?);
        let me = Self::new(geometry, [ca.losses, cb.losses], threshold)?;
        Ok((me, [ca, cb]))
    }
}

const OVERFLOW: &str = "a tension or a loss parameter is too large for the model";

/// Rows of two `(T, 4)` logs, checked.
fn rows_of(motors: &[f64], measured: &[f64]) -> Result<usize> {
    let t = motors.len() / 4;
    if !motors.len().is_multiple_of(4) || measured.len() != motors.len() {
        return Err(CableError::Shape {
            what: "motors and measured".into(),
            expected: format!("(T, 4) each; motors holds {} values", motors.len()),
            got: format!("{} measured values", measured.len()),
        });
    }
    check::all_finite("motors", motors, 4)?;
    check::all_finite("measured", measured, 4)?;
    Ok(t)
}

#[cfg(test)]
mod tests {
    use super::super::twin::{self, Noise, Profile, Twin, PULSE, RAMP};
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn direction_state_is_the_exact_solution_of_its_travel_ode() {
        // many small steps agree with one big step (rate independence, exactness)
        let mut s = -0.3;
        for _ in 0..1000 {
            s = direction(s, 1e-8, 5e-5);
        }
        assert_relative_eq!(s, direction(-0.3, 1e-5, 5e-5), max_relative = 1e-12);
        assert_relative_eq!(direction(0.2, 0.0, 5e-5), 0.2);
        assert!(direction(0.0, 1.0, 5e-5) <= 1.0);
    }

    fn seed_geometry(tw: &Twin) -> Geometry {
        Geometry {
            r2: tw.a.r2,
            arm_a: tw.a.contact.lever_arm,
            arm_b: tw.b.contact.lever_arm,
        }
    }

    #[test]
    fn calibrated_on_free_motion_it_recovers_a_clamping_force() {
        let mut tw = Twin::seed();
        tw.noise = Noise {
            tension: 0.0,
            pressure: 0.0,
            seed: 1,
        };
        let prog = |j| {
            Profile::new(
                0.0,
                &twin::free_motion_program(j, &[0.8e-3], 0.3),
                RAMP,
                PULSE,
            )
        };
        let free = tw
            .run(&prog(&tw.a).unwrap(), &prog(&tw.b).unwrap(), false)
            .unwrap();
        let g = seed_geometry(&tw);
        let zeros = vec![0.0; 2 * free.len];
        let (obs, cal) = PhysicsObserver::calibrate(
            g,
            0.11,
            [Losses::START; 2],
            &free.motors,
            &free.measured,
            &zeros,
        )
        .unwrap();
        assert!(cal[0].rmse < 0.3 * cal[0].rmse_start, "{cal:?}");
        let run = tw.clamp(0.8e-3, 1.5, 5, 1.0).unwrap();
        let log = obs.estimate_log(&run.motors, &run.measured).unwrap();
        let truth: Vec<f64> = run
            .external_true
            .chunks(2)
            .map(|r| 0.5 * (r[0].abs() + r[1].abs()))
            .collect();
        let rmse = (log
            .clamping
            .iter()
            .zip(&truth)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            / truth.len() as f64)
            .sqrt();
        assert!(rmse < 0.07, "clamping RMSE {rmse} N");
    }
}
