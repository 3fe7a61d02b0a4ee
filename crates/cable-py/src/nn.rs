//! `Mlp`: a network loaded from a safetensors weight file, evaluated by cable-core.

use std::path::PathBuf;
use std::sync::Mutex;

use cable_core::nn::{Mlp as CoreMlp, Scratch};
use numpy::ndarray::Array2;
use numpy::ndarray::Dimension;
use numpy::{
    IntoPyArray, PyArray, PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray, PyReadwriteArray,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use crate::convert::{any_vector, matrix, ndim_of, to_vector};
use crate::errors::{arg_error, guarded, Class};

/// `(weight, bias)` of one layer as numpy arrays.
type LayerArrays<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<f64>>);

/// A multilayer perceptron with `mapminmax` normalisation (seed 000 §2.3.3, seed 002 eq. 9).
/// Safe to share between threads: the network is immutable, and a single-sample call that finds
/// the work buffers in use by another thread takes fresh ones (one small allocation).
#[pyclass(frozen, module = "cablekit._cablekit")]
pub struct Mlp {
    pub(crate) inner: CoreMlp,
    scratch: Mutex<Scratch>,
}

impl Mlp {
    fn new(inner: CoreMlp) -> Self {
        let scratch = Mutex::new(inner.scratch());
        Self { inner, scratch }
    }

    /// One sample, allocation-free unless another thread is in a single-sample call.
    fn forward(&self, x: &[f64], out: &mut [f64]) -> PyResult<()> {
        guarded(|| self.inner.forward_shared(x, out, &self.scratch))
    }
}

fn layout_error(name: &str) -> PyErr {
    let msg = format!("{name} must be C-contiguous; pass np.ascontiguousarray({name})");
    arg_error(Class::Layout, name, msg)
}

/// Borrow `x` read-only and `out` read-write (`out` must be writeable and not `x` itself).
fn borrow_pair<'py, D: Dimension>(
    x: &Bound<'py, PyArray<f64, D>>,
    out: &Bound<'py, PyArray<f64, D>>,
) -> PyResult<(PyReadonlyArray<'py, f64, D>, PyReadwriteArray<'py, f64, D>)> {
    let xr = x
        .try_readonly()
        .map_err(|_| arg_error(Class::Layout, "x", "x is being written elsewhere".into()))?;
    let ow = out.try_readwrite().map_err(|_| {
        let msg = "out must be a writeable array not borrowed elsewhere";
        arg_error(Class::Layout, "out", msg.into())
    })?;
    Ok((xr, ow))
}

