//! Multilayer-perceptron inference for real-time loops: the free-motion cable-tension model of
//! the PSO-BPNN paper (seed 000, §2.3.3, Table 1: 4-10-4) and the pulley-friction compensator
//! of the CDPR paper (seed 002, §3.2, eq. 9: 14-L-8). Training lives in Python
//! (`cablekit.nn`, torch); this module only loads and evaluates.
//!
//! A network maps a physical input `x ∈ ℝⁿ⁰` to a physical output `y ∈ ℝⁿᴸ`:
//!
//! ```text
//! a⁰ = mapminmax(x)                     a  = 2 (x − x_min) / (x_max − x_min) − 1
//! aˡ = σˡ(Wˡ aˡ⁻¹ + bˡ),  l = 1 … L     Wˡ: (nˡ, nˡ⁻¹), bˡ: (nˡ,)
//! y  = mapminmax⁻¹(aᴸ)                  y  = (aᴸ + 1) (y_max − y_min) / 2 + y_min
//! ```
//!
//! with σ one of MATLAB's `logsig` (1/(1+e⁻ⁿ)), `tansig` (2/(1+e⁻²ⁿ) − 1 = tanh n) or
//! `purelin` (n). A feature whose training range is empty (x_max = x_min) passes with gain 1,
//! as `mapminmax` does.
//!
//! Weights come from a safetensors file ([`Mlp::from_safetensors`]); the layout is in
//! [`format`]. Loading validates everything (shapes against the metadata, finite values, known
//! activations) and names the offending tensor in a [`CableError::Weights`](crate::CableError).
//!
//! [`Mlp::forward`] evaluates one sample without allocating (scratch lives in the struct);
//! [`Mlp::forward_batch`] evaluates `(N, n⁰)` rows, in parallel (rayon) above
//! [`PARALLEL_MIN_ROWS`].

mod activation;
pub mod format;
mod mlp;
mod normalize;

pub use activation::Activation;
pub use mlp::{Layer, Mlp, MlpInfo, Scratch, PARALLEL_MIN_ROWS};
pub use normalize::MapMinMax;

#[cfg(test)]
mod tests;
