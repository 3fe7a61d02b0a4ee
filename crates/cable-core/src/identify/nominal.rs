//! The nominal model of a diagnosis ([`Plant`]: the antagonistic joint, the torque-driven
//! transmission, or the transmission under its servo) and its plain replays over a run, which
//! both the problem ([`super::problem`]) and the data scales ([`super::scales`]) use.

use crate::control::{simulate_closed_loop_into, ClosedLoopMut, MotorPd};
use crate::dynamics::{AntagonisticJoint, AnyModel, CableTransmission, Model};
use crate::error::{CableError, Result};
use crate::integrate::{simulate_into, InputHold, SimOptions, TrajectoryMut};

use super::plant::{JOINT_OUTPUTS, JOINT_OUTPUT_NAMES};
use super::run::JointRun;

/// The nominal model of a diagnosis.
#[derive(Debug, Clone, PartialEq)]
pub enum Plant {
    /// Antagonistic joint, position-driven (outputs `[T_m,1, T_m,2, T_j,1, T_j,2, θ, F_c,
    /// T_m,1 − T_m,2]`).
    Joint(AntagonisticJoint),
    /// Cable transmission of 1–3 links, torque-driven (outputs per link `[q_m, q_l, T_a, T_b,
    /// joint torque]`).
    Transmission(CableTransmission),
    /// Cable transmission replayed in closed loop under its motor-space PD servo: inputs the
    /// recorded references `[q_m,ref (n), q̇_m,ref (n)]`; outputs per link as `Transmission`,
    /// then the applied motor torques `(n)`. The loop keeps the replay near the measurement, where
    /// an open-loop torque replay of frictional links drifts.
    Servo(CableTransmission, MotorPd),
}

impl From<AntagonisticJoint> for Plant {
    fn from(j: AntagonisticJoint) -> Self {
        Plant::Joint(j)
    }
}

impl From<CableTransmission> for Plant {
    fn from(t: CableTransmission) -> Self {
        Plant::Transmission(t)
    }
}

impl Plant {
    /// The plant of a model: an antagonistic joint, or a transmission (replayed under the
    /// motor PD servo `(kp, kd, torque_limit)` when given).
    pub fn of(model: &AnyModel, servo: Option<(Vec<f64>, Vec<f64>, Vec<f64>)>) -> Result<Self> {
        match (model, servo) {
            (AnyModel::Antagonistic(j), _) => Ok(Plant::Joint(*j)),
            (AnyModel::Transmission(t), None) => Ok(Plant::Transmission(t.clone())),
            (AnyModel::Transmission(t), Some((kp, kd, lim))) => {
                Ok(Plant::Servo(t.clone(), MotorPd::new(kp, kd, lim)?))
            }
            (other, _) => Err(CableError::InvalidOption {
                name: "model".into(),
                value: other.kind().into(),
                allowed: "AntagonisticJoint or CableTransmission (the diagnosis' plants)".into(),
            }),
        }
    }

    /// Number of outputs a channel may index.
    pub fn n_outputs(&self) -> usize {
        match self {
            Plant::Joint(_) => JOINT_OUTPUTS,
            Plant::Transmission(t) => t.n_outputs(),
            Plant::Servo(t, _) => t.n_outputs() + t.n_links(),
        }
    }

    /// Columns of the recorded input (joint: 1; transmission: one torque per link).
    pub fn input_width(&self) -> usize {
        match self {
            Plant::Joint(_) => 1,
            Plant::Transmission(t) => t.n_links(),
            Plant::Servo(t, _) => 2 * t.n_links(),
        }
    }

    /// Name of output `i` (the documented output vocabulary).
    pub fn output_name(&self, i: usize) -> String {
        match self {
            Plant::Joint(_) => JOINT_OUTPUT_NAMES
                .get(i)
                .map_or_else(|| format!("output{i}"), |s| (*s).into()),
            Plant::Transmission(t) | Plant::Servo(t, _) => {
                let p = t.n_outputs();
                if i < p {
                    t.output_names()[i].clone()
                } else {
                    format!("tau_m{}", i - p + 1)
                }
            }
        }
    }

    /// Number of links (joint: 1).
    pub fn links(&self) -> usize {
        match self {
            Plant::Joint(_) => 1,
            Plant::Transmission(t) | Plant::Servo(t, _) => t.n_links(),
        }
    }

    /// `"antagonistic joint"` or `"cable transmission"`.
    pub fn name(&self) -> &'static str {
        match self {
            Plant::Joint(_) => "antagonistic joint",
            Plant::Transmission(_) => "cable transmission",
            Plant::Servo(..) => "cable transmission (servo replay)",
        }
    }
}

/// Simulate `model` over a run into fresh output buffers; returns the outputs `(T, p)`.
pub(crate) fn run_into<M: Model>(
    model: &M,
    u: &[f64],
    x0: &[f64],
    run: &JointRun,
    substeps: usize,
    hold: InputHold,
) -> Result<Vec<f64>> {
    let t = run.len();
    let mut states = vec![0.0; t * model.n_states()];
    let mut outputs = vec![0.0; t * model.n_outputs()];
    let opts = SimOptions::new(run.dt, substeps, hold)?;
    simulate_into(
        model,
        u,
        x0,
        &opts,
        TrajectoryMut {
            states: &mut states,
            outputs: &mut outputs,
        },
    )?;
    Ok(outputs)
}

/// Closed-loop replay of `model` under `pd` on references `(T, 2n)` with external loads
/// `(T, n)`; returns the outputs `(T, p)` and the applied inputs `(T, 2n)`.
pub(crate) fn servo_into(
    model: &CableTransmission,
    pd: &MotorPd,
    refs: &[f64],
    ext: &[f64],
    x0: &[f64],
    dt: f64,
    substeps: usize,
) -> Result<(Vec<f64>, Vec<f64>)> {
    let t = refs.len() / (2 * model.n_links());
    let mut states = vec![0.0; t * model.n_states()];
    let mut outputs = vec![0.0; t * model.n_outputs()];
    let mut applied = vec![0.0; t * model.n_inputs()];
    let opts = SimOptions::new(dt, substeps, InputHold::Zoh)?;
    simulate_closed_loop_into(
        model,
        pd,
        refs,
        ext,
        x0,
        &opts,
        ClosedLoopMut {
            trajectory: TrajectoryMut {
                states: &mut states,
                outputs: &mut outputs,
            },
            inputs: &mut applied,
        },
    )?;
    Ok((outputs, applied))
}
