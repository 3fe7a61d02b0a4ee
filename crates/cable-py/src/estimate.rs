//! `SrUkf`: the square-root UKF over a cablekit model or a discrete linear system.

use cable_core::estimate::{self as core, DynSrUkf as Filter, Measure, Moments, ProcessKind};
use std::sync::{Arc, Mutex, MutexGuard};

use numpy::{PyArray1, PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::callback::{raised, Failure, PyObserve, PyParamModel, PyProcess};
use crate::convert::{matrix, opt_tuples, out_vector, rows, square, to_matrix, to_vector, vector};
use crate::dynamics::Model;
use crate::errors::{arg_error, guarded, lock, Class};
use crate::results::{DualRun, FilterHealth, FilterRun};

/// `(u, y, mask)` of one step; `(Y, U, mask)` of a log.
type Measurement = (Vec<f64>, Vec<f64>, Option<Vec<bool>>);
/// What `bounds` must be.
const BOUNDS: &str = "a list of (lower, upper) pairs, one per parameter";
/// `(gamma, (Wm0, Wmi), (Wc0, Wci))`.
type WeightTuple = (f64, (f64, f64), (f64, f64));

/// Square-root unscented Kalman filter (seed 001, eqs 3.9–3.25). One thread at a time: a
/// call while another thread's is running raises `ConcurrentUseError`.
#[pyclass(frozen, module = "cablekit._cablekit")]
pub struct SrUkf {
    inner: Mutex<Filter>,
    m: usize,
    /// A user model's callback error of the running call (`from_functions` only).
    failure: Option<Arc<Failure>>,
}

/// `x0`, `P0`, `Q`, `R` as the core's moments (sizes checked there).
#[allow(non_snake_case)]
fn moments(
    x0: &Bound<'_, PyAny>,
    P0: &Bound<'_, PyAny>,
    Q: &Bound<'_, PyAny>,
    R: &Bound<'_, PyAny>,
) -> PyResult<Moments> {
    let x0 = crate::convert::any_vector(x0, "x0")?;
    let (p0, q, r) = (square(P0, "P0")?, square(Q, "Q")?, square(R, "R")?);
    Ok(Moments { x0, p0, q, r })
}

/// `H` as `(values, rows)`, when given.
#[allow(non_snake_case)]
fn h_rows(H: Option<&Bound<'_, PyAny>>) -> PyResult<Option<(Vec<f64>, usize)>> {
    H.filter(|h| !h.is_none()).map(|h| rows(h, "H")).transpose()
}

/// `f`, a callable (a `DTypeError` naming `name` otherwise).
fn callable(f: &Bound<'_, PyAny>, name: &str) -> PyResult<Py<PyAny>> {
    if f.is_callable() {
        return Ok(f.clone().unbind());
    }
    let msg = format!("{name} must be callable, got {}", f.get_type().name()?);
    Err(arg_error(Class::DType, name, msg))
}

fn mask_vec(obj: Option<&Bound<'_, PyAny>>, p: usize) -> PyResult<Option<Vec<bool>>> {
    let Some(o) = obj.filter(|o| !o.is_none()) else {
        return Ok(None);
    };
    let msg = "mask must be a sequence of booleans (True = measured)";
    let v: Vec<bool> = o
        .extract()
        .map_err(|_| arg_error(Class::DType, "mask", msg.into()))?;
    if v.len() != p {
        let msg = format!("mask must have length {p}, got {}", v.len());
        return Err(arg_error(Class::Shape, "mask", msg));
    }
    Ok(Some(v))
}

impl SrUkf {
    fn build(kind: ProcessKind, measure: Measure, init: Moments, s: [f64; 3]) -> PyResult<Self> {
        let [alpha, beta, kappa] = s;
        let scaling = core::SigmaScaling { alpha, beta, kappa };
        let inner = guarded(|| core::filter(kind, measure, &init, scaling))?;
        let m = inner.n_inputs();
        Ok(Self {
            inner: Mutex::new(inner),
            m,
            failure: None,
        })
    }

    /// `result`, unless a user model's callback raised during the call: then its exception
    /// (the filter has undone the step).
    fn callbacks<T>(&self, result: PyResult<T>) -> PyResult<T> {
        raised(self.failure.as_ref(), result)
    }

    /// The filter, for this call only (`ConcurrentUseError` if another thread is in a call).
    fn filter(&self) -> PyResult<MutexGuard<'_, Filter>> {
        lock(&self.inner, "SrUkf")
    }

    /// `u`, `y` and the optional mask of one step, checked.
    fn measurement(
        &self,
        u: &Bound<'_, PyAny>,
        y: &Bound<'_, PyAny>,
        mask: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Measurement> {
        let p = self.filter()?.n_outputs();
        Ok((
            vector(u, "u", self.m)?,
            vector(y, "y", p)?,
            mask_vec(mask, p)?,
        ))
    }
}

#[pymethods]
impl SrUkf {
    /// Filter over `model` integrated by RK4 (`substeps` per period `dt`, input held), measuring
    /// either selected states (`states`), selected model outputs (`outputs`) or `H·x` (`H`).
    #[new]
    #[pyo3(signature = (model, x0, P0, Q, R, *, dt, substeps = 1, states = None, outputs = None, H = None, alpha = 1e-3, beta = 2.0, kappa = 0.0))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn new(
        model: &Bound<'_, Model>,
        x0: &Bound<'_, PyAny>,
        P0: &Bound<'_, PyAny>,
        Q: &Bound<'_, PyAny>,
        R: &Bound<'_, PyAny>,
        dt: f64,
        substeps: usize,
        states: Option<Vec<usize>>,
        outputs: Option<Vec<usize>>,
        H: Option<&Bound<'_, PyAny>>,
        alpha: f64,
        beta: f64,
        kappa: f64,
    ) -> PyResult<Self> {
        let model = model.get().inner.clone();
        let kind = ProcessKind::Model {
            model,
            dt,
            substeps,
        };
        let h = h_rows(H)?;
        let measure = guarded(|| Measure::one_of(states, outputs, h))?;
        Self::build(kind, measure, moments(x0, P0, Q, R)?, [alpha, beta, kappa])
    }

    /// Joint state–parameter filter over a cable transmission: the state is `[x; θ]` with `θ`
    /// the named transmission parameters (`"cable_stiffness[1]"`, `"coupling[2][0]"`, ...) as
    /// random walks; every sigma point's `θ` and the mean are projected into `bounds`
    /// (`(lower, upper)` per parameter, intersected with the physical ranges). `x0`, `P0`, `Q`
    /// cover `n + len(params)` entries; measurements are selected `states` or `H`.
    #[staticmethod]
    #[pyo3(signature = (model, params, x0, P0, Q, R, *, dt, substeps = 1, states = None, H = None, bounds = None, alpha = 1e-3, beta = 2.0, kappa = 0.0))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn with_parameters(
        model: &Bound<'_, Model>,
        params: Vec<String>,
        x0: &Bound<'_, PyAny>,
        P0: &Bound<'_, PyAny>,
        Q: &Bound<'_, PyAny>,
        R: &Bound<'_, PyAny>,
        dt: f64,
        substeps: usize,
        states: Option<Vec<usize>>,
        H: Option<&Bound<'_, PyAny>>,
        bounds: Option<&Bound<'_, PyAny>>,
        alpha: f64,
        beta: f64,
        kappa: f64,
    ) -> PyResult<Self> {
        let model = model.get().inner.clone();
        let h = h_rows(H)?;
        let bounds = opt_tuples(bounds, "bounds", BOUNDS)?;
        let measure = guarded(|| Measure::one_of(states, None, h))?;
        let kind = ProcessKind::Parameters {
            model,
            names: params,
            bounds,
            dt,
            substeps,
        };
        Self::build(kind, measure, moments(x0, P0, Q, R)?, [alpha, beta, kappa])
    }

    /// Filter over `model` with unknown inputs as random-walk states (seed 001 §5.3): the state
    /// is `[x; w]` and model input `inputs[k]` receives `u[inputs[k]] + w[k]` (e.g. an external
    /// joint force). `x0`, `P0`, `Q` cover `n + len(inputs)` entries.
    #[staticmethod]
    #[pyo3(signature = (model, inputs, x0, P0, Q, R, *, dt, substeps = 1, states = None, H = None, alpha = 1e-3, beta = 2.0, kappa = 0.0))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn with_input_states(
        model: &Bound<'_, Model>,
        inputs: Vec<usize>,
        x0: &Bound<'_, PyAny>,
        P0: &Bound<'_, PyAny>,
        Q: &Bound<'_, PyAny>,
        R: &Bound<'_, PyAny>,
        dt: f64,
        substeps: usize,
        states: Option<Vec<usize>>,
        H: Option<&Bound<'_, PyAny>>,
        alpha: f64,
        beta: f64,
        kappa: f64,
    ) -> PyResult<Self> {
        let model = model.get().inner.clone();
        let h = h_rows(H)?;
        let measure = guarded(|| Measure::one_of(states, None, h))?;
        let kind = ProcessKind::InputStates {
            model,
            inputs,
            dt,
            substeps,
        };
        Self::build(kind, measure, moments(x0, P0, Q, R)?, [alpha, beta, kappa])
    }

    /// Filter over the discrete linear system `x' = F·x + B·u`, `y = H·x`.
    #[staticmethod]
    #[pyo3(signature = (F, H, x0, P0, Q, R, *, B = None, alpha = 1e-3, beta = 2.0, kappa = 0.0))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn linear(
        F: &Bound<'_, PyAny>,
        H: &Bound<'_, PyAny>,
        x0: &Bound<'_, PyAny>,
        P0: &Bound<'_, PyAny>,
        Q: &Bound<'_, PyAny>,
        R: &Bound<'_, PyAny>,
        B: Option<&Bound<'_, PyAny>>,
        alpha: f64,
        beta: f64,
        kappa: f64,
    ) -> PyResult<Self> {
        let (f, n) = rows(F, "F")?;
        let b = B
            .filter(|b| !b.is_none())
            .map(|b| rows(b, "B"))
            .transpose()?;
        let (h, p) = rows(H, "H")?;
        let kind = ProcessKind::Linear {
            f,
            b: b.map(|b| b.0).unwrap_or_default(),
            n,
        };
        let measure = Measure::Matrix { rows: p, h };
        Self::build(kind, measure, moments(x0, P0, Q, R)?, [alpha, beta, kappa])
    }

    /// Filter over your own model: `fx(x, dt)` (or `fx(x, dt, u)` with `n_inputs` inputs)
    /// returns the state one period `dt` later and `hx(x)` the measurement, NumPy arrays in
    /// and out (filterpy's convention). `vectorized=True`: both take all sigma points at once,
    /// `(k, n)` in, `(k, n)` / `(k, p)` out. Sizes come from `x0` (`n`) and `R` (`p`). The same
    /// filter as the built-in models: recovery, masks, gating, health, typed errors; an
    /// exception raised by a callback is raised by the call that ran it, the step undone.
    #[staticmethod]
    #[pyo3(signature = (fx, hx, x0, P0, Q, R, *, dt, n_inputs = 0, vectorized = false, alpha = 1e-3, beta = 2.0, kappa = 0.0))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn from_functions(
        fx: &Bound<'_, PyAny>,
        hx: &Bound<'_, PyAny>,
        x0: &Bound<'_, PyAny>,
        P0: &Bound<'_, PyAny>,
        Q: &Bound<'_, PyAny>,
        R: &Bound<'_, PyAny>,
        dt: f64,
        n_inputs: usize,
        vectorized: bool,
        alpha: f64,
        beta: f64,
        kappa: f64,
    ) -> PyResult<Self> {
        let (fx, hx) = (callable(fx, "fx")?, callable(hx, "hx")?);
        let init = moments(x0, P0, Q, R)?;
        let (n, p) = (init.x0.len(), init.r.len().isqrt());
        let failure = Arc::new(Failure::default());
        let process = PyProcess::new(fx, dt, n, n_inputs, vectorized, failure.clone());
        let observe = PyObserve::new(hx, n, p, vectorized, failure.clone());
        let scaling = core::SigmaScaling { alpha, beta, kappa };
        let inner = guarded(|| {
            cable_core::error::check::positive("dt", dt)?;
            core::custom_filter(Box::new(process), Box::new(observe), &init, scaling)
        })?;
        let (inner, m) = (Mutex::new(inner), n_inputs);
        Ok(Self {
            inner,
            m,
            failure: Some(failure),
        })
    }

    /// Number of states the filter estimates.
    #[getter]
    fn n_states(&self) -> PyResult<usize> {
        Ok(self.filter()?.n_states())
    }
    /// Number of measured outputs.
    #[getter]
    fn n_outputs(&self) -> PyResult<usize> {
        Ok(self.filter()?.n_outputs())
    }
    /// Number of inputs the process takes.
    #[getter]
    fn n_inputs(&self) -> usize {
        self.m
    }
    /// Current mean.
    #[getter]
    fn x<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        Ok(to_vector(py, self.filter()?.x().to_vec()))
    }
    /// Write the current mean into `out` `(n,)` (a writable float64 array) and return it: no
    /// allocation, for a controller's loop (`x` returns a new array).
    fn x_into<'py>(&self, out: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let f = self.filter()?;
        let mut rw = out_vector(out, "out", f.n_states())?;
        rw.as_slice_mut()?.copy_from_slice(f.x());
        Ok(out.clone())
    }
    /// Current lower-triangular square root of the covariance.
    #[getter(S)]
    fn sqrt_covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let f = self.filter()?;
        let n = f.n_states();
        Ok(to_matrix(py, f.sqrt_covariance_rows(), n, n))
    }
    /// Current covariance `S·Sᵀ`.
    #[getter(P)]
    fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let f = self.filter()?;
        let n = f.n_states();
        Ok(to_matrix(py, f.covariance(), n, n)) // symmetric: either order
    }
    /// `(gamma, (Wm0, Wmi), (Wc0, Wci))`.
    #[getter]
    fn weights(&self) -> PyResult<WeightTuple> {
        let f = self.filter()?;
        let w = f.weights();
        Ok((w.gamma, w.wm, w.wc))
    }
    /// Innovation gate: updates whose NIS exceeds it are rejected and counted (`None`: off).
    #[getter]
    fn nis_gate(&self) -> PyResult<Option<f64>> {
        let g = self.filter()?.nis_gate();
        Ok(g.is_finite().then_some(g))
    }
    #[setter]
    fn set_nis_gate(&self, value: Option<f64>) -> PyResult<()> {
        let mut f = self.filter()?;
        guarded(|| f.set_nis_gate(value))
    }
    /// Health of the last step: `nis`, `measured`, `condition`, `recovered`,
    /// `recoveries_total`, `gated`, `rejected_total`, `steps`.
    #[getter]
    fn health(&self) -> PyResult<FilterHealth> {
        Ok(self.filter()?.health().into())
    }

    /// Time update with input `u` held over one period.
    fn predict(&self, u: &Bound<'_, PyAny>) -> PyResult<()> {
        let u = vector(u, "u", self.m)?;
        let mut f = self.filter()?;
        self.callbacks(guarded(|| f.predict(&u)))
    }

    /// Measurement update with `y` (entries where `mask` is true; all without a mask).
    #[pyo3(signature = (u, y, mask = None))]
    fn update(
        &self,
        u: &Bound<'_, PyAny>,
        y: &Bound<'_, PyAny>,
        mask: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let (u, y, mask) = self.measurement(u, y, mask)?;
        let mut f = self.filter()?;
        self.callbacks(guarded(|| f.update(&u, &y, mask.as_deref())))
    }

    /// Predict with `u`, then update with `y` (see `update`). Bad input raises before
    /// anything changes.
    #[pyo3(signature = (u, y, mask = None))]
    fn step(
        &self,
        u: &Bound<'_, PyAny>,
        y: &Bound<'_, PyAny>,
        mask: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let (u, y, mask) = self.measurement(u, y, mask)?;
        let mut f = self.filter()?;
        self.callbacks(guarded(|| f.step(&u, &y, mask.as_deref())))
    }

    /// Replace the mean and covariance.
    #[allow(non_snake_case)]
    fn reset(&self, x: &Bound<'_, PyAny>, P: &Bound<'_, PyAny>) -> PyResult<()> {
        let (x, p) = (crate::convert::any_vector(x, "x")?, square(P, "P")?);
        let mut f = self.filter()?;
        guarded(|| f.reset(&x, &p))
    }

    /// Filter a whole log: `U` `(T, m)` inputs (the input over the period ending at sample
    /// `k`), `Y` `(T, p)` measurements, `mask` `(T, p)` booleans (default: all measured; a NaN
    /// where the mask is true is an error). Returns `x` `(T, n)`, `S` `(T, n, n)`, `nis`,
    /// `condition`, `recovered` `(T,)` and `measured` `(T,)`. The GIL is released.
    ///
    /// With `smooth=True` the square-root URTS smoother then runs backwards over the filtered
    /// run and `x_smooth` `(T, n)`, `S_smooth` `(T, n, n)` are added (offline identification).
    #[pyo3(signature = (U, Y, mask = None, smooth = false))]
    #[allow(non_snake_case)]
    fn run<'py>(
        &self,
        py: Python<'py>,
        U: &Bound<'py, PyAny>,
        Y: &Bound<'py, PyAny>,
        mask: Option<&Bound<'py, PyAny>>,
        smooth: bool,
    ) -> PyResult<FilterRun> {
        let (p, m) = (self.filter()?.n_outputs(), self.m);
        let (y, u, mk) = log_arrays(U, Y, mask, m, p)?;
        let mut guard = self.filter()?;
        let f: &mut Filter = &mut guard; // a plain borrow crosses into the GIL-free closure
        let run = self.callbacks(py.detach(|| guarded(|| f.run(&u, &y, mk.as_deref(), smooth))))?;
        Ok(FilterRun::new(py, run))
    }
}

