//! Continuous-time models `ẋ = f(x, u)`, `y = h(x, u)` of cable-driven mechanisms.
//!
//! Every model implements [`Model`], which is all the integrator (and later the square-root UKF
//! and the gap diagnosis) needs. Models are immutable after validation; evaluation is
//! allocation-free and works on flat slices whose layouts the models document and name.

mod antagonistic;
mod any;
mod cdpr;
mod dahl;
mod raven2;
mod spec;
mod transmission;
mod winch;

pub use antagonistic::{AntagonisticJoint, Contact, OUTPUT_NAMES as ANTAGONISTIC_OUTPUTS};
pub use any::AnyModel;
pub mod network;
pub use cdpr::{CdprPlant, Creep, PlantOptions};
pub use dahl::DahlElement;
pub use raven2::raven2;
pub use spec::{
    FieldDefault, JointSpec, SpecValue, TransmissionSpec, JOINT_FIELDS, TRANSMISSION_FIELDS,
};
pub use transmission::{CableTransmission, Gravity, JointKind, TransmissionLink, MAX_LINKS};
pub use winch::{
    Control, WinchDrive, WINCH_CURRENT_INPUT, WINCH_INPUT_NAMES, WINCH_OUTPUT_NAMES,
    WINCH_STATE_NAMES,
};

/// A continuous-time state-space model `ẋ = f(x, u)`, `y = h(x, u)`.
///
/// Implementations must be pure functions of their arguments (no interior state), so that a
/// model can be shared across threads and evaluated at arbitrary points (RK4 stages, sigma
/// points, finite differences).
pub trait Model {
    /// Number of states `n`.
    fn n_states(&self) -> usize;
    /// Number of inputs `m`.
    fn n_inputs(&self) -> usize;
    /// Number of outputs `p`.
    fn n_outputs(&self) -> usize;
    /// Writes `f(x, u)` into `dx` (length `n`). `x` has length `n`, `u` length `m`.
    fn derivative(&self, x: &[f64], u: &[f64], dx: &mut [f64]);
    /// Writes `h(x, u)` into `y` (length `p`).
    fn output(&self, x: &[f64], u: &[f64], y: &mut [f64]);
    /// Names of the states, in layout order (units in the model docs).
    fn state_names(&self) -> Vec<String>;
    /// Names of the inputs, in layout order.
    fn input_names(&self) -> Vec<String>;
    /// Names of the outputs, in layout order.
    fn output_names(&self) -> Vec<String>;
    /// `f` at `W` states at once ([`LANES`](crate::lanes::LANES), or
    /// [`WIDE`](crate::lanes::WIDE) for two lane groups side by side), structure of arrays: `x[s][l]` is state
    /// `s` of point `l`, `dx` likewise; the input `u` is shared. The default calls
    /// [`Model::derivative`] once per lane; models override it with vectorised arithmetic
    /// that performs the same operations, so both give the same bits (tested per model).
    fn derivative_lanes<const W: usize>(&self, x: &[[f64; W]], u: &[f64], dx: &mut [[f64; W]])
    where
        Self: Sized,
    {
        const STACK: usize = 64;
        let n = x.len();
        let (mut xs_stack, mut ds_stack) = ([0.0; STACK], [0.0; STACK]);
        let (mut xs_heap, mut ds_heap) = (Vec::new(), Vec::new());
        let (xs, ds) = if n <= STACK {
            (&mut xs_stack[..n], &mut ds_stack[..n])
        } else {
            xs_heap.resize(n, 0.0);
            ds_heap.resize(n, 0.0);
            (&mut xs_heap[..], &mut ds_heap[..])
        };
        for l in 0..W {
            for (v, xl) in xs.iter_mut().zip(x) {
                *v = xl[l];
            }
            self.derivative(xs, u, ds);
            for (d, dl) in ds.iter().zip(dx.iter_mut()) {
                dl[l] = *d;
            }
        }
    }
    /// [`Model::derivative_lanes`] with products and sums fused into multiply-adds where the
    /// model has them (one rounding each instead of two, so the results differ from
    /// [`Model::derivative`] in the last bits). Called from code compiled for CPUs with FMA;
    /// the default is [`Model::derivative_lanes`].
    #[inline(always)]
    fn derivative_lanes_fused<const W: usize>(&self, x: &[[f64; W]], u: &[f64], dx: &mut [[f64; W]])
    where
        Self: Sized,
    {
        self.derivative_lanes(x, u, dx)
    }
    /// A representative state for step-size advice (equilibrium at rest by default: zeros).
    fn rest_state(&self) -> Vec<f64> {
        vec![0.0; self.n_states()]
    }
}

/// Standard gravity (m/s²).
pub const GRAVITY: f64 = 9.80665;
