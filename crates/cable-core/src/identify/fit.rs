//! Fitting a [`JointProblem`]: bounded Levenberg–Marquardt from the best of the candidates'
//! starting values, a grid search for sample-and-hold, update-instant detection, and RK4 step
//! advice for an augmented model.

use std::sync::{Arc, Mutex};

use crate::dynamics::Model;
use crate::error::{check, Result};
use crate::integrate::propose_step;

use super::effects::{Effect, SWEEP};

/// Seconds of every run the global stage scores its starting points on (the local search uses
/// the whole runs): 8 s hold several sweeps and reversals of a bench run at a fifth of the
/// simulations of a 40 s pair.
pub const GLOBAL_STAGE_S: f64 = 8.0;
use super::lm::{least_squares, LmOptions, LmReport};
use super::problem::{Augmented, JointProblem, Replay};
use super::signal;
use super::site::{Candidate, Site};

/// The plant's outputs at the last point, keyed by the parameters that change the plant
/// ([`JointProblem::plant_parameters`]): an evaluation that differs from it only in sensor-stage
/// parameters (a Jacobian column of a gain, a sweep of a lag) runs the sensor stage alone. Exact:
/// the outputs are reused only for an identical key.
pub(super) struct PlantCache<'p> {
    problem: &'p JointProblem,
    plant: Vec<usize>,
    /// `(fd_step, scale)` of a local search: a point that differs from the cached one in one
    /// plant parameter by at most a finite-difference step is a Jacobian column and leaves the
    /// cache to the columns after it; any other point replaces it.
    fd: Option<(f64, Vec<f64>)>,
    last: Mutex<Option<Replayed>>,
}

/// A replay's plant parameters and its plant outputs (one per run).
type Replayed = (Vec<f64>, Arc<Vec<Vec<f64>>>);

impl<'p> PlantCache<'p> {
    pub(super) fn new(problem: &'p JointProblem, fd: Option<(f64, Vec<f64>)>) -> Self {
        Self {
            problem,
            plant: problem.plant_parameters(),
            fd,
            last: Mutex::new(None),
        }
    }

    pub(super) fn residuals(&self, theta: &[f64], r: &mut [f64]) -> Result<()> {
        let p = self.problem;
        let a = p.augment(theta)?;
        let key: Vec<f64> = self.plant.iter().map(|&j| theta[j]).collect();
        // (the lock is held only to copy or replace the entry: a poisoned one holds a whole entry)
        let cached = self.last.lock().unwrap_or_else(|e| e.into_inner()).clone();
        if let Some((k, plants)) = &cached {
            #[allow(clippy::float_cmp)] // the very same parameters, not nearly the same
            if *k == key {
                return p.residuals_of(&a, plants, r);
            }
        }
        let plants: Vec<Vec<f64>> = (0..p.runs().len())
            .map(|i| p.plant_outputs(&a, i))
            .collect::<Result<_>>()?;
        let column = match (&cached, &self.fd) {
            (Some((k, _)), Some((step, scale))) => {
                #[allow(clippy::float_cmp)] // which parameters moved at all
                let moved: Vec<usize> = (0..key.len()).filter(|&i| key[i] != k[i]).collect();
                moved.len() == 1 && {
                    let (i, j) = (moved[0], self.plant[moved[0]]);
                    (key[i] - k[i]).abs() <= 2.0 * step * k[i].abs().max(scale[j])
                }
            }
            _ => false,
        };
        p.residuals_of(&a, &plants, r)?;
        if !column {
            *self.last.lock().unwrap_or_else(|e| e.into_inner()) = Some((key, Arc::new(plants)));
        }
        Ok(())
    }
}

impl JointProblem {
    /// Fit the active candidates' parameters from `theta0`, or, by default, from the two best of
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
        if let Some(c) = self.sampling_candidate() {
            let k = self.offset_of(&c);
            for (m, (period, phase)) in self.grid_sample_hold(&x0)?.into_iter().enumerate() {
                x0[k + 2 * m] = period;
                x0[k + 2 * m + 1] = phase;
            }
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
        // a Jacobian column of a sensor-stage parameter replays the plant of the point it
        // differentiates at (with sensor-site candidates only, the nominal's throughout)
        let cache = PlantCache::new(self, Some((opts.fd_step, scale.clone())));
        least_squares(
            |th, r| cache.residuals(th, r),
            &x0,
            &lower,
            &upper,
            &scale,
            self.n_residuals(),
            opts,
        )
    }