/// `Y` `(T, p)`, `U` `(T, m)` (empty when `m` is 0) and the optional mask of a log, converted.
#[allow(non_snake_case)]
fn log_arrays(
    U: &Bound<'_, PyAny>,
    Y: &Bound<'_, PyAny>,
    mask: Option<&Bound<'_, PyAny>>,
    m: usize,
    p: usize,
) -> PyResult<Measurement> {
    let (yarr, t) = matrix(Y, "Y", Some(p))?;
    let y = yarr.as_slice()?.to_vec();
    let u = match m {
        0 => Vec::new(),
        _ => match matrix(U, "U", Some(m))? {
            (_, tu) if tu != t => {
                let msg = format!("U has {tu} rows but Y has {t}");
                return Err(arg_error(Class::Shape, "U", msg));
            }
            (uarr, _) => uarr.as_slice()?.to_vec(),
        },
    };
    Ok((y, u, bool_matrix(mask, t, p)?))
}

/// Dual state–parameter estimation (seed 001 eqs 3.7–3.8): a state filter over the transmission
/// and a parameter filter over the named parameters, run side by side.
#[pyclass(frozen, module = "cablekit._cablekit")]
pub struct DualSrUkf {
    inner: Mutex<Dual>,
    m: usize,
    /// A user model's callback error of the running call (`from_functions` only).
    failure: Option<Arc<Failure>>,
}

