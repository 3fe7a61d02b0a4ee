//! Four independent evaluations side by side, one per SIMD lane (sigma points of the filter,
//! outputs of a network layer), and the runtime check for 256-bit lanes.
//!
//! Code written on [`Lanes`] with fixed-length loops compiles to one vector instruction per
//! operation. Callers that want 256-bit instructions wrap their hot loop in a
//! `#[target_feature(enable = "avx2")]` function chosen when [`cpu_has_avx2`] is true; the
//! operations and their order are the same either way, so are the results, bit for bit (Rust
//! never contracts `a + b·c` into an FMA).

/// Values evaluated together.
pub const LANES: usize = 4;

/// One value per lane.
pub type Lanes = [f64; LANES];

/// The CPU has AVX2 (always false off x86-64).
pub fn cpu_has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
