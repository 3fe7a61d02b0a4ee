//! Process and measurement models of the filter: any cable-core [`Model`] integrated by RK4
//! with sub-steps, a discrete linear system, and linear-selection or model-output measurements.

use crate::dynamics::Model;
use crate::error::{check, CableError, Result};
use crate::integrate::{InputHold, Rk4, SimOptions};

/// A discrete-time process `x_k = F(x_{k−1}, u_{k−1})` (additive noise is the filter's).
pub trait Process {
    /// State dimension `n`.
    fn n_states(&self) -> usize;
    /// Input dimension.
    fn n_inputs(&self) -> usize;
    /// Propagates `x` over one filter period in place with input `u` (held over the period).
    fn propagate(&mut self, x: &mut [f64], u: &[f64]);
    /// Projects a mean onto the admissible set (bounded parameters); identity by default.
    fn project(&self, _x: &mut [f64]) {}
}

/// A measurement `y = H(x, u)`.
pub trait Observe {
    /// Measurement dimension `p`.
    fn n_outputs(&self) -> usize;
    /// Writes `H(x, u)` into `y`.
    fn observe(&mut self, x: &[f64], u: &[f64], y: &mut [f64]);
}

/// A cable-core model integrated over the filter period `dt` by `substeps` RK4 steps with the
/// input held (zero-order hold, as a servo applies it).
#[derive(Debug, Clone)]
pub struct ModelProcess<M: Model> {
    /// The continuous-time model.
    pub model: M,
    dt: f64,
    substeps: usize,
    rk4: Rk4,
}

impl<M: Model> ModelProcess<M> {
    /// `dt > 0` s per filter step, `substeps ≥ 1`.
    pub fn new(model: M, dt: f64, substeps: usize) -> Result<Self> {
        SimOptions::new(dt, substeps, InputHold::Zoh)?;
        let rk4 = Rk4::for_model(&model);
        Ok(Self {
            model,
            dt,
            substeps,
            rk4,
        })
    }

    /// Filter period (s).
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// RK4 steps per period.
    pub fn substeps(&self) -> usize {
        self.substeps
    }
}

impl<M: Model> Process for ModelProcess<M> {
    fn n_states(&self) -> usize {
        self.model.n_states()
    }
    fn n_inputs(&self) -> usize {
        self.model.n_inputs()
    }
    #[inline]
    fn propagate(&mut self, x: &mut [f64], u: &[f64]) {
        let h = self.dt / self.substeps as f64;
        for _ in 0..self.substeps {
            self.rk4.step(&self.model, x, u, h);
        }
    }
}

/// `x_k = A·x_{k−1} + B·u_{k−1}` (matrices row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct LinearProcess {
    n: usize,
    m: usize,
    a: Vec<f64>,
    b: Vec<f64>,
    tmp: Vec<f64>,
}

impl LinearProcess {
    /// `a` is `n × n`, `b` is `n × m` (`m` may be 0), both row-major and finite.
    pub fn new(n: usize, m: usize, a: Vec<f64>, b: Vec<f64>) -> Result<Self> {
        check::len("A", &a, n * n)?;
        check::len("B", &b, n * m)?;
        check::all_finite("A", &a, n)?;
        check::all_finite("B", &b, m.max(1))?;
        Ok(Self {
            n,
            m,
            a,
            b,
            tmp: vec![0.0; n],
        })
    }
}

impl Process for LinearProcess {
    fn n_states(&self) -> usize {
        self.n
    }
    fn n_inputs(&self) -> usize {
        self.m
    }
    fn propagate(&mut self, x: &mut [f64], u: &[f64]) {
        let (n, m) = (self.n, self.m);
        for i in 0..n {
            let row = &self.a[i * n..(i + 1) * n];
            let mut s: f64 = row.iter().zip(x.iter()).map(|(a, x)| a * x).sum();
            for j in 0..m {
                s += self.b[i * m + j] * u[j];
            }
            self.tmp[i] = s;
        }
        x.copy_from_slice(&self.tmp);
    }
}

/// `y = H·x` (row-major `p × n`).
#[derive(Debug, Clone, PartialEq)]
pub struct LinearObserve {
    p: usize,
    n: usize,
    h: Vec<f64>,
}

impl LinearObserve {
    /// `h` is `p × n` row-major and finite.
    pub fn new(p: usize, n: usize, h: Vec<f64>) -> Result<Self> {
        check::len("H", &h, p * n)?;
        check::all_finite("H", &h, n)?;
        Ok(Self { p, n, h })
    }

    /// Measures the listed states directly (`y_i = x[idx_i]`).
    pub fn select(n: usize, idx: &[usize]) -> Result<Self> {
        let mut h = vec![0.0; idx.len() * n];
        for (i, &k) in idx.iter().enumerate() {
            if k >= n {
                return Err(CableError::InvalidParameter {
                    name: format!("measured state index [{i}]"),
                    value: k as f64,
                    requirement: "below the number of states",
                });
            }
            h[i * n + k] = 1.0;
        }
        Self::new(idx.len(), n, h)
    }

