//! Grey-box least-squares problem of a nominal [`Plant`] — the antagonistic joint or the cable
//! transmission: recorded runs, the nominal model, a set of candidate effects, and the residual
//! `prediction − measurement` through the RK4 simulator.
//!
//! A run holds the recorded input (joint: the motor displacement `x_m` in m; transmission: the
//! motor torques `(T, n)` in the model's torque convention), optionally a coupled-axis signal
//! (joint), an external joint torque (`(T, 1)` joint, `(T, n)` transmission), an initial state,
//! and the measured channels. The prediction for parameters `θ` of the active effects is
//!
//! 1. input stage: joint: `x = x_m + κ_c·x_c` (coupling), play of half-width `δ` (backlash),
//!    delay `d` (time delay), `ẋ` by central differences; transmission: the torques delayed by `d`;
//! 2. plant stage: the augmented plant simulated with the problem's substeps — joint: first-order
//!    input hold from `θ₀ = x(0)/r`, at rest, cables at pretension; transmission: zero-order hold
//!    (torques from a digital controller) from the run's initial state, or rest;
//! 3. sensor stage, on force-sensor channels only: first-order lag, sample-and-hold, gain and bias.
//!
//! Residuals are `w_c·(ŷ_c − y_c)` over samples `start..T` of each run (the first samples are a
//! warm-up that absorbs the unknown initial state) and channels `c` with weights `w_c` (1/noise).

use crate::cable::{CableLaw, Creep};
use crate::control::{simulate_closed_loop_into, ClosedLoopMut, MotorPd};
use crate::dynamics::{AntagonisticJoint, CableTransmission, Model};
use crate::error::{check, CableError, Result};
use crate::friction::Dahl;
use crate::integrate::{propose_step, simulate_into, InputHold, SimOptions, TrajectoryMut};

use super::effects::{Effect, ParamSpec, Scales};
use super::lm::{least_squares, LmOptions, LmReport};
use super::signal;

