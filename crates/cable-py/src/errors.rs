//! Maps core errors (and panics) to the `cablekit.errors` exception hierarchy.
//!
//! The classes are defined in Python (`python/cablekit/errors.py`) so they can also derive from
//! the matching built-ins (`ValueError`, `TypeError`, `ArithmeticError`); each is imported once
//! per interpreter ([`Class`]) when it is first raised, never on the hot path.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::{Mutex, MutexGuard, TryLockError};

use cable_core::{CableError, WeightsErrorKind};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;

/// `Class::X` for each exception class of `cablekit.errors`, with its Python name.
macro_rules! classes {
    ($($variant:ident => $name:literal),* $(,)?) => {
        /// The exception classes of `cablekit.errors` (defined in Python so that they also
        /// derive from the matching built-ins), each imported once per interpreter and kept.
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        #[allow(missing_docs)]
        pub enum Class { $($variant),* }

        impl Class {
            const ALL: &[Class] = &[$(Class::$variant),*];
            fn name(self) -> &'static str {
                match self { $(Class::$variant => $name),* }
            }
        }
    };
}

classes! {
    Cablekit => "CablekitError",
    ConcurrentUse => "ConcurrentUseError",
    Convergence => "ConvergenceError",
    DType => "DTypeError",
    Data => "DataError",
    FilterDiverged => "FilterDivergedError",
    Internal => "InternalError",
    Layout => "LayoutError",
    NonFiniteResult => "NonFiniteResultError",
    NotFinite => "NotFiniteError",
    Parameter => "ParameterError",
    Shape => "ShapeError",
    SimulationDiverged => "SimulationDivergedError",
    WeightsCorrupt => "WeightsCorruptError",
    WeightsFormat => "WeightsFormatError",
    WeightsMetadata => "WeightsMetadataError",
    WeightsShape => "WeightsShapeError",
    WeightsValue => "WeightsValueError",
}

impl Class {
    /// The class object, imported on first use and kept for the interpreter's life.
    fn get(self, py: Python<'_>) -> PyResult<&Bound<'_, PyAny>> {
        static CLASSES: [PyOnceLock<Py<PyAny>>; Class::ALL.len()] =
            [const { PyOnceLock::new() }; Class::ALL.len()];
        let at = Class::ALL.iter().position(|c| *c == self).unwrap_or(0);
        CLASSES[at]
            .get_or_try_init(py, || {
                Ok::<_, PyErr>(py.import("cablekit.errors")?.getattr(self.name())?.unbind())
            })
            .map(|c| c.bind(py))
    }
}

/// Raise `class(message)` with extra attributes (`argument`, `index`, `step`, ...).
pub fn raise(class: Class, message: String, attrs: &[(&str, Py<PyAny>)]) -> PyErr {
    Python::attach(|py| -> PyResult<PyErr> {
        let exc = class.get(py)?.call1((message,))?;
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
                        raise(Class::Shape, msg, &[("argument", s(what)?)])
                    }
                    CableError::NotFinite { what, index, .. } => raise(
                        Class::NotFinite,
                        msg,
                        &[("argument", s(what)?), ("index", int(*index)?)],
                    ),
                    CableError::InvalidParameter { name, value, .. } => raise(
                        Class::Parameter,
                        msg,
                        &[("parameter", s(name)?), ("value", float(*value)?)],
                    ),
                    CableError::InvalidOption { name, .. } => {
                        raise(Class::Parameter, msg, &[("parameter", s(name)?)])
                    }
                    CableError::Diverged { step, time_s } => raise(
                        Class::SimulationDiverged,
                        msg,
                        &[("step", int(*step)?), ("time", float(*time_s)?)],
                    ),
                    CableError::FilterDiverged { step } => {
                        raise(Class::FilterDiverged, msg, &[("step", int(*step)?)])
                    }
                    CableError::NonFiniteResult { what, index, .. } => raise(
                        Class::NonFiniteResult,
                        msg,
                        &[("argument", s(what)?), ("index", int(*index)?)],
                    ),
                    CableError::NotConverged { what, limit, .. } => raise(
                        Class::Convergence,
                        msg,
                        &[("argument", s(what)?), ("limit", int(*limit)?)],
                    ),
                    CableError::Weights { kind, item, .. } => raise(
                        match kind {
                            WeightsErrorKind::Corrupt => Class::WeightsCorrupt,
                            WeightsErrorKind::Metadata => Class::WeightsMetadata,
                            WeightsErrorKind::Shape => Class::WeightsShape,
                            WeightsErrorKind::Value => Class::WeightsValue,
                            _ => Class::WeightsFormat,
                        },
                        msg,
                        &[("item", s(item)?)],
                    ),
                    _ => raise(Class::Cablekit, msg, &[]),
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
                Class::Internal,
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
            Class::ConcurrentUse,
            format!(
                "this {what} is in use by another thread; use one {what} per thread \
                 (or serialise the calls with a lock)"
            ),
            &[],
        )),
    }
}
