//! Models stated the way a user or a file states them — parameters by name, defaults for what
//! is left out — and the reverse, for reporting a model's parameters. Defaults, broadcasting and
//! validation live here once, for every front end (the Python constructors, model files, robot
//! descriptions); the bindings only convert.

mod joint;
mod transmission;

pub use joint::{FieldDefault, JointSpec, JOINT_FIELDS};
pub use transmission::{TransmissionSpec, TRANSMISSION_FIELDS};

/// Every name in `names` must be one of `fields` (a misspelt parameter is an error, never
/// silently ignored).
fn known_names<'a>(
    what: &str,
    mut names: impl Iterator<Item = &'a String>,
    fields: &[&str],
) -> crate::error::Result<()> {
    match names.find(|k| !fields.contains(&k.as_str())) {
        None => Ok(()),
        Some(name) => Err(crate::error::CableError::InvalidOption {
            name: what.into(),
            value: name.clone(),
            allowed: fields.join(", "),
        }),
    }
}
