//! `SrUkf`: the square-root UKF over a cablekit model or a discrete linear system.

use cable_core::dynamics::Model as _;
use cable_core::estimate::{
    self as core, InputStates, LinearObserve, LinearProcess, ModelOutputs, ModelProcess, Observe,
    ParamTransmission, Process, SigmaScaling, TransmissionParam,
};
use cable_core::CableError;
use std::sync::{Mutex, MutexGuard};

use numpy::{PyArray1, PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::convert::{matrix, to_matrix, to_vector, vector};
use crate::dynamics::{with_model, AnyModel, Model};
use crate::errors::{guarded, lock, raise, Class};
use crate::results::{DualRun, FilterHealth, FilterRun};

type DynProcess = Box<dyn Process + Send + Sync>;
type DynObserve = Box<dyn Observe + Send + Sync>;
type Filter = core::SrUkf<DynProcess, DynObserve>;
/// `(u, y, mask)` of one step; `(Y, U, mask)` of a log.
type Measurement = (Vec<f64>, Vec<f64>, Option<Vec<bool>>);
/// `(gamma, (Wm0, Wmi), (Wc0, Wci))`.
type WeightTuple = (f64, (f64, f64), (f64, f64));

/// Square-root unscented Kalman filter (seed 001, eqs 3.9–3.25). One thread at a time: a
/// call while another thread's is running raises `ConcurrentUseError`.
#[pyclass(frozen, module = "cablekit._cablekit")]
pub struct SrUkf {
    inner: Mutex<Filter>,
    m: usize,
}

/// A `(k, k)` covariance as a flat row-major copy.
fn square(obj: &Bound<'_, PyAny>, name: &str, k: usize) -> PyResult<Vec<f64>> {
    let (arr, rows) = matrix(obj, name, Some(k))?;
    if rows != k {
        return Err(raise(
            Class::Shape,
            format!("{name} must have shape ({k}, {k}), got ({rows}, {k})"),
            &[],
        ));
    }
    Ok(arr.as_slice()?.to_vec())
}

/// Transpose a row-major `(r, c)` buffer into column-major (the same numbers for a symmetric
/// matrix; needed for the non-symmetric ones the core reads column-major).
fn col_major_from_lower(l: &[f64], n: usize) -> Vec<f64> {
    // column-major lower → row-major (n, n)
    let mut out = vec![0.0; n * n];
    for j in 0..n {
        for i in 0..n {
            out[i * n + j] = l[i + j * n];
        }
    }
    out
}

/// Selected states or `H·x` (exactly one of them).
fn linear_observe(
    n: usize,
    states: Option<Vec<usize>>,
    h: Option<&Bound<'_, PyAny>>,
) -> PyResult<DynObserve> {
    match (states, h) {
        (Some(idx), None) => Ok(Box::new(guarded(|| LinearObserve::select(n, &idx))?)),
        (None, Some(h)) => {
            let (arr, rows) = matrix(h, "H", Some(n))?;
            let hv = arr.as_slice()?.to_vec();
            Ok(Box::new(guarded(|| LinearObserve::new(rows, n, hv))?))
        }
        _ => Err(raise(
            Class::Parameter,
            format!("give exactly one measurement: states=[...] or H=<(p, {n}) array>"),
            &[],
        )),
    }
}

fn scaling(alpha: f64, beta: f64, kappa: f64) -> SigmaScaling {
    SigmaScaling { alpha, beta, kappa }
}

fn mask_vec(obj: Option<&Bound<'_, PyAny>>, p: usize) -> PyResult<Option<Vec<bool>>> {
    let Some(o) = obj else { return Ok(None) };
    if o.is_none() {
        return Ok(None);
    }
    let v: Vec<bool> = o.extract().map_err(|_| {
        raise(
            Class::DType,
            "mask must be a sequence of booleans (True = measured)".into(),
            &[],
        )
    })?;
    if v.len() != p {
        return Err(raise(
            Class::Shape,
            format!("mask must have length {p}, got {}", v.len()),
            &[],
        ));
    }
    Ok(Some(v))
}

impl SrUkf {
    fn build(
        process: DynProcess,
        observe: DynObserve,
        x0: &Bound<'_, PyAny>,
        p0: &Bound<'_, PyAny>,
        q: &Bound<'_, PyAny>,
        r: &Bound<'_, PyAny>,
        s: SigmaScaling,
    ) -> PyResult<Self> {
        let (n, p, m) = (process.n_states(), observe.n_outputs(), process.n_inputs());
        let x0 = vector(x0, "x0", n)?;
        let p0 = square(p0, "P0", n)?;
        let q = square(q, "Q", n)?;
        let r = square(r, "R", p)?;
        let inner = guarded(|| core::SrUkf::new(process, observe, &x0, &p0, &q, &r, s))?;
        Ok(Self {
            inner: Mutex::new(inner),
            m,
        })
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
        let any = model.get().inner.clone();
        let n = with_model!(&any, m => m.n_states());
        let given = [states.is_some(), outputs.is_some(), H.is_some()];
        if given.iter().filter(|&&g| g).count() != 1 {
            return Err(raise(
                Class::Parameter,
                "give exactly one measurement: states=[...], outputs=[...] or H=<(p, n) array>"
                    .into(),
                &[],
            ));
        }
        let process: DynProcess = guarded(|| {
            Ok::<DynProcess, CableError>(
                with_model!(any.clone(), m => Box::new(ModelProcess::new(m, dt, substeps)?)),
            )
        })?;
        let observe: DynObserve = if let Some(idx) = outputs {
            guarded(|| {
                Ok::<DynObserve, CableError>(
                    with_model!(any, m => Box::new(ModelOutputs::new(m, idx)?)),
                )
            })?
        } else {
            linear_observe(n, states, H)?
        };
        Self::build(process, observe, x0, P0, Q, R, scaling(alpha, beta, kappa))
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
        bounds: Option<Vec<(f64, f64)>>,
        alpha: f64,
        beta: f64,
        kappa: f64,
    ) -> PyResult<Self> {
        let AnyModel::Transmission(base) = model.get().inner.clone() else {
            return Err(raise(
                Class::Parameter,
                "parameter estimation needs a CableTransmission".into(),
                &[],
            ));
        };
        let links = base.n_links();
        let parsed = guarded(|| {
            params
                .iter()
                .map(|p| TransmissionParam::parse(p, links))
                .collect::<Result<Vec<_>, _>>()
        })?;
        let process = guarded(|| ParamTransmission::new(base, parsed, bounds, dt, substeps))?;
        let n = process.n_states();
        let observe = linear_observe(n, states, H)?;
        Self::build(
            Box::new(process),
            observe,
            x0,
            P0,
            Q,
            R,
            scaling(alpha, beta, kappa),
        )
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
        let process: DynProcess = guarded(|| {
            Ok::<DynProcess, CableError>(with_model!(
                model.get().inner.clone(),
                m => Box::new(InputStates::new(m, inputs, dt, substeps)?)
            ))
        })?;
        let observe = linear_observe(process.n_states(), states, H)?;
        Self::build(process, observe, x0, P0, Q, R, scaling(alpha, beta, kappa))
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
        let (farr, n) = matrix(F, "F", None)?;
        let fv = farr.as_slice()?.to_vec();
        if fv.len() != n * n {
            return Err(raise(
                Class::Shape,
                format!("F must be square, got ({n}, {})", fv.len() / n),
                &[],
            ));
        }
        let (bv, m) = match B {
            Some(b) if !b.is_none() => {
                let (barr, rows) = matrix(b, "B", None)?;
                if rows != n {
                    return Err(raise(
                        Class::Shape,
                        format!("B must have {n} rows, got {rows}"),
                        &[],
                    ));
                }
                let v = barr.as_slice()?.to_vec();
                let m = v.len() / n;
                (v, m)
            }
            _ => (Vec::new(), 0),
        };
        let (harr, p) = matrix(H, "H", Some(n))?;
        let hv = harr.as_slice()?.to_vec();
        let process: DynProcess = Box::new(guarded(|| LinearProcess::new(n, m, fv, bv))?);
        let observe: DynObserve = Box::new(guarded(|| LinearObserve::new(p, n, hv))?);
        Self::build(process, observe, x0, P0, Q, R, scaling(alpha, beta, kappa))
    }

    #[getter]
    fn n_states(&self) -> PyResult<usize> {
        Ok(self.filter()?.n_states())
    }
    #[getter]
    fn n_outputs(&self) -> PyResult<usize> {
        Ok(self.filter()?.n_outputs())
    }
    #[getter]
    fn n_inputs(&self) -> usize {
        self.m
    }
    /// Current mean.
    #[getter]
    fn x<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        Ok(to_vector(py, self.filter()?.x().to_vec()))
    }
    /// Current lower-triangular square root of the covariance.
    #[getter(S)]
    fn sqrt_covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let f = self.filter()?;
        let n = f.n_states();
        let s = col_major_from_lower(f.sqrt_covariance(), n);
        Ok(to_matrix(py, s, n, n))
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
        guarded(|| f.predict(&u))
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
        guarded(|| f.update(&u, &y, mask.as_deref()))
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
        guarded(|| f.step(&u, &y, mask.as_deref()))
    }

    /// Replace the mean and covariance.
    #[allow(non_snake_case)]
    fn reset(&self, x: &Bound<'_, PyAny>, P: &Bound<'_, PyAny>) -> PyResult<()> {
        let mut f = self.filter()?;
        let n = f.n_states();
        let x = vector(x, "x", n)?;
        let p = square(P, "P", n)?;
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
        let run = py.detach(|| guarded(|| f.run(&u, &y, mk.as_deref(), smooth)))?;
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
    let u = if m == 0 {
        Vec::new()
    } else {
        let (uarr, tu) = matrix(U, "U", Some(m))?;
        if tu != t {
            return Err(raise(
                Class::Shape,
                format!("U has {tu} rows but Y has {t}"),
                &[],
            ));
        }
        uarr.as_slice()?.to_vec()
    };
    Ok((y, u, bool_matrix(mask, t, p)?))
}

