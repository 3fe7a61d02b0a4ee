//! NumPy ↔ Rust conversion at the edge: dtype, dimension, contiguity and shape checks with
//! errors that name the argument, then a private copy so the GIL can be released without
//! another Python thread changing the data under us.
//!
//! Large arrays are copied by numpy, not into a Rust `Vec`: numpy recycles big buffers and asks
//! for huge pages, while a fresh multi-megabyte Rust allocation pays a page fault per 4 KiB on
//! every call (measured: the input copy was most of the page faults of a 100k-step run).

use numpy::ndarray::Array2;
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyArrayDescrMethods, PyArrayMethods, PyReadonlyArray2,
    PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::conversion::FromPyObjectOwned;
use pyo3::exceptions::{PyOverflowError, PyValueError};
use pyo3::prelude::*;

use cable_core::dynamics::SpecValue;
use pyo3::types::{PyDict, PyString};

use crate::errors::{arg_error, Class};

fn shape_str(shape: &[usize]) -> String {
    match shape {
        [a] => format!("({a},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|s| s.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Check that `obj` is a C-contiguous float64 ndarray with `ndim` dimensions; returns its shape.
fn checked<'py>(obj: &Bound<'py, PyAny>, name: &str, ndim: usize) -> PyResult<Vec<usize>> {
    let arr = obj.cast::<PyUntypedArray>().map_err(|_| {
        let got = obj.get_type().name().map(|n| n.to_string()).unwrap_or_default();
        let msg = format!("{name} must be a numpy.ndarray of float64, got {got}; pass np.asarray({name}, dtype=np.float64)");
        arg_error(Class::DType, name, msg)
    })?;
    if !arr.dtype().is_equiv_to(&numpy::dtype::<f64>(obj.py())) {
        let msg = format!(
            "{name} must have dtype float64, got {}; convert with {name}.astype(np.float64)",
            arr.dtype()
        );
        return Err(arg_error(Class::DType, name, msg));
    }
    if arr.ndim() != ndim {
        let msg = format!(
            "{name} must be {ndim}-D, got shape {}",
            shape_str(arr.shape())
        );
        return Err(arg_error(Class::Shape, name, msg));
    }
    if !arr.is_c_contiguous() {
        let msg = format!("{name} must be C-contiguous (no copy is made behind your back); pass np.ascontiguousarray({name})");
        return Err(arg_error(Class::Layout, name, msg));
    }
    Ok(arr.shape().to_vec())
}

/// A `(rows, cols)` float64 matrix as a private C-contiguous numpy copy, borrowed read-only
/// (take `.as_slice()` for the row-major data); `cols` is checked if given.
pub fn matrix<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    cols: Option<usize>,
) -> PyResult<(PyReadonlyArray2<'py, f64>, usize)> {
    let shape = checked(obj, name, 2)?;
    match cols {
        Some(c) if shape[1] != c => {
            let msg = format!("{name} must have shape (T, {c}), got {}", shape_str(&shape));
            return Err(arg_error(Class::Shape, name, msg));
        }
        _ if shape[0] == 0 => {
            let msg = format!("{name} must have at least one row");
            return Err(arg_error(Class::Shape, name, msg));
        }
        _ => {}
    }
    let copy = obj.call_method0("copy")?.cast_into::<PyArray2<f64>>()?;
    Ok((copy.readonly(), shape[0]))
}

/// A length-`len` float64 vector copied into a `Vec`.
pub fn vector(obj: &Bound<'_, PyAny>, name: &str, len: usize) -> PyResult<Vec<f64>> {
    let shape = checked(obj, name, 1)?;
    if shape[0] != len {
        let msg = format!("{name} must have shape ({len},), got {}", shape_str(&shape));
        return Err(arg_error(Class::Shape, name, msg));
    }
    let arr = obj.cast::<PyArray1<f64>>()?.readonly();
    Ok(arr.as_slice()?.to_vec())
}

/// A length-`len` float64 vector copied into `out` (no allocation; for per-call APIs).
pub fn vector_into(obj: &Bound<'_, PyAny>, name: &str, out: &mut [f64]) -> PyResult<()> {
    let shape = checked(obj, name, 1)?;
    if shape[0] != out.len() {
        let msg = format!(
            "{name} must have shape ({},), got {}",
            out.len(),
            shape_str(&shape)
        );
        return Err(arg_error(Class::Shape, name, msg));
    }
    out.copy_from_slice(obj.cast::<PyArray1<f64>>()?.readonly().as_slice()?);
    Ok(())
}

/// A writable length-`len` float64 vector the caller owns (results are written in place).
pub fn out_vector<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    len: usize,
) -> PyResult<numpy::PyReadwriteArray1<'py, f64>> {
    let shape = checked(obj, name, 1)?;
    if shape[0] != len {
        let msg = format!("{name} must have shape ({len},), got {}", shape_str(&shape));
        return Err(arg_error(Class::Shape, name, msg));
    }
    obj.cast::<PyArray1<f64>>()?.try_readwrite().map_err(|e| {
        let msg = format!("{name} must be a writable array not borrowed elsewhere: {e}");
        arg_error(Class::Layout, name, msg)
    })
}

