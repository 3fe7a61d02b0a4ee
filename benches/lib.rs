//! Shared fixtures for the criterion benches (see `dynamics.rs`).
