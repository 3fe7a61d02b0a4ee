//! Typical magnitudes of a diagnosis data set ([`Scales`]): they scale and bound every
//! candidate's parameters.

use crate::control::MotorPd;
use crate::dynamics::network::Network;
use crate::dynamics::{AntagonisticJoint, CableTransmission, Model};
use crate::integrate::InputHold;

use super::effects::Scales;
use super::netplant::simulate_network;
use super::nominal::{network_hold, network_inputs, run_into, servo_into, Plant};
use super::run::{Channel, JointRun};
use super::signal;

pub(crate) fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    if n == 0 {
        0.0
    } else {
        (s / n as f64).sqrt()
    }
}

pub(crate) fn scales_of(nominal: &Plant, channels: &[Channel], runs: &[JointRun]) -> Scales {
    match nominal {
        Plant::Joint(j) => joint_scales(j, channels, runs),
        Plant::Transmission(t) => transmission_scales(t, None, channels, runs),
        Plant::Servo(t, pd) => transmission_scales(t, Some(pd), channels, runs),
        Plant::Network(n) => network_scales(n, channels, runs),
    }
}

/// Scales of a cable network: forces from the pretensions and the force channels, torques
/// through the mean moment arm, speeds from a nominal replay of the first run.
fn network_scales(net: &Network, channels: &[Channel], runs: &[JointRun]) -> Scales {
    let (dt, duration) = time_scales(runs);
    let (n, m) = (net.n_joints(), net.n_cables());
    let arms: Vec<f64> = net
        .moment_arms()
        .iter()
        .map(|a| a.abs())
        .filter(|a| *a > 0.0)
        .collect();
    let arm = if arms.is_empty() {
        1.0
    } else {
        arms.iter().sum::<f64>() / arms.len() as f64
    };
    let runs_of = |f: fn(&crate::cable::CableRun) -> f64| (0..m).map(move |c| f(net.cable_run(c)));
    let pretension = runs_of(|r| r.pretension).fold(0.0, f64::max);
    let stiffness = runs_of(|r| r.law.stiffness()).fold(f64::INFINITY, f64::min);
    let damping = runs_of(|r| r.damping).fold(f64::INFINITY, f64::min);
    let force = pretension.max(sensor_force(channels, runs)).max(1e-9);
    let run = &runs[0];
    let cols: Vec<Vec<f64>> = (0..run.width).map(|c| run.input_column(c)).collect();
    let u = network_inputs(net, &cols, &run.external, run.dt);
    let x0 = if run.x0.len() == net.n_states() {
        run.x0.clone()
    } else {
        net.rest_at(&u[..net.n_inputs().min(u.len())])
    };
    let p = net.n_outputs();
    // the joints' RMS speed and their largest range of motion, in a nominal replay
    let (speed, range) = simulate_network(net, &u, &x0, run.dt, 4, network_hold(net))
        .ok()
        .map(|y| {
            let tl = run.len();
            let mut v = vec![0.0; tl];
            let (mut acc, mut range) = (0.0, 0.0_f64);
            for j in 0..n {
                let q: Vec<f64> = (0..tl).map(|k| y[k * p + j]).collect();
                signal::velocity(&q, run.dt, &mut v);
                acc += rms(v.iter().copied()).powi(2);
                let (lo, hi) = q
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                        (a.min(*x), b.max(*x))
                    });
                range = range.max(hi - lo);
            }
            ((acc / n as f64).sqrt(), range)
        })
        .filter(|(v, r)| v.is_finite() && *v > 0.0 && r.is_finite())
        .unwrap_or((1.0, 0.0));
    let joints = (0..n).map(|j| net.joint_friction(j));
    Scales {
        dt,
        duration,
        torque: force * arm,
        speed,
        force,
        stretch: force / stiffness.max(1e-12),
        // the cable travel of that motion (m)
        travel: range * arm,
        motor_speed: speed * arm,
        coupled: 0.0,
        pretension,
        viscous: joints
            .clone()
            .map(|f| f.viscous)
            .fold(f64::INFINITY, f64::min),
        smoothing: joints.map(|f| f.smoothing).fold(f64::INFINITY, f64::min),
        damping: if damping.is_finite() { damping } else { 0.0 },
        sensors: channels.iter().filter(|c| c.sensor).count(),
        links: n,
        transmission: false,
        routing_smoothing: (0..m)
            .map(|c| net.cable_smoothing(c))
            .fold(f64::INFINITY, f64::min)
            .min(1.0),
    }
}

/// RMS of the force-sensor channels of all runs (N).
fn sensor_force(channels: &[Channel], runs: &[JointRun]) -> f64 {
    let q = channels.len();
    rms(runs.iter().flat_map(|r| {
        channels
            .iter()
            .enumerate()
            .filter(|(_, c)| c.sensor)
            .flat_map(move |(c, _)| (0..r.len()).map(move |k| r.measured[k * q + c]))
    }))
}

