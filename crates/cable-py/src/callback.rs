//! A user's own process and measurement models for `SrUkf.from_functions` and
//! `DualSrUkf.from_functions`: Python callables in filterpy's convention, called with the GIL taken back for the call. They only convert: the
//! state goes out as a NumPy array and comes back as floats. An exception inside a callback (or a
//! return value of the wrong shape) is kept, the step fails and the filter undoes it, and the
//! call that ran the step raises it.

use std::sync::{Arc, Mutex};

use cable_core::estimate::{Observe, ParamModel, Process};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;

use crate::convert::{matrix, vector};
use crate::errors::{arg_error, Class};

/// The first error a callback raised during the running call, shared by the two models and
/// the filter object that raises it.
#[derive(Default)]
pub struct Failure(Mutex<Option<PyErr>>);

impl Failure {
    fn set(&self, err: PyErr) {
        let mut slot = self.0.lock().unwrap_or_else(|p| p.into_inner());
        if slot.is_none() {
            *slot = Some(err);
        }
    }

    fn is_set(&self) -> bool {
        self.0.lock().map(|s| s.is_some()).unwrap_or(true)
    }

    /// The kept error, if any (the slot is empty afterwards).
    pub fn take(&self) -> Option<PyErr> {
        self.0.lock().unwrap_or_else(|p| p.into_inner()).take()
    }
}

/// `result`, unless a user model's callback raised during the call (`failure`, when the filter
/// has user models): then its exception — the filter has undone the step.
pub fn raised<T>(failure: Option<&Arc<Failure>>, result: PyResult<T>) -> PyResult<T> {
    match failure.and_then(|f| f.take()) {
        Some(err) => Err(err),
        None => result,
    }
}

/// `values` unless one is NaN or inf: a `NotFiniteError` naming `what` (a user's model that
/// returned them, not the filter, diverged).
fn finite(values: &[f64], what: &str) -> PyResult<()> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => {
            let msg = format!("{what} returned NaN or inf (entry {i})");
            Err(arg_error(Class::NotFinite, what, msg))
        }
    }
}

/// `obj` as a float64 NumPy array (a list, another dtype), or a `DTypeError` naming `what`.
fn floats<'py>(obj: Bound<'py, PyAny>, what: &str) -> PyResult<Bound<'py, PyAny>> {
    // looked up once: this runs for every sigma point
    static CONTIGUOUS: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
    CONTIGUOUS
        .import(obj.py(), "numpy", "ascontiguousarray")?
        .call1((obj, "float64"))
        .map_err(|_| {
            let msg = format!("{what} must return an array of numbers");
            arg_error(Class::DType, what, msg)
        })
}

/// `fx(x, dt)` (no inputs) or `fx(x, dt, u)`; vectorised, `x` is `(k, n)` and so is the result.
pub struct PyProcess {
    fx: Py<PyAny>,
    dt: f64,
    n: usize,
    m: usize,
    vectorized: bool,
    failure: Arc<Failure>,
}

impl PyProcess {
    /// The process `fx` over `n` states and `m` inputs at period `dt`.
    pub fn new(
        fx: Py<PyAny>,
        dt: f64,
        n: usize,
        m: usize,
        vectorized: bool,
        failure: Arc<Failure>,
    ) -> Self {
        Self {
            fx,
            dt,
            n,
            m,
            vectorized,
            failure,
        }
    }

    /// `fx` on `xs` (`k` states, row after row), written back into `xs`.
    fn call(&self, xs: &mut [f64], u: &[f64], k: usize) -> PyResult<()> {
        Python::attach(|py| {
            let x = states(py, xs, k, self.n, self.vectorized)?;
            let fx = self.fx.bind(py);
            let ret = if self.m == 0 {
                fx.call1((x, self.dt))?
            } else {
                fx.call1((x, self.dt, PyArray1::from_slice(py, u)))?
            };
            read_back(ret, "fx", self.n, k, self.vectorized, xs)
        })
    }
}

/// `xs` (`k` states of `n`) as a callback takes them: `(n,)`, or `(k, n)` when vectorised.
fn states<'py>(
    py: Python<'py>,
    xs: &[f64],
    k: usize,
    n: usize,
    vectorized: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let x = PyArray1::from_slice(py, xs);
    Ok(if vectorized {
        x.reshape([k, n])?.into_any()
    } else {
        x.into_any()
    })
}

/// A callback's return into `out` (`k` rows of `cols`), checked: its shape, that it is numbers,
/// that they are finite.
fn read_back(
    ret: Bound<'_, PyAny>,
    what: &str,
    cols: usize,
    k: usize,
    vectorized: bool,
    out: &mut [f64],
) -> PyResult<()> {
    let ret = floats(ret, what)?;
    let name = format!("{what}'s return");
    if vectorized {
        let (arr, rows) = matrix(&ret, &name, Some(cols))?;
        check_rows(what, rows, k)?;
        out.copy_from_slice(arr.as_slice()?);
    } else {
        out.copy_from_slice(&vector(&ret, &name, cols)?);
    }
    finite(out, what)
}

