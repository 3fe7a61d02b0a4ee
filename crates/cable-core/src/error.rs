//! Typed errors of the core and the validation helpers that produce them.
//!
//! Every fallible entry point returns [`Result`]. The Python binding maps each variant to one
//! exception class of the `cablekit.CablekitError` hierarchy, so the variant names are part of
//! the public contract.

use thiserror::Error;

/// The most RK4 substeps one sample interval may take (every loop in cablekit is bounded; a
/// sample interval that needs more is a sign of a wrong `dt` or an extreme parameter). It lives
/// beside the error type because [`check::substeps`] enforces it; `integrate` re-exports it.
pub const MAX_SUBSTEPS: usize = 100_000;

/// Everything that can go wrong in cable-core, with enough structure to say what and where.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum CableError {
    /// An array or slice has the wrong length or shape.
    #[error("shape mismatch for {what}: expected {expected}, got {got}")]
    Shape {
        /// Which argument (e.g. `"inputs"`).
        what: String,
        /// The expected shape, human readable (e.g. `"(T, 6)"`).
        expected: String,
        /// The shape that was passed.
        got: String,
    },
    /// An input contains NaN or ±inf.
    #[error("{what} contains a non-finite value ({value:?}) at flat index {index}{location}")]
    NotFinite {
        /// Which argument.
        what: String,
        /// Flat (row-major) index of the first offending element.
        index: usize,
        /// The offending value.
        value: f64,
        /// Optional `(row, column)` rendering of the index, empty for 1-D data.
        location: String,
    },
    /// A physical or numerical parameter is out of its admissible range.
    #[error("invalid parameter {name} = {value:?}: must be {requirement}")]
    InvalidParameter {
        /// Parameter path, e.g. `"links[1].cable_stiffness"`.
        name: String,
        /// The rejected value.
        value: f64,
        /// The admissible range in words, e.g. `"finite and > 0"`.
        requirement: &'static str,
    },
    /// A value of the wrong kind (a string where a number belongs, ...).
    #[error("{name} must be {expected}, got {got}")]
    WrongType {
        /// Argument or parameter name.
        name: String,
        /// What it must be, in words.
        expected: String,
        /// What it was, in words.
        got: String,
    },
    /// A categorical option was not recognised.
    #[error("invalid option {name} = {value:?}: expected one of {allowed}")]
    InvalidOption {
        /// Option name.
        name: String,
        /// Rejected value.
        value: String,
        /// Allowed values.
        allowed: String,
    },
    /// The integrated state became non-finite: the step is too large for the model's stiffest
    /// mode or the model itself diverges.
    #[error(
        "simulation diverged at step {step} (t = {time_s:?} s): the state became non-finite; \
         use a smaller dt or more substeps (see propose_step)"
    )]
    Diverged {
        /// Index of the first sample whose state is non-finite (1-based from the initial state).
        step: usize,
        /// Time of that sample, s.
        time_s: f64,
    },
    /// A computation from finite inputs left the floating-point range (overflow to ±inf, or an
    /// indeterminate form): the input or a parameter is too extreme for the model.
    #[error(
        "{what} is not finite ({value:?}) at flat index {index}{location} although its inputs are: \
         {hint}"
    )]
    NonFiniteResult {
        /// Which result (e.g. `"derivative"`, `"capstan_ratio"`).
        what: String,
        /// Flat (row-major) index of the first non-finite element.
        index: usize,
        /// The non-finite value.
        value: f64,
        /// Optional `(row, column)` rendering of the index, empty for 1-D data.
        location: String,
        /// What to change, in words.
        hint: &'static str,
    },
    /// An iterative computation did not finish within its iteration cap.
    #[error("{what} did not converge within {limit} iterations: {hint}")]
    NotConverged {
        /// Which computation.
        what: String,
        /// The iteration cap that was reached.
        limit: usize,
        /// What to change, in words.
        hint: &'static str,
    },
    /// The filter's mean or square-root covariance became non-finite in a step (a diverging
    /// model, too large a step, or inconsistent noise covariances). The filter is left as it
    /// was before that step.
    #[error(
        "filter diverged at step {step}: the state or its covariance became non-finite; the \
         filter is left as before that step (check the model's dt/substeps, Q and R, or gate \
         outliers with nis_gate)"
    )]
    FilterDiverged {
        /// The step that failed: the row of the log in a run, else the steps since the filter
        /// was built or reset.
        step: usize,
    },
    /// A cable network (a model file's mechanism) is not a valid mechanism; `element` names the
    /// body, joint, pulley, cable or motor at fault.
    #[error("invalid cable network: {element} {reason}")]
    Network {
        /// The element at fault (`cable "flexor"`, `joint "mcp"`, `cable "a".routing[1]`).
        element: String,
        /// What is wrong, in words.
        reason: String,
    },
    /// A weight file is unreadable or does not describe a valid network.
    #[error("invalid weight file ({kind}) at {item}: {reason}")]
    Weights {
        /// What kind of defect (corrupt file, metadata, shape, non-finite value).
        kind: WeightsErrorKind,
        /// The offending tensor or metadata key (`"layers.0.weight"`, `"architecture"`, `"file"`).
        item: String,
        /// What is wrong, in words.
        reason: String,
    },
}