/// Any-length float64 vector.
pub fn any_vector(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<f64>> {
    checked(obj, name, 1)?;
    let arr = obj.cast::<PyArray1<f64>>()?.readonly();
    Ok(arr.as_slice()?.to_vec())
}

/// Row-major buffer → `(rows, cols)` ndarray.
pub fn to_matrix(
    py: Python<'_>,
    data: Vec<f64>,
    rows: usize,
    cols: usize,
) -> Bound<'_, PyArray2<f64>> {
    Array2::from_shape_vec((rows, cols), data)
        .expect("buffer length matches the shape by construction")
        .into_pyarray(py)
}

/// `Vec` → 1-D ndarray.
pub fn to_vector(py: Python<'_>, data: Vec<f64>) -> Bound<'_, PyArray1<f64>> {
    data.into_pyarray(py)
}

/// Number of dimensions of an ndarray argument (`DTypeError` if it is not one).
pub fn ndim_of(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<usize> {
    obj.cast::<PyUntypedArray>().map(|a| a.ndim()).map_err(|_| {
        let msg = format!(
            "{name} must be a numpy.ndarray of float64; pass np.asarray({name}, dtype=np.float64)"
        );
        arg_error(Class::DType, name, msg)
    })
}

/// A square `(k, k)` float64 matrix as its row-major values (the core checks `k`).
pub fn square(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<f64>> {
    let (arr, rows) = matrix(obj, name, None)?;
    let values = arr.as_slice()?.to_vec();
    if values.len() != rows * rows {
        let msg = format!(
            "{name} must be square, got ({rows}, {})",
            values.len() / rows
        );
        return Err(arg_error(Class::Shape, name, msg));
    }
    Ok(values)
}

/// A `(rows, cols)` float64 matrix as `(row-major values, rows)`.
pub fn rows(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<(Vec<f64>, usize)> {
    let (arr, rows) = matrix(obj, name, None)?;
    Ok((arr.as_slice()?.to_vec(), rows))
}

/// Named spec values as a dict (the constructor's keywords).
pub fn spec_dict(py: Python<'_>, named: Vec<(String, SpecValue)>) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    for (name, value) in named {
        match value {
            SpecValue::Number(v) => d.set_item(name, v)?,
            SpecValue::Numbers(v) => d.set_item(name, v)?,
            SpecValue::Text(v) => d.set_item(name, v)?,
            SpecValue::Texts(v) => d.set_item(name, v)?,
            SpecValue::Rows(v) => d.set_item(name, v)?,
        }
    }
    Ok(d)
}

/// Keyword arguments as named spec values (a `None` is left out: the core's default applies).
pub fn spec_values(kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<(String, SpecValue)>> {
    let mut out = Vec::new();
    for (k, v) in kwargs.into_iter().flatten() {
        let name: String = k.extract()?;
        if v.is_none() {
            continue;
        }
        let value = if let Ok(s) = v.cast::<PyString>() {
            SpecValue::Text(s.to_string())
        } else if let Ok(x) = v.extract::<f64>() {
            SpecValue::Number(x)
        } else if let Ok(x) = v.extract::<Vec<f64>>() {
            SpecValue::Numbers(x)
        } else if let Ok(x) = v.extract::<Vec<String>>() {
            SpecValue::Texts(x)
        } else if let Ok(x) = v.extract::<Vec<Vec<f64>>>() {
            SpecValue::Rows(x)
        } else {
            let msg = format!("{name} must be a number, a string or a list of them");
            return Err(arg_error(Class::DType, &name, msg));
        };
        out.push((name, value));
    }
    Ok(out)
}

/// An argument PyO3 converts itself (a tuple, a list of tuples) with its errors typed: a wrong
/// length is a `ShapeError`, an integer out of range a `ParameterError` and anything else a
/// `DTypeError`, each naming the argument (PyO3's own conversion raises a bare `ValueError`
/// for `bias=()` or a bound `(1.0,)`).
pub fn tuples<'py, T: FromPyObjectOwned<'py>>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    what: &str,
) -> PyResult<T> {
    obj.extract::<T>().map_err(|e| {
        let e: PyErr = e.into();
        let py = obj.py();
        let class = if e.is_instance_of::<PyOverflowError>(py) {
            Class::Parameter
        } else if e.is_instance_of::<PyValueError>(py) {
            Class::Shape
        } else {
            Class::DType
        };
        arg_error(class, name, format!("{name} must be {what}: {e}"))
    })
}

/// `tuples` for an optional argument (`None` is absent).
pub fn opt_tuples<'py, T: FromPyObjectOwned<'py>>(
    obj: Option<&Bound<'py, PyAny>>,
    name: &str,
    what: &str,
) -> PyResult<Option<T>> {
    obj.filter(|o| !o.is_none())
        .map(|o| tuples(o, name, what))
        .transpose()
}