/// The two filters of a `DualSrUkf`: over a transmission's named parameters, or a user's model.
enum Dual {
    Transmission(Box<core::DualSrUkf>),
    User(Box<core::DualFilter<PyParamModel, PyObserve>>),
}

impl Dual {
    /// States `n`, measured channels `q`, parameters `p`.
    fn sizes(&self) -> (usize, usize, usize) {
        match self {
            Self::Transmission(d) => (d.state.n_states(), d.state.n_outputs(), d.params.n_states()),
            Self::User(d) => (d.state.n_states(), d.state.n_outputs(), d.params.n_states()),
        }
    }

    fn run(
        &mut self,
        u: &[f64],
        y: &[f64],
        mask: Option<&[bool]>,
    ) -> cable_core::Result<core::DualRun> {
        match self {
            Self::Transmission(d) => d.run(u, y, mask),
            Self::User(d) => d.run(u, y, mask),
        }
    }
}

#[pymethods]
impl DualSrUkf {
    #[new]
    #[pyo3(signature = (model, params, x0, P0, Q, P0_theta, Q_theta, R, *, dt, substeps = 1, states, bounds = None, alpha = 1e-3, beta = 2.0, kappa = 0.0))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn new(
        model: &Bound<'_, Model>,
        params: Vec<String>,
        x0: &Bound<'_, PyAny>,
        P0: &Bound<'_, PyAny>,
        Q: &Bound<'_, PyAny>,
        P0_theta: &Bound<'_, PyAny>,
        Q_theta: &Bound<'_, PyAny>,
        R: &Bound<'_, PyAny>,
        dt: f64,
        substeps: usize,
        states: Vec<usize>,
        bounds: Option<&Bound<'_, PyAny>>,
        alpha: f64,
        beta: f64,
        kappa: f64,
    ) -> PyResult<Self> {
        let init = moments(x0, P0, Q, R)?;
        let bounds = opt_tuples(bounds, "bounds", BOUNDS)?;
        let theta = (square(P0_theta, "P0_theta")?, square(Q_theta, "Q_theta")?);
        let scaling = core::SigmaScaling { alpha, beta, kappa };
        let model = &model.get().inner;
        let inner = guarded(|| {
            let theta = (theta.0.as_slice(), theta.1.as_slice());
            core::dual_filter(
                model, &params, bounds, dt, substeps, &states, &init, theta, scaling,
            )
        })?;
        let m = inner.state.n_inputs();
        Ok(Self {
            inner: Mutex::new(Dual::Transmission(Box::new(inner))),
            m,
            failure: None,
        })
    }

    /// Dual filter over your own model: `fx(x, theta, dt)` (or `fx(x, theta, dt, u)` with
    /// `n_inputs` inputs) returns the state one period later with parameters `theta`, `hx(x)`
    /// the measurement (one point per call). The state filter runs the model at the current
    /// parameter estimate; the parameter filter (a random walk from `theta0`, kept within
    /// `bounds`) measures the last state estimate propagated with each parameter sigma point.
    #[staticmethod]
    #[pyo3(signature = (fx, hx, x0, P0, Q, theta0, P0_theta, Q_theta, R, *, dt, n_inputs = 0, bounds = None, alpha = 1e-3, beta = 2.0, kappa = 0.0))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn from_functions(
        fx: &Bound<'_, PyAny>,
        hx: &Bound<'_, PyAny>,
        x0: &Bound<'_, PyAny>,
        P0: &Bound<'_, PyAny>,
        Q: &Bound<'_, PyAny>,
        theta0: &Bound<'_, PyAny>,
        P0_theta: &Bound<'_, PyAny>,
        Q_theta: &Bound<'_, PyAny>,
        R: &Bound<'_, PyAny>,
        dt: f64,
        n_inputs: usize,
        bounds: Option<&Bound<'_, PyAny>>,
        alpha: f64,
        beta: f64,
        kappa: f64,
    ) -> PyResult<Self> {
        let (fx, hx) = (callable(fx, "fx")?, callable(hx, "hx")?);
        let init = core::DualMoments {
            state: moments(x0, P0, Q, R)?,
            theta0: crate::convert::any_vector(theta0, "theta0")?,
            p0_theta: square(P0_theta, "P0_theta")?,
            q_theta: square(Q_theta, "Q_theta")?,
        };
        let bounds = opt_tuples(bounds, "bounds", BOUNDS)?;
        let failure = Arc::new(Failure::default());
        let models = user_models(&fx, &hx, dt, (&init, n_inputs), &failure);
        let scaling = core::SigmaScaling { alpha, beta, kappa };
        let inner = guarded(|| {
            cable_core::error::check::positive("dt", dt)?;
            core::DualFilter::new(models.0, models.1, &init, bounds, scaling)
        })?;
        let (inner, m) = (Mutex::new(Dual::User(Box::new(inner))), n_inputs);
        Ok(Self {
            inner,
            m,
            failure: Some(failure),
        })
    }

    /// Filter a log (`U` `(T, m)`, `Y` `(T, len(states))`, optional `mask`): returns `x`
    /// `(T, n)`, `theta` `(T, p)` and `theta_std` `(T, p)`. The GIL is released.
    #[pyo3(signature = (U, Y, mask = None))]
    #[allow(non_snake_case)]
    fn run<'py>(
        &self,
        py: Python<'py>,
        U: &Bound<'py, PyAny>,
        Y: &Bound<'py, PyAny>,
        mask: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<DualRun> {
        let mut f = lock(&self.inner, "DualSrUkf")?;
        let (n, q, p) = f.sizes();
        let (y, u, mk) = log_arrays(U, Y, mask, self.m, q)?;
        let fr: &mut Dual = &mut f; // a plain borrow crosses into the closure
        let run = py.detach(|| guarded(|| fr.run(&u, &y, mk.as_deref())));
        let run = raised(self.failure.as_ref(), run)?;
        Ok(DualRun::new(py, run, n, p))
    }
}