    /// The global stage before the local search: the `keep` best starting points over every
    /// parameter. Each parameter's options are its `initial` and `starts` — or, for a parameter
    /// given none, a spread of its own ([`ParamSpec::spread`]): in a resonant plant every
    /// parameter is non-convex (an inertia error moves the resonance), so none is left to the
    /// local search alone. Parameters with [`SWEEP`] or more options are swept alone first;
    /// the others are combined exhaustively when there are at most 27 combinations, and swept
    /// coordinate by coordinate (twice) otherwise. Points whose simulation fails are skipped.
    fn best_starts(&self, mut x0: Vec<f64>, keep: usize) -> Vec<Vec<f64>> {
        // the cheap objective: the first GLOBAL_STAGE_S seconds of every run (same parameters,
        // scales and specs); the local search then works on the whole runs
        let cheap = self.head(GLOBAL_STAGE_S).ok().flatten();
        let p = cheap.as_ref().unwrap_or(self);
        let mut r = vec![0.0; p.n_residuals()];
        // a sweep of a sensor-stage parameter replays the plant once
        let cache = PlantCache::new(p, None);
        let mut cost = |x: &[f64]| -> Option<f64> {
            cache
                .residuals(x, &mut r)
                .ok()
                .map(|_| r.iter().map(|v| v * v).sum::<f64>())
                .filter(|c| c.is_finite())
        };
        let options: Vec<Vec<f64>> = self
            .specs
            .iter()
            .zip(&x0)
            .map(|(s, &x)| {
                if s.grid {
                    return vec![x];
                }
                let extra = if s.starts.is_empty() {
                    s.spread()
                } else {
                    s.starts.clone()
                };
                let mut o = vec![x];
                for v in extra {
                    if o.iter().all(|&u| (u - v).abs() > 1e-9 * s.scale) {
                        o.push(v);
                    }
                }
                o
            })
            .collect();
        let mut base = cost(&x0).unwrap_or(f64::INFINITY);
        // 1-D sweeps of the parameters with many options, one at a time
        let sweep = |j: usize,
                     x0: &mut Vec<f64>,
                     base: &mut f64,
                     cost: &mut dyn FnMut(&[f64]) -> Option<f64>| {
            let mut x = x0.clone();
            for &v in &options[j][1..] {
                x[j] = v;
                if let Some(c) = cost(&x) {
                    if c < *base {
                        *base = c;
                        x0[j] = v;
                    }
                }
            }
        };
        for j in 0..options.len() {
            if options[j].len() > SWEEP {
                sweep(j, &mut x0, &mut base, &mut cost);
            }
        }
        let few: Vec<usize> = (0..options.len())
            .filter(|&j| options[j].len() > 1 && options[j].len() <= SWEEP)
            .collect();
        let total: usize = few.iter().map(|&j| options[j].len()).product();
        if few.is_empty() {
            return vec![x0];
        }
        if total > 27 {
            for _ in 0..2 {
                for &j in &few {
                    sweep(j, &mut x0, &mut base, &mut cost);
                }
            }
            return vec![x0];
        }
        let mut scored: Vec<(f64, Vec<f64>)> = Vec::new();
        for mut code in 0..total {
            let mut x = x0.clone();
            for &j in &few {
                let o = &options[j];
                // option 0 is the current value (the 1-D sweeps' best for swept parameters)
                x[j] = if code % o.len() == 0 {
                    x0[j]
                } else {
                    o[code % o.len()]
                };
                code /= o.len();
            }
            if let Some(c) = cost(&x) {
                scored.push((c, x));
            }
        }
        if scored.is_empty() {
            return vec![x0];
        }
        scored.sort_by(|a, b| a.0.total_cmp(&b.0));
        scored.into_iter().take(keep).map(|(_, x)| x).collect()
    }