#[pymethods]
impl Mlp {
    /// Load a weight file written by `cablekit.nn.export` (safetensors; never pickle).
    /// Raises `FileNotFoundError`/`OSError` for an unreadable path and a `WeightsFormatError`
    /// subclass naming the tensor or metadata key for a bad file.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let bytes = py.detach(|| std::fs::read(&path))?;
        Self::from_bytes(&bytes)
    }

    /// Load from the bytes of a weight file.
    #[staticmethod]
    fn from_bytes(data: &[u8]) -> PyResult<Self> {
        Ok(Self::new(guarded(|| CoreMlp::from_safetensors(data))?))
    }

    /// The weight file as bytes (what `save` writes).
    fn to_bytes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let bytes = guarded(|| self.inner.to_safetensors())?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// Write the weight file to `path`.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let bytes = guarded(|| self.inner.to_safetensors())?;
        py.detach(|| std::fs::write(&path, bytes))?;
        Ok(())
    }

    /// Evaluate: `x` `(n_in,)` → `(n_out,)`, or `x` `(N, n_in)` → `(N, n_out)` (GIL released,
    /// parallel for large N). Physical units in and out.
    fn predict<'py>(&self, py: Python<'py>, x: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let (n_in, n_out) = (self.inner.n_inputs(), self.inner.n_outputs());
        if ndim_of(x, "x")? == 1 {
            let xv = any_vector(x, "x")?;
            let mut out = vec![0.0; n_out];
            self.forward(&xv, &mut out)?;
            return Ok(to_vector(py, out).into_any());
        }
        let (arr, rows) = matrix(x, "x", Some(n_in))?;
        let xs = arr.as_slice()?;
        // numpy allocates the result (recycled, huge-page backed buffers; see convert.rs)
        let out = PyArray2::<f64>::zeros(py, [rows, n_out], false);
        {
            let mut ow = out.readwrite();
            let os = ow.as_slice_mut()?;
            let net = &self.inner;
            py.detach(|| guarded(|| net.forward_batch(xs, os)))?;
        }
        Ok(out.into_any())
    }

    /// Evaluate into a preallocated `out` without allocating (for controllers): `x` `(n_in,)`
    /// and `out` `(n_out,)`, or `(N, n_in)` and `(N, n_out)`. On error `out` is untouched.
    fn predict_into(
        &self,
        py: Python<'_>,
        x: &Bound<'_, PyAny>,
        out: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        // typed casts first: the 1-D controller path stays at ~0.25 µs (dynamic-rank arrays
        // cost ~0.15 µs more per call)
        if let (Ok(xa), Ok(oa)) = (x.cast::<PyArray1<f64>>(), out.cast::<PyArray1<f64>>()) {
            let (xr, mut ow) = borrow_pair(xa, oa)?;
            let xs = xr.as_slice().map_err(|_| layout_error("x"))?;
            let os = ow.as_slice_mut().map_err(|_| layout_error("out"))?;
            return self.forward(xs, os);
        }
        if let (Ok(xa), Ok(oa)) = (x.cast::<PyArray2<f64>>(), out.cast::<PyArray2<f64>>()) {
            let (xr, mut ow) = borrow_pair(xa, oa)?;
            let n_in = self.inner.n_inputs();
            if xr.shape()[1] != n_in {
                let msg = format!("x must have shape (N, {n_in}), got {:?}", xr.shape());
                return Err(arg_error(Class::Shape, "x", msg));
            }
            let xs = xr.as_slice().map_err(|_| layout_error("x"))?;
            let os = ow.as_slice_mut().map_err(|_| layout_error("out"))?;
            let net = &self.inner;
            return py.detach(|| guarded(|| net.forward_batch(xs, os)));
        }
        let (nx, no) = (ndim_of(x, "x")?, ndim_of(out, "out")?);
        let same_rank = nx == no && (nx == 1 || nx == 2);
        let class = if same_rank {
            Class::DType
        } else {
            Class::Shape
        };
        let msg = format!(
            "x and out must be float64 arrays, both 1-D or both 2-D; got {nx}-D and {no}-D"
        );
        Err(arg_error(class, "out", msg))
    }

    /// Layer sizes `[n_in, hidden…, n_out]`.
    #[getter]
    fn sizes(&self) -> Vec<usize> {
        self.inner.sizes()
    }

    /// Activation name of each layer (`logsig`, `tansig`, `purelin`).
    #[getter]
    fn activations(&self) -> Vec<&'static str> {
        self.inner
            .layers()
            .iter()
            .map(|l| l.activation.name())
            .collect()
    }

    /// Number of inputs.
    #[getter]
    fn n_inputs(&self) -> usize {
        self.inner.n_inputs()
    }

    /// Number of outputs.
    #[getter]
    fn n_outputs(&self) -> usize {
        self.inner.n_outputs()
    }

    /// Input names from the file (empty if none were stored).
    #[getter]
    fn input_names(&self) -> Vec<String> {
        self.inner.info().input_names.clone()
    }

    /// Input units from the file.
    #[getter]
    fn input_units(&self) -> Vec<String> {
        self.inner.info().input_units.clone()
    }

    /// Output names from the file.
    #[getter]
    fn output_names(&self) -> Vec<String> {
        self.inner.info().output_names.clone()
    }

    /// Output units from the file.
    #[getter]
    fn output_units(&self) -> Vec<String> {
        self.inner.info().output_units.clone()
    }

    /// Every `__metadata__` entry of the file (strings, JSON where structured).
    #[getter]
    fn metadata<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (k, v) in &self.inner.info().metadata {
            d.set_item(k, v)?;
        }
        Ok(d)
    }

    /// `[(weight (n_out, n_in), bias (n_out,)), …]`, copies.
    fn layers<'py>(&self, py: Python<'py>) -> Vec<LayerArrays<'py>> {
        self.inner
            .layers()
            .iter()
            .map(|l| {
                let w = Array2::from_shape_vec((l.n_out, l.n_in), l.weight.clone())
                    .expect("validated at load")
                    .into_pyarray(py);
                (w, to_vector(py, l.bias.clone()))
            })
            .collect()
    }

    /// `(min, max)` training ranges of the inputs (`mapminmax`).
    fn input_range<'py>(
        &self,
        py: Python<'py>,
    ) -> (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>) {
        let m = self.inner.input_map();
        (to_vector(py, m.min.clone()), to_vector(py, m.max.clone()))
    }

    /// `(min, max)` training ranges of the outputs.
    fn output_range<'py>(
        &self,
        py: Python<'py>,
    ) -> (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>) {
        let m = self.inner.output_map();
        (to_vector(py, m.min.clone()), to_vector(py, m.max.clone()))
    }

    fn __repr__(&self) -> String {
        let sizes = self.inner.sizes();
        format!("Mlp(sizes={sizes:?}, activations={:?})", self.activations())
    }
}

/// Add this file's classes and functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Mlp>()?;
    Ok(())
}