/// The kinds of defect a weight file can have; each maps to its own Python exception class.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum WeightsErrorKind {
    /// Not a safetensors file: truncated, bad header, overlapping or short data, wrong dtype.
    Corrupt,
    /// `__metadata__` missing, a required key missing or unparsable, an unknown activation or
    /// format version.
    Metadata,
    /// A tensor is missing or its shape disagrees with the architecture in the metadata.
    Shape,
    /// A weight, bias or normalisation bound is NaN or infinite, or a range is reversed.
    Value,
}

impl std::fmt::Display for WeightsErrorKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Corrupt => "corrupt",
            Self::Metadata => "metadata",
            Self::Shape => "shape",
            Self::Value => "value",
        })
    }
}

/// Result alias used throughout the core.
pub type Result<T> = std::result::Result<T, CableError>;

/// Parameter validation helpers. Each returns the value on success so constructors stay terse.
pub mod check {
    use super::{CableError, Result};

    fn invalid(name: &str, value: f64, requirement: &'static str) -> CableError {
        CableError::InvalidParameter {
            name: name.to_owned(),
            value,
            requirement,
        }
    }

    /// `value` must be finite and strictly positive.
    pub fn positive(name: &str, value: f64) -> Result<f64> {
        if value.is_finite() && value > 0.0 {
            Ok(value)
        } else {
            Err(invalid(name, value, "finite and > 0"))
        }
    }

    /// `value` must be finite and non-negative.
    pub fn non_negative(name: &str, value: f64) -> Result<f64> {
        if value.is_finite() && value >= 0.0 {
            Ok(value)
        } else {
            Err(invalid(name, value, "finite and >= 0"))
        }
    }

    /// `value` must lie in `[0, hi]` (a physical bound past which the model's numbers
    /// overflow, stated in `requirement`).
    pub fn at_most(name: &str, value: f64, hi: f64, requirement: &'static str) -> Result<f64> {
        if value.is_finite() && (0.0..=hi).contains(&value) {
            Ok(value)
        } else {
            Err(invalid(name, value, requirement))
        }
    }

    /// `value` must be finite (any sign).
    pub fn finite(name: &str, value: f64) -> Result<f64> {
        if value.is_finite() {
            Ok(value)
        } else {
            Err(invalid(name, value, "finite"))
        }
    }

    /// Every element of `data` must be finite; `cols` (> 0) renders the index as (row, col).
    #[inline]
    pub fn all_finite(what: &str, data: &[f64], cols: usize) -> Result<()> {
        match data.iter().position(|v| !v.is_finite()) {
            None => Ok(()),
            Some(index) => Err(CableError::NotFinite {
                what: what.to_owned(),
                index,
                value: data[index],
                location: location(index, cols),
            }),
        }
    }

    /// `" (row r, column c)"` for a flat index into rows of `cols` (> 1) values, else empty.
    fn location(index: usize, cols: usize) -> String {
        if cols > 1 {
            format!(" (row {}, column {})", index / cols, index % cols)
        } else {
            String::new()
        }
    }

    /// Every element of a result computed from finite inputs must be finite; `cols` (> 0)
    /// renders the index as (row, col).
    #[inline]
    pub fn result_finite(what: &str, data: &[f64], cols: usize, hint: &'static str) -> Result<()> {
        match data.iter().position(|v| !v.is_finite()) {
            None => Ok(()),
            Some(index) => Err(CableError::NonFiniteResult {
                what: what.to_owned(),
                index,
                value: data[index],
                location: location(index, cols),
                hint,
            }),
        }
    }