/// Two copies (one per filter) of a user's dual model and measurement, sharing one failure slot.
type UserModels = ((PyParamModel, PyParamModel), (PyObserve, PyObserve));

fn user_models(
    fx: &Py<PyAny>,
    hx: &Py<PyAny>,
    dt: f64,
    (init, m): (&core::DualMoments, usize),
    failure: &Arc<Failure>,
) -> UserModels {
    let sizes = (init.state.x0.len(), init.theta0.len(), m);
    let p = init.state.r.len().isqrt();
    Python::attach(|py| {
        let model = || PyParamModel::new(fx.clone_ref(py), dt, sizes, failure.clone());
        let observe = || PyObserve::new(hx.clone_ref(py), sizes.0, p, false, failure.clone());
        ((model(), model()), (observe(), observe()))
    })
}

/// An optional `(t, q)` boolean numpy mask.
fn bool_matrix(mask: Option<&Bound<'_, PyAny>>, t: usize, q: usize) -> PyResult<Option<Vec<bool>>> {
    match mask {
        Some(mk) if !mk.is_none() => {
            let arr = mk.cast::<numpy::PyArray2<bool>>().map_err(|_| {
                let msg = "mask must be a (T, p) numpy array of bool";
                arg_error(Class::DType, "mask", msg.into())
            })?;
            if arr.shape() != [t, q] {
                let msg = format!("mask must have shape ({t}, {q}), got {:?}", arr.shape());
                return Err(arg_error(Class::Shape, "mask", msg));
            }
            Ok(Some(arr.readonly().as_array().iter().copied().collect()))
        }
        _ => Ok(None),
    }
}

/// Add this file's classes and functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<SrUkf>()?;
    m.add_class::<DualSrUkf>()?;
    Ok(())
}
