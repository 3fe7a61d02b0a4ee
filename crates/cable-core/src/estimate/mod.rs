//! State, parameter and force estimation: the square-root unscented Kalman filter of seed 001
//! (van der Merwe's form, eqs 3.9–3.25) over any cable-core model.
//!
//! * [`SrUkf`]: scaled sigma points (α, β, κ), QR of the weighted deviations, Cholesky rank-one
//!   update/downdate for the 0th point (whose covariance weight is negative for small α),
//!   triangular-solve gain, rank-`m` downdate by `U = K·S_y`. A downdate that loses positive
//!   definiteness is detected, the covariance rebuilt and projected onto the positive definite
//!   cone, and counted in [`Health`].
//! * [`Process`]/[`Observe`]: a cable-core [`Model`](crate::Model) integrated by RK4 with
//!   sub-steps ([`ModelProcess`]), a discrete linear system ([`LinearProcess`]); linear
//!   measurements ([`LinearObserve`]) or selected model outputs ([`ModelOutputs`]).
//! * Missing measurements per step by a mask (camera occlusion, seed 001 ch. 4).
//! * Joint state–parameter estimation: [`ParamTransmission`] appends transmission parameters
//!   (stiffness, damping, coupling, pulley radius, …) to the state as random walks, with bounds
//!   enforced by projecting the sigma points and the mean.
//!
//! Matrices handed to the filter are `n × n` symmetric covariances (either storage order);
//! square roots it returns are lower-triangular, column-major.

mod build;
mod dual;
pub mod linalg;
mod models;
mod params;
mod run;
mod srukf;

pub use build::{
    custom_filter, dual_filter, filter, DynObserve, DynProcess, DynSrUkf, Measure, Moments,
    ProcessKind,
};
pub use dual::{AtParams, DualFilter, DualMoments, ParamModel, Through};
pub use models::{
    InputStates, LinearObserve, LinearProcess, LinearRows, ModelOutputs, ModelProcess, Observe,
    Process,
};
pub use params::{
    with_named_params, with_params, DualSrUkf, ParamObserve, ParamTransmission, RandomWalk,
    TransmissionParam,
};
pub use run::{DualRun, FilterRun};
pub use srukf::{Health, SigmaScaling, SrUkf, Weights, SPECIALISED_UP_TO};