    /// `g` at every element of `input` (named `what`), refusing non-finite elements and
    /// reporting a non-finite result as [`CableError::NonFiniteResult`] named `result`.
    pub fn finite_map(
        what: &str,
        input: &[f64],
        result: &str,
        g: impl Fn(f64) -> f64,
    ) -> Result<Vec<f64>> {
        all_finite(what, input, 1)?;
        let out: Vec<f64> = input.iter().map(|&x| g(x)).collect();
        result_finite(result, &out, 1, "the input or a parameter is too extreme")?;
        Ok(out)
    }

    /// [`finite_map`] over two equally long inputs.
    pub fn finite_map2(
        what: (&str, &str),
        a: &[f64],
        b: &[f64],
        result: &str,
        g: impl Fn(f64, f64) -> f64,
    ) -> Result<Vec<f64>> {
        len(what.1, b, a.len())?;
        all_finite(what.0, a, 1)?;
        all_finite(what.1, b, 1)?;
        let out: Vec<f64> = a.iter().zip(b).map(|(&x, &y)| g(x, y)).collect();
        result_finite(result, &out, 1, "the input or a parameter is too extreme")?;
        Ok(out)
    }

    /// `eval` into a fresh buffer of `out_len` values, after checking each argument
    /// `(name, data, expected length)` for its length and finiteness, and before returning the
    /// result checked finite (named `result`). One evaluation of a model function for a caller
    /// outside the hot loops (the bindings, tests).
    pub fn evaluate(
        args: &[(&str, &[f64], usize)],
        result: &str,
        out_len: usize,
        eval: impl FnOnce(&mut [f64]),
    ) -> Result<Vec<f64>> {
        for (name, data, n) in args {
            len(name, data, *n)?;
            all_finite(name, data, 1)?;
        }
        let mut out = vec![0.0; out_len];
        eval(&mut out);
        result_finite(
            result,
            &out,
            1,
            "the state, the input or a parameter is too extreme for the model",
        )?;
        Ok(out)
    }

    /// [`evaluate`] into `out` through `scratch` (resized to `out`'s length; no allocation once
    /// it has the capacity): `out` changes only when every argument and the result pass.
    pub fn evaluate_into(
        args: &[(&str, &[f64], usize)],
        result: &str,
        out: &mut [f64],
        scratch: &mut Vec<f64>,
        eval: impl FnOnce(&mut [f64]),
    ) -> Result<()> {
        for (name, data, n) in args {
            len(name, data, *n)?;
            all_finite(name, data, 1)?;
        }
        scratch.clear();
        scratch.resize(out.len(), 0.0);
        eval(scratch);
        result_finite(
            result,
            scratch,
            1,
            "the state, the input or a parameter is too extreme for the model",
        )?;
        out.copy_from_slice(scratch);
        Ok(())
    }

    /// An interval `[lo, hi]` with finite ends, `lo <= hi`; `name` names it.
    pub fn interval(name: &str, lo: f64, hi: f64) -> Result<(f64, f64)> {
        finite(&format!("{name}.lower"), lo)?;
        finite(&format!("{name}.upper"), hi)?;
        if lo > hi {
            return Err(invalid(&format!("{name}.lower"), lo, "<= the upper bound"));
        }
        Ok((lo, hi))
    }

    /// A count of RK4 substeps per sample: `1 ..= MAX_SUBSTEPS`.
    pub fn substeps(name: &str, n: usize) -> Result<usize> {
        if (1..=super::MAX_SUBSTEPS).contains(&n) {
            Ok(n)
        } else {
            Err(invalid(
                name,
                n as f64,
                "an integer in 1 ..= 100000 (MAX_SUBSTEPS); use a smaller dt",
            ))
        }
    }

    /// `data` must hold exactly `expected` values.
    #[inline]
    pub fn len(what: &str, data: &[f64], expected: usize) -> Result<()> {
        if data.len() == expected {
            Ok(())
        } else {
            Err(CableError::Shape {
                what: what.to_owned(),
                expected: format!("({expected},)"),
                got: format!("({},)", data.len()),
            })
        }
    }
}
