//! Grey-box identification for the sim-to-real gap diagnosis: candidates as effects located by
//! site ([`site`]), their parameters ([`effects`]), the diagnosis joint ([`plant`]), the
//! candidates applied to a nominal model ([`augment`]), recorded runs ([`run`]), the
//! least-squares problem through the simulator ([`problem`], [`fit`]), signal operators for
//! input- and sensor-side effects, and a bounded Levenberg–Marquardt solver.
//!
//! The Python layer (`cablekit.diagnose`) orchestrates: it localises the gap, screens and fits
//! candidates with [`JointProblem::fit`] (in parallel, GIL released), ranks them on held-out runs
//! and writes the report. Everything that touches a simulation lives here.

pub mod augment;
pub mod effects;
pub mod fit;
pub mod lm;
pub mod netplant;
pub mod nominal;
pub mod plant;
pub mod problem;
pub mod run;
pub mod scales;
pub mod signal;
pub mod site;

pub use augment::SensorChain;
pub use effects::{Effect, ParamSpec, Scales, Stage};
pub use lm::{least_squares, LmOptions, LmReport};
pub use plant::{Hysteresis, JointPlant, JOINT_OUTPUTS, JOINT_OUTPUT_NAMES};
pub use problem::{Augmented, JointProblem, Plant, Replay};
pub use run::{Channel, JointRun};
pub use site::{Candidate, Element, Form, NetworkSites, Side, Site, SiteContext};
