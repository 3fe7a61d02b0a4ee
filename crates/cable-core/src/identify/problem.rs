//! Grey-box least-squares problem of a nominal [`Plant`] — the antagonistic joint or the cable
//! transmission: recorded runs, the nominal model, a set of candidates (effects at sites, see
//! [`super::site`]), and the residual `prediction − measurement` through the simulator.
//!
//! A run holds the recorded input (joint: the motor displacement `x_m` in m; transmission: the
//! motor torques `(T, n)` in the model's torque convention, or the servo's references),
//! optionally a coupled-axis signal (joint), an external joint torque, an initial state, and the
//! measured channels. The prediction for parameters `θ` of the active candidates is
//!
//! 1. input stage (site `input`): joint: `x = x_m + κ_c·x_c` (coupling), play of half-width `δ`
//!    (backlash), delay `d`, `ẋ` by central differences; transmission: the torques (or
//!    references) delayed by `d`;
//! 2. plant stage: the joint as [`JointPlant`] (effects in cables, contacts and at the joint;
//!    first-order input hold from `θ₀ = x(0)/r` at rest), the transmission with its effects
//!    (zero-order hold, or the servo in the loop) from the run's initial state;
//! 3. sensor stage, per channel: first- or second-order lag, delay, sample-and-hold, gain and
//!    bias (sites `sensor.<output>` and `sensors.force`).
//!
//! Residuals are `w_c·(ŷ_c − y_c)` over samples `start..T` of each run (the first samples are a
//! warm-up that absorbs the unknown initial state) and channels `c` with weights `w_c` (1/noise).

use crate::control::MotorPd;
use crate::dynamics::network::Network;
use crate::dynamics::{CableTransmission, Model};
use crate::error::{check, CableError, Result};
use crate::integrate::InputHold;

use super::augment::{augment_joint, augment_network, augment_transmission, SensorChain};
use super::effects::{Effect, ParamSpec, Scales};
use super::netplant::simulate_network;
pub use super::nominal::Plant;
use super::nominal::{network_hold, network_inputs, run_into, servo_into};
use super::plant::{JointPlant, KINK_REFINE};
use super::run::{Channel, JointRun};
use super::scales::scales_of;
use super::signal;
use super::site::{Candidate, NetworkSites, Site, SiteContext};

/// The effect-augmented pieces for one parameter vector.
#[derive(Debug, Clone, PartialEq)]
pub struct Augmented {
    /// The plant to replay.
    pub model: Replay,
    /// Coupling gain `κ_c` (input site).
    pub coupling: f64,
    /// Play half-width `δ` (m, input site).
    pub backlash: f64,
    /// Delay `d` (s) of the recorded input.
    pub delay: f64,
    /// Per channel, the sensor path's operators.
    pub sensors: Vec<SensorChain>,
}

/// The plant a replay simulates: the joint with located effects, or the transmission.
// one value per simulation, never stored in bulk: the joint's size costs nothing to keep inline
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum Replay {
    /// The antagonistic joint with its located effects.
    Joint(JointPlant),
    /// Torque-driven transmission.
    Transmission(CableTransmission),
    /// Transmission under its servo.
    Servo(CableTransmission, MotorPd),
    /// A cable network with its located effects.
    Network(Network),
}

/// Grey-box problem: nominal model, channels, runs and active candidates.
#[derive(Debug, Clone)]
pub struct JointProblem {
    pub(super) nominal: Plant,
    pub(super) channels: Vec<Channel>,
    pub(super) runs: Vec<JointRun>,
    pub(super) candidates: Vec<Candidate>,
    pub(super) specs: Vec<ParamSpec>,
    pub(super) scales: Scales,
    pub(super) substeps: usize,
    pub(super) kink_refine: usize,
}