/// Number of outputs of the antagonistic joint as the diagnosis simulates it.
const N_OUT: usize = 7;

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
    /// Number of outputs a channel may index.
    pub fn n_outputs(&self) -> usize {
        match self {
            Plant::Joint(_) => N_OUT,
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

    /// Whether effect `e` applies to this plant.
    pub fn supports(&self, e: Effect) -> bool {
        match self {
            Plant::Joint(_) => true,
            Plant::Transmission(t) | Plant::Servo(t, _) => e.applies_to_transmission(t.n_links()),
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

/// The antagonistic joint as the diagnosis simulates it: a recorded external joint torque
/// `τ_ext` (N·m, positive along `θ`) as a third input, and the net motor-side cable force
/// `T_m,1 − T_m,2` (N; times the capstan radius it is the drive torque a spindle sensor
/// measures) as a seventh output.
struct LoadedJoint<'a>(&'a AntagonisticJoint);

impl Model for LoadedJoint<'_> {
    fn n_states(&self) -> usize {
        self.0.n_states()
    }
    fn n_inputs(&self) -> usize {
        3
    }
    fn n_outputs(&self) -> usize {
        N_OUT
    }
    fn derivative(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
        self.0.derivative(x, &u[..2], dx);
        dx[1] += u[2] / self.0.inertia;
    }
    fn output(&self, x: &[f64], u: &[f64], y: &mut [f64]) {
        self.0.output(x, &u[..2], &mut y[..6]);
        y[6] = y[0] - y[1];
    }
    fn state_names(&self) -> Vec<String> {
        self.0.state_names()
    }
    fn input_names(&self) -> Vec<String> {
        vec!["x_m".into(), "dx_m".into(), "tau_ext".into()]
    }
    fn output_names(&self) -> Vec<String> {
        let mut v = self.0.output_names();
        v.push("net_motor_force".into());
        v
    }
}

/// One measured channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Channel {
    /// Index into the outputs `[T_m,1, T_m,2, T_j,1, T_j,2, θ, F_c, T_m,1 − T_m,2]`.
    pub output: usize,
    /// Residual weight (1 / noise standard deviation), > 0.
    pub weight: f64,
    /// Whether sensor-stage effects (lag, sampling, gain/bias) apply: force sensors yes,
    /// encoders no.
    pub sensor: bool,
}

/// One recorded run.
#[derive(Debug, Clone, PartialEq)]
pub struct JointRun {
    /// Sample interval (s).
    pub dt: f64,
    /// Recorded input, row-major `(T, width)`: joint `x_m` (m); transmission motor torques.
    pub input: Vec<f64>,
    /// Columns of `input` (joint 1, transmission `n`).
    pub width: usize,
    /// Initial state (the plant's layout), or empty for the default.
    pub x0: Vec<f64>,
    /// Coupled-axis signal, length `T`, or empty.
    pub coupled: Vec<f64>,
    /// External joint torque(s), row-major `(T, width)` (N·m, or N on a prismatic link), or
    /// empty (none).
    pub external: Vec<f64>,
    /// Measured channels, row-major `(T, q)`.
    pub measured: Vec<f64>,
    /// First sample that counts in the residual.
    pub start: usize,
}

impl JointRun {
    /// Number of samples `T`.
    pub fn len(&self) -> usize {
        self.input.len() / self.width.max(1)
    }

    /// Whether the run has no samples.
    pub fn is_empty(&self) -> bool {
        self.input.is_empty()
    }

    /// Column `c` of the input.
    fn input_column(&self, c: usize) -> Vec<f64> {
        self.input
            .iter()
            .skip(c)
            .step_by(self.width.max(1))
            .copied()
            .collect()
    }
}

/// The effect-augmented pieces for one parameter vector.
#[derive(Debug, Clone, PartialEq)]
pub struct Augmented {
    /// Plant model.
    pub model: Plant,
    /// Coupling gain `κ_c`.
    pub coupling: f64,
    /// Play half-width `δ` (m).
    pub backlash: f64,
    /// Delay `d` (s).
    pub delay: f64,
    /// Sensor lag `τ_s` (s).
    pub lag: f64,
    /// Sample-and-hold `(period, phase)` (s); period 0 = continuous.
    pub sampling: (f64, f64),
    /// Per sensor channel `(gain error, bias)`.
    pub gain_bias: Vec<(f64, f64)>,
}

/// Grey-box problem: nominal model, channels, runs and active effects.
#[derive(Debug, Clone)]
pub struct JointProblem {
    nominal: Plant,
    channels: Vec<Channel>,
    runs: Vec<JointRun>,
    effects: Vec<Effect>,
    specs: Vec<ParamSpec>,
    scales: Scales,
    substeps: usize,
}

impl JointProblem {
    /// Validated problem. `effects` may be empty (the nominal model alone).
    pub fn new(
        nominal: impl Into<Plant>,
        channels: Vec<Channel>,
        runs: Vec<JointRun>,
        effects: Vec<Effect>,
        substeps: usize,
    ) -> Result<Self> {
        let nominal: Plant = nominal.into();
        if channels.is_empty() || runs.is_empty() {
            return Err(CableError::Shape {
                what: "diagnosis problem".into(),
                expected: "at least one channel and one run".into(),
                got: format!("{} channels, {} runs", channels.len(), runs.len()),
            });
        }
        for (i, c) in channels.iter().enumerate() {
            if c.output >= nominal.n_outputs() {
                return Err(CableError::InvalidParameter {
                    name: format!("channels[{i}].output"),
                    value: c.output as f64,
                    requirement: "an output index of the plant (joint 0..7, transmission 0..5n)",
                });
            }
            check::positive(&format!("channels[{i}].weight"), c.weight)?;
        }
        let q = channels.len();
        let mut effects = effects;
        effects.sort_unstable();
        effects.dedup();
        if let Some(e) = effects.iter().find(|e| !nominal.supports(**e)) {
            return Err(CableError::InvalidOption {
                name: "effect".into(),
                value: e.name().into(),
                allowed: format!("an effect that applies to the {}", nominal.name()),
            });
        }
        let width = nominal.input_width();
        for (i, r) in runs.iter().enumerate() {
            check::positive(&format!("runs[{i}].dt"), r.dt)?;
            let t = r.len();
            let optional_ok = |v: &Vec<f64>, w: usize| v.is_empty() || v.len() == t * w;
            if t < 4
                || r.width != width
                || r.input.len() != t * width
                || r.measured.len() != t * q
                || !optional_ok(&r.coupled, 1)
                || !optional_ok(&r.external, width)
            {
                return Err(CableError::Shape {
                    what: format!("runs[{i}]"),
                    expected: format!(
                        "input (T >= 4, {width}), measured (T, {q}), coupled (T,) and external \
                         (T, {width}) or empty"
                    ),
                    got: format!(
                        "input {} values in {} columns, measured {} values, coupled {}, external {}",
                        r.input.len(),
                        r.width,
                        r.measured.len(),
                        r.coupled.len(),
                        r.external.len()
                    ),
                });
            }
            if r.start >= t {
                return Err(CableError::InvalidParameter {
                    name: format!("runs[{i}].start"),
                    value: r.start as f64,
                    requirement: "smaller than the run length",
                });
            }
            check::all_finite(&format!("runs[{i}].input"), &r.input, width)?;
            check::all_finite(&format!("runs[{i}].x0"), &r.x0, 1)?;
            check::all_finite(&format!("runs[{i}].measured"), &r.measured, q)?;
            check::all_finite(&format!("runs[{i}].coupled"), &r.coupled, 1)?;
            check::all_finite(&format!("runs[{i}].external"), &r.external, width)?;
            let joint = matches!(nominal, Plant::Joint(_));
            if joint && effects.contains(&Effect::Coupling) && r.coupled.is_empty() {
                return Err(CableError::InvalidOption {
                    name: format!("runs[{i}].coupled"),
                    value: "missing".into(),
                    allowed: "a coupled-axis signal, required by the coupling effect".into(),
                });
            }
        }
        if substeps == 0 {
            return Err(CableError::InvalidParameter {
                name: "substeps".into(),
                value: 0.0,
                requirement: "an integer >= 1",
            });
        }
        let scales = scales_of(&nominal, &channels, &runs);
        let specs = effects.iter().flat_map(|e| e.params(&scales)).collect();
        Ok(Self {
            nominal,
            channels,
            runs,
            effects,
            specs,
            scales,
            substeps,
        })
    }

    /// The same data with another set of effects (and substeps).
    pub fn with_effects(&self, effects: Vec<Effect>, substeps: usize) -> Result<Self> {
        Self::new(
            self.nominal.clone(),
            self.channels.clone(),
            self.runs.clone(),
            effects,
            substeps,
        )
    }

    /// RK4 substeps per sample interval.
    pub fn substeps(&self) -> usize {
        self.substeps
    }

    /// Active effects (sorted, unique).
    pub fn effects(&self) -> &[Effect] {
        &self.effects
    }

    /// Parameter specs of the active effects, concatenated in effect order.
    pub fn specs(&self) -> &[ParamSpec] {
        &self.specs
    }

    /// Typical magnitudes of the data.
    pub fn scales(&self) -> &Scales {
        &self.scales
    }

    /// The runs.
    pub fn runs(&self) -> &[JointRun] {
        &self.runs
    }

    /// Number of residuals.
    pub fn n_residuals(&self) -> usize {
        self.runs
            .iter()
            .map(|r| (r.len() - r.start) * self.channels.len())
            .sum()
    }

    /// Reference parameters (every effect off).
    pub fn reference(&self) -> Vec<f64> {
        self.specs.iter().map(|s| s.reference).collect()
    }

    /// Build the augmented model and operators for `theta`.
    pub fn augment(&self, theta: &[f64]) -> Result<Augmented> {
        check::len("theta", theta, self.specs.len())?;
        check::all_finite("theta", theta, 1)?;
        let mut a = Augmented {
            model: self.nominal.clone(),
            coupling: 0.0,
            backlash: 0.0,
            delay: 0.0,
            lag: 0.0,
            sampling: (0.0, 0.0),
            gain_bias: vec![(0.0, 0.0); self.n_sensor_channels()],
        };
        // (effect, its parameters) in order; operators are plant-independent
        let mut plant_effects = Vec::new();
        let mut k = 0;
        for &e in &self.effects {
            let n = e.params(&self.scales).len();
            let p = &theta[k..k + n];
            k += n;
            match e {
                Effect::Backlash => a.backlash = p[0].max(0.0),
                Effect::SensorLag => a.lag = p[0].max(0.0),
                Effect::SensorSampling => a.sampling = (p[0].max(0.0), p[1].max(0.0)),
                Effect::TimeDelay => a.delay = p[0].max(0.0),
                Effect::SensorGainBias => {
                    for (i, gb) in a.gain_bias.iter_mut().enumerate() {
                        *gb = (p[2 * i], p[2 * i + 1]);
                    }
                }
                Effect::Coupling if matches!(self.nominal, Plant::Joint(_)) => a.coupling = p[0],
                _ => plant_effects.push((e, p)),
            }
        }
        a.model = match &self.nominal {
            Plant::Joint(nom) => Plant::Joint(augment_joint(nom, &plant_effects)),
            Plant::Transmission(nom) => {
                Plant::Transmission(augment_transmission(nom, &plant_effects)?)
            }
            Plant::Servo(nom, pd) => {
                Plant::Servo(augment_transmission(nom, &plant_effects)?, pd.clone())
            }
        };
        Ok(a)
    }

    fn n_sensor_channels(&self) -> usize {
        self.channels.iter().filter(|c| c.sensor).count()
    }

    /// Joint input after the input stage: `(T, 3)` row-major `[x, ẋ, τ_ext]`.
    fn joint_inputs(&self, a: &Augmented, run: &JointRun) -> Vec<f64> {
        let t = run.len();
        let mut x: Vec<f64> = if a.coupling != 0.0 {
            run.input
                .iter()
                .zip(&run.coupled)
                .map(|(xm, xc)| xm + a.coupling * xc)
                .collect()
        } else {
            run.input.clone()
        };
        let mut tmp = vec![0.0; t];
        if a.backlash > 0.0 {
            signal::play(&x, a.backlash, &mut tmp);
            std::mem::swap(&mut x, &mut tmp);
        }
        if a.delay > 0.0 {
            signal::delay(&x, a.delay, run.dt, &mut tmp);
            std::mem::swap(&mut x, &mut tmp);
        }
        signal::velocity(&x, run.dt, &mut tmp);
        (0..t)
            .flat_map(|k| [x[k], tmp[k], run.external.get(k).copied().unwrap_or(0.0)])
            .collect()
    }

    /// Transmission input after the input stage: `(T, 2n)` row-major `[τ_m (n), τ_ext (n)]`,
    /// the motor torques delayed by `d`.
    fn transmission_inputs(&self, a: &Augmented, run: &JointRun) -> Vec<f64> {
        let (t, n) = (run.len(), run.width);
        let mut cols: Vec<Vec<f64>> = (0..n).map(|c| run.input_column(c)).collect();
        if a.delay > 0.0 {
            let mut tmp = vec![0.0; t];
            for col in &mut cols {
                signal::delay(col, a.delay, run.dt, &mut tmp);
                col.copy_from_slice(&tmp);
            }
        }
        let mut u = vec![0.0; t * 2 * n];
        for k in 0..t {
            for c in 0..n {
                u[k * 2 * n + c] = cols[c][k];
                u[k * 2 * n + n + c] = run.external.get(k * n + c).copied().unwrap_or(0.0);
            }
        }
        u
    }

    /// Plant outputs of run `i` for `a` (before the sensor stage): joint `(T, 7)`
    /// `[T_m,1, T_m,2, T_j,1, T_j,2, θ, F_c, T_m,1 − T_m,2]`; transmission `(T, 5n)`.
    pub fn plant_outputs(&self, a: &Augmented, i: usize) -> Result<Vec<f64>> {
        let run = &self.runs[i];
        let t = run.len();
        match &a.model {
            Plant::Joint(joint) => {
                let u = self.joint_inputs(a, run);
                let mut x0 = vec![0.0; joint.n_states()];
                x0[0] = u[0] / joint.radius;
                run_into(
                    &LoadedJoint(joint),
                    &u,
                    &x0,
                    run,
                    self.substeps,
                    InputHold::Foh,
                )
            }
            Plant::Transmission(tr) => {
                let u = self.transmission_inputs(a, run);
                let x0 = if run.x0.len() == tr.n_states() {
                    run.x0.clone()
                } else {
                    tr.rest_state()
                };
                debug_assert_eq!(u.len(), t * tr.n_inputs());
                run_into(tr, &u, &x0, run, self.substeps, InputHold::Zoh)
            }
            Plant::Servo(tr, pd) => {
                let n = tr.n_links();
                let mut cols: Vec<Vec<f64>> = (0..2 * n).map(|c| run.input_column(c)).collect();
                if a.delay > 0.0 {
                    let mut tmp = vec![0.0; t];
                    for col in &mut cols {
                        signal::delay(col, a.delay, run.dt, &mut tmp);
                        col.copy_from_slice(&tmp);
                    }
                }
                let refs: Vec<f64> = (0..t)
                    .flat_map(|k| cols.iter().map(move |c| c[k]))
                    .collect();
                let ext = if run.external.is_empty() {
                    vec![0.0; t * n]
                } else {
                    run.external.clone()
                };
                let x0 = if run.x0.len() == tr.n_states() {
                    run.x0.clone()
                } else {
                    tr.rest_state()
                };
                let (p, m) = (tr.n_outputs(), tr.n_inputs());
                let (outputs, applied) =
                    servo_into(tr, pd, &refs, &ext, &x0, run.dt, self.substeps)?;
                Ok((0..t)
                    .flat_map(|k| {
                        outputs[k * p..(k + 1) * p]
                            .iter()
                            .chain(&applied[k * m..k * m + n])
                            .copied()
                            .collect::<Vec<_>>()
                    })
                    .collect())
            }
        }
    }

    /// Predicted measurements `(T, q)` of run `i` from plant outputs, through the sensor stage.
    pub fn sensor_stage(&self, a: &Augmented, i: usize, plant: &[f64]) -> Vec<f64> {
        let run = &self.runs[i];
        let (t, q) = (run.len(), self.channels.len());
        let mut pred = vec![0.0; t * q];
        let mut col = vec![0.0; t];
        let mut tmp = vec![0.0; t];
        let mut sensor_i = 0;
        let n_out = self.nominal.n_outputs();
        for (c, ch) in self.channels.iter().enumerate() {
            for k in 0..t {
                col[k] = plant[k * n_out + ch.output];
            }
            if ch.sensor {
                if a.lag > 0.0 {
                    signal::first_order_lag(&col, a.lag, run.dt, &mut tmp);
                    std::mem::swap(&mut col, &mut tmp);
                }
                if a.sampling.0 > 0.0 {
                    signal::sample_hold(&col, a.sampling.0, a.sampling.1, run.dt, &mut tmp);
                    std::mem::swap(&mut col, &mut tmp);
                }
                let (g, b) = a.gain_bias[sensor_i];
                if g != 0.0 || b != 0.0 {
                    signal::gain_bias(&col, 1.0 + g, b, &mut tmp);
                    std::mem::swap(&mut col, &mut tmp);
                }
                sensor_i += 1;
            }
            for k in 0..t {
                pred[k * q + c] = col[k];
            }
        }
        pred
    }

    /// Predicted measurements `(T, q)` of run `i` at `theta`.
    pub fn predict(&self, theta: &[f64], i: usize) -> Result<Vec<f64>> {
        if i >= self.runs.len() {
            return Err(CableError::InvalidParameter {
                name: "run index".into(),
                value: i as f64,
                requirement: "smaller than the number of runs",
            });
        }
        let a = self.augment(theta)?;
        let plant = self.plant_outputs(&a, i)?;
        Ok(self.sensor_stage(&a, i, &plant))
    }

    /// Weighted residuals at `theta` into `r` (length [`Self::n_residuals`]).
    pub fn residuals(&self, theta: &[f64], r: &mut [f64]) -> Result<()> {
        check::len("residuals", r, self.n_residuals())?;
        let a = self.augment(theta)?;
        let mut off = 0;
        for i in 0..self.runs.len() {
            let plant = self.plant_outputs(&a, i)?;
            let pred = self.sensor_stage(&a, i, &plant);
            off += self.write_residuals(i, &pred, &mut r[off..]);
        }
        Ok(())
    }

    fn write_residuals(&self, i: usize, pred: &[f64], r: &mut [f64]) -> usize {
        let run = &self.runs[i];
        let q = self.channels.len();
        let mut j = 0;
        for k in run.start..run.len() {
            for (c, ch) in self.channels.iter().enumerate() {
                r[j] = ch.weight * (pred[k * q + c] - run.measured[k * q + c]);
                j += 1;
            }
        }
        j
    }

    /// Fit the active effects' parameters from `theta0`, or, by default, from the two best of
    /// the specs' starting combinations (keeping the better local optimum). Grid parameters
    /// (sample-and-hold) are searched on a grid first with the other parameters at their start
    /// values, then held while the rest is fitted.
    pub fn fit(&self, theta0: Option<&[f64]>, opts: &LmOptions) -> Result<LmReport> {
        let starts: Vec<Vec<f64>> = match theta0 {
            Some(t) => {
                check::len("theta0", t, self.specs.len())?;
                vec![t.to_vec()]
            }
            // two local searches for small problems, one for large ones (each LM iteration
            // costs p + 1 simulations)
            None => {
                let keep = if self.specs.len() <= 2 { 2 } else { 1 };
                self.best_starts(self.specs.iter().map(|s| s.initial).collect(), keep)
            }
        };
        let mut best: Option<LmReport> = None;
        let mut last_err = None;
        for x0 in starts {
            match self.fit_from(x0, opts) {
                Ok(rep) => {
                    if best.as_ref().is_none_or(|b| rep.cost < b.cost) {
                        best = Some(rep);
                    }
                }
                Err(e) => last_err = Some(e),
            }
        }
        match (best, last_err) {
            (Some(b), _) => Ok(b),
            (None, Some(e)) => Err(e),
            (None, None) => unreachable!("at least one start"),
        }
    }

    fn fit_from(&self, mut x0: Vec<f64>, opts: &LmOptions) -> Result<LmReport> {
        if self.effects.contains(&Effect::SensorSampling) {
            let (period, phase) = self.grid_sample_hold(&x0)?;
            let k = self.offset_of(Effect::SensorSampling);
            x0[k] = period;
            x0[k + 1] = phase;
        }
        let (mut lower, mut upper): (Vec<f64>, Vec<f64>) =
            self.specs.iter().map(|s| (s.lower, s.upper)).unzip();
        for (j, s) in self.specs.iter().enumerate() {
            if s.grid {
                lower[j] = x0[j];
                upper[j] = x0[j];
            }
        }
        let scale: Vec<f64> = self.specs.iter().map(|s| s.scale).collect();
        least_squares(
            |th, r| self.residuals(th, r),
            &x0,
            &lower,
            &upper,
            &scale,
            self.n_residuals(),
            opts,
        )
    }

    /// The `keep` lowest-cost combinations of the specs' starting values (`initial` and
    /// `starts`, at most 27 combinations); combinations whose simulation fails are skipped.
    fn best_starts(&self, x0: Vec<f64>, keep: usize) -> Vec<Vec<f64>> {
        let options: Vec<Vec<f64>> = self
            .specs
            .iter()
            .zip(&x0)
            .map(|(s, &x)| std::iter::once(x).chain(s.starts.iter().copied()).collect())
            .collect();
        let total: usize = options.iter().map(Vec::len).product();
        if total <= 1 || total > 27 {
            return vec![x0];
        }
        let mut r = vec![0.0; self.n_residuals()];
        let mut scored: Vec<(f64, Vec<f64>)> = Vec::new();
        for mut code in 0..total {
            let x: Vec<f64> = options
                .iter()
                .map(|o| {
                    let v = o[code % o.len()];
                    code /= o.len();
                    v
                })
                .collect();
            if self.residuals(&x, &mut r).is_ok() {
                scored.push((r.iter().map(|v| v * v).sum(), x));
            }
        }
        if scored.is_empty() {
            return vec![x0];
        }
        scored.sort_by(|a, b| a.0.total_cmp(&b.0));
        scored.into_iter().take(keep).map(|(_, x)| x).collect()
    }

    /// Offset of effect `e`'s parameters in `theta`.
    fn offset_of(&self, e: Effect) -> usize {
        self.effects
            .iter()
            .take_while(|&&f| f != e)
            .map(|f| f.params(&self.scales).len())
            .sum()
    }

    /// Grid search of the sample-and-hold period and phase with the other parameters at
    /// `theta`: periods log-spaced from 2·dt to a quarter of the shortest run, 12 phases each.
    /// The plant is simulated once per run.
    pub fn grid_sample_hold(&self, theta: &[f64]) -> Result<(f64, f64)> {
        let k = self.offset_of(Effect::SensorSampling);
        let mut th = theta.to_vec();
        th[k] = 0.0;
        let a0 = self.augment(&th)?;
        let plants: Vec<Vec<f64>> = (0..self.runs.len())
            .map(|i| self.plant_outputs(&a0, i))
            .collect::<Result<_>>()?;
        let dt = self.scales.dt;
        let mut r = vec![0.0; self.n_residuals()];
        let mut cost = |period: f64, phase: f64| -> f64 {
            let mut a = a0.clone();
            a.sampling = (period, phase);
            let mut off = 0;
            for (i, plant) in plants.iter().enumerate() {
                let pred = self.sensor_stage(&a, i, plant);
                off += self.write_residuals(i, &pred, &mut r[off..]);
            }
            r.iter().map(|v| v * v).sum::<f64>()
        };
        let mut best = (f64::INFINITY, 0.0, 0.0);
        let consider = |c: f64, period: f64, phase: f64, best: &mut (f64, f64, f64)| {
            if c < best.0 {
                *best = (c, period, phase);
            }
        };
        // coarse: log-spaced periods, 12 phases each
        let (lo, hi) = (2.0 * dt, (0.25 * self.scales.duration).max(4.0 * dt));
        let n_periods = 60;
        for ip in 0..n_periods {
            let period = lo * (hi / lo).powf(ip as f64 / (n_periods - 1) as f64);
            let n_phase = 12.min((period / dt).round() as usize).max(1);
            for jp in 0..n_phase {
                let phase = period * jp as f64 / n_phase as f64;
                consider(cost(period, phase), period, phase, &mut best);
            }
        }
        // a held signal shows its update instants directly: take them as a further candidate
        if let Some((period, phase)) = self.hold_from_updates() {
            consider(cost(period, phase), period, phase, &mut best);
        }
        // fine: ±12 % around the best period, phases at the sample resolution
        let (_, p0, _) = best;
        for ip in 0..=24 {
            let period = p0 * (0.88 + 0.01 * ip as f64);
            let n_phase = ((period / dt).ceil() as usize).max(1);
            for jp in 0..n_phase {
                let phase = jp as f64 * dt;
                consider(cost(period, phase), period, phase, &mut best);
            }
        }
        Ok((best.1, best.2))
    }

    /// Sample-and-hold period and phase read off the update instants of the measured force
    /// channels (samples where a held signal changes), when the first sensor channel of the
    /// first run changes at fewer than half of its samples; `None` otherwise.
    ///
    /// The instants `t_j` are fitted by least squares to `phase + n_j·period`, with `n_j` the
    /// update count accumulated from the intervals in units of the median interval, so missed
    /// updates (a value that did not change) do not bias the estimate.
    pub fn hold_from_updates(&self) -> Option<(f64, f64)> {
        let c = self.channels.iter().position(|c| c.sensor)?;
        let run = &self.runs[0];
        let q = self.channels.len();
        let y: Vec<f64> = (0..run.len()).map(|k| run.measured[k * q + c]).collect();
        let events: Vec<f64> = (1..y.len())
            .filter(|&k| y[k].to_bits() != y[k - 1].to_bits()) // a held value repeats exactly
            .map(|k| k as f64 * run.dt)
            .collect();
        if events.len() < 3 || 2 * events.len() > y.len() {
            return None;
        }
        let mut gaps: Vec<f64> = events.windows(2).map(|w| w[1] - w[0]).collect();
        gaps.sort_by(f64::total_cmp);
        let p_est = gaps[gaps.len() / 2];
        // update counts from the local intervals (a global (t − t₀)/p would drift by a whole
        // period over a long run when p is only known to a sample)
        let mut n = vec![0.0; events.len()];
        for j in 1..events.len() {
            n[j] = n[j - 1] + ((events[j] - events[j - 1]) / p_est).round().max(1.0);
        }
        let m = events.len() as f64;
        let (sn, st) = (n.iter().sum::<f64>(), events.iter().sum::<f64>());
        let snn: f64 = n.iter().map(|v| v * v).sum();
        let snt: f64 = n.iter().zip(&events).map(|(a, b)| a * b).sum();
        let den = m * snn - sn * sn;
        if den <= 0.0 {
            return None;
        }
        let period = (m * snt - sn * st) / den;
        let first = (st - period * sn) / m;
        // an update seen at sample k was taken at the instant in (t_{k−1}, t_k]
        Some((period, (first - 0.5 * run.dt).rem_euclid(period)))
    }

    /// RK4 substeps the augmented model at `theta` needs at the run's sample interval, from its
    /// stiffest mode at rest (see [`propose_step`]).
    pub fn advised_substeps(&self, theta: &[f64]) -> Result<usize> {
        let a = self.augment(theta)?;
        let mut worst = 1;
        for run in &self.runs {
            let advice = match &a.model {
                Plant::Joint(m) => {
                    let mut x = vec![0.0; m.n_states()];
                    x[0] = run.input[0] / m.radius;
                    propose_step(m, &x, &[run.input[0], 0.0], run.dt, 0.9)?
                }
                Plant::Transmission(m) | Plant::Servo(m, _) => {
                    let x = if run.x0.len() == m.n_states() {
                        run.x0.clone()
                    } else {
                        m.rest_state()
                    };
                    propose_step(m, &x, &vec![0.0; m.n_inputs()], run.dt, 0.9)?
                }
            };
            worst = worst.max(advice.substeps);
        }
        Ok(worst)
    }
}

/// Simulate `model` over a run into fresh output buffers; returns the outputs `(T, p)`.
fn run_into<M: Model>(
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
fn servo_into(
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

/// The antagonistic joint with its plant effects applied.
fn augment_joint(nom: &AntagonisticJoint, effects: &[(Effect, &[f64])]) -> AntagonisticJoint {
    let mut m = *nom;
    let mu_phi_nominal = nom.capstan_mu * nom.capstan_wrap;
    m.capstan_mu = mu_phi_nominal;
    m.capstan_wrap = 1.0;
    for &(e, p) in effects {
        match e {
            Effect::CoulombFriction => {
                m.friction.coulomb += p[0];
                m.friction.static_level += p[0];
                m.friction.smoothing = p[1];
            }
            Effect::ViscousFriction => m.friction.viscous = (m.friction.viscous + p[0]).max(0.0),
            Effect::StribeckFriction => {
                m.friction.coulomb += p[0];
                m.friction.static_level += p[0] + p[1];
                m.friction.stribeck_velocity = p[2];
                m.friction.stribeck_exponent = p[3];
            }
            Effect::DahlHysteresis if p[0] > 0.0 => {
                m.dahl = Some(Dahl {
                    sigma0: p[0] / p[1],
                    coulomb: p[0],
                    exponent: 1.0,
                });
            }
            Effect::CapstanFriction => m.capstan_mu = mu_phi_nominal + p[0],
            Effect::NonlinearStiffness if p[0] != 0.0 => {
                for run in [&mut m.drive, &mut m.ret] {
                    run.law = CableLaw::Exponential {
                        stiffness: run.law.stiffness(),
                        length_scale: 1.0 / p[0],
                    };
                }
            }
            Effect::CableDamping => {
                m.drive.damping = (m.drive.damping + p[0]).max(0.0);
                m.ret.damping = (m.ret.damping + p[0]).max(0.0);
            }
            Effect::Creep if p[0] > 0.0 => {
                m.creep = Some(Creep {
                    fraction: p[0],
                    time_constant: p[1],
                });
            }
            Effect::Slack => {
                m.drive.pretension = (m.drive.pretension - p[0]).max(0.0);
                m.ret.pretension = (m.ret.pretension - p[0]).max(0.0);
            }
            Effect::InertiaError => m.inertia *= 1.0 + p[0],
            // operators, handled by the caller
            _ => {}
        }
    }
    m
}

/// The cable transmission with its plant effects applied (per-link joint effects, shared cable
/// effects, coupling coefficients added to the nominal `C_ij`). Errors when a trial value makes
/// the transmission invalid (the fit rejects that step).
fn augment_transmission(
    nom: &CableTransmission,
    effects: &[(Effect, &[f64])],
) -> Result<CableTransmission> {
    let n = nom.n_links();
    let mut links = nom.links().to_vec();
    let mut coupling = nom.coupling();
    for &(e, p) in effects {
        match e {
            Effect::CoulombFriction => {
                for (l, f) in links.iter_mut().zip(p) {
                    l.link_friction.coulomb += f;
                    l.link_friction.static_level += f;
                }
            }
            Effect::ViscousFriction => {
                for (l, b) in links.iter_mut().zip(p) {
                    l.link_friction.viscous = (l.link_friction.viscous + b).max(0.0);
                }
            }
            Effect::InertiaError => {
                for (l, eps) in links.iter_mut().zip(p) {
                    l.link_inertia *= 1.0 + eps;
                }
            }
            Effect::NonlinearStiffness if p[0] > 0.0 => {
                for l in &mut links {
                    l.cable.run.law = CableLaw::Exponential {
                        stiffness: l.cable.run.law.stiffness(),
                        length_scale: 1.0 / p[0],
                    };
                }
            }
            Effect::CableDamping => {
                for l in &mut links {
                    l.cable.run.damping = (l.cable.run.damping + p[0]).max(0.0);
                }
            }
            Effect::Slack => {
                for l in &mut links {
                    l.cable.run.pretension *= 1.0 - p[0];
                }
            }
            Effect::Coupling => {
                let mut c = 0;
                for i in 1..n {
                    for j in 0..i {
                        coupling[i * n + j] += p[c];
                        c += 1;
                    }
                }
            }
            _ => {}
        }
    }
    CableTransmission::new(links, &coupling)
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    if n == 0 {
        0.0
    } else {
        (s / n as f64).sqrt()
    }
}

fn scales_of(nominal: &Plant, channels: &[Channel], runs: &[JointRun]) -> Scales {
    match nominal {
        Plant::Joint(j) => joint_scales(j, channels, runs),
        Plant::Transmission(t) => transmission_scales(t, None, channels, runs),
        Plant::Servo(t, pd) => transmission_scales(t, Some(pd), channels, runs),
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
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::friction::StaticFriction;
    use approx::assert_relative_eq;

    fn nominal() -> AntagonisticJoint {
        let mut j = AntagonisticJoint::forceps_example();
        j.contact = None;
        j.friction = StaticFriction {
            viscous: 2e-5,
            ..StaticFriction::NONE
        };
        j.friction.smoothing = 0.5;
        j.inertia = 2e-6;
        j.capstan_mu = 0.0;
        j
    }

    fn run(seconds: f64) -> JointRun {
        let dt = 1e-3;
        let t_len = (seconds / dt) as usize;
        let input = (0..t_len)
            .map(|k| {
                let t = k as f64 * dt;
                1e-3 * (2.0 * std::f64::consts::PI * 0.7 * t).sin()
                    + 3e-4 * (2.0 * std::f64::consts::PI * 2.3 * t).sin()
            })
            .collect();
        JointRun {
            dt,
            input,
            width: 1,
            x0: vec![],
            coupled: vec![],
            external: vec![],
            measured: vec![0.0; t_len * 3],
            start: 50,
        }
    }

    fn channels() -> Vec<Channel> {
        vec![
            Channel {
                output: 0,
                weight: 1.0,
                sensor: true,
            },
            Channel {
                output: 1,
                weight: 1.0,
                sensor: true,
            },
            Channel {
                output: 4,
                weight: 100.0,
                sensor: false,
            },
        ]
    }

    /// Data generated by the problem itself at `truth`, then fitted from the spec start.
    fn recover(effect: Effect, truth: &[f64], rel: f64) {
        let base =
            JointProblem::new(nominal(), channels(), vec![run(3.0)], vec![effect], 4).unwrap();
        let mut data = base.runs()[0].clone();
        data.measured = base.predict(truth, 0).unwrap();
        let p = JointProblem::new(nominal(), channels(), vec![data], vec![effect], 4).unwrap();
        let fit = p.fit(None, &LmOptions::default()).unwrap();
        for (got, want) in fit.params.iter().zip(truth) {
            assert_relative_eq!(*got, *want, max_relative = rel, epsilon = 1e-12);
        }
        assert!(
            fit.cost < 1e-10 * fit.initial_cost.max(1e-30) + 1e-20,
            "{effect:?} {fit:?}"
        );
    }

    #[test]
    fn injected_effects_are_recovered_exactly_on_noise_free_data() {
        recover(Effect::CoulombFriction, &[4e-3, 0.2], 1e-4);
        recover(Effect::SensorLag, &[0.02], 1e-4);
        recover(Effect::Backlash, &[1e-4], 1e-3);
        recover(Effect::Slack, &[3.0], 1e-4);
        recover(Effect::SensorGainBias, &[0.05, -0.4, -0.02, 0.3], 1e-4);
    }

    #[test]
    fn sample_hold_is_found_by_grid_search() {
        let base = JointProblem::new(
            nominal(),
            channels(),
            vec![run(3.0)],
            vec![Effect::SensorSampling],
            4,
        )
        .unwrap();
        let truth = [0.1, 0.04];
        let mut data = base.runs()[0].clone();
        data.measured = base.predict(&truth, 0).unwrap();
        let p = base.with_effects(vec![Effect::SensorSampling], 4).unwrap();
        let p =
            JointProblem::new(nominal(), channels(), vec![data], p.effects().to_vec(), 4).unwrap();
        let (period, phase) = p.grid_sample_hold(&p.reference()).unwrap();
        assert!((period - 0.1).abs() < 0.01, "period {period}");
        assert!((phase - 0.04).abs() <= 0.1 / 12.0 + 1e-3, "phase {phase}");
    }

    #[test]
    fn external_torque_is_balanced_by_the_net_cable_force() {
        // held motor, constant load: at rest r·(T_j1 − T_j2) + τ = 0, and without capstan
        // losses the net motor-side force equals the joint-side one
        let tau = 2e-3;
        let t_len = 3000;
        let chans = vec![Channel {
            output: 6,
            weight: 1.0,
            sensor: true,
        }];
        let r = JointRun {
            dt: 1e-3,
            input: vec![1e-4; t_len],
            width: 1,
            x0: vec![],
            coupled: vec![],
            external: vec![tau; t_len],
            measured: vec![0.0; t_len],
            start: 0,
        };
        let p = JointProblem::new(nominal(), chans, vec![r], vec![], 4).unwrap();
        let y = p.predict(&[], 0).unwrap();
        assert_relative_eq!(y[t_len - 1], -tau / nominal().radius, max_relative = 1e-6);
    }

    fn raven_run(seconds: f64) -> JointRun {
        let dt = 1e-3;
        let t_len = (seconds / dt) as usize;
        let input = (0..t_len)
            .flat_map(|k| {
                let t = k as f64 * dt;
                let w = 2.0 * std::f64::consts::PI;
                [
                    0.05 * (w * 0.8 * t).sin() + 0.02 * (w * 3.1 * t).sin(),
                    0.04 * (w * 1.1 * t).cos() + 0.01 * (w * 4.3 * t).sin(),
                ]
            })
            .collect();
        JointRun {
            dt,
            input,
            width: 2,
            x0: vec![],
            coupled: vec![],
            external: vec![],
            measured: vec![0.0; t_len * 4],
            start: 20,
        }
    }

    fn encoder_channels() -> Vec<Channel> {
        [0, 1, 5, 6]
            .iter()
            .map(|&output| Channel {
                output,
                weight: 1e3,
                sensor: false,
            })
            .collect()
    }

    #[test]
    fn transmission_effects_are_recovered() {
        let raven = crate::dynamics::raven2(2).unwrap();
        for (effect, truth) in [
            (Effect::CoulombFriction, vec![0.05, 0.02]),
            (Effect::Coupling, vec![-0.3]),
            (Effect::InertiaError, vec![0.5, -0.3]),
            (Effect::TimeDelay, vec![0.004]),
        ] {
            let base = JointProblem::new(
                raven.clone(),
                encoder_channels(),
                vec![raven_run(2.0)],
                vec![effect],
                4,
            )
            .unwrap();
            let mut data = base.runs()[0].clone();
            data.measured = base.predict(&truth, 0).unwrap();
            let p = JointProblem::new(
                raven.clone(),
                encoder_channels(),
                vec![data],
                vec![effect],
                4,
            )
            .unwrap();
            let fit = p.fit(None, &LmOptions::default()).unwrap();
            for (got, want) in fit.params.iter().zip(&truth) {
                assert_relative_eq!(*got, *want, max_relative = 1e-3);
            }
        }
        // effects without a transmission counterpart are refused by name
        assert!(matches!(
            JointProblem::new(
                raven,
                encoder_channels(),
                vec![raven_run(1.0)],
                vec![Effect::Creep],
                1
            ),
            Err(CableError::InvalidOption { .. })
        ));
    }

    #[test]
    fn servo_replay_recovers_effects_and_reports_applied_torques() {
        let raven = crate::dynamics::raven2(2).unwrap();
        let pd = MotorPd::raven2(2);
        let tr = raven.transmission_matrix();
        let dt = 1e-3;
        let t_len = 2000;
        // motor references for smooth joint sines, q_m = T·q_l
        let input: Vec<f64> = (0..t_len)
            .flat_map(|k| {
                let t = k as f64 * dt;
                let w = 2.0 * std::f64::consts::PI;
                let ql = [0.4 * (w * 0.5 * t).sin(), 0.3 * (w * 0.8 * t).sin()];
                let dql = [
                    0.4 * w * 0.5 * (w * 0.5 * t).cos(),
                    0.3 * w * 0.8 * (w * 0.8 * t).cos(),
                ];
                let qm = [tr[0] * ql[0], tr[2] * ql[0] + tr[3] * ql[1]];
                let dqm = [tr[0] * dql[0], tr[2] * dql[0] + tr[3] * dql[1]];
                [qm[0], qm[1], dqm[0], dqm[1]]
            })
            .collect();
        let chans: Vec<Channel> = [0, 1, 5, 6, 10, 11]
            .iter()
            .map(|&output| Channel {
                output,
                weight: 1e3,
                sensor: output >= 10,
            })
            .collect();
        let run = JointRun {
            dt,
            input,
            width: 4,
            x0: vec![],
            coupled: vec![],
            external: vec![],
            measured: vec![0.0; t_len * 6],
            start: 10,
        };
        let plant = Plant::Servo(raven, pd);
        assert_eq!(plant.n_outputs(), 12);
        for (effect, truth) in [
            (Effect::Coupling, vec![-0.2]),
            (Effect::CoulombFriction, vec![0.2, 0.3]),
        ] {
            let base = JointProblem::new(
                plant.clone(),
                chans.clone(),
                vec![run.clone()],
                vec![effect],
                2,
            )
            .unwrap();
            let mut data = run.clone();
            data.measured = base.predict(&truth, 0).unwrap();
            // the applied torques stay within the servo's limits
            assert!(data
                .measured
                .chunks(6)
                .all(|r| r[4].abs() <= 0.68 && r[5].abs() <= 0.68));
            let p = JointProblem::new(plant.clone(), chans.clone(), vec![data], vec![effect], 2)
                .unwrap();
            let fit = p.fit(None, &LmOptions::default()).unwrap();
            for (got, want) in fit.params.iter().zip(&truth) {
                assert_relative_eq!(*got, *want, max_relative = 1e-3);
            }
        }
    }

    #[test]
    fn bad_problems_are_typed_errors() {
        let mut r = run(1.0);
        r.measured.pop();
        assert!(matches!(
            JointProblem::new(nominal(), channels(), vec![r], vec![], 1),
            Err(CableError::Shape { .. })
        ));
        assert!(matches!(
            JointProblem::new(
                nominal(),
                channels(),
                vec![run(1.0)],
                vec![Effect::Coupling],
                1
            ),
            Err(CableError::InvalidOption { .. })
        ));
        let mut r = run(1.0);
        r.input[3] = f64::NAN;
        assert!(matches!(
            JointProblem::new(nominal(), channels(), vec![r], vec![], 1),
            Err(CableError::NotFinite { .. })
        ));
    }
}
