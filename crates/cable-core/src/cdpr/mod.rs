//! Cable-driven parallel robots (seeds 002 and 003): robot descriptions, inverse and forward
//! kinematics with pulleys, the structure matrix, and real-time tension distribution.
//!
//! Sign convention (seed 002 eq. 5): tensions `f ≥ 0` hold the platform against an external
//! wrench `w` (gravity included) when `Aᵀ·f + w = 0`.
//!
//! This is the statics layer: geometry, the structure matrix and the tension distribution. The
//! robot as a dynamic model is [`crate::dynamics::CdprPlant`], its closed loop
//! [`crate::control::closed_loop`]; neither is imported here.

mod batch;
mod controller;
mod kinematics;
mod path;
mod qp;
mod robot;
pub mod sensors;
mod tension;
pub mod winch;
mod workspace;

pub use batch::{
    capacity_batch, distribute_batch, inverse_kinematics_batch, CapacityMut, KinematicsMut,
    TensionsMut, PARALLEL_MIN_POSES,
};
pub use controller::{Controller, Step};
pub use kinematics::{
    coordinates, elongation, forward_kinematics, inverse_kinematics, rpy, CableGeometry,
    ForwardKinematics, Pose, FK_MAX_ITER,
};
pub(crate) use path::{dahl_slope, shared_or_own};
pub use path::{equilibrium_projection, path_friction, PathFriction, PathLaw, PathRun};
pub use qp::{Distributor, LEAST_ERROR_REGULARISATION, QP_MAX_ITER};
pub use robot::{Cable, Motion, Platform, Pulley, Robot, MAX_CABLES};
pub use tension::{
    closed_form, improved_closed_form, minimum_norm, Distribution, Method, BOUND_TOLERANCE,
};

pub use workspace::{capacity, capacity_margin, Capacity, Margins, Requirement, RANK_TOLERANCE};

#[cfg(test)]
pub(crate) mod tests;