impl JointProblem {
    /// Validated problem. `candidates` may be empty (the nominal model alone).
    pub fn new(
        nominal: impl Into<Plant>,
        channels: Vec<Channel>,
        runs: Vec<JointRun>,
        candidates: Vec<Candidate>,
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
            if c.window == 0 || c.window % 2 == 0 {
                return Err(CableError::InvalidParameter {
                    name: format!("channels[{i}].window"),
                    value: c.window as f64,
                    requirement: "an odd number of samples >= 1 (1: no averaging)",
                });
            }
        }
        let q = channels.len();
        let mut candidates = candidates;
        candidates.sort_unstable();
        candidates.dedup();
        let width = nominal.input_width();
        let ext_width = nominal.external_width();
        let joint = matches!(nominal, Plant::Joint(_));
        for (i, r) in runs.iter().enumerate() {
            check::positive(&format!("runs[{i}].dt"), r.dt)?;
            let t = r.len();
            crate::integrate::check_time_base(r.dt, t)?;
            let optional_ok = |v: &Vec<f64>, w: usize| v.is_empty() || v.len() == t * w;
            if t < 4
                || r.width != width
                || r.input.len() != t * width
                || r.measured.len() != t * q
                || !optional_ok(&r.coupled, 1)
                || !optional_ok(&r.external, ext_width)
            {
                return Err(CableError::Shape {
                    what: format!("runs[{i}]"),
                    expected: format!(
                        "input (T >= 4, {width}), measured (T, {q}), coupled (T,) and external \
                         (T, {ext_width}) or empty"
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
            let n_cmd = r.n_commands();
            if r.commands.len() != t * n_cmd {
                return Err(CableError::Shape {
                    what: format!("runs[{i}].commands"),
                    expected: format!("(T = {t}, c) row-major, or empty"),
                    got: format!("{} values", r.commands.len()),
                });
            }
            check::all_finite(&format!("runs[{i}].commands"), &r.commands, n_cmd.max(1))?;
            for (c, ch) in channels.iter().enumerate() {
                if let Some(j) = ch.command.filter(|&j| j >= n_cmd) {
                    return Err(CableError::InvalidParameter {
                        name: format!("channels[{c}].command"),
                        value: j as f64,
                        requirement: "a command column of every run (runs[i].commands)",
                    });
                }
            }
            let wants_coupled = candidates.iter().any(|c| c.effect == Effect::Coupling);
            if joint && wants_coupled && r.coupled.is_empty() {
                return Err(CableError::InvalidOption {
                    name: format!("runs[{i}].coupled"),
                    value: "missing".into(),
                    allowed: "a coupled-axis signal, required by the coupling effect".into(),
                });
            }
        }
        if substeps == 0 || substeps > crate::integrate::MAX_SUBSTEPS {
            return Err(CableError::InvalidParameter {
                name: "substeps".into(),
                value: substeps as f64,
                requirement: "an integer in 1..=100000 (MAX_SUBSTEPS)",
            });
        }
        let ctx = site_context(
            &nominal,
            &channels,
            runs.iter().all(|r| !r.coupled.is_empty()),
        );
        if let Some(c) = candidates.iter().find(|c| !c.applies(&ctx)) {
            let name = |i: usize| nominal.output_name(channels[i].output);
            return Err(CableError::InvalidOption {
                name: "candidate".into(),
                value: c.id(&name),
                allowed: format!(
                    "a candidate that can act on the {} with these channels",
                    nominal.name()
                ),
            });
        }
        // the joint has one bristle state: Dahl, sticking Coulomb and LuGre Stribeck share it
        let bristles: Vec<&Candidate> = candidates
            .iter()
            .filter(|c| c.site == Site::Joint && c.uses_joint_bristle())
            .collect();
        if joint && bristles.len() > 1 {
            let name = |i: usize| nominal.output_name(channels[i].output);
            return Err(CableError::InvalidOption {
                name: "candidates".into(),
                value: bristles
                    .iter()
                    .map(|c| c.id(&name))
                    .collect::<Vec<_>>()
                    .join(" + "),
                allowed: "at most one candidate with the joint's bristle state (Dahl hysteresis,                           sticking Coulomb or LuGre Stribeck friction)"
                    .into(),
            });
        }
        let scales = scales_of(&nominal, &channels, &runs);
        let specs = candidates.iter().flat_map(|c| c.params(&scales)).collect();
        Ok(Self {
            nominal,
            channels,
            runs,
            candidates,
            specs,
            scales,
            substeps,
            kink_refine: KINK_REFINE,
        })
    }

    /// The same problem with kink intervals integrated with `refine` times the substeps (1: no
    /// refinement; default [`KINK_REFINE`]); values below 1 count as 1.
    pub fn with_kink_refine(mut self, refine: usize) -> Self {
        self.kink_refine = refine.clamp(1, 64);
        self
    }

    /// The same data with other candidates (and substeps).
    pub fn with_candidates(&self, candidates: Vec<Candidate>, substeps: usize) -> Result<Self> {
        Ok(Self::new(
            self.nominal.clone(),
            self.channels.clone(),
            self.runs.clone(),
            candidates,
            substeps,
        )?
        .with_kink_refine(self.kink_refine))
    }

    /// What the plant and channels offer to candidates.
    pub fn context(&self) -> SiteContext {
        site_context(
            &self.nominal,
            &self.channels,
            self.runs.iter().all(|r| !r.coupled.is_empty()),
        )
    }

    /// Name of channel `i` (its plant output's name).
    pub fn channel_name(&self, i: usize) -> String {
        self.nominal.output_name(self.channels[i].output)
    }

    /// Index of the channel measuring the output called `name`.
    pub fn channel_index(&self, name: &str) -> Option<usize> {
        (0..self.channels.len()).find(|&i| self.channel_name(i) == name)
    }

    /// Parse a candidate id (`effect`, `effect@site`, `effect@site/form`) for this problem.
    pub fn parse_candidate(&self, id: &str) -> Result<Candidate> {
        let transmission = !matches!(self.nominal, Plant::Joint(_));
        Candidate::parse(id, transmission, &self.context())
    }

    /// The identifier of a candidate on this problem's channels and elements.
    pub fn candidate_id(&self, c: &Candidate) -> String {
        c.id(&self.context())
    }

    /// The name of a site on this problem's channels and elements.
    pub fn site_name(&self, site: Site) -> String {
        site.name(&self.context())
    }

    /// The sentence describing a candidate on this problem's channels.
    pub fn candidate_sentence(&self, c: &Candidate) -> String {
        c.sentence(&self.context())
    }

    /// RK4 substeps per sample interval.
    pub fn substeps(&self) -> usize {
        self.substeps
    }

    /// Active candidates (sorted, unique).
    pub fn candidates(&self) -> &[Candidate] {
        &self.candidates
    }

    /// Parameter specs of the active candidates, concatenated in candidate order.
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

    /// The channels.
    pub fn channels(&self) -> &[Channel] {
        &self.channels
    }

    /// The nominal plant.
    pub fn nominal(&self) -> &Plant {
        &self.nominal
    }

    /// Number of residuals.
    pub fn n_residuals(&self) -> usize {
        self.runs
            .iter()
            .map(|r| (r.len() - r.start) * self.channels.len())
            .sum()
    }

    /// Reference parameters (every candidate off).
    pub fn reference(&self) -> Vec<f64> {
        self.specs.iter().map(|s| s.reference).collect()
    }

    /// Indices of the parameters that change the plant's outputs: every active candidate's but
    /// those of the sensor stage (whose parameters act on the plant's outputs after it).
    pub fn plant_parameters(&self) -> Vec<usize> {
        let mut k = 0;
        let mut idx = Vec::new();
        for c in &self.candidates {
            let n = c.params(&self.scales).len();
            if !c.site.after_plant() {
                idx.extend(k..k + n);
            }
            k += n;
        }
        idx
    }

    /// `(candidate, its parameters)` for `theta`.
    pub(super) fn split<'a>(&self, theta: &'a [f64]) -> Vec<(Candidate, &'a [f64])> {
        let mut k = 0;
        self.candidates
            .iter()
            .map(|c| {
                let n = c.params(&self.scales).len();
                k += n;
                (*c, &theta[k - n..k])
            })
            .collect()
    }

    /// Build the augmented model and operators for `theta`.
    pub fn augment(&self, theta: &[f64]) -> Result<Augmented> {
        check::len("theta", theta, self.specs.len())?;
        check::all_finite("theta", theta, 1)?;
        let (mut coupling, mut backlash, mut delay) = (0.0, 0.0, 0.0);
        let mut sensors = vec![SensorChain::default(); self.channels.len()];
        let mut plant_effects = Vec::new();
        for (c, p) in self.split(theta) {
            match (c.effect, c.site) {
                (Effect::Backlash, Site::Input) => backlash = p[0].max(0.0),
                (Effect::TimeDelay, Site::Input) => delay = p[0].max(0.0),
                (Effect::Coupling, Site::Input) if matches!(self.nominal, Plant::Joint(_)) => {
                    coupling = p[0]
                }
                (_, Site::Sensor(i)) => sensors[i].apply(c, p, 0),
                (_, Site::ForceSensors) => {
                    let mut j = 0;
                    for (i, ch) in self.channels.iter().enumerate() {
                        if ch.sensor {
                            sensors[i].apply(c, p, j);
                            j += 1;
                        }
                    }
                }
                _ => plant_effects.push((c, p)),
            }
        }
        let model = match &self.nominal {
            Plant::Joint(nom) => Replay::Joint(augment_joint(nom, &plant_effects)),
            Plant::Transmission(nom) => {
                Replay::Transmission(augment_transmission(nom, &plant_effects)?)
            }
            Plant::Servo(nom, pd) => {
                Replay::Servo(augment_transmission(nom, &plant_effects)?, pd.clone())
            }
            Plant::Network(nom) => Replay::Network(augment_network(nom, &plant_effects)),
        };
        let a = Augmented {
            model,
            coupling,
            backlash,
            delay,
            sensors,
        };
        Ok(a)
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

    /// Input columns `0..width` of a run, each delayed by `d`.
    fn delayed_columns(run: &JointRun, width: usize, d: f64) -> Vec<Vec<f64>> {
        Self::delayed_where(run, width, |_| true, d)
    }

    /// The first `width` input columns of `run`, those that are commands (`delayed(c)`; not a
    /// network's measured signals or a motor's measured angle) delayed by `d` s.
    fn delayed_where(
        run: &JointRun,
        width: usize,
        delayed: impl Fn(usize) -> bool,
        d: f64,
    ) -> Vec<Vec<f64>> {
        let mut cols: Vec<Vec<f64>> = (0..width).map(|c| run.input_column(c)).collect();
        if d > 0.0 {
            let mut tmp = vec![0.0; run.len()];
            for (c, col) in cols.iter_mut().enumerate() {
                if delayed(c) {
                    signal::delay(col, d, run.dt, &mut tmp);
                    col.copy_from_slice(&tmp);
                }
            }
        }
        cols
    }

    /// Whether motor `i` of a network is replayed from its measured angle: a channel holds its
    /// command ([`Channel::command`]) and scores its load.
    fn measured_motor(&self, net: &Network, i: usize) -> bool {
        let load = net.load_output(i);
        self.channels
            .iter()
            .any(|c| c.command.is_some() && c.output == load)
    }

    /// Plant outputs of run `i` for `a` (before the sensor stage): joint `(T, 7)`
    /// `[T_m,1, T_m,2, T_j,1, T_j,2, θ, F_c, T_m,1 − T_m,2]`; transmission `(T, 5n)`, servo
    /// `(T, 6n)`.
    pub fn plant_outputs(&self, a: &Augmented, i: usize) -> Result<Vec<f64>> {
        let run = &self.runs[i];
        let t = run.len();
        match &a.model {
            Replay::Joint(joint) => {
                let u = self.joint_inputs(a, run);
                joint.simulate_refined(
                    &u,
                    &joint.rest(u[0] / joint.radius),
                    run.dt,
                    self.substeps,
                    self.kink_refine,
                )
            }
            Replay::Transmission(tr) => {
                let n = run.width;
                let cols = Self::delayed_columns(run, n, a.delay);
                let mut u = vec![0.0; t * 2 * n];
                for k in 0..t {
                    for c in 0..n {
                        u[k * 2 * n + c] = cols[c][k];
                        u[k * 2 * n + n + c] = run.external.get(k * n + c).copied().unwrap_or(0.0);
                    }
                }
                let x0 = if run.x0.len() == tr.n_states() {
                    run.x0.clone()
                } else {
                    tr.rest_state()
                };
                run_into(tr, &u, &x0, run, self.substeps, InputHold::Zoh)
            }
            Replay::Servo(tr, pd) => {
                let n = tr.n_links();
                let cols = Self::delayed_columns(run, 2 * n, a.delay);
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
            Replay::Network(net) => self.network_outputs(net, a, run),
        }
    }

    /// Plant outputs of a network run.
    fn network_outputs(&self, net: &Network, a: &Augmented, run: &JointRun) -> Result<Vec<f64>> {
        let delayed = |c: usize| c < net.n_motors() && !self.measured_motor(net, c);
        let cols = Self::delayed_where(run, run.width, delayed, a.delay);
        let u = network_inputs(net, &cols, &run.external, run.dt);
        let x0 = if run.x0.len() == net.n_states() {
            run.x0.clone()
        } else {
            net.rest_at(&u[..net.n_inputs()])
        };
        simulate_network(net, &u, &x0, run.dt, self.substeps, network_hold(net))
    }

    /// Predicted measurements `(T, q)` of run `i` from plant outputs, through each channel's
    /// sensor path.
    pub fn sensor_stage(&self, a: &Augmented, i: usize, plant: &[f64]) -> Vec<f64> {
        let run = &self.runs[i];
        let (t, q) = (run.len(), self.channels.len());
        let mut pred = vec![0.0; t * q];
        let mut col = vec![0.0; t];
        let mut tmp = vec![0.0; t];
        let n_out = self.nominal.n_outputs();
        for (c, ch) in self.channels.iter().enumerate() {
            for k in 0..t {
                col[k] = plant[k * n_out + ch.output];
            }
            a.sensors[c].run(&mut col, &mut tmp, run.dt);
            if let (Some(j), true) = (ch.command, a.delay > 0.0) {
                // the measurement holds the command as recorded, the plant felt it `d` late
                let cmd = run.command_column(j);
                signal::delay(&cmd, a.delay, run.dt, &mut tmp);
                for k in 0..t {
                    col[k] += cmd[k] - tmp[k];
                }
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

    /// Weighted residuals of sensor-stage parameters `theta` on precomputed plant outputs
    /// (one per run): the plant is not simulated again.
    pub fn residuals_on(&self, theta: &[f64], plants: &[Vec<f64>], r: &mut [f64]) -> Result<()> {
        let a = self.augment(theta)?;
        self.residuals_of(&a, plants, r)
    }

    /// Weighted residuals of the augmented model `a` on its plant outputs (one per run).
    pub(super) fn residuals_of(
        &self,
        a: &Augmented,
        plants: &[Vec<f64>],
        r: &mut [f64],
    ) -> Result<()> {
        check::len("residuals", r, self.n_residuals())?;
        let mut off = 0;
        for (i, plant) in plants.iter().enumerate() {
            let pred = self.sensor_stage(a, i, plant);
            off += self.write_residuals(i, &pred, &mut r[off..]);
        }
        Ok(())
    }

    pub(super) fn write_residuals(&self, i: usize, pred: &[f64], r: &mut [f64]) -> usize {
        let run = &self.runs[i];
        let q = self.channels.len();
        let n = run.len().saturating_sub(run.start);
        for (c, ch) in self.channels.iter().enumerate() {
            let e = |k: usize| pred[k * q + c] - run.measured[k * q + c];
            if ch.window <= 1 {
                for (m, k) in (run.start..run.len()).enumerate() {
                    r[m * q + c] = ch.weight * e(k);
                }
                continue;
            }
            // centred moving average by prefix sums; the window keeps its width at the ends
            // (clamped inside the scored samples), or is the whole run when the run is shorter
            let mut sum = Vec::with_capacity(n + 1);
            sum.push(0.0);
            for k in run.start..run.len() {
                sum.push(sum[sum.len() - 1] + e(k));
            }
            let w = ch.window.min(n);
            let h = ch.window / 2;
            for m in 0..n {
                let lo = if w < ch.window {
                    0
                } else {
                    m.saturating_sub(h).min(n - w)
                };
                r[m * q + c] = ch.weight * (sum[lo + w] - sum[lo]) / w as f64;
            }
        }
        n * q
    }
}

fn site_context(nominal: &Plant, channels: &[Channel], coupled: bool) -> SiteContext {
    SiteContext {
        transmission: !matches!(nominal, Plant::Joint(_)),
        links: nominal.links(),
        channels: channels
            .iter()
            .map(|c| nominal.output_name(c.output))
            .collect(),
        force: channels.iter().map(|c| c.sensor).collect(),
        coupled,
        network: match nominal {
            Plant::Network(n) => Some(NetworkSites {
                joints: n.joint_names().to_vec(),
                cables: n.cable_names().to_vec(),
                motors: n.motor_names().to_vec(),
                torque_driven: (0..n.n_motors())
                    .map(|i| n.motor_is_torque_driven(i))
                    .collect(),
                cable_motor: (0..n.n_cables()).map(|c| n.cable_motor(c)).collect(),
                routing_in_dynamics: (0..n.n_cables())
                    .map(|c| n.routing_driver(c).is_some())
                    .collect(),
                wound: (0..n.n_cables()).map(|c| n.is_wound(c)).collect(),
            }),
            _ => None,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::AntagonisticJoint;
    use crate::friction::StaticFriction;
    use crate::identify::lm::LmOptions;

    fn cand(e: Effect) -> Candidate {
        Candidate::default_for(e, false)
    }

    fn tcand(e: Effect) -> Candidate {
        Candidate::default_for(e, true)
    }
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
            commands: vec![],
            start: 50,
        }
    }

    fn channels() -> Vec<Channel> {
        vec![
            Channel::new(0, 1.0, true),
            Channel::new(1, 1.0, true),
            Channel::new(4, 100.0, false),
        ]
    }

    #[test]
    #[allow(clippy::float_cmp)] // the untouched channels are the same numbers
    fn a_windowed_channel_scores_the_moving_average_of_its_residual() {
        let mut data = run(0.3);
        let t_len = data.len();
        data.measured = (0..t_len * 3)
            .map(|i| ((i * 7919) % 13) as f64 * 1e-3)
            .collect();
        let plain =
            JointProblem::new(nominal(), channels(), vec![data.clone()], vec![], 2).unwrap();
        let mut chans = channels();
        chans[1] = chans[1].with_window(9);
        let windowed = JointProblem::new(nominal(), chans, vec![data], vec![], 2).unwrap();
        let mut r0 = vec![0.0; plain.n_residuals()];
        let mut r1 = vec![0.0; windowed.n_residuals()];
        plain.residuals(&[], &mut r0).unwrap();
        windowed.residuals(&[], &mut r1).unwrap();
        let n = r0.len() / 3;
        for m in 0..n {
            // untouched channels are equal; the windowed one is the clamped centred mean
            assert_eq!(r0[m * 3], r1[m * 3]);
            assert_eq!(r0[m * 3 + 2], r1[m * 3 + 2]);
            let lo = m.saturating_sub(4).min(n - 9);
            let mean = (lo..lo + 9).map(|k| r0[k * 3 + 1]).sum::<f64>() / 9.0;
            assert_relative_eq!(r1[m * 3 + 1], mean, max_relative = 1e-12, epsilon = 1e-15);
        }
        for bad in [0, 4] {
            let mut chans = channels();
            chans[0] = chans[0].with_window(bad);
            let e = JointProblem::new(nominal(), chans, vec![run(0.3)], vec![], 2).unwrap_err();
            assert!(e.to_string().contains("channels[0].window"), "{e}");
        }
    }

    /// Data generated by the problem itself at `truth`, then fitted from the spec start.
    fn recover(effect: Effect, truth: &[f64], rel: f64) {
        let base = JointProblem::new(nominal(), channels(), vec![run(3.0)], vec![cand(effect)], 4)
            .unwrap();
        let mut data = base.runs()[0].clone();
        data.measured = base.predict(truth, 0).unwrap();
        let p =
            JointProblem::new(nominal(), channels(), vec![data], vec![cand(effect)], 4).unwrap();
        let fit = p.fit(None, &LmOptions::default()).unwrap();
        for (got, want) in fit.params.iter().zip(truth) {
            assert_relative_eq!(*got, *want, max_relative = rel, epsilon = 1e-12);
        }
        assert!(
            fit.cost < 1e-10 * fit.initial_cost.max(1e-30) + 1e-20,
            "{effect:?} {fit:?}"
        );
    }

    /// The plant cache of the fits reuses a replay only for the very same plant parameters:
    /// along a local search's evaluations (a point, its Jacobian columns of both kinds, a trial
    /// step, a sensor sweep) its residuals are the problem's to the bit.
    #[test]
    #[allow(clippy::float_cmp)] // the same numbers, not nearly
    fn the_plant_cache_gives_the_problems_residuals_exactly() {
        use super::super::fit::PlantCache;
        let gain = Candidate::new(Effect::SensorGainBias, Site::Sensor(1));
        let effects = vec![cand(Effect::CoulombFriction), gain];
        let p = JointProblem::new(nominal(), channels(), vec![run(0.4)], effects, 2).unwrap();
        assert_eq!(p.plant_parameters(), vec![0, 1]);
        let scale: Vec<f64> = p.specs().iter().map(|s| s.scale).collect();
        let step = LmOptions::default().fd_step;
        let cache = PlantCache::new(&p, Some((step, scale.clone())));
        let x = [3e-3, 0.2, 0.05, -0.1];
        let h = |j: usize, x: &[f64]| step * x[j].abs().max(scale[j]);
        let mut points = vec![x.to_vec()];
        for j in 0..4 {
            let mut c = x.to_vec();
            c[j] += h(j, &x);
            points.push(c);
        }
        let trial = [3.5e-3, 0.25, 0.04, -0.1];
        points.push(trial.to_vec());
        for j in [2, 3, 0] {
            let mut c = trial.to_vec();
            c[j] -= h(j, &trial);
            points.push(c);
        }
        points.push(vec![3.5e-3, 0.25, 0.5, 0.3]); // a sweep of the gain
        let (mut want, mut got) = (vec![0.0; p.n_residuals()], vec![0.0; p.n_residuals()]);
        for x in &points {
            p.residuals(x, &mut want).unwrap();
            cache.residuals(x, &mut got).unwrap();
            assert_eq!(got, want, "{x:?}");
        }
        // a global stage's cache (no steps): every new plant replaces the entry
        let sweep = PlantCache::new(&p, None);
        for x in points.iter().rev() {
            p.residuals(x, &mut want).unwrap();
            sweep.residuals(x, &mut got).unwrap();
            assert_eq!(got, want, "{x:?}");
        }
    }

    #[test]
    fn substeps_beyond_the_integrators_cap_are_refused_up_front() {
        let err = JointProblem::new(nominal(), channels(), vec![run(0.1)], vec![], 10_000_000)
            .unwrap_err();
        assert!(err.to_string().contains("substeps"), "{err}");
        let p = JointProblem::new(nominal(), channels(), vec![run(0.1)], vec![], 1).unwrap();
        assert!(p.with_candidates(vec![], 100_001).is_err());
        assert!(p.with_candidates(vec![], 100_000).is_ok());
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
    #[allow(clippy::float_cmp)] // a fixed parameter is exactly its bound: the claim under test
    fn stick_phase_forms_are_recovered_with_their_bristle_fixed_and_never_share_it() {
        use super::super::site::Form;
        let lugre = cand(Effect::StribeckFriction).with_form(Form::Lugre);
        let base =
            JointProblem::new(nominal(), channels(), vec![run(3.0)], vec![lugre], 4).unwrap();
        let specs = base.specs();
        assert_eq!(specs.len(), 4);
        // the break-away displacement is part of the law: lower = upper = one sample's travel
        let th = specs[3].initial;
        assert!(th > 0.0 && specs[3].lower == th && specs[3].upper == th);
        let truth = [3e-3, 4e-3, 0.05, th];
        let mut data = base.runs()[0].clone();
        data.measured = base.predict(&truth, 0).unwrap();
        let p = JointProblem::new(nominal(), channels(), vec![data], vec![lugre], 4).unwrap();
        // locally: from 30 % off in every level and the Stribeck speed (the global stage of
        // this form is weak: its cost has several basins in v_s, docs/diagnosis.md)
        let start = [0.7 * truth[0], 1.3 * truth[1], 1.3 * truth[2], th];
        let fit = p.fit(Some(&start), &LmOptions::default()).unwrap();
        assert_eq!(fit.params[3], th);
        for (got, want) in fit.params.iter().zip(&truth).take(3) {
            assert_relative_eq!(*got, *want, max_relative = 2e-2);
        }
        // two candidates of the joint's one bristle state are refused by name
        let sticking = cand(Effect::CoulombFriction).with_form(Form::Sticking);
        match JointProblem::new(
            nominal(),
            channels(),
            vec![run(1.0)],
            vec![cand(Effect::DahlHysteresis), sticking],
            4,
        ) {
            Err(CableError::InvalidOption { value, .. }) => {
                assert!(value.contains("dahl_hysteresis@joint") && value.contains("/sticking"))
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn sample_hold_is_found_by_grid_search() {
        let base = JointProblem::new(
            nominal(),
            channels(),
            vec![run(3.0)],
            vec![cand(Effect::SensorSampling)],
            4,
        )
        .unwrap();
        // each force channel its own converter clock
        let truth = [0.1, 0.04, 0.083, 0.011];
        let mut data = base.runs()[0].clone();
        data.measured = base.predict(&truth, 0).unwrap();
        let p = base
            .with_candidates(vec![cand(Effect::SensorSampling)], 4)
            .unwrap();
        let p = JointProblem::new(
            nominal(),
            channels(),
            vec![data],
            p.candidates().to_vec(),
            4,
        )
        .unwrap();
        let holds = p.grid_sample_hold(&p.reference()).unwrap();
        assert_eq!(holds.len(), 2);
        for (m, &(period, phase)) in holds.iter().enumerate() {
            let (want_p, want_ph) = (truth[2 * m], truth[2 * m + 1]);
            assert!(
                (period - want_p).abs() < 0.01 * want_p,
                "{m}: period {period}"
            );
            let d = (phase - want_ph).rem_euclid(period);
            assert!(d.min(period - d) <= 1e-3 + 1e-9, "{m}: phase {phase}");
        }
    }

    #[test]
    fn external_torque_is_balanced_by_the_net_cable_force() {
        // held motor, constant load: at rest r·(T_j1 − T_j2) + τ = 0, and without capstan
        // losses the net motor-side force equals the joint-side one
        let tau = 2e-3;
        let t_len = 3000;
        let chans = vec![Channel::new(6, 1.0, true)];
        let r = JointRun {
            dt: 1e-3,
            input: vec![1e-4; t_len],
            width: 1,
            x0: vec![],
            coupled: vec![],
            external: vec![tau; t_len],
            measured: vec![0.0; t_len],
            commands: vec![],
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
            commands: vec![],
            start: 20,
        }
    }

    fn encoder_channels() -> Vec<Channel> {
        [0, 1, 5, 6]
            .iter()
            .map(|&output| Channel::new(output, 1e3, false))
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
                vec![tcand(effect)],
                4,
            )
            .unwrap();
            let mut data = base.runs()[0].clone();
            data.measured = base.predict(&truth, 0).unwrap();
            let p = JointProblem::new(
                raven.clone(),
                encoder_channels(),
                vec![data],
                vec![tcand(effect)],
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
                vec![Candidate::new(
                    Effect::Creep,
                    Site::Cable(super::super::site::Side::Both)
                )],
                1
            ),
            Err(CableError::InvalidOption { .. })
        ));
    }

    /// The test joint as a network (`joint`, cables `drive` and `return`, motor `motor`):
    /// outputs `[q, q_m, T_d, T_r, T_m,d, T_m,r, τ, load_m]`.
    fn network() -> Network {
        use crate::dynamics::network::NetworkSpec;
        let mut j = nominal();
        j.friction.coulomb = 2e-3;
        j.friction.static_level = 2e-3;
        Network::new(&NetworkSpec::from_joint(&j).unwrap()).unwrap()
    }

    fn network_channels() -> Vec<Channel> {
        [
            (0, 100.0, false),
            (4, 1.0, true),
            (5, 1.0, true),
            (7, 1e3, true),
        ]
        .iter()
        .map(|&(output, weight, sensor)| Channel::new(output, weight, sensor))
        .collect()
    }

    #[test]
    fn network_sites_follow_the_structure_and_effects_are_recovered() {
        let net = network();
        let mut data = run(3.0);
        data.measured = vec![0.0; data.len() * 4];
        let probe = JointProblem::new(
            net.clone(),
            network_channels(),
            vec![data.clone()],
            vec![],
            4,
        )
        .unwrap();
        let lib = Candidate::library(&probe.context());
        let ids: Vec<String> = lib.iter().map(|c| probe.candidate_id(c)).collect();
        for want in [
            "coulomb_friction@joint.joint",
            "stribeck_friction@joint.joint",
            "cable_damping@cable.drive",
            "slack@cable.return",
            "nonlinear_stiffness@cable.return/scale",
            "capstan_friction@routing.drive",
            "dahl_hysteresis@routing.return",
            "coulomb_friction@motor.motor",
            "sensor_gain_bias@sensor.load_m:motor",
        ] {
            assert!(ids.iter().any(|i| i == want), "{want} not in {ids:?}");
        }
        // ids round trip; no site of the built-in plants is offered
        for (c, id) in lib.iter().zip(&ids) {
            assert_eq!(probe.parse_candidate(id).unwrap(), *c, "{id}");
            assert!(!matches!(
                c.site,
                Site::Joint | Site::Cable(_) | Site::Links
            ));
        }
        for (id, truth) in [
            ("coulomb_friction@joint.joint", vec![3e-3]),
            ("cable_damping@cable.return", vec![4.0]),
            ("slack@cable.drive", vec![3.0]),
            ("capstan_friction@routing.drive", vec![0.15, f64::NAN]), // NaN: the nominal's
            ("nonlinear_stiffness@cable.return/scale", vec![0.4]),
            ("viscous_friction@motor.motor", vec![300.0]),
            // (the nominal motor has no dry friction: the added one is as sharp as the capstan's)
            ("coulomb_friction@motor.motor", vec![0.4]),
            // the states a network gets from the diagnosis: pre-sliding (its level 1 mN·m above
            // the nominal Coulomb's, break-away 2 mrad), creep, play behind the motor
            ("dahl_hysteresis@joint.joint", vec![1e-3, 2e-3]),
            (
                "coulomb_friction@joint.joint/sticking",
                vec![1e-3, f64::NAN],
            ),
            ("creep@cable.drive", vec![0.3, 0.4]),
            ("creep@cable.return/whole", vec![0.2, 0.8]),
            ("backlash@motor.motor", vec![6e-5]),
            // a routing's friction with pre-sliding: 0.15 above the nominal's μφ, the break-away
            // at the data's stretch scale
            ("dahl_hysteresis@routing.drive", vec![0.15, f64::NAN]),
        ] {
            let c = probe.parse_candidate(id).unwrap();
            let base = probe.with_candidates(vec![c], 4).unwrap();
            let truth: Vec<f64> = truth
                .iter()
                .zip(base.reference())
                .map(|(t, r)| if t.is_nan() { r } else { *t })
                .collect();
            let mut d = data.clone();
            d.measured = base.predict(&truth, 0).unwrap();
            let p =
                JointProblem::new(net.clone(), network_channels(), vec![d], vec![c], 4).unwrap();
            // the reference values replay the nominal network
            let reference = p.reference();
            let nominal = probe.predict(&[], 0).unwrap();
            let at_ref = p.predict(&reference, 0).unwrap();
            // (a pre-sliding candidate turns the joint's dry friction into its own element, the
            // sticking forms sharpen its sign: their reference is not the nominal law)
            let bristle =
                id.starts_with("dahl") || id.ends_with("/sticking") || id.ends_with("/lugre");
            if !bristle {
                assert!(max_abs_diff(&nominal, &at_ref) < 1e-9, "{id}");
            }
            let fit = p.fit(None, &LmOptions::default()).unwrap();
            for (got, want) in fit.params.iter().zip(&truth) {
                assert_relative_eq!(*got, *want, max_relative = 2e-3);
            }
        }
    }

    #[test]
    fn a_late_command_acts_on_the_load_that_holds_it_not_on_the_measured_angle() {
        // the motor is replayed from its measured angle; its load channel holds the torque
        // command as recorded, which the plant felt `d` late
        let net = network();
        let mut data = run(2.0);
        let t = data.len();
        let w = 2.0 * std::f64::consts::PI * 1.5;
        data.commands = (0..t)
            .map(|k| 0.02 * (w * k as f64 * data.dt).sin())
            .collect();
        data.measured = vec![0.0; t * 2];
        let load = net.load_output(0);
        assert_eq!(load, 7);
        let chans = vec![
            Channel::new(0, 100.0, false),
            Channel::new(load, 1e3, false).with_command(0),
        ];
        let nominal =
            JointProblem::new(net.clone(), chans.clone(), vec![data.clone()], vec![], 4).unwrap();
        let plant = nominal.predict(&[], 0).unwrap();
        let d = 0.012;
        let cmd = data.command_column(0);
        let mut late = vec![0.0; t];
        signal::delay(&cmd, d, data.dt, &mut late);
        data.measured = (0..t)
            .flat_map(|k| [plant[2 * k], plant[2 * k + 1] + cmd[k] - late[k]])
            .collect();
        let c = nominal.parse_candidate("time_delay@input").unwrap();
        let p =
            JointProblem::new(net.clone(), chans.clone(), vec![data.clone()], vec![c], 4).unwrap();
        let mut r = vec![0.0; p.n_residuals()];
        p.residuals(&[d], &mut r).unwrap();
        assert!(
            r.iter().all(|v| v.abs() < 1e-9),
            "the truth leaves a residual"
        );
        // without the delay the load's residual is the command's change over d; the angle's
        // channel (the motor's measured angle drives the plant) is untouched either way
        p.residuals(&[0.0], &mut r).unwrap();
        let angle = r.iter().step_by(2).fold(0.0_f64, |m, v| m.max(v.abs()));
        let loads = r
            .iter()
            .skip(1)
            .step_by(2)
            .fold(0.0_f64, |m, v| m.max(v.abs()));
        assert!(
            angle < 1e-9 && loads > 1e3 * 0.02 * w * d * 0.5,
            "{angle} {loads}"
        );
        let fit = p.fit(None, &LmOptions::default()).unwrap();
        assert_relative_eq!(fit.params[0], d, max_relative = 1e-3);
        // a channel without the command: the delay moves the (position-commanded) motor instead
        let plain = vec![chans[0], Channel::new(load, 1e3, false)];
        let q = JointProblem::new(net, plain, vec![data.clone()], vec![c], 4).unwrap();
        let moved = q.predict(&[d], 0).unwrap();
        let still = q.predict(&[0.0], 0).unwrap();
        assert!(max_abs_diff(&moved, &still) > 1e-6);
        // a command column no run has is a typed error naming the channel
        let bad = vec![chans[0], Channel::new(load, 1e3, false).with_command(1)];
        let e = JointProblem::new(network(), bad, vec![data], vec![], 4).unwrap_err();
        assert!(e.to_string().contains("channels[1].command"), "{e}");
    }

    #[test]
    fn a_position_motors_added_dry_friction_is_as_sharp_as_its_capstan() {
        let net = network();
        let mut data = run(0.2);
        data.measured = vec![0.0; data.len() * 4];
        let probe =
            JointProblem::new(net.clone(), network_channels(), vec![data], vec![], 2).unwrap();
        let c = probe
            .parse_candidate("coulomb_friction@motor.motor")
            .unwrap();
        let mut aug = augment_network(&net, &[(c, &[0.4])]);
        let rho = net.motor_rho(0);
        let f = *aug.motor_friction_mut(0);
        assert_relative_eq!(
            f.smoothing,
            net.capstan_smoothing() / rho,
            max_relative = 1e-12
        );
        assert_relative_eq!(f.coulomb, 0.4 * rho, max_relative = 1e-12);
        // a nominal with its own motor friction keeps its law
        let mut own = net.clone();
        own.motor_friction_mut(0).coulomb = 1e-3;
        let before = own.motor_friction_mut(0).smoothing;
        let after = augment_network(&own, &[(c, &[0.4])])
            .motor_friction_mut(0)
            .smoothing;
        assert_relative_eq!(after, before);
    }

    fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
        a.iter().zip(b).fold(0.0, |m, (x, y)| m.max((x - y).abs()))
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
            .map(|&output| Channel::new(output, 1e3, output >= 10))
            .collect();
        let run = JointRun {
            dt,
            input,
            width: 4,
            x0: vec![],
            coupled: vec![],
            external: vec![],
            measured: vec![0.0; t_len * 6],
            commands: vec![],
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
                vec![tcand(effect)],
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
            let p = JointProblem::new(
                plant.clone(),
                chans.clone(),
                vec![data],
                vec![tcand(effect)],
                2,
            )
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
                vec![cand(Effect::Coupling)],
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
