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

/// The 4 × 4 transpose `out[t][l] = rows[l][t]`: four states in lanes from four consecutive
/// blocks of four (and back). With `AVX` (only in code compiled for AVX, where the call is
/// inlined) it is four unpacks and four lane permutes instead of sixteen scalar moves.
#[inline(always)]
pub fn transpose4<const AVX: bool>(rows: &[Lanes; LANES]) -> [Lanes; LANES] {
    #[cfg(target_arch = "x86_64")]
    if AVX {
        #[allow(unsafe_code)]
        // SAFETY: `AVX` is set only by callers compiled with the `avx` target feature (the
        // AVX2 + FMA kernels, reached after `cpu_has_avx2_fma`)
        return unsafe { transpose4_avx(rows) };
    }
    std::array::from_fn(|t| std::array::from_fn(|l| rows[l][t]))
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
#[inline]
fn transpose4_avx(rows: &[Lanes; LANES]) -> [Lanes; LANES] {
    use std::arch::x86_64::{
        __m256d, _mm256_permute2f128_pd, _mm256_unpackhi_pd, _mm256_unpacklo_pd,
    };
    #[allow(unsafe_code)]
    // SAFETY: `[f64; 4]` and `__m256d` have the same size and every bit pattern is valid
    // for both (an unaligned load / store)
    let r: [__m256d; LANES] = rows.map(|r| unsafe { std::mem::transmute::<Lanes, __m256d>(r) });
    let lo01 = _mm256_unpacklo_pd(r[0], r[1]); // a0 b0 a2 b2
    let hi01 = _mm256_unpackhi_pd(r[0], r[1]); // a1 b1 a3 b3
    let lo23 = _mm256_unpacklo_pd(r[2], r[3]); // c0 d0 c2 d2
    let hi23 = _mm256_unpackhi_pd(r[2], r[3]); // c1 d1 c3 d3
    let out = [
        _mm256_permute2f128_pd::<0x20>(lo01, lo23),
        _mm256_permute2f128_pd::<0x20>(hi01, hi23),
        _mm256_permute2f128_pd::<0x31>(lo01, lo23),
        _mm256_permute2f128_pd::<0x31>(hi01, hi23),
    ];
    #[allow(unsafe_code)]
    // SAFETY: as above
    out.map(|v| unsafe { std::mem::transmute::<__m256d, Lanes>(v) })
}