/// Dual state–parameter estimation (seed 001 eqs 3.7–3.8): a state filter over the transmission
/// and a parameter filter over the named parameters, run side by side.
#[pyclass(frozen, module = "cablekit._cablekit")]
pub struct DualSrUkf {
    inner: Mutex<core::DualSrUkf>,
    m: usize,
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
        bounds: Option<Vec<(f64, f64)>>,
        alpha: f64,
        beta: f64,
        kappa: f64,
    ) -> PyResult<Self> {
        let AnyModel::Transmission(base) = model.get().inner.clone() else {
            return Err(raise(
                Class::Parameter,
                "dual estimation needs a CableTransmission".into(),
                &[],
            ));
        };
        let (n, m, p) = (base.n_states(), base.n_inputs(), params.len());
        let links = base.n_links();
        let parsed = guarded(|| {
            params
                .iter()
                .map(|s| TransmissionParam::parse(s, links))
                .collect::<Result<Vec<_>, _>>()
        })?;
        let x0 = vector(x0, "x0", n)?;
        let p0 = square(P0, "P0", n)?;
        let q = square(Q, "Q", n)?;
        let p0t = square(P0_theta, "P0_theta", p)?;
        let qt = square(Q_theta, "Q_theta", p)?;
        let r = square(R, "R", states.len())?;
        let inner = guarded(|| {
            core::DualSrUkf::new(
                base,
                parsed,
                bounds,
                dt,
                substeps,
                &states,
                &x0,
                &p0,
                &q,
                &p0t,
                &qt,
                &r,
                scaling(alpha, beta, kappa),
            )
        })?;
        Ok(Self {
            inner: Mutex::new(inner),
            m,
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
        let (n, q, p) = (f.state.n_states(), f.state.n_outputs(), f.params.n_states());
        if self.m == 0 {
            return Err(raise(
                Class::Shape,
                "the transmission has no inputs".into(),
                &[],
            ));
        }
        let (y, u, mk) = log_arrays(U, Y, mask, self.m, q)?;
        let fr: &mut core::DualSrUkf = &mut f; // a plain borrow crosses into the closure
        let run = py.detach(|| guarded(|| fr.run(&u, &y, mk.as_deref())))?;
        Ok(DualRun::new(py, run, n, p))
    }
}

/// An optional `(t, q)` boolean numpy mask.
fn bool_matrix(mask: Option<&Bound<'_, PyAny>>, t: usize, q: usize) -> PyResult<Option<Vec<bool>>> {
    match mask {
        Some(mk) if !mk.is_none() => {
            let arr = mk.cast::<numpy::PyArray2<bool>>().map_err(|_| {
                raise(
                    Class::DType,
                    "mask must be a (T, p) numpy array of bool".into(),
                    &[],
                )
            })?;
            if arr.shape() != [t, q] {
                return Err(raise(
                    Class::Shape,
                    format!("mask must have shape ({t}, {q}), got {:?}", arr.shape()),
                    &[],
                ));
            }
            Ok(Some(arr.readonly().as_array().iter().copied().collect()))
        }
        _ => Ok(None),
    }
}
