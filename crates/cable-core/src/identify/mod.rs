//! Grey-box identification for the sim-to-real gap diagnosis: candidate effects as named
//! augmentations of a nominal model, signal operators for input- and sensor-side effects, the
//! least-squares problem through the RK4 simulator, and a bounded Levenberg–Marquardt solver.
//!
//! The Python layer (`cablekit.diagnose`) orchestrates: it localises the gap, fits candidates
//! with [`JointProblem::fit`] (in parallel, GIL released), ranks them on held-out runs and writes
//! the report. Everything that touches a simulation lives here.

pub mod effects;
pub mod lm;
pub mod problem;
pub mod signal;

pub use effects::{Effect, ParamSpec, Scales, Stage};
pub use lm::{least_squares, LmOptions, LmReport};
pub use problem::{Augmented, Channel, JointProblem, JointRun, Plant};
