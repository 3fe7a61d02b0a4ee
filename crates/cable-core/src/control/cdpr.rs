//! The parallel robot in closed loop: [`closed_loop`] runs a [`CdprPlant`] under a trajectory
//! controller with the tension distribution in the loop and, optionally, seed 002's P force
//! control (§4, eqs 10–15). The plant itself is [`crate::dynamics::CdprPlant`]; the tension
//! distribution per call is [`crate::cdpr::Controller`].

use crate::cdpr::{inverse_kinematics, CableGeometry, Controller, Method, Motion, Pose, Robot};
use crate::dynamics::{CdprPlant, Model};
use crate::error::{check, CableError, Result, MAX_SUBSTEPS};
use crate::integrate::Rk4;
use crate::nn::Mlp;

/// Which tension closes seed 002's force loop (`f_u = k_p·(f_d − f̂)`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Feedback {
    /// No force loop: the lengths alone (with the elastic feed-forward) set the tensions.
    Open,
    /// The platform-side tension (an ideal sensor at the platform).
    Platform,
    /// The winch-side sensor (PUL), with its noise.
    Sensor,
    /// A network's estimate of the platform-side tension from the desired position and
    /// velocity and the sensor (seed 002's NN-tension).
    Network,
}

impl Feedback {
    /// From its name (`"open"`, `"platform"`, `"sensor"`, `"network"`).
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "open" => Ok(Self::Open),
            "platform" => Ok(Self::Platform),
            "sensor" => Ok(Self::Sensor),
            "network" => Ok(Self::Network),
            other => Err(CableError::InvalidOption {
                name: "feedback".into(),
                value: other.into(),
                allowed: "open, platform, sensor, network".into(),
            }),
        }
    }
}

/// The trajectory controller of [`closed_loop`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopOptions {
    /// Controller period (s), > 0.
    pub dt: f64,
    /// RK4 steps of the plant per period (1 ..= `MAX_SUBSTEPS`).
    pub substeps: usize,
    /// Tension distribution method for `f_d` (seed 002 uses the closed form).
    pub method: Method,
    /// Force-loop gain `k_p` (seed 002 Table 3), ≥ 0.
    pub gain: f64,
    /// The tension the force loop feeds back.
    pub feedback: Feedback,
    /// Periods by which the fed-back tensions lag beyond the one period of any sampled loop
    /// (a sensor's conversion and link latency); default 0.
    pub sensor_delay: usize,
    /// Feed forward the current that carries the target tension at the drum and turns the drum
    /// as referenced (step 4 of [`closed_loop`]); default true.
    pub current_feedforward: bool,
}

impl LoopOptions {
    /// Period `dt`, 5 substeps, `auto` distribution, no force loop, no extra delay, current
    /// feed-forward.
    pub fn new(dt: f64) -> Self {
        Self {
            dt,
            substeps: 5,
            method: Method::Auto,
            gain: 0.0,
            feedback: Feedback::Open,
            sensor_delay: 0,
            current_feedforward: true,
        }
    }
}

/// A [`closed_loop`] run: per controller period `k` (rows), row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct LoopRun {
    /// Samples `T`.
    pub samples: usize,
    /// Platform pose `(T, n)`.
    pub pose: Vec<f64>,
    /// Desired tensions `f_d` `(T, m)` (N).
    pub desired: Vec<f64>,
    /// Platform-side tensions `(T, m)` (N).
    pub ee: Vec<f64>,
    /// Winch-side sensor `(T, m)` (N, noise included).
    pub sensor: Vec<f64>,
    /// The tension the force loop used `(T, m)` (N; the sensor under `Open`).
    pub feedback: Vec<f64>,
    /// Motor currents `(T, m)` (A), each its period's mean (trapezoidal: just after the
    /// period's reference step and at its end), as a drive's current measurement averages. (The
    /// PID runs continuously inside the period, so the current at the period's end alone sits
    /// about `K_p·α̇·Δt/2` below the mean that turned the drum.)
    pub current: Vec<f64>,
    /// Drum angles `(T, m)` (rad).
    pub alpha: Vec<f64>,
    /// Desired wrench `Aᵀ·f_d = M·ẍ_d − w_g` at the desired pose `(T, n)`.
    pub wrench_desired: Vec<f64>,
    /// Actual cable wrench `Aᵀ(q)·T_EE` at the actual pose `(T, n)`.
    pub wrench_ee: Vec<f64>,
    /// `Aᵀ(q_d)·T_PUL` from the sensor `(T, n)`.
    pub wrench_sensor: Vec<f64>,
    /// `Aᵀ(q_d)·f̂` from the fed-back tension `(T, n)`.
    pub wrench_feedback: Vec<f64>,
    /// Periods whose `f_d` was not feasible (the distribution's closest answer was used).
    pub infeasible: usize,
    /// The plant's inputs per period `(T, 3m + n)`, held over the period: with
    /// [`LoopRun::initial_state`] they replay the run through the model (the simulator, the
    /// sr-UKF).
    pub inputs: Vec<f64>,
    /// The plant's state at the start.
    pub initial_state: Vec<f64>,
}

