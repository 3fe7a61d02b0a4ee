//! The nominal model of a diagnosis ([`Plant`]: the antagonistic joint, the torque-driven
//! transmission, or the transmission under its servo) and its plain replays over a run, which
//! both the problem ([`super::problem`]) and the data scales ([`super::scales`]) use.

use crate::control::{simulate_closed_loop_into, ClosedLoopMut, MotorPd};
use crate::dynamics::network::Network;
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
    /// A cable network ([`crate::dynamics::network`]): inputs one column per motor, in the
    /// network's motor order — a position-driven motor's angle (rad; its rate is the column's
    /// derivative), a torque-driven motor's torque (N·m); outputs the network's.
    Network(Network),
}

impl From<AntagonisticJoint> for Plant {
    fn from(j: AntagonisticJoint) -> Self {
        Plant::Joint(j)
    }
}

impl From<Network> for Plant {
    fn from(n: Network) -> Self {
        Plant::Network(n)
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
            (AnyModel::Network(n), None) => Ok(Plant::Network(n.clone())),
            (AnyModel::Network(_), Some(_)) => Err(CableError::InvalidOption {
                name: "servo".into(),
                value: "given".into(),
                allowed: "none for a cable network (drive its motors by position or torque in \
                          its file)"
                    .into(),
            }),
            (other, _) => Err(CableError::InvalidOption {
                name: "model".into(),
                value: other.kind().into(),
                allowed: "AntagonisticJoint, CableTransmission or CableNetwork (the diagnosis' \
                          plants)"
                    .into(),
            }),
        }
    }

    /// Number of outputs a channel may index.
    pub fn n_outputs(&self) -> usize {
        match self {
            Plant::Joint(_) => JOINT_OUTPUTS,
            Plant::Transmission(t) => t.n_outputs(),
            Plant::Servo(t, _) => t.n_outputs() + t.n_links(),
            Plant::Network(n) => n.n_outputs(),
        }
    }

    /// Columns of the recorded input (joint: 1; transmission: one torque per link).
    pub fn input_width(&self) -> usize {
        match self {
            Plant::Joint(_) => 1,
            Plant::Transmission(t) => t.n_links(),
            Plant::Servo(t, _) => 2 * t.n_links(),
            Plant::Network(n) => n.n_motors() + n.signal_names().len(),
        }
    }

    /// Columns of a run's external loads (joint: 1; transmission: one per link; network: one
    /// per joint).
    pub fn external_width(&self) -> usize {
        match self {
            Plant::Joint(_) => 1,
            Plant::Transmission(t) | Plant::Servo(t, _) => t.n_links(),
            Plant::Network(n) => n.n_joints(),
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
            Plant::Network(n) => n
                .output_names()
                .get(i)
                .cloned()
                .unwrap_or_else(|| format!("output{i}")),
        }
    }

    /// Number of links (joint: 1).
    pub fn links(&self) -> usize {
        match self {
            Plant::Joint(_) => 1,
            Plant::Transmission(t) | Plant::Servo(t, _) => t.n_links(),
            Plant::Network(n) => n.n_joints(),
        }
    }

    /// `"antagonistic joint"`, `"cable transmission"` or `"cable network"`.
    pub fn name(&self) -> &'static str {
        match self {
            Plant::Joint(_) => "antagonistic joint",
            Plant::Transmission(_) => "cable transmission",
            Plant::Servo(..) => "cable transmission (servo replay)",
            Plant::Network(_) => "cable network",
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

/// A network's input rows `(T, n_inputs)` from one column per motor (a position-driven motor's
/// angle, whose rate is its derivative; a torque-driven motor's torque), then one per signal,
/// and the joints' external loads `(T, n)` (empty: none).
pub(crate) fn network_inputs(
    net: &Network,
    cols: &[Vec<f64>],
    external: &[f64],
    dt: f64,
) -> Vec<f64> {
    let t = cols.first().map_or(0, Vec::len);
    let (w, n) = (net.n_inputs(), net.n_joints());
    let n_pos = (0..net.n_motors())
        .filter(|&i| !net.motor_is_torque_driven(i))
        .count();
    let mut u = vec![0.0; t * w];
    let (mut pos, mut tor) = (0, 2 * n_pos);
    let mut rate = vec![0.0; t];
    for (i, col) in cols.iter().enumerate() {
        if i >= net.n_motors() {
            // a measured signal, as recorded
            let s = net.signal_input() + i - net.n_motors();
            for k in 0..t {
                u[k * w + s] = col[k];
            }
        } else if net.motor_is_torque_driven(i) {
            for k in 0..t {
                u[k * w + tor] = col[k];
            }
            tor += 1;
        } else {
            super::signal::velocity(col, dt, &mut rate);
            for k in 0..t {
                u[k * w + pos] = col[k];
                u[k * w + pos + 1] = rate[k];
            }
            pos += 2;
        }
    }
    if external.len() == t * n {
        for k in 0..t {
            u[k * w + w - n..(k + 1) * w].copy_from_slice(&external[k * n..(k + 1) * n]);
        }
    }
    u
}

/// The hold of a network's inputs: first order when a motor is position-driven (its angle is a
/// sampled trajectory), zero order for torques alone.
pub(crate) fn network_hold(net: &Network) -> InputHold {
    if (0..net.n_motors()).all(|i| net.motor_is_torque_driven(i)) {
        InputHold::Zoh
    } else {
        InputHold::Foh
    }
}