/// Run one callback unless one already failed in this call; on a failure keep its error and
/// fill `out` with NaN (the filter undoes the step).
fn guard(failure: &Failure, out: &mut [f64], call: impl FnOnce(&mut [f64]) -> PyResult<()>) {
    if failure.is_set() {
        out.fill(f64::NAN);
    } else if let Err(e) = call(out) {
        failure.set(e);
        out.fill(f64::NAN);
    }
}

fn check_rows(what: &str, rows: usize, k: usize) -> PyResult<()> {
    if rows == k {
        return Ok(());
    }
    let msg = format!("{what} must return one row per state given ({k}), got {rows}");
    Err(arg_error(Class::Shape, what, msg))
}

impl Process for PyProcess {
    fn n_states(&self) -> usize {
        self.n
    }
    fn n_inputs(&self) -> usize {
        self.m
    }
    fn propagate(&mut self, x: &mut [f64], u: &[f64]) {
        guard(&self.failure, x, |x| self.call(x, u, 1));
    }
    fn propagate_many(&mut self, xs: &mut [f64], u: &[f64]) {
        if self.vectorized {
            let k = xs.len() / self.n.max(1);
            guard(&self.failure, xs, |xs| self.call(xs, u, k));
        } else {
            for x in xs.chunks_exact_mut(self.n.max(1)) {
                self.propagate(x, u);
            }
        }
    }
    fn failed(&self) -> bool {
        self.failure.is_set()
    }
}

/// `hx(x)`; vectorised, `x` is `(k, n)` and the result `(k, p)`.
pub struct PyObserve {
    hx: Py<PyAny>,
    n: usize,
    p: usize,
    vectorized: bool,
    failure: Arc<Failure>,
}

impl PyObserve {
    /// The measurement `hx` of `p` channels from `n` states.
    pub fn new(hx: Py<PyAny>, n: usize, p: usize, vectorized: bool, failure: Arc<Failure>) -> Self {
        Self {
            hx,
            n,
            p,
            vectorized,
            failure,
        }
    }

    fn call(&self, xs: &[f64], ys: &mut [f64], k: usize) -> PyResult<()> {
        Python::attach(|py| {
            let x = states(py, xs, k, self.n, self.vectorized)?;
            let ret = self.hx.bind(py).call1((x,))?;
            read_back(ret, "hx", self.p, k, self.vectorized, ys)
        })
    }
}

impl Observe for PyObserve {
    fn n_outputs(&self) -> usize {
        self.p
    }
    fn observe(&mut self, x: &[f64], _u: &[f64], y: &mut [f64]) {
        guard(&self.failure, y, |y| self.call(x, y, 1));
    }
    fn observe_many(&mut self, xs: &[f64], u: &[f64], ys: &mut [f64]) {
        if self.vectorized {
            let k = xs.len() / self.n.max(1);
            guard(&self.failure, ys, |ys| self.call(xs, ys, k));
        } else {
            let (n, p) = (self.n.max(1), self.p.max(1));
            for (x, y) in xs.chunks_exact(n).zip(ys.chunks_exact_mut(p)) {
                self.observe(x, u, y);
            }
        }
    }
    fn failed(&self) -> bool {
        self.failure.is_set()
    }
}

/// `fx(x, theta, dt)` (no inputs) or `fx(x, theta, dt, u)`: a dual filter's model, per point.
pub struct PyParamModel {
    fx: Py<PyAny>,
    dt: f64,
    /// States `n`, parameters `p`, inputs `m`.
    sizes: (usize, usize, usize),
    failure: Arc<Failure>,
}

impl PyParamModel {
    /// The model `fx` over `sizes = (n, p, m)` at period `dt`.
    pub fn new(
        fx: Py<PyAny>,
        dt: f64,
        sizes: (usize, usize, usize),
        failure: Arc<Failure>,
    ) -> Self {
        Self {
            fx,
            dt,
            sizes,
            failure,
        }
    }

    fn call(&self, x: &mut [f64], theta: &[f64], u: &[f64]) -> PyResult<()> {
        Python::attach(|py| {
            let (xa, th) = (PyArray1::from_slice(py, x), PyArray1::from_slice(py, theta));
            let fx = self.fx.bind(py);
            let ret = if self.sizes.2 == 0 {
                fx.call1((xa, th, self.dt))?
            } else {
                fx.call1((xa, th, self.dt, PyArray1::from_slice(py, u)))?
            };
            read_back(ret, "fx", self.sizes.0, 1, false, x)
        })
    }
}

impl ParamModel for PyParamModel {
    fn n_states(&self) -> usize {
        self.sizes.0
    }
    fn n_params(&self) -> usize {
        self.sizes.1
    }
    fn n_inputs(&self) -> usize {
        self.sizes.2
    }
    fn propagate(&mut self, x: &mut [f64], theta: &[f64], u: &[f64]) {
        guard(&self.failure, x, |x| self.call(x, theta, u));
    }
    fn failed(&self) -> bool {
        self.failure.is_set()
    }
}
