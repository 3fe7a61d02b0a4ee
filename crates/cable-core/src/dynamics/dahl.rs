//! Dahl friction element as a one-state model (seed 002 eq. 8), for simulation and for the
//! `dahl_hysteresis` effect of the gap diagnosis.
//!
//! State `x = [F]` (N or N·m); input `u = [v]` (m/s or rad/s); output `y = [F]`.
//! `Ḟ = σ₀·|1 − (F/F_c)·sgn v|^n · sgn(1 − (F/F_c)·sgn v) · v`.

use super::Model;
use crate::friction::Dahl;

/// A Dahl friction element driven by a velocity input.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DahlElement {
    /// The friction law.
    pub dahl: Dahl,
}

impl Model for DahlElement {
    fn n_states(&self) -> usize {
        1
    }
    fn n_inputs(&self) -> usize {
        1
    }
    fn n_outputs(&self) -> usize {
        1
    }
    fn derivative(&self, x: &[f64], u: &[f64], dx: &mut [f64]) {
        dx[0] = self.dahl.rate(x[0], u[0]);
    }
    fn output(&self, x: &[f64], _u: &[f64], y: &mut [f64]) {
        y[0] = x[0];
    }
    fn state_names(&self) -> Vec<String> {
        vec!["friction".into()]
    }
    fn input_names(&self) -> Vec<String> {
        vec!["velocity".into()]
    }
    fn output_names(&self) -> Vec<String> {
        vec!["friction".into()]
    }
}
