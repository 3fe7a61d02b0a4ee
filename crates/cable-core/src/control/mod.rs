//! Discrete controllers that close the loop around a model in simulation.
//!
//! [`MotorPd`] is the Raven-II servo structure: a PD law in motor space evaluated once per
//! sample period from the motor encoders and held over the period (zero-order hold), with
//! per-axis torque saturation:
//!
//! ```text
//! τ_k = sat(K_p·(q_m,ref − q_m) + K_d·(q̇_m,ref − q̇_m) + τ_ff, ±τ_max)
//! ```
//!
//! [`simulate_closed_loop`] runs it against a [`CableTransmission`]: the references are a
//! `(T, 2n)` array `[q_m,ref (n), q̇_m,ref (n)]` and the applied torques are returned with the
//! trajectory.

mod cdpr;

pub use cdpr::{closed_loop, Feedback, LoopOptions, LoopRun};

use crate::dynamics::{CableTransmission, Model};
use crate::error::{check, CableError, Result};
use crate::integrate::{record, Rk4, SimOptions, Trajectory, TrajectoryMut};

/// Motor-space PD servo with saturation (per axis).
#[derive(Debug, Clone, PartialEq)]
pub struct MotorPd {
    /// Proportional gains (N·m/rad), ≥ 0.
    pub kp: Vec<f64>,
    /// Derivative gains (N·m·s/rad), ≥ 0.
    pub kd: Vec<f64>,
    /// Torque limits (N·m), > 0.
    pub torque_limit: Vec<f64>,
}

impl MotorPd {
    /// Validated constructor; all three vectors must have the model's number of links.
    pub fn new(kp: Vec<f64>, kd: Vec<f64>, torque_limit: Vec<f64>) -> Result<Self> {
        let n = kp.len();
        for (name, v) in [("kd", &kd), ("torque_limit", &torque_limit)] {
            if v.len() != n {
                return Err(CableError::Shape {
                    what: name.into(),
                    expected: format!("({n},) like kp"),
                    got: format!("({},)", v.len()),
                });
            }
        }
        for i in 0..n {
            check::non_negative(&format!("kp[{i}]"), kp[i])?;
            check::non_negative(&format!("kd[{i}]"), kd[i])?;
            check::positive(&format!("torque_limit[{i}]"), torque_limit[i])?;
        }
        Ok(Self {
            kp,
            kd,
            torque_limit,
        })
    }

    /// The Raven-II servo gains and default current limits for `n` links (gearbox-output
    /// torque convention): kp = 0.30/0.30/0.15, kd = 0.008/0.008/0.012, limits 0.68/0.68/0.54.
    pub fn raven2(n: usize) -> Self {
        Self {
            kp: [0.30, 0.30, 0.15][..n].to_vec(),
            kd: [0.008, 0.008, 0.012][..n].to_vec(),
            torque_limit: [0.68, 0.68, 0.54][..n].to_vec(),
        }
    }

    /// Torque command for motor states `(q_m, q̇_m)` per axis and references.
    #[inline]
    pub fn command(&self, axis: usize, q: f64, w: f64, q_ref: f64, w_ref: f64) -> f64 {
        let lim = self.torque_limit[axis];
        (self.kp[axis] * (q_ref - q) + self.kd[axis] * (w_ref - w)).clamp(-lim, lim)
    }
}

/// Result of [`simulate_closed_loop`]: the trajectory and the applied motor torques `(T, n)`.
#[derive(Debug, Clone, PartialEq)]
pub struct ClosedLoopRun {
    /// States and outputs.
    pub trajectory: Trajectory,
    /// Model inputs actually applied, row-major `(T, 2n)`: `[τ_m (n), τ_ext (n)]`.
    pub inputs: Vec<f64>,
}

