//! Models stated the way a user or a file states them — parameters by name, defaults for what
//! is left out — and the reverse, for reporting a model's parameters. Defaults, broadcasting and
//! validation live here once, for every front end (the Python constructors, model files, robot
//! descriptions); the bindings only convert.

mod joint;
mod transmission;

pub use joint::{FieldDefault, JointSpec, JOINT_FIELDS};
pub use transmission::{TransmissionSpec, TRANSMISSION_FIELDS};

use crate::error::{CableError, Result};

/// A parameter value as a front end states it (a Python keyword, a TOML value); the spec
/// checks that each name gets the kind of value it takes.
#[derive(Debug, Clone, PartialEq)]
pub enum SpecValue {
    /// One number.
    Number(f64),
    /// A list of numbers (one per link).
    Numbers(Vec<f64>),
    /// A name (`cable_law`).
    Text(String),
    /// A list of names (`joint_kind`, one per link).
    Texts(Vec<String>),
    /// Rows of numbers (`coupling`).
    Rows(Vec<Vec<f64>>),
}

impl SpecValue {
    fn kind(&self) -> &'static str {
        match self {
            Self::Number(_) => "a number",
            Self::Numbers(_) => "a list of numbers",
            Self::Text(_) => "a string",
            Self::Texts(_) => "a list of strings",
            Self::Rows(_) => "a list of lists",
        }
    }

    fn wrong(&self, name: &str, expected: &str) -> CableError {
        CableError::WrongType {
            name: name.into(),
            expected: expected.into(),
            got: self.kind().into(),
        }
    }

    /// An empty list, which every list kind accepts.
    fn is_empty_list(&self) -> bool {
        matches!(self, Self::Numbers(v) if v.is_empty())
    }

    pub(crate) fn number(self, name: &str) -> Result<f64> {
        match self {
            Self::Number(v) => Ok(v),
            other => Err(other.wrong(name, "a number")),
        }
    }

    pub(crate) fn numbers(self, name: &str) -> Result<Vec<f64>> {
        match self {
            Self::Number(v) => Ok(vec![v]),
            Self::Numbers(v) => Ok(v),
            other => Err(other.wrong(name, "a number or a list of numbers (one per link)")),
        }
    }

    pub(crate) fn text(self, name: &str) -> Result<String> {
        match self {
            Self::Text(v) => Ok(v),
            other => Err(other.wrong(name, "a string")),
        }
    }

    pub(crate) fn texts(self, name: &str) -> Result<Vec<String>> {
        match self {
            Self::Texts(v) => Ok(v),
            e if e.is_empty_list() => Ok(Vec::new()),
            other => Err(other.wrong(name, "a list of strings (one per link)")),
        }
    }

    pub(crate) fn rows(self, name: &str) -> Result<Vec<Vec<f64>>> {
        match self {
            Self::Rows(v) => Ok(v),
            e if e.is_empty_list() => Ok(Vec::new()),
            other => Err(other.wrong(name, "a list of rows of numbers")),
        }
    }
}

/// Every name in `names` must be one of `fields` (a misspelt parameter is an error, never
/// silently ignored).
fn known_names<'a>(
    what: &str,
    mut names: impl Iterator<Item = &'a String>,
    fields: &[&str],
) -> Result<()> {
    match names.find(|k| !fields.contains(&k.as_str())) {
        None => Ok(()),
        Some(name) => Err(CableError::InvalidOption {
            name: what.into(),
            value: name.clone(),
            allowed: fields.join(", "),
        }),
    }
}
