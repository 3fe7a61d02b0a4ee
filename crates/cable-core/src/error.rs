//! Typed errors of the core and the validation helpers that produce them.
//!
//! Every fallible entry point returns [`Result`]. The Python binding maps each variant to one
//! exception class of the `cablekit.CablekitError` hierarchy, so the variant names are part of
//! the public contract.

use thiserror::Error;

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
    #[error("{what} contains a non-finite value ({value}) at flat index {index}{location}")]
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
    #[error("invalid parameter {name} = {value}: must be {requirement}")]
    InvalidParameter {
        /// Parameter path, e.g. `"links[1].cable_stiffness"`.
        name: String,
        /// The rejected value.
        value: f64,
        /// The admissible range in words, e.g. `"finite and > 0"`.
        requirement: &'static str,
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
        "simulation diverged at step {step} (t = {time_s} s): the state became non-finite; \
         use a smaller dt or more substeps (see propose_step)"
    )]
    Diverged {
        /// Index of the first sample whose state is non-finite (1-based from the initial state).
        step: usize,
        /// Time of that sample, s.
        time_s: f64,
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
                location: if cols > 1 {
                    format!(" (row {}, column {})", index / cols, index % cols)
                } else {
                    String::new()
                },
            }),
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
