//! Four independent evaluations side by side, one per SIMD lane (sigma points of the filter,
//! outputs of a network layer), and the runtime check for 256-bit lanes.
//!
//! Code written on [`Lanes`] with fixed-length loops compiles to one vector instruction per
//! operation. Callers that want 256-bit instructions wrap their hot loop in a
//! `#[target_feature(enable = "avx2")]` function chosen when [`cpu_has_avx2`] is true; the
//! operations and their order are the same either way, so are the results, bit for bit (Rust
//! never contracts `a + b·c` into an FMA). Kernels that want fused multiply-adds say so with
//! [`madd`] and dispatch on [`cpu_has_avx2_fma`]; their results then depend on the CPU in the
//! last bits.

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

/// The CPU has AVX2 and FMA (always false off x86-64): kernels whose fast path fuses
/// multiply-adds ([`madd`]) dispatch on this.
pub fn cpu_has_avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// `a·b + c`: one fused operation with one rounding when `FUSED` (for code compiled with the
/// `fma` target feature, where it is one instruction), else a product and a sum. The two
/// differ by rounding only; a kernel uses one or the other throughout.
#[inline(always)]
pub fn madd<const FUSED: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FUSED {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}
