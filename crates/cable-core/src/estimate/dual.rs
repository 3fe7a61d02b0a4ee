//! Dual state–parameter estimation (seed 001 eqs 3.7–3.8) over any model whose parameters `θ`
//! are an argument of its propagation — a front end's own `fx(x, θ, dt, u)` and `hx(x)`: a state
//! filter over the model at the current parameter estimate, and a parameter filter over `θ`
//! alone (a random walk) whose measurement is the state filter's last estimate propagated with
//! each parameter sigma point, then measured. [`DualSrUkf`](super::DualSrUkf) is the same
//! scheme over a cable transmission's named parameters.

use crate::error::{check, Result};

use super::run::{run_dual, DualRun, DualSteps};
use super::{Observe, Process, RandomWalk, SigmaScaling, SrUkf};

/// A process with parameters: `x_k = F(x_{k−1}, u_{k−1}; θ)` (additive noise is the filter's).
pub trait ParamModel {
    /// State dimension `n`.
    fn n_states(&self) -> usize;
    /// Parameter dimension `p`.
    fn n_params(&self) -> usize;
    /// Input dimension.
    fn n_inputs(&self) -> usize;
    /// Propagates `x` over one period with parameters `theta` and input `u` (held).
    fn propagate(&mut self, x: &mut [f64], theta: &[f64], u: &[f64]);
    /// Whether a propagation since the step began could not be computed (see
    /// [`Process::failed`]).
    fn failed(&self) -> bool {
        false
    }
}

impl<T: ParamModel + ?Sized> ParamModel for Box<T> {
    fn n_states(&self) -> usize {
        (**self).n_states()
    }
    fn n_params(&self) -> usize {
        (**self).n_params()
    }
    fn n_inputs(&self) -> usize {
        (**self).n_inputs()
    }
    fn propagate(&mut self, x: &mut [f64], theta: &[f64], u: &[f64]) {
        (**self).propagate(x, theta, u)
    }
    fn failed(&self) -> bool {
        (**self).failed()
    }
}

/// The state filter's process: the model at the parameter filter's current estimate.
pub struct AtParams<M: ParamModel> {
    model: M,
    theta: Vec<f64>,
}

impl<M: ParamModel> Process for AtParams<M> {
    fn n_states(&self) -> usize {
        self.model.n_states()
    }
    fn n_inputs(&self) -> usize {
        self.model.n_inputs()
    }
    fn propagate(&mut self, x: &mut [f64], u: &[f64]) {
        self.model.propagate(x, &self.theta, u);
    }
    fn failed(&self) -> bool {
        self.model.failed()
    }
}

/// The parameter filter's measurement: the state filter's previous estimate propagated one
/// period with the parameters `θ`, then measured (eq 3.8).
pub struct Through<M: ParamModel, O: Observe> {
    model: M,
    observe: O,
    x_prev: Vec<f64>,
    u: Vec<f64>,
    buf: Vec<f64>,
}

impl<M: ParamModel, O: Observe> Observe for Through<M, O> {
    fn n_outputs(&self) -> usize {
        self.observe.n_outputs()
    }
    fn observe(&mut self, theta: &[f64], _u: &[f64], y: &mut [f64]) {
        self.buf.copy_from_slice(&self.x_prev);
        self.model.propagate(&mut self.buf, theta, &self.u);
        self.observe.observe(&self.buf, &self.u, y);
    }
    fn failed(&self) -> bool {
        self.model.failed() || self.observe.failed()
    }
}

/// Dual filter over a [`ParamModel`] and a measurement: the state filter and the parameter
/// filter side by side (module docs). Each step updates the parameters first, then the state
/// with the new parameters; a failing step leaves both as they were.
pub struct DualFilter<M: ParamModel, O: Observe> {
    /// The state filter.
    pub state: SrUkf<AtParams<M>, O>,
    /// The parameter filter.
    pub params: SrUkf<RandomWalk, Through<M, O>>,
}

/// The starting point of a [`DualFilter`]: the state's and the parameters' means, covariances
/// and noise (symmetric matrices in either storage order), and the measurement noise `r`.
#[derive(Debug, Clone, PartialEq)]
pub struct DualMoments {
    /// The state filter's `x0`, `P0`, `Q` and the measurement's `R`.
    pub state: super::Moments,
    /// Initial parameters `θ0` `(p,)`.
    pub theta0: Vec<f64>,
    /// Their covariance `(p, p)`.
    pub p0_theta: Vec<f64>,
    /// Their random walk's covariance per period `(p, p)`.
    pub q_theta: Vec<f64>,
}

