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
use pyo3::prelude::*;

use crate::errors::{raise, Class};

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
        raise(
            Class::DType,
            format!(
                "{name} must be a numpy.ndarray of float64, got {}; pass np.asarray({name}, dtype=np.float64)",
                obj.get_type().name().map(|n| n.to_string()).unwrap_or_default()
            ),
            &[],
        )
    })?;
    let py = obj.py();
    if !arr.dtype().is_equiv_to(&numpy::dtype::<f64>(py)) {
        return Err(raise(
            Class::DType,
            format!(
                "{name} must have dtype float64, got {}; convert with {name}.astype(np.float64)",
                arr.dtype()
            ),
            &[],
        ));
    }
    if arr.ndim() != ndim {
        return Err(raise(
            Class::Shape,
            format!(
                "{name} must be {ndim}-D, got shape {}",
                shape_str(arr.shape())
            ),
            &[],
        ));
    }
    if !arr.is_c_contiguous() {
        return Err(raise(
            Class::Layout,
            format!("{name} must be C-contiguous (no copy is made behind your back); pass np.ascontiguousarray({name})"),
            &[],
        ));
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
    if let Some(c) = cols {
        if shape[1] != c {
            return Err(raise(
                Class::Shape,
                format!("{name} must have shape (T, {c}), got {}", shape_str(&shape)),
                &[],
            ));
        }
    }
    if shape[0] == 0 {
        return Err(raise(
            Class::Shape,
            format!("{name} must have at least one row"),
            &[],
        ));
    }
    let copy = obj.call_method0("copy")?.cast_into::<PyArray2<f64>>()?;
    Ok((copy.readonly(), shape[0]))
}

/// A length-`len` float64 vector copied into a `Vec`.
pub fn vector(obj: &Bound<'_, PyAny>, name: &str, len: usize) -> PyResult<Vec<f64>> {
    let shape = checked(obj, name, 1)?;
    if shape[0] != len {
        return Err(raise(
            Class::Shape,
            format!("{name} must have shape ({len},), got {}", shape_str(&shape)),
            &[],
        ));
    }
    let arr = obj.cast::<PyArray1<f64>>()?.readonly();
    Ok(arr.as_slice()?.to_vec())
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
        raise(
            Class::DType,
            format!("{name} must be a numpy.ndarray of float64; pass np.asarray({name}, dtype=np.float64)"),
            &[],
        )
    })
}
