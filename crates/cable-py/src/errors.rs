//! Maps core errors (and panics) to the `cablekit.errors` exception hierarchy.
//!
//! The classes are defined in Python (`python/cablekit/errors.py`) so they can also derive from
//! the matching built-ins (`ValueError`, `TypeError`, `ArithmeticError`); this module looks them
//! up by name when an error is raised, never on the hot path.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::{Mutex, MutexGuard, TryLockError};

use cable_core::{CableError, WeightsErrorKind};
use pyo3::prelude::*;

/// Raise `cablekit.errors.<class>(message)` with extra attributes.
pub fn raise(class: &str, message: String, attrs: &[(&str, Py<PyAny>)]) -> PyErr {
    Python::attach(|py| -> PyResult<PyErr> {
        let cls = py.import("cablekit.errors")?.getattr(class)?;
        let exc = cls.call1((message,))?;
        for (k, v) in attrs {
            exc.setattr(*k, v.bind(py))?;
        }
        Ok(PyErr::from_value(exc))
    })
    .unwrap_or_else(|e| e)
}

/// Newtype around [`CableError`] so it can become a `PyErr` (orphan rule).
pub struct PyCableError(pub CableError);

impl From<CableError> for PyCableError {
    fn from(e: CableError) -> Self {
        Self(e)
    }
}

impl From<PyCableError> for PyErr {
    fn from(err: PyCableError) -> PyErr {
        let msg = err.0.to_string();
        Python::attach(|py| {
            let int = |v: usize| v.into_pyobject(py).map(|o| o.into_any().unbind());
            let float = |v: f64| v.into_pyobject(py).map(|o| o.into_any().unbind());
            let s = |v: &str| v.into_pyobject(py).map(|o| o.into_any().unbind());
            let built: PyResult<PyErr> = (|| {
                Ok(match &err.0 {
                    CableError::Shape { what, .. } => {
                        raise("ShapeError", msg, &[("argument", s(what)?)])
                    }
                    CableError::NotFinite { what, index, .. } => raise(
                        "NotFiniteError",
                        msg,
                        &[("argument", s(what)?), ("index", int(*index)?)],
                    ),
                    CableError::InvalidParameter { name, value, .. } => raise(
                        "ParameterError",
                        msg,
                        &[("parameter", s(name)?), ("value", float(*value)?)],
                    ),
                    CableError::InvalidOption { name, .. } => {
                        raise("ParameterError", msg, &[("parameter", s(name)?)])
                    }
                    CableError::Diverged { step, time_s } => raise(
                        "SimulationDivergedError",
                        msg,
                        &[("step", int(*step)?), ("time", float(*time_s)?)],
                    ),
                    CableError::FilterDiverged { step } => {
                        raise("FilterDivergedError", msg, &[("step", int(*step)?)])
                    }
                    CableError::NonFiniteResult { what, index, .. } => raise(
                        "NonFiniteResultError",
                        msg,
                        &[("argument", s(what)?), ("index", int(*index)?)],
                    ),
                    CableError::NotConverged { what, limit, .. } => raise(
                        "ConvergenceError",
                        msg,
                        &[("argument", s(what)?), ("limit", int(*limit)?)],
                    ),
                    CableError::Weights { kind, item, .. } => raise(
                        match kind {
                            WeightsErrorKind::Corrupt => "WeightsCorruptError",
                            WeightsErrorKind::Metadata => "WeightsMetadataError",
                            WeightsErrorKind::Shape => "WeightsShapeError",
                            WeightsErrorKind::Value => "WeightsValueError",
                            _ => "WeightsFormatError",
                        },
                        msg,
                        &[("item", s(item)?)],
                    ),
                    _ => raise("CablekitError", msg, &[]),
                })
            })();
            built.unwrap_or_else(|e| e)
        })
    }
}

/// Run core work, turning a Rust panic into `cablekit.errors.InternalError` instead of letting
/// it reach Python as a `PanicException`.
pub fn guarded<T>(work: impl FnOnce() -> Result<T, CableError>) -> PyResult<T> {
    match catch_unwind(AssertUnwindSafe(work)) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(PyCableError(e).into()),
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Err(raise(
                "InternalError",
                format!("internal error in cable-core (please report): {what}"),
                &[],
            ))
        }
    }
}

/// Lock an object's state for one call. Objects with state (filters, a network's scratch) are
/// used by one thread at a time: a call while another thread's call is running raises
/// `cablekit.ConcurrentUseError` at once (never blocks: a blocked thread holding the GIL would
/// deadlock with the running call, which needs the GIL to return). A lock poisoned by a caught
/// panic is taken over (the panic was reported as `InternalError`).
pub fn lock<'a, T>(m: &'a Mutex<T>, what: &str) -> PyResult<MutexGuard<'a, T>> {
    match m.try_lock() {
        Ok(g) => Ok(g),
        Err(TryLockError::Poisoned(p)) => Ok(p.into_inner()),
        Err(TryLockError::WouldBlock) => Err(raise(
            "ConcurrentUseError",
            format!(
                "this {what} is in use by another thread; use one {what} per thread \
                 (or serialise the calls with a lock)"
            ),
            &[],
        )),
    }
}