    /// State dimension.
    pub fn n_states(&self) -> usize {
        self.n
    }
}

impl Observe for LinearObserve {
    fn n_outputs(&self) -> usize {
        self.p
    }
    #[inline]
    fn observe(&mut self, x: &[f64], _u: &[f64], y: &mut [f64]) {
        let n = self.n;
        for (i, yi) in y.iter_mut().enumerate().take(self.p) {
            *yi = self.h[i * n..(i + 1) * n]
                .iter()
                .zip(x)
                .map(|(h, x)| h * x)
                .sum();
        }
    }
}

/// Selected outputs of a model's (nonlinear) output map, e.g. cable tensions.
#[derive(Debug, Clone)]
pub struct ModelOutputs<M: Model> {
    /// The model whose `output` is measured.
    pub model: M,
    idx: Vec<usize>,
    buf: Vec<f64>,
}

impl<M: Model> ModelOutputs<M> {
    /// Measures outputs `idx` of `model.output`.
    pub fn new(model: M, idx: Vec<usize>) -> Result<Self> {
        let p = model.n_outputs();
        if let Some((i, &k)) = idx.iter().enumerate().find(|(_, &k)| k >= p) {
            return Err(CableError::InvalidParameter {
                name: format!("measured output index [{i}]"),
                value: k as f64,
                requirement: "below the model's number of outputs",
            });
        }
        Ok(Self {
            buf: vec![0.0; p],
            model,
            idx,
        })
    }
}

impl<M: Model> Observe for ModelOutputs<M> {
    fn n_outputs(&self) -> usize {
        self.idx.len()
    }
    fn observe(&mut self, x: &[f64], u: &[f64], y: &mut [f64]) {
        self.model.output(x, u, &mut self.buf);
        for (yi, &k) in y.iter_mut().zip(&self.idx) {
            *yi = self.buf[k];
        }
    }
}

impl<T: Process + ?Sized> Process for Box<T> {
    fn n_states(&self) -> usize {
        (**self).n_states()
    }
    fn n_inputs(&self) -> usize {
        (**self).n_inputs()
    }
    #[inline]
    fn propagate(&mut self, x: &mut [f64], u: &[f64]) {
        (**self).propagate(x, u)
    }
    fn project(&self, x: &mut [f64]) {
        (**self).project(x)
    }
}

impl<T: Observe + ?Sized> Observe for Box<T> {
    fn n_outputs(&self) -> usize {
        (**self).n_outputs()
    }
    #[inline]
    fn observe(&mut self, x: &[f64], u: &[f64], y: &mut [f64]) {
        (**self).observe(x, u, y)
    }
}

/// A model whose selected inputs carry extra random-walk states: the state is `[x; w]` and
/// input `inputs[k]` receives `u[inputs[k]] + w[k]` (an unknown external force or torque as a
/// filter state, seed 001 §5.3).
#[derive(Debug, Clone)]
pub struct InputStates<M: Model> {
    /// The model.
    pub model: M,
    inputs: Vec<usize>,
    dt: f64,
    substeps: usize,
    rk4: Rk4,
    u: Vec<f64>,
}

impl<M: Model> InputStates<M> {
    /// `inputs`: the model input indices driven by the extra states (distinct, in range).
    pub fn new(model: M, inputs: Vec<usize>, dt: f64, substeps: usize) -> Result<Self> {
        SimOptions::new(dt, substeps, InputHold::Zoh)?;
        let m = model.n_inputs();
        for (k, &i) in inputs.iter().enumerate() {
            if i >= m || inputs[..k].contains(&i) {
                return Err(CableError::InvalidParameter {
                    name: format!("input_states[{k}]"),
                    value: i as f64,
                    requirement: "a distinct model input index",
                });
            }
        }
        let rk4 = Rk4::for_model(&model);
        Ok(Self {
            u: vec![0.0; m],
            model,
            inputs,
            dt,
            substeps,
            rk4,
        })
    }
}

impl<M: Model> Process for InputStates<M> {
    fn n_states(&self) -> usize {
        self.model.n_states() + self.inputs.len()
    }
    fn n_inputs(&self) -> usize {
        self.model.n_inputs()
    }
    fn propagate(&mut self, x: &mut [f64], u: &[f64]) {
        let n = self.model.n_states();
        self.u.copy_from_slice(u);
        for (k, &i) in self.inputs.iter().enumerate() {
            self.u[i] += x[n + k];
        }
        let h = self.dt / self.substeps as f64;
        for _ in 0..self.substeps {
            self.rk4.step(&self.model, &mut x[..n], &self.u, h);
        }
    }
}
