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

/// `Class::X` for each exception class `XError` of `cablekit.errors`.
macro_rules! classes {
    ($($variant:ident),* $(,)?) => {
        /// The exception classes of `cablekit.errors` (defined in Python so that they also
        /// derive from the matching built-ins), each imported once per interpreter and kept.
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        #[allow(missing_docs)]
        pub enum Class { $($variant),* }

        impl Class {
            const ALL: &[Class] = &[$(Class::$variant),*];
            fn name(self) -> &'static str {
                match self { $(Class::$variant => concat!(stringify!($variant), "Error")),* }
            }
        }
    };
}

classes! {
    Cablekit, ConcurrentUse, Convergence, DType, Data, FilterDiverged, Internal, Layout, Network,
    NonFiniteResult, NotFinite, Parameter, Shape, SimulationDiverged, WeightsCorrupt,
    WeightsFormat, WeightsMetadata, WeightsShape, WeightsValue,
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

/// An attribute value of a raised exception.
#[derive(Debug, Clone, Copy)]
pub enum Attr<'a> {
    /// A name.
    Str(&'a str),
    /// An index, step or limit.
    Int(usize),
    /// A value or time.
    Float(f64),
}

/// Raise `class(message)` with extra attributes (`argument`, `index`, `step`, ...).
pub fn raise(class: Class, message: String, attrs: &[(&str, Attr<'_>)]) -> PyErr {
    Python::attach(|py| -> PyResult<PyErr> {
        let exc = class.get(py)?.call1((message,))?;
        for (k, v) in attrs {
            match *v {
                Attr::Str(s) => exc.setattr(*k, s)?,
                Attr::Int(i) => exc.setattr(*k, i)?,
                Attr::Float(f) => exc.setattr(*k, f)?,
            }
        }
        Ok(PyErr::from_value(exc))
    })
    .unwrap_or_else(|e| e)
}

/// `class(message)` about argument `name` (its `.argument`).
pub fn arg_error(class: Class, name: &str, message: String) -> PyErr {
    raise(class, message, &[("argument", Attr::Str(name))])
}

/// The exception of a core error: its class, with what it names as attributes.
pub fn core_error(err: CableError) -> PyErr {
    let (class, attrs) = classify(&err);
    raise(class, err.to_string(), &attrs)
}

/// The class of a core error and the attributes its exception carries.
fn classify(err: &CableError) -> (Class, Vec<(&'static str, Attr<'_>)>) {
    use Attr::{Float, Int, Str};
    match err {
        CableError::Shape { what, .. } => (Class::Shape, vec![("argument", Str(what))]),
        CableError::WrongType { name, .. } => (Class::DType, vec![("argument", Str(name))]),
        CableError::NotFinite { what, index, .. } => (
            Class::NotFinite,
            vec![("argument", Str(what)), ("index", Int(*index))],
        ),
        CableError::InvalidParameter { name, value, .. } => (
            Class::Parameter,
            vec![
                ("argument", Str(name)),
                ("parameter", Str(name)),
                ("value", Float(*value)),
            ],
        ),
        CableError::InvalidOption { name, .. } => (
            Class::Parameter,
            vec![("argument", Str(name)), ("parameter", Str(name))],
        ),
        CableError::Diverged { step, time_s } => (
            Class::SimulationDiverged,
            vec![("step", Int(*step)), ("time", Float(*time_s))],
        ),
        CableError::FilterDiverged { step } => (Class::FilterDiverged, vec![("step", Int(*step))]),
        CableError::NonFiniteResult { what, index, .. } => (
            Class::NonFiniteResult,
            vec![("argument", Str(what)), ("index", Int(*index))],
        ),
        CableError::NotConverged { what, limit, .. } => (
            Class::Convergence,
            vec![("argument", Str(what)), ("limit", Int(*limit))],
        ),
        CableError::Weights { kind, item, .. } => (weights_class(*kind), vec![("item", Str(item))]),
        CableError::Network { element, .. } => (Class::Network, vec![("element", Str(element))]),
        _ => (Class::Cablekit, vec![]),
    }
}

/// The class of a weight file's error of kind `kind`.
fn weights_class(kind: WeightsErrorKind) -> Class {
    match kind {
        WeightsErrorKind::Corrupt => Class::WeightsCorrupt,
        WeightsErrorKind::Metadata => Class::WeightsMetadata,
        WeightsErrorKind::Shape => Class::WeightsShape,
        WeightsErrorKind::Value => Class::WeightsValue,
        _ => Class::WeightsFormat,
    }
}

/// Run core work, turning a Rust panic into `cablekit.errors.InternalError` instead of letting
/// it reach Python as a `PanicException`.
pub fn guarded<T>(work: impl FnOnce() -> Result<T, CableError>) -> PyResult<T> {
    match catch_unwind(AssertUnwindSafe(work)) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(core_error(e)),
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
