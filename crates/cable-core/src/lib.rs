//! # cable-core
//!
//! Pure-Rust numerical core of cablekit: dynamics of cable-driven robots (friction, cable laws,
//! cable-driven transmissions, antagonistic joints), a fixed-step RK4 integrator with
//! sub-stepping and a stability advisor, the square-root UKF ([`estimate`]) and multilayer
//! perceptron inference ([`nn`]). Later modules (tension distribution) plug into the same
//! [`Model`](dynamics::Model) trait and [`CableError`] type.
//!
//! This crate knows nothing of Python; `crates/cable-py` converts arrays and errors at the edge.
//!
//! Conventions: SI units everywhere (m, rad, s, N, N·m, kg, kg·m²); states, inputs and outputs are
//! flat `f64` slices whose layout each model documents and names (`state_names()` …);
//! trajectories are row-major `(T, n)` buffers.
#![warn(missing_docs)]

pub mod cable;
pub mod cdpr;
pub mod control;
pub mod dynamics;
pub mod error;
pub mod estimate;
pub mod forceps;
pub mod friction;
pub mod identify;
pub mod integrate;
pub mod lanes;
pub mod nn;

pub use dynamics::Model;
pub use error::{check, CableError, Result, WeightsErrorKind};