/// Run `plant` under the trajectory controller: desired poses `(T, n)` every `opts.dt`
/// (velocity and acceleration by central differences), starting at rest at its home pose
/// (which should be the first desired pose). Each period:
///
/// 1. `f_d` = the tension distribution of the weight and the inertia `M·ẍ_d` at `q_d`;
/// 2. `f̂` = the fed-back tension measured at the end of period `k − 1 − sensor_delay` (the
///    home tensions before; `sensor_noise` `(T, m)` N is added to the sensor);
/// 3. `f_u = k_p·(f_d − f̂)` (0 under [`Feedback::Open`]);
/// 4. the drums take the unstretched lengths that give the target `f_t = max(0, f_d + f_u)`
///    at `q_d` (the length loop of seed 002 eq. 15), the rate `α̇_ref = A·v_d/r` of the desired
///    motion, and the current that carries the target at the drum and turns it as referenced,
///    `i_ff = (r·f_t + B_l·α̇_ref + J_l·α̈_ref)/(k_φ·r_gb)` (seed 003's winch is soft against a
///    stiff cable: a length alone would hold a tension only through the PID's integral);
/// 5. the plant advances one period.
///
/// `tension_offset` `(T, m)` N is added to `f_d` in step 4 (an excitation: in the null space
/// of `Aᵀ` it changes the internal forces and not the wrench).
///
/// `network` (14 → 8 for seed 002's robot: inputs the desired position and linear velocity
/// and the `m` sensor tensions, outputs the `m` platform-side tensions) is needed by
/// [`Feedback::Network`]. A diverged plant is [`CableError::Diverged`] at its period.
pub fn closed_loop(
    plant: &CdprPlant,
    poses: &[f64],
    opts: &LoopOptions,
    sensor_noise: Option<&[f64]>,
    tension_offset: Option<&[f64]>,
    network: Option<&Mlp>,
) -> Result<LoopRun> {
    let (n, m) = plant.sizes();
    check::positive("dt", opts.dt)?;
    check::non_negative("gain", opts.gain)?;
    if opts.substeps == 0 || opts.substeps > MAX_SUBSTEPS {
        return Err(CableError::InvalidParameter {
            name: "substeps".into(),
            value: opts.substeps as f64,
            requirement: "between 1 and 100000",
        });
    }
    if poses.is_empty() || !poses.len().is_multiple_of(n) {
        return Err(CableError::Shape {
            what: "poses".into(),
            expected: format!("(T ≥ 1, {n})"),
            got: format!("{} values", poses.len()),
        });
    }
    check::all_finite("poses", poses, n)?;
    let t_len = poses.len() / n;
    if let Some(noise) = sensor_noise {
        check::len("sensor_noise", noise, t_len * m)?;
        check::all_finite("sensor_noise", noise, m)?;
    }
    if let Some(offset) = tension_offset {
        check::len("tension_offset", offset, t_len * m)?;
        check::all_finite("tension_offset", offset, m)?;
    }
    let translation = match plant.robot.motion {
        Motion::Planar => 2,
        Motion::Spatial => 3,
    };
    let net = match (opts.feedback, network) {
        (Feedback::Network, None) => {
            return Err(CableError::InvalidOption {
                name: "network".into(),
                value: "None".into(),
                allowed: "a network (feedback = \"network\" needs one)".into(),
            })
        }
        (Feedback::Network, Some(net)) => {
            if net.n_inputs() != 2 * translation + m || net.n_outputs() != m {
                return Err(CableError::Shape {
                    what: "network".into(),
                    expected: format!("{} inputs and {m} outputs", 2 * translation + m),
                    got: format!("{} inputs and {} outputs", net.n_inputs(), net.n_outputs()),
                });
            }
            Some(net)
        }
        _ => None,
    };
    let mut scratch = net.map(Mlp::scratch);
    let mut ctl = Controller::new(&plant.robot, opts.method, true)?;
    let mut rk = Rk4::for_model(plant);
    let mut x = plant.rest_state();
    if opts.current_feedforward {
        x[2 * n + 2 * m..2 * n + 3 * m].fill(0.0);
    }
    let mut u = vec![0.0; 3 * m + n];
    let mut y = vec![0.0; n + 5 * m];
    let mut y_start = y.clone();
    let (tm, tn) = (t_len * m, t_len * n);
    let mut run = LoopRun {
        samples: t_len,
        pose: vec![0.0; tn],
        desired: vec![0.0; tm],
        ee: vec![0.0; tm],
        sensor: vec![0.0; tm],
        feedback: vec![0.0; tm],
        current: vec![0.0; tm],
        alpha: vec![0.0; tm],
        wrench_desired: vec![0.0; tn],
        wrench_ee: vec![0.0; tn],
        wrench_sensor: vec![0.0; tn],
        wrench_feedback: vec![0.0; tn],
        infeasible: 0,
        inputs: vec![0.0; t_len * (3 * m + n)],
        initial_state: x.clone(),
    };
    let row = |k: usize| &poses[k.min(t_len - 1) * n..(k.min(t_len - 1) + 1) * n];
    let mut last_rate: Option<Vec<f64>> = None;
    // platform-side and (noiseless) sensor tensions at the end of each period, for the delay
    let mut pul_raw = vec![0.0; tm];
    let mut measured_ee = plant.home_tensions.clone();
    let mut measured_pul = plant.home_tensions.clone();
    let mut f_hat = vec![0.0; m];
    let mut noisy = vec![0.0; m];
    let mut net_in = vec![0.0; 2 * translation + m];
    let mut geom = CableGeometry::default();
    let mut inertial = [0.0; 6];
    for k in 0..t_len {
        // desired motion by central differences (one-sided at the ends)
        let (a, b) = (k.saturating_sub(1), (k + 1).min(t_len - 1));
        let qd = row(k);
        let span = (b - a).max(1) as f64 * opts.dt;
        let mut vel = [0.0; 6];
        let mut acc = [0.0; 6];
        for i in 0..n {
            vel[i] = (row(b)[i] - row(a)[i]) / span;
            if k > 0 && k + 1 < t_len {
                acc[i] = (row(k + 1)[i] - 2.0 * qd[i] + row(k - 1)[i]) / (opts.dt * opts.dt);
            }
        }
        inertial_wrench(&plant.robot, &acc[..n], &mut inertial[..n]);
        let step = ctl.step(qd, Some(&inertial[..n]))?;
        let fd = step.distribution.tensions();
        if !step.distribution.feasible {
            run.infeasible += 1;
        }
        geom.clone_from(ctl.geometry());
        // the fed-back tension: the measurement `sensor_delay` periods before the last one
        if let Some(p) = k.checked_sub(opts.sensor_delay.saturating_add(1)) {
            measured_ee.copy_from_slice(&run.ee[p * m..(p + 1) * m]);
            measured_pul.copy_from_slice(&pul_raw[p * m..(p + 1) * m]);
        }
        for (j, v) in noisy.iter_mut().enumerate() {
            *v = measured_pul[j] + sensor_noise.map_or(0.0, |s| s[k * m + j]);
        }
        match opts.feedback {
            Feedback::Open | Feedback::Sensor => f_hat.copy_from_slice(&noisy),
            Feedback::Platform => f_hat.copy_from_slice(&measured_ee),
            Feedback::Network => {
                net_in[..translation].copy_from_slice(&qd[..translation]);
                net_in[translation..2 * translation].copy_from_slice(&vel[..translation]);
                net_in[2 * translation..].copy_from_slice(&noisy);
                if let (Some(net), Some(s)) = (net, scratch.as_mut()) {
                    net.forward_with(&net_in, &mut f_hat, s)?;
                }
            }
        }
        let gain = if opts.feedback == Feedback::Open {
            0.0
        } else {
            opts.gain
        };
        let wch = &plant.winch;
        let sd = geom.structure();
        for j in 0..m {
            let excite = tension_offset.map_or(0.0, |o| o[k * m + j]);
            let target = (fd[j] + excite + gain * (fd[j] - f_hat[j])).max(0.0);
            u[j] = plant.angle_for_length(j, plant.unstretched_length(j, geom.length[j], target));
            // the drum rate that follows the desired motion (l̇ = −A·v), and its change
            let rate = (0..n).map(|i| sd[i * m + j] * vel[i]).sum::<f64>() / wch.drum_radius;
            let accel = last_rate
                .as_ref()
                .map_or(0.0, |l: &Vec<f64>| (rate - l[j]) / opts.dt);
            u[m + j] = rate;
            u[2 * m + j] = if opts.current_feedforward {
                (wch.drum_radius * target + wch.load_viscous() * rate + wch.load_inertia() * accel)
                    / (wch.torque_constant * wch.gear_ratio)
            } else {
                0.0
            };
        }
        last_rate = Some(u[m..2 * m].to_vec());
        run.inputs[k * (3 * m + n)..(k + 1) * (3 * m + n)].copy_from_slice(&u);
        plant.output(&x, &u, &mut y_start);
        rk.advance(plant, &mut x, &u, &u, opts.dt, opts.substeps);
        if !x.iter().all(|v| v.is_finite()) {
            return Err(CableError::Diverged {
                step: k,
                time_s: k as f64 * opts.dt,
            });
        }
        plant.output(&x, &u, &mut y);
        // record
        let s_d = geom.structure();
        run.pose[k * n..(k + 1) * n].copy_from_slice(&y[..n]);
        for j in 0..m {
            pul_raw[k * m + j] = y[n + m + j];
            let i = k * m + j;
            run.desired[i] = fd[j];
            run.ee[i] = y[n + j];
            run.sensor[i] = noisy[j];
            run.feedback[i] = f_hat[j];
            run.current[i] = 0.5 * (y_start[n + 2 * m + j] + y[n + 2 * m + j]);
            run.alpha[i] = y[n + 4 * m + j];
        }
        let actual = Pose::from_coordinates(plant.robot.motion, &y[..n])?;
        let mut g = CableGeometry::default();
        inverse_kinematics(&plant.robot, &actual, &mut g)?;
        let s_a = g.structure();
        for i in 0..n {
            let at = k * n + i;
            let dot = |s: &[f64], f: &[f64]| (0..m).map(|j| s[i * m + j] * f[j]).sum::<f64>();
            run.wrench_desired[at] = dot(s_d, fd);
            run.wrench_ee[at] = dot(s_a, &y[n..n + m]);
            run.wrench_sensor[at] = dot(s_d, &noisy);
            run.wrench_feedback[at] = dot(s_d, &f_hat);
        }
    }
    Ok(run)
}