/// Caller-owned storage of a closed-loop run: trajectory and applied inputs `(T, 2n)`.
#[derive(Debug)]
pub struct ClosedLoopMut<'a> {
    /// States and outputs.
    pub trajectory: TrajectoryMut<'a>,
    /// Applied inputs, row-major `(T, 2n)`.
    pub inputs: &'a mut [f64],
}

/// Simulate `model` under `controller`, tracking motor-space references `(T, 2n)`
/// `[q_m,ref, q̇_m,ref]` with external loads `(T, n)` (empty: none).
pub fn simulate_closed_loop(
    model: &CableTransmission,
    controller: &MotorPd,
    references: &[f64],
    external: &[f64],
    x0: &[f64],
    opts: &SimOptions,
) -> Result<ClosedLoopRun> {
    let t_len = validate_servo(model, controller, references, external, x0)?;
    let mut trajectory = Trajectory::zeros(model, t_len);
    let mut inputs = vec![0.0; t_len * model.n_inputs()];
    let out = ClosedLoopMut {
        trajectory: trajectory.as_mut(),
        inputs: &mut inputs,
    };
    simulate_closed_loop_into(model, controller, references, external, x0, opts, out)?;
    Ok(ClosedLoopRun { trajectory, inputs })
}

fn validate_servo(
    model: &CableTransmission,
    controller: &MotorPd,
    references: &[f64],
    external: &[f64],
    x0: &[f64],
) -> Result<usize> {
    let n = model.n_links();
    if controller.kp.len() != n {
        return Err(CableError::Shape {
            what: "controller gains".into(),
            expected: format!("({n},)"),
            got: format!("({},)", controller.kp.len()),
        });
    }
    if references.is_empty() || !references.len().is_multiple_of(2 * n) {
        return Err(CableError::Shape {
            what: "references".into(),
            expected: format!("(T, {})", 2 * n),
            got: format!("{} values", references.len()),
        });
    }
    let t_len = references.len() / (2 * n);
    if !external.is_empty() && external.len() != t_len * n {
        return Err(CableError::Shape {
            what: "external".into(),
            expected: format!("({t_len}, {n})"),
            got: format!("{} values", external.len()),
        });
    }
    check::len("x0", x0, model.n_states())?;
    check::all_finite("references", references, 2 * n)?;
    check::all_finite("external", external, n)?;
    check::all_finite("x0", x0, 1)?;
    Ok(t_len)
}

/// [`simulate_closed_loop`] into caller-owned buffers; returns `T`.
pub fn simulate_closed_loop_into(
    model: &CableTransmission,
    controller: &MotorPd,
    references: &[f64],
    external: &[f64],
    x0: &[f64],
    opts: &SimOptions,
    out: ClosedLoopMut<'_>,
) -> Result<usize> {
    let t_len = validate_servo(model, controller, references, external, x0)?;
    crate::integrate::check_time_base(opts.dt, t_len)?;
    let ClosedLoopMut {
        mut trajectory,
        inputs,
    } = out;
    trajectory.check(model, t_len)?;
    let (n, m) = (model.n_links(), model.n_inputs());
    if inputs.len() != t_len * m {
        return Err(CableError::Shape {
            what: "inputs buffer".into(),
            expected: format!("({t_len}, {m})"),
            got: format!("{} values", inputs.len()),
        });
    }
    let mut ws = Rk4::for_model(model);
    let mut x = x0.to_vec();
    for k in 0..t_len {
        if k > 0 {
            let u_prev = &inputs[(k - 1) * m..k * m];
            ws.advance(model, &mut x, u_prev, u_prev, opts.dt, opts.substeps);
        }
        let r = &references[k * 2 * n..(k + 1) * 2 * n];
        let u = &mut inputs[k * m..(k + 1) * m];
        for i in 0..n {
            u[i] = controller.command(i, x[4 * i], x[4 * i + 1], r[i], r[n + i]);
            u[n + i] = external.get(k * n + i).copied().unwrap_or(0.0);
        }
        record(model, k, &x, u, opts.dt, &mut trajectory)?;
    }
    Ok(t_len)
}