    /// The same problem on the first `seconds` of every run (plus its warm-up), or `None` when
    /// every run is shorter than twice that: the cheap objective of the global stage and of
    /// screening fits. Error: `seconds` not finite and positive.
    pub fn head(&self, seconds: f64) -> Result<Option<JointProblem>> {
        check::positive("seconds", seconds)?;
        let keep = |run: &crate::identify::JointRun| run.start + (seconds / run.dt).ceil() as usize;
        if self.runs.iter().all(|r| 2 * keep(r) > r.len()) {
            return Ok(None);
        }
        let mut p = self.clone();
        let q = self.channels.len();
        for run in &mut p.runs {
            let n = keep(run).min(run.len());
            let w = run.width.max(1);
            run.input.truncate(n * w);
            run.measured.truncate(n * q);
            if !run.coupled.is_empty() {
                run.coupled.truncate(n);
            }
            if !run.external.is_empty() {
                run.external.truncate(n * w);
            }
        }
        Ok(Some(p))
    }

    /// Offset of candidate `c`'s parameters in `theta`.
    pub fn offset_of(&self, c: &Candidate) -> usize {
        self.candidates
            .iter()
            .take_while(|&f| f != c)
            .map(|f| f.params(&self.scales).len())
            .sum()
    }

    /// The active sample-and-hold candidate, if any.
    fn sampling_candidate(&self) -> Option<Candidate> {
        self.candidates
            .iter()
            .copied()
            .find(|c| c.effect == Effect::SensorSampling)
    }

    /// Grid search of the sample-and-hold period and phase with the other parameters at
    /// `theta`: periods log-spaced from 2·dt to a quarter of the shortest run, 12 phases each,
    /// then the update instants read off the channel's jumps, then a fine grid. One
    /// `(period, phase)` per parameter pair of the candidate: a single channel's, or each force
    /// channel's own (searched channel by channel: a channel's hold changes only its residuals).
    /// The plant is simulated once per run.
    pub fn grid_sample_hold(&self, theta: &[f64]) -> Result<Vec<(f64, f64)>> {
        let Some(cand) = self.sampling_candidate() else {
            return Ok(vec![]);
        };
        let k = self.offset_of(&cand);
        let mut th = theta.to_vec();
        let pairs = cand.params(&self.scales).len() / 2;
        for m in 0..pairs {
            th[k + 2 * m] = 0.0;
        }
        let a0 = self.augment(&th)?;
        let held: Vec<usize> = (0..self.channels.len())
            .filter(|&c| match cand.site {
                Site::Sensor(i) => i == c,
                _ => self.channels[c].sensor,
            })
            .collect();
        let plants: Vec<Vec<f64>> = (0..self.runs.len())
            .map(|i| self.plant_outputs(&a0, i))
            .collect::<Result<_>>()?;
        if pairs == 1 {
            return Ok(vec![self.search_hold(&a0, &plants, &held)]);
        }
        Ok(held
            .iter()
            .take(pairs)
            .map(|&c| self.search_hold(&a0, &plants, &[c]))
            .collect())
    }