/// `−M·ẍ` as an external wrench for the distribution: the mass times the acceleration and the
/// inertia times the orientation coordinates' second derivatives (the angular acceleration
/// for small angles; gyroscopic terms and the centre of mass's offset are neglected).
fn inertial_wrench(robot: &Robot, acc: &[f64], out: &mut [f64]) {
    let p = &robot.platform;
    match robot.motion {
        Motion::Planar => {
            out[0] = -p.mass * acc[0];
            out[1] = -p.mass * acc[1];
            out[2] = -p.inertia[8] * acc[2];
        }
        Motion::Spatial => {
            for i in 0..3 {
                out[i] = -p.mass * acc[i];
                out[3 + i] = -(0..3)
                    .map(|c| p.inertia[3 * i + c] * acc[3 + c])
                    .sum::<f64>();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cdpr::tests::{box_robot, planar_robot};
    use crate::cdpr::winch::Winch;
    use crate::cdpr::{PathFriction, PathLaw};
    use crate::dynamics::{Creep, PlantOptions};
    use nalgebra::{Matrix3, Vector3};

    fn coulomb(mu: f64, wrap: f64, m: usize) -> Vec<PathFriction> {
        vec![
            PathFriction {
                coefficient: mu,
                viscous: 2.0,
                guide_wrap: wrap,
                law: PathLaw::Coulomb { smoothing: 1e-3 },
            };
            m
        ]
    }

    fn circle(home: &[f64], n: usize, radius: f64, period: f64, dt: f64, t_end: f64) -> Vec<f64> {
        let steps = (t_end / dt) as usize;
        let mut poses = Vec::with_capacity(steps * n);
        for k in 0..steps {
            let t = k as f64 * dt;
            // start at rest: the radius ramps in over the first second
            let tau = (t / 1.0).min(1.0);
            let ramp = tau * tau * (3.0 - 2.0 * tau);
            let ph = std::f64::consts::TAU * t / period;
            let mut q = home.to_vec();
            q[0] += ramp * radius * ph.sin();
            q[1] += ramp * radius * (1.0 - ph.cos());
            poses.extend(q);
        }
        poses
    }

    fn rmse(a: &[f64], b: &[f64]) -> f64 {
        (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
    }

    fn run(plant: &CdprPlant, poses: &[f64], feedback: Feedback, gain: f64) -> LoopRun {
        let mut o = LoopOptions::new(1e-3);
        o.feedback = feedback;
        o.gain = gain;
        closed_loop(plant, poses, &o, None, None, None).unwrap()
    }

    /// At rest at home the plant is in equilibrium (every derivative 0) and both sensors and
    /// the current estimate read the home tensions: planar, and spatial with pulleys and the
    /// centre of mass off the origin.
    #[test]
    fn a_creep_ratio_past_any_cable_is_refused() {
        assert!(Creep::per_cable(&[1e308], &[1.0], 4).is_err());
        assert!(Creep::per_cable(&[2.0], &[1.0], 4).is_ok());
    }

    #[test]
    fn rest_is_an_equilibrium_holding_the_home_tensions() {
        for (robot, home) in [
            (planar_robot(), vec![0.5, 0.4, 0.0]),
            (box_robot(true), vec![0.02, -0.01, 0.03, 0.0, 0.0, 0.05]),
        ] {
            let plant =
                CdprPlant::new(&robot, Winch::seed003(), &home, PlantOptions::default()).unwrap();
            let (n, m) = (robot.dof(), robot.n_cables());
            let x = plant.rest_state();
            let u = vec![0.0; plant.n_inputs()];
            let mut dx = vec![1.0; plant.n_states()];
            plant.derivative(&x, &u, &mut dx);
            let worst = dx.iter().fold(0.0_f64, |a, b| a.max(b.abs()));
            assert!(worst < 1e-8, "{}: |dx| = {worst:e}", robot.name);
            let mut y = vec![0.0; plant.n_outputs()];
            plant.output(&x, &u, &mut y);
            for j in 0..m {
                let f0 = plant.home_tensions()[j];
                assert!(f0 >= robot.cables[j].f_min - 1e-9);
                for (what, v) in [
                    ("ee", y[n + j]),
                    ("pul", y[n + m + j]),
                    ("current", y[n + 3 * m + j]),
                ] {
                    assert!(
                        (v - f0).abs() < 1e-9 * (1.0 + f0),
                        "{what} {j}: {v} vs {f0}"
                    );
                }
            }
            assert_eq!(plant.state_names().len(), plant.n_states());
            assert_eq!(plant.input_names().len(), plant.n_inputs());
            assert_eq!(plant.output_names().len(), plant.n_outputs());
        }
    }

    /// Creep: at rest with settled creep the plant is in equilibrium; after a push held for
    /// 20 s (`τ` = 3 s) the platform has sunk further than without creep, and each cable's
    /// creep has settled at `ρ` times its elastic stretch.
    #[test]
    fn creep_lets_the_platform_sink_further_and_settles_at_its_ratio() {
        let robot = planar_robot();
        let home = [0.5, 0.4, 0.0];
        let (n, m) = (robot.dof(), robot.n_cables());
        let sink = |ratio: f64| {
            let opts = PlantOptions {
                creep: vec![
                    Creep {
                        ratio,
                        time_constant: 3.0,
                    };
                    m
                ],
                ..PlantOptions::default()
            };
            let plant = CdprPlant::new(&robot, Winch::seed003(), &home, opts).unwrap();
            let mut x = plant.rest_state();
            let mut u = vec![0.0; plant.n_inputs()];
            let mut dx = vec![1.0; plant.n_states()];
            plant.derivative(&x, &u, &mut dx);
            assert!(dx.iter().all(|d| d.abs() < 1e-8), "rest with creep {ratio}");
            u[3 * m + 1] = -20.0;
            let mut rk = Rk4::for_model(&plant);
            let mut y = 0.0;
            for k in 0..20_000 {
                rk.advance(&plant, &mut x, &u, &u, 1e-3, 2);
                if k == 19_999 {
                    y = home[1] - x[1];
                }
            }
            (plant, x, y)
        };
        let (_, _, stiff) = sink(0.0);
        let (plant, x, creepy) = sink(0.5);
        assert!(stiff > 0.0 && creepy > 1.3 * stiff, "{creepy} vs {stiff}");
        let pose = Pose::from_coordinates(robot.motion, &x[..n]).unwrap();
        let mut g = CableGeometry::default();
        inverse_kinematics(&robot, &pose, &mut g).unwrap();
        for j in 0..m {
            let len = plant.rest_length()[j] - plant.winch().drum_radius * x[2 * n + j];
            let c = x[2 * n + 6 * m + j];
            let elastic = g.length[j] - len - c;
            assert!(
                (c - 0.5 * elastic).abs() < 1e-3 * c.abs(),
                "{j}: {c} vs {elastic}"
            );
        }
    }

    /// With no wrench, the rigid body (centre of mass off the origin, a full inertia, spinning
    /// about no principal axis) keeps its kinetic energy and its linear and angular momenta.
    #[test]
    fn a_free_platform_keeps_its_energy_and_momenta() {
        let mut robot = box_robot(false);
        robot.platform.com = [0.02, -0.01, 0.015];
        robot.platform.inertia = [2e-3, 2e-4, -1e-4, 2e-4, 3e-3, 3e-4, -1e-4, 3e-4, 4e-3];
        let plant =
            CdprPlant::new(&robot, Winch::seed003(), &[0.0; 6], PlantOptions::default()).unwrap();
        let mass = robot.platform.mass;
        let body = |q: &[f64], v: &[f64]| {
            let pose = Pose::from_coordinates(Motion::Spatial, q).unwrap();
            let rot = Matrix3::from_row_slice(&pose.rotation);
            let ic = rot * Matrix3::from_row_slice(&robot.platform.inertia) * rot.transpose();
            let c = Vector3::from(pose.rotate(&robot.platform.com));
            let om = Vector3::new(v[3], v[4], v[5]);
            let vc = Vector3::new(v[0], v[1], v[2]) + om.cross(&c);
            let energy = 0.5 * mass * vc.norm_squared() + 0.5 * om.dot(&(ic * om));
            let p = mass * vc;
            let pc = Vector3::new(q[0], q[1], q[2]) + c;
            let l = ic * om + pc.cross(&p);
            (energy, p, l)
        };
        let f = |s: &[f64; 12]| -> [f64; 12] {
            let (q, v) = (&s[..6], &s[6..]);
            let pose = Pose::from_coordinates(Motion::Spatial, q).unwrap();
            let a = plant.platform_acceleration(&pose, v, &[0.0; 6]).unwrap();
            let (sp, cp) = q[4].sin_cos();
            let (sy, cy) = q[5].sin_cos();
            let roll = (cy * v[3] + sy * v[4]) / cp;
            let mut d = [0.0; 12];
            d[..3].copy_from_slice(&v[..3]);
            d[3] = roll;
            d[4] = -sy * v[3] + cy * v[4];
            d[5] = v[5] + sp * roll;
            d[6..].copy_from_slice(&a);
            d
        };
        let mut s = [
            0.0, 0.0, 0.0, 0.1, -0.2, 0.3, 0.05, -0.02, 0.01, 1.5, -0.7, 2.0,
        ];
        let (e0, p0, l0) = body(&s[..6], &s[6..]);
        let h = 1e-4;
        for _ in 0..5000 {
            let k1 = f(&s);
            let k2 = f(&std::array::from_fn(|i| s[i] + 0.5 * h * k1[i]));
            let k3 = f(&std::array::from_fn(|i| s[i] + 0.5 * h * k2[i]));
            let k4 = f(&std::array::from_fn(|i| s[i] + h * k3[i]));
            s = std::array::from_fn(|i| {
                s[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
            });
        }
        let (e1, p1, l1) = body(&s[..6], &s[6..]);
        assert!((e1 - e0).abs() < 1e-9 * e0, "energy {e0} -> {e1}");
        assert!((p1 - p0).norm() < 1e-9, "momentum {p0} -> {p1}");
        assert!((l1 - l0).norm() < 1e-9, "angular momentum {l0} -> {l1}");
    }

    /// Seed 002's force loop: frictionless, the feed-forward alone tracks `f_d`; with pulley
    /// friction between the sensor and the platform, feeding back the platform-side tension
    /// takes the error down by about `1/(1 + k_p)`, while feeding back the winch-side sensor
    /// cannot (it reads the friction as tension).
    #[test]
    fn the_force_loop_needs_the_platform_side_tension() {
        let robot = planar_robot();
        let home = [0.5, 0.4, 0.0];
        let poses = circle(&home, 3, 0.05, 2.0, 1e-3, 4.0);
        let plain = CdprPlant::new(
            &robot,
            Winch {
                static_friction: 0.0,
                ..Winch::seed003()
            },
            &home,
            PlantOptions::default(),
        )
        .unwrap();
        let r = run(&plain, &poses, Feedback::Open, 0.0);
        assert!(
            rmse(&r.ee, &r.desired) < 0.05,
            "{}",
            rmse(&r.ee, &r.desired)
        );
        assert!(rmse(&r.pose, &poses) < 1e-4);
        assert_eq!(r.infeasible, 0);
        let opts = PlantOptions {
            platform_side: coulomb(0.05, std::f64::consts::PI, 4),
            ..PlantOptions::default()
        };
        let rough = CdprPlant::new(
            &robot,
            Winch {
                static_friction: 0.0,
                ..Winch::seed003()
            },
            &home,
            opts,
        )
        .unwrap();
        let err = |fb, k| {
            let r = run(&rough, &poses, fb, k);
            rmse(&r.ee, &r.desired)
        };
        let open = err(Feedback::Open, 0.0);
        assert!(open > 1.0, "{open}");
        let (p07, p3) = (err(Feedback::Platform, 0.7), err(Feedback::Platform, 3.0));
        assert!(
            p07 < 0.7 * open && p3 < 0.3 * open && p3 < p07,
            "{open} {p07} {p3}"
        );
        let s07 = err(Feedback::Sensor, 0.7);
        assert!(s07 > 0.95 * open, "{open} {s07}");
    }

    #[test]
    fn bad_input_is_a_typed_error() {
        let robot = planar_robot();
        let home = [0.5, 0.4, 0.0];
        let plant =
            CdprPlant::new(&robot, Winch::seed003(), &home, PlantOptions::default()).unwrap();
        let poses = vec![0.5, 0.4, 0.0, 0.5, 0.4, 0.0];
        let mut o = LoopOptions::new(1e-3);
        o.feedback = Feedback::Network;
        assert!(matches!(
            closed_loop(&plant, &poses, &o, None, None, None),
            Err(CableError::InvalidOption { .. })
        ));
        let mut o = LoopOptions::new(1e-3);
        o.substeps = 0;
        assert!(matches!(
            closed_loop(&plant, &poses, &o, None, None, None),
            Err(CableError::InvalidParameter { .. })
        ));
        let o = LoopOptions::new(1e-3);
        assert!(matches!(
            closed_loop(&plant, &poses[..4], &o, None, None, None),
            Err(CableError::Shape { .. })
        ));
        assert!(matches!(
            closed_loop(&plant, &poses, &o, Some(&[0.0; 3]), None, None),
            Err(CableError::Shape { .. })
        ));
        let mut bad = poses.clone();
        bad[1] = f64::NAN;
        assert!(matches!(
            closed_loop(&plant, &bad, &o, None, None, None),
            Err(CableError::NotFinite { .. })
        ));
        // outside the frame: the weight cannot be held
        assert!(CdprPlant::new(
            &robot,
            Winch::seed003(),
            &[0.5, 2.0, 0.0],
            PlantOptions::default()
        )
        .is_err());
        let mut light = robot.clone();
        light.platform.mass = 0.0;
        assert!(matches!(
            CdprPlant::new(&light, Winch::seed003(), &home, PlantOptions::default()),
            Err(CableError::InvalidParameter { .. })
        ));
        let opts = PlantOptions {
            platform_side: coulomb(0.05, 1.0, 3),
            ..PlantOptions::default()
        };
        assert!(matches!(
            CdprPlant::new(&robot, Winch::seed003(), &home, opts),
            Err(CableError::Shape { .. })
        ));
        let opts = PlantOptions {
            cable_damping: -1.0,
            ..PlantOptions::default()
        };
        assert!(CdprPlant::new(&robot, Winch::seed003(), &home, opts).is_err());
    }
}