/// Shortest sample interval and shortest run duration (s).
fn time_scales(runs: &[JointRun]) -> (f64, f64) {
    let dt = runs.iter().map(|r| r.dt).fold(f64::INFINITY, f64::min);
    let duration = runs
        .iter()
        .map(|r| r.dt * r.len() as f64)
        .fold(f64::INFINITY, f64::min);
    (dt, duration)
}

/// Scales of the transmission: joint torques from the motor torques through the transmission
/// ratio, speeds from a replay of the nominal on the first run.
fn transmission_scales(
    t: &CableTransmission,
    servo: Option<&MotorPd>,
    channels: &[Channel],
    runs: &[JointRun],
) -> Scales {
    let (dt, duration) = time_scales(runs);
    let n = t.n_links();
    let ratio: f64 = t.links().iter().map(|l| l.ratio()).sum::<f64>() / n as f64;
    let run = &runs[0];
    let x0 = if run.x0.len() == t.n_states() {
        run.x0.clone()
    } else {
        t.rest_state()
    };
    let (tl, p) = (run.len(), t.n_outputs());
    // a nominal replay of the first run gives the joint speeds (and, under the servo, the
    // applied torques); a replay that fails falls back to 1 rad/s and the recorded inputs
    let replay: Option<(Vec<f64>, Vec<f64>)> = match servo {
        None => {
            let u: Vec<f64> = (0..tl)
                .flat_map(|k| {
                    (0..2 * n).map(move |c| if c < n { run.input[k * n + c] } else { 0.0 })
                })
                .collect();
            run_into(t, &u, &x0, run, 4, InputHold::Zoh)
                .ok()
                .map(|y| (y, run.input.clone()))
        }
        Some(pd) => {
            let ext = vec![0.0; tl * n];
            servo_into(t, pd, &run.input, &ext, &x0, run.dt, 4)
                .ok()
                .map(|(y, applied)| {
                    let tau = (0..tl)
                        .flat_map(|k| applied[k * 2 * n..k * 2 * n + n].to_vec())
                        .collect();
                    (y, tau)
                })
        }
    };
    let torque_in = replay.as_ref().map_or(&run.input, |r| &r.1);
    let torque = (rms(torque_in.iter().copied()) * ratio).max(1e-9);
    let speed = replay
        .as_ref()
        .map(|(y, _)| {
            let mut v = vec![0.0; tl];
            let mut acc = 0.0;
            for i in 0..n {
                let q: Vec<f64> = (0..tl).map(|k| y[k * p + 5 * i + 1]).collect();
                signal::velocity(&q, run.dt, &mut v);
                acc += rms(v.iter().copied()).powi(2);
            }
            (acc / n as f64).sqrt()
        })
        .filter(|v| v.is_finite() && *v > 0.0)
        .unwrap_or(1.0);
    let l0 = &t.links()[0];
    let pretension = l0.cable.run.pretension;
    let force = pretension.max(sensor_force(channels, runs)).max(1e-9);
    Scales {
        dt,
        duration,
        torque,
        speed,
        force,
        stretch: force / l0.cable.run.law.stiffness(),
        travel: 0.0,
        motor_speed: speed * l0.joint_radius,
        coupled: 0.0,
        pretension,
        viscous: t
            .links()
            .iter()
            .map(|l| l.link_friction.viscous)
            .fold(f64::INFINITY, f64::min),
        smoothing: l0.link_friction.smoothing,
        damping: t
            .links()
            .iter()
            .map(|l| l.cable.run.damping)
            .fold(f64::INFINITY, f64::min),
        sensors: channels.iter().filter(|c| c.sensor).count(),
        links: n,
        transmission: true,
        routing_smoothing: 1e-3,
    }
}

fn joint_scales(nominal: &AntagonisticJoint, channels: &[Channel], runs: &[JointRun]) -> Scales {
    let (dt, duration) = time_scales(runs);
    let pretension = nominal.drive.pretension.max(nominal.ret.pretension);
    let force = pretension.max(sensor_force(channels, runs)).max(1e-9);
    let motor_speed = rms(runs.iter().flat_map(|r| {
        let mut v = vec![0.0; r.len()];
        signal::velocity(&r.input, r.dt, &mut v);
        v
    }));
    let travel = runs
        .iter()
        .map(|r| {
            let (lo, hi) = r
                .input
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                    (a.min(x), b.max(x))
                });
            0.5 * (hi - lo)
        })
        .fold(0.0, f64::max);
    let coupled = rms(runs.iter().flat_map(|r| r.coupled.iter().copied()));
    Scales {
        dt,
        duration,
        torque: nominal.radius * force,
        speed: motor_speed / nominal.radius,
        force,
        stretch: force / nominal.drive.law.stiffness(),
        travel,
        motor_speed,
        coupled,
        pretension,
        viscous: nominal.friction.viscous,
        smoothing: nominal.friction.smoothing,
        damping: nominal.drive.damping.min(nominal.ret.damping),
        sensors: channels.iter().filter(|c| c.sensor).count(),
        links: 1,
        transmission: false,
        routing_smoothing: 1e-3,
    }
}