impl<M: ParamModel, O: Observe> DualFilter<M, O> {
    /// The dual filter over two copies of the same model and measurement (one for each
    /// filter), from `init`; `bounds` `(lower, upper)` per parameter (default unbounded).
    pub fn new(
        models: (M, M),
        observes: (O, O),
        init: &DualMoments,
        bounds: Option<Vec<(f64, f64)>>,
        scaling: SigmaScaling,
    ) -> Result<Self> {
        let (n, p) = (models.0.n_states(), models.0.n_params());
        check::len("theta0", &init.theta0, p)?;
        check::all_finite("theta0", &init.theta0, 1)?;
        let bounds = bounds.unwrap_or_else(|| vec![(f64::NEG_INFINITY, f64::INFINITY); p]);
        let walk = RandomWalk::new(bounds, p)?;
        let m = models.0.n_inputs();
        let s = &init.state;
        let at = AtParams {
            model: models.0,
            theta: init.theta0.clone(),
        };
        let state = SrUkf::new(at, observes.0, &s.x0, &s.p0, &s.q, &s.r, scaling)?;
        let through = Through {
            model: models.1,
            observe: observes.1,
            x_prev: s.x0.clone(),
            u: vec![0.0; m],
            buf: vec![0.0; n],
        };
        let (p0, q) = (&init.p0_theta, &init.q_theta);
        let params = SrUkf::new(walk, through, &init.theta0, p0, q, &s.r, scaling)?;
        Ok(Self { state, params })
    }

    /// One step with input `u` and measurement `y` (entries where `mask` is true).
    pub fn step(&mut self, u: &[f64], y: &[f64], mask: Option<&[bool]>) -> Result<()> {
        check::len("u", u, self.state.process.n_inputs())?;
        check::all_finite("u", u, 1)?;
        self.params.observe.x_prev.copy_from_slice(self.state.x());
        self.params.observe.u.copy_from_slice(u);
        self.params.step(&[], y, mask)?;
        let before = std::mem::replace(&mut self.state.process.theta, self.params.x().to_vec());
        let stepped = self.state.step(u, y, mask);
        if stepped.is_err() {
            // leave both filters as they were before this step
            self.params.undo_last_step();
            self.state.process.theta = before;
        }
        stepped
    }

    /// Filter a whole log (as [`DualSrUkf::run`](super::DualSrUkf::run)).
    pub fn run(&mut self, us: &[f64], ys: &[f64], mask: Option<&[bool]>) -> Result<DualRun> {
        run_dual(self, us, ys, mask)
    }
}

impl<M: ParamModel, O: Observe> DualSteps for DualFilter<M, O> {
    fn sizes(&self) -> (usize, usize, usize) {
        let (n, q) = (self.state.n_states(), self.state.n_outputs());
        (n, q, self.state.process.n_inputs())
    }
    fn step(&mut self, u: &[f64], y: &[f64], mask: Option<&[bool]>) -> Result<()> {
        DualFilter::step(self, u, y, mask)
    }
    fn estimates(&self) -> (&[f64], &[f64], &[f64]) {
        (
            self.state.x(),
            self.params.x(),
            self.params.sqrt_covariance(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::{LinearObserve, Moments};

    /// `x' = x + dt·(−θ·x + u)`.
    #[derive(Clone)]
    struct Decay {
        fail_below: f64,
        failed: bool,
    }

    impl ParamModel for Decay {
        fn n_states(&self) -> usize {
            1
        }
        fn n_params(&self) -> usize {
            1
        }
        fn n_inputs(&self) -> usize {
            1
        }
        fn propagate(&mut self, x: &mut [f64], theta: &[f64], u: &[f64]) {
            self.failed |= theta[0] < self.fail_below;
            x[0] += 0.01 * (-theta[0] * x[0] + u[0]);
        }
        fn failed(&self) -> bool {
            self.failed
        }
    }

    fn dual(fail_below: f64) -> DualFilter<Decay, LinearObserve> {
        let m = Decay {
            fail_below,
            failed: false,
        };
        let h = LinearObserve::select(1, &[0]).unwrap();
        let init = DualMoments {
            state: Moments {
                x0: vec![0.0],
                p0: vec![1e-4],
                q: vec![1e-8],
                r: vec![1e-6],
            },
            theta0: vec![1.0],
            p0_theta: vec![1.0],
            q_theta: vec![1e-8],
        };
        let s = SigmaScaling::default();
        DualFilter::new((m.clone(), m), (h.clone(), h), &init, None, s).unwrap()
    }

    /// Noise-free samples of the model with `θ = 2.5` under a sine input.
    fn log(steps: usize) -> (Vec<f64>, Vec<f64>) {
        let (mut x, mut us, mut ys) = (0.0, vec![], vec![]);
        for k in 0..steps {
            let u = 3.0 * (0.007 * k as f64).sin();
            x += 0.01 * (-2.5 * x + u);
            us.push(u);
            ys.push(x);
        }
        (us, ys)
    }

    #[test]
    fn the_parameter_filter_finds_the_model_parameter() {
        let (us, ys) = log(1500);
        let run = dual(f64::NEG_INFINITY).run(&us, &ys, None).unwrap();
        assert!((run.theta[1499] - 2.5).abs() < 0.05, "{}", run.theta[1499]);
        assert!((run.x[1499] - ys[1499]).abs() < 1e-3);
    }

    #[test]
    fn a_failing_model_leaves_both_filters_as_they_were() {
        let (us, ys) = log(3);
        let mut d = dual(f64::INFINITY); // every propagation reports a failure
        let (x, theta) = (d.state.x().to_vec(), d.params.x().to_vec());
        assert!(d.step(&us[..1], &ys[..1], None).is_err());
        assert_eq!((d.state.x(), d.params.x()), (&x[..], &theta[..]));
        assert_eq!((d.state.health().steps, d.params.health().steps), (0, 0));
    }
}
