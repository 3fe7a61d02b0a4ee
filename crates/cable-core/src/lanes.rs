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

/// Two groups of [`LANES`] side by side. Code written on `[f64; WIDE]` compiles to two vector
/// instructions per operation whose dependency chains are independent, so the CPU overlaps
/// them; a latency-bound kernel (the RK4 stages of the sigma-point propagation) runs more
/// points per unit time this way than one group at a time. Broadcast parameters stay
/// [`Lanes`] and are read as `p[l % LANES]`.
pub const WIDE: usize = 2 * LANES;

/// A zeroed `f64` buffer that starts on a 64-byte boundary (a cache line). A `Vec<f64>` is
/// only 16-byte aligned by the allocator, so whether its 32-byte vector loads straddle two
/// lines (for every other block) depends on where it lands: kernels over such buffers then
/// run at one of two speeds from one allocation to the next (measured on the sigma-point
/// propagation: 1.75 µs against 1.5 µs). Safe code: a `Vec` with room to slide to the
/// boundary; dereferences to the aligned slice.
#[derive(Default)]
pub struct Aligned {
    buf: Vec<f64>,
    start: usize,
    len: usize,
}

impl Aligned {
    const LINE: usize = 64 / std::mem::size_of::<f64>();

    /// `len` zeros.
    pub fn zeros(len: usize) -> Self {
        let buf = vec![0.0; len + Self::LINE];
        let misalign = (buf.as_ptr() as usize / std::mem::size_of::<f64>()) % Self::LINE;
        let start = (Self::LINE - misalign) % Self::LINE;
        Self { buf, start, len }
    }

    /// A copy of `v`.
    pub fn from_slice(v: &[f64]) -> Self {
        let mut a = Self::zeros(v.len());
        a.copy_from_slice(v);
        a
    }
}

impl std::ops::Deref for Aligned {
    type Target = [f64];
    #[inline(always)]
    fn deref(&self) -> &[f64] {
        &self.buf[self.start..self.start + self.len]
    }
}

impl std::ops::DerefMut for Aligned {
    #[inline(always)]
    fn deref_mut(&mut self) -> &mut [f64] {
        &mut self.buf[self.start..self.start + self.len]
    }
}

impl Clone for Aligned {
    /// A new aligned buffer with the same values (a cloned `Vec` may land elsewhere).
    fn clone(&self) -> Self {
        Self::from_slice(self)
    }
}

impl std::fmt::Debug for Aligned {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

impl<'a> IntoIterator for &'a Aligned {
    type Item = &'a f64;
    type IntoIter = std::slice::Iter<'a, f64>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

impl From<Vec<f64>> for Aligned {
    fn from(v: Vec<f64>) -> Self {
        Self::from_slice(&v)
    }
}

/// `n` zeroed blocks of `W` lanes on a cache-line boundary ([`Aligned`] viewed as blocks).
#[derive(Debug, Clone)]
pub struct LaneBuf<const W: usize>(Aligned);

impl<const W: usize> LaneBuf<W> {
    /// `n` zeroed blocks.
    pub fn new(n: usize) -> Self {
        Self(Aligned::zeros(n * W))
    }

    /// The blocks.
    #[inline(always)]
    pub fn blocks(&self) -> &[[f64; W]] {
        self.0.as_chunks::<W>().0
    }

    /// The blocks, mutable.
    #[inline(always)]
    pub fn blocks_mut(&mut self) -> &mut [[f64; W]] {
        self.0.as_chunks_mut::<W>().0
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aligned_buffers_start_on_a_cache_line_and_keep_their_values() {
        for len in [0, 1, 3, 8, 13, 100] {
            let v: Vec<f64> = (0..len).map(|k| k as f64 - 0.5).collect();
            let a = Aligned::from_slice(&v);
            // clones land elsewhere and are aligned again
            for b in [&a, &a.clone(), &Aligned::from(v.clone())] {
                assert_eq!(b.as_ptr() as usize % 64, 0, "len {len}");
                assert_eq!(&b[..], &v[..]);
            }
            let l = LaneBuf::<WIDE>::new(len);
            assert_eq!(l.blocks().len(), len);
            assert_eq!(l.clone().blocks().as_ptr() as usize % 64, 0);
            assert!(l.blocks().iter().flatten().all(|&x| x == 0.0));
        }
    }
}
