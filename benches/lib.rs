//! Shared fixtures for the criterion benches in `dynamics.rs`.
#![allow(missing_docs)]

use cable_core::dynamics::{raven2, CableTransmission, Model};

/// The Raven-II 3-link model at a taut, moving state with a torque input.
pub fn raven_fixture() -> (CableTransmission, Vec<f64>, Vec<f64>) {
    let model = raven2(3).expect("shipped parameter set is valid");
    let q_l = [0.7, 1.5, 0.4];
    let mut q_m = [0.0; 3];
    model.joint_to_motor(&q_l, &mut q_m);
    let mut x = vec![0.0; model.n_states()];
    for i in 0..3 {
        x[4 * i] = q_m[i] + 0.01;
        x[4 * i + 1] = 5.0;
        x[4 * i + 2] = q_l[i];
        x[4 * i + 3] = 0.03;
    }
    let u = vec![0.1, -0.05, 0.2, 0.0, 0.0, 0.0];
    (model, x, u)
}
