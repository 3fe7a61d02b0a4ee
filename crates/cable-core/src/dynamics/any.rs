//! [`AnyModel`]: the closed set of cablekit models as one value, for front ends that choose a
//! model at run time (the Python classes, model files).

use super::CdprPlant;
use super::{AntagonisticJoint, CableTransmission, DahlElement, Model, WinchDrive};
use crate::error::{CableError, Result};

/// One of cablekit's models. Implements [`Model`] by forwarding (one branch per call); hot
/// loops dispatch once with [`with_model!`](crate::with_model) instead.
// A model is built once per run and dispatched by `with_model!` as an owned value; boxing the
// plant (the largest, ~0.5 kB) would need `Model` for `Box<M>` for no measurable gain.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum AnyModel {
    /// Coupled cable transmission.
    Transmission(CableTransmission),
    /// Antagonistic joint.
    Antagonistic(AntagonisticJoint),
    /// Dahl friction element.
    Dahl(DahlElement),
    /// Seed 003's winch, cable and EE under its PID.
    Winch(WinchDrive),
    /// A cable-driven parallel robot with its winches and pulleys.
    Cdpr(CdprPlant),
    /// A cable network from a model file.
    Network(crate::dynamics::network::Network),
}

/// Evaluate `$body` with `$m` bound to the concrete model inside an [`AnyModel`]
/// (monomorphised per variant: the branch is taken once, not per evaluation).
#[macro_export]
macro_rules! with_model {
    ($any:expr, $m:ident => $body:expr) => {
        match $any {
            $crate::dynamics::AnyModel::Transmission($m) => $body,
            $crate::dynamics::AnyModel::Antagonistic($m) => $body,
            $crate::dynamics::AnyModel::Dahl($m) => $body,
            $crate::dynamics::AnyModel::Winch($m) => $body,
            $crate::dynamics::AnyModel::Cdpr($m) => $body,
            $crate::dynamics::AnyModel::Network($m) => $body,
        }
    };
}

impl AnyModel {
    /// The transmission inside, or an error naming what needs one.
    pub fn transmission(&self, purpose: &str) -> Result<&CableTransmission> {
        match self {
            Self::Transmission(t) => Ok(t),
            other => Err(CableError::InvalidOption {
                name: "model".into(),
                value: other.kind().into(),
                allowed: format!("CableTransmission ({purpose} needs one)"),
            }),
        }
    }

    /// The class name of the model inside.
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Transmission(_) => "CableTransmission",
            Self::Antagonistic(_) => "AntagonisticJoint",
            Self::Dahl(_) => "DahlElement",
            Self::Winch(_) => "WinchDrive",
            Self::Cdpr(_) => "CdprPlant",
            Self::Network(_) => "CableNetwork",
        }
    }
}

impl Model for AnyModel {
    fn n_states(&self) -> usize {
        with_model!(self, m => m.n_states())
    }
    fn n_inputs(&self) -> usize {
        with_model!(self, m => m.n_inputs())
    }
    fn n_outputs(&self) -> usize {
        with_model!(self, m => m.n_outputs())
    }
    fn derivative(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
        with_model!(self, m => m.derivative(x, u, dx))
    }
    fn output(&self, x: &[f64], u: &[f64], y: &mut [f64]) {
        with_model!(self, m => m.output(x, u, y))
    }
    fn state_names(&self) -> Vec<String> {
        with_model!(self, m => m.state_names())
    }
    fn input_names(&self) -> Vec<String> {
        with_model!(self, m => m.input_names())
    }
    fn output_names(&self) -> Vec<String> {
        with_model!(self, m => m.output_names())
    }
    fn derivative_lanes<const W: usize>(&self, x: &[[f64; W]], u: &[f64], dx: &mut [[f64; W]]) {
        with_model!(self, m => m.derivative_lanes(x, u, dx))
    }
    fn derivative_lanes_fused<const W: usize>(
        &self,
        x: &[[f64; W]],
        u: &[f64],
        dx: &mut [[f64; W]],
    ) {
        with_model!(self, m => m.derivative_lanes_fused(x, u, dx))
    }
    fn rest_state(&self) -> Vec<f64> {
        with_model!(self, m => m.rest_state())
    }
}

impl From<CableTransmission> for AnyModel {
    fn from(t: CableTransmission) -> Self {
        Self::Transmission(t)
    }
}

impl From<AntagonisticJoint> for AnyModel {
    fn from(j: AntagonisticJoint) -> Self {
        Self::Antagonistic(j)
    }
}

impl From<WinchDrive> for AnyModel {
    fn from(w: WinchDrive) -> Self {
        Self::Winch(w)
    }
}

impl From<CdprPlant> for AnyModel {
    fn from(p: CdprPlant) -> Self {
        Self::Cdpr(p)
    }
}

impl From<DahlElement> for AnyModel {
    fn from(d: DahlElement) -> Self {
        Self::Dahl(d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::raven2;

    #[test]
    fn forwarding_gives_the_same_bits_as_the_model_and_names_what_is_missing() {
        let t = raven2(2).unwrap();
        let any = AnyModel::from(t.clone());
        let x: Vec<f64> = (0..t.n_states()).map(|i| 0.01 * i as f64).collect();
        let u: Vec<f64> = (0..t.n_inputs()).map(|i| 0.1 - 0.05 * i as f64).collect();
        let (mut a, mut b) = (vec![0.0; 8], vec![0.0; 8]);
        t.derivative(&x, &u, &mut a);
        any.derivative(&x, &u, &mut b);
        assert_eq!(a, b);
        assert!(any.transmission("x").is_ok());
        let joint = AnyModel::from(AntagonisticJoint::forceps_example());
        let err = joint.transmission("parameter estimation").unwrap_err();
        assert!(err.to_string().contains("AntagonisticJoint"), "{err}");
    }
}