    /// The sample-and-hold `(period, phase)` of the channels `held` (one clock) that best fits
    /// the runs, the other channels as in `a0`.
    fn search_hold(&self, a0: &Augmented, plants: &[Vec<f64>], held: &[usize]) -> (f64, f64) {
        let dt = self.scales.dt;
        let mut r = vec![0.0; self.n_residuals()];
        let mut cost = |period: f64, phase: f64| -> f64 {
            let mut a = a0.clone();
            for &c in held {
                a.sensors[c].period = period;
                a.sensors[c].phase = phase;
            }
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
        // a held signal shows its update instants in its jumps: take them, and their
        // neighbourhood at a fiftieth of a sample in period and a quarter in phase
        if let Some((period, phase)) = self.hold_from_updates_of(held[0]) {
            for ip in -10..=10 {
                let p = period + ip as f64 * 0.02 * dt;
                for jp in -4..=4 {
                    let ph = (phase + jp as f64 * 0.25 * dt).rem_euclid(p);
                    consider(cost(p, ph), p, ph, &mut best);
                }
            }
        }
        // fine: ±12 % around the best period, phases at the sample resolution (at most
        // FINE_PHASES per period; a longer period's best phase is then refined sample by sample
        // around it, so a spurious long period costs ~2k evaluations, not period/dt × 25)
        let (_, p0, _) = best;
        if p0 <= 0.0 {
            return (0.0, 0.0);
        }
        const FINE_PHASES: usize = 64;
        for ip in 0..=24 {
            let period = p0 * (0.88 + 0.01 * ip as f64);
            let n_phase = ((period / dt).ceil() as usize).clamp(1, FINE_PHASES);
            let step = if n_phase == FINE_PHASES {
                period / n_phase as f64
            } else {
                dt
            };
            for jp in 0..n_phase {
                let phase = jp as f64 * step;
                consider(cost(period, phase), period, phase, &mut best);
            }
        }
        let (_, period, ph0) = best;
        let half = (period / FINE_PHASES as f64 / dt).ceil() as i64;
        if (period / dt).ceil() as usize > FINE_PHASES {
            for j in -half..=half {
                let phase = (((ph0 / dt).round() + j as f64) * dt).rem_euclid(period);
                consider(cost(period, phase), period, phase, &mut best);
            }
        }
        (best.1, best.2)
    }

    /// Sample-and-hold period and phase of the first measured force channel of the first run:
    /// from its exactly repeated values when it has them, else from its isolated single-sample
    /// jumps ([`signal::hold_from_jumps`]: noise after the hold, updates at rest unseen, the
    /// period fitted over the whole run), else from the jumps' periodogram
    /// ([`signal::hold_period`]); `None` when none finds a hold.
    pub fn hold_from_updates(&self) -> Option<(f64, f64)> {
        let c = self.channels.iter().position(|c| c.sensor)?;
        self.hold_from_updates_of(c)
    }

    /// [`Self::hold_from_updates`] on channel `c`.
    pub fn hold_from_updates_of(&self, c: usize) -> Option<(f64, f64)> {
        let run = &self.runs[0];
        let q = self.channels.len();
        let y: Vec<f64> = (0..run.len()).map(|k| run.measured[k * q + c]).collect();
        Self::hold_from_repeats(&y, run.dt)
            .or_else(|| signal::hold_from_jumps(&y, run.dt))
            .or_else(|| signal::hold_period(&y, run.dt, 0.25 * self.scales.duration))
    }

    /// Update instants of a held channel whose value repeats exactly between updates (no
    /// noise after the hold): the instants `t_j` where it changes are fitted by least squares
    /// to `phase + n_j·period`, with `n_j` the update count accumulated from the intervals in
    /// units of the median interval, so missed updates (a value that did not change) do not
    /// bias the estimate. `None` when the channel changes at more than half of its samples.
    fn hold_from_repeats(y: &[f64], dt: f64) -> Option<(f64, f64)> {
        let events: Vec<f64> = (1..y.len())
            .filter(|&k| y[k].to_bits() != y[k - 1].to_bits()) // a held value repeats exactly
            .map(|k| k as f64 * dt)
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
        Some((period, (first - 0.5 * dt).rem_euclid(period)))
    }

    /// RK4 substeps the augmented model at `theta` needs at the run's sample interval, from its
    /// stiffest mode at rest (see [`propose_step`]); the joint's dry friction is left out (its
    /// substeps are chosen interval by interval, see [`super::plant`]).
    pub fn advised_substeps(&self, theta: &[f64]) -> Result<usize> {
        let a = self.augment(theta)?;
        let mut worst = 1;
        for run in &self.runs {
            let advice = match &a.model {
                Replay::Joint(m) => {
                    // the joint's dry friction gets its substeps interval by interval from its
                    // local rate (plant.rs): advise for the other modes
                    let mut q = m.clone();
                    q.friction.coulomb = 0.0;
                    q.friction.static_level = 0.0;
                    q.load_friction = 0.0;
                    let x = q.rest(run.input[0] / q.radius);
                    propose_step(&q, &x, &[run.input[0], 0.0, 0.0], run.dt, 0.9)?
                }
                Replay::Transmission(m) | Replay::Servo(m, _) => {
                    let x = if run.x0.len() == m.n_states() {
                        run.x0.clone()
                    } else {
                        m.rest_state()
                    };
                    propose_step(m, &x, &vec![0.0; m.n_inputs()], run.dt, 0.9)?
                }
                Replay::Network(m) => {
                    // the friction is integrated implicitly (netplant.rs): advise for the rest
                    let q = m.frictionless();
                    let x = if run.x0.len() == q.n_states() {
                        run.x0.clone()
                    } else {
                        q.rest_at(&[])
                    };
                    propose_step(&q, &x, &vec![0.0; q.n_inputs()], run.dt, 0.9)?
                }
            };
            worst = worst.max(advice.substeps);
        }
        Ok(worst)
    }
}
