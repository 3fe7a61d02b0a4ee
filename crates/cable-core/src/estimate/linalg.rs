//! Small dense kernels of the square-root UKF: column-major, in place, allocation-free.
//!
//! Triangular factors are **lower** with a non-negative diagonal (`P = L·Lᵀ`), stored
//! column-major in an `n × n` slice: element `(i, j)` at `i + j·n`.

use nalgebra::{DMatrix, SymmetricEigen};

use crate::lanes::{madd, Lanes, LANES};

/// The rank-one update or downdate of a Cholesky factor lost positive definiteness at `column`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DowndateFailed {
    /// Column (0-based) where `L[k,k]² + σ·v[k]²` was not positive.
    pub column: usize,
}

/// `L ← chol(L·Lᵀ + sign·v·vᵀ)` for lower `L` (`n × n`, column-major), `sign = ±1`. `v` is
/// overwritten. Fails (leaving `L` partly modified) when the result is not positive definite
/// or not finite: callers that must recover keep a copy.
pub fn cholupdate(l: &mut [f64], n: usize, v: &mut [f64], sign: f64) -> Result<(), DowndateFailed> {
    debug_assert!(l.len() >= n * n && v.len() >= n);
    cholupdate_columns(l, n, v, n, 1, sign)
}

/// `count` rank-one updates (`sign = 1`) or downdates (`sign = −1`) of the lower factor `L`
/// (`n × n`, column-major) by the columns of `vs` (`n × count`, column-major with leading
/// dimension `ld ≥ n`, overwritten), with the same arithmetic as `count` calls of
/// [`cholupdate`] one after the other. The loops run column by column of `L`, each vector in
/// turn, so that the independent rotations of the vectors overlap in the pipeline instead of
/// waiting on one square root and one division per column of each (the rank-`m` downdate
/// `S ← cholupdate(S, K·S_y, −1)` of the measurement update). For `n` a multiple of four the
/// rotations of a column by up to four vectors run in one pass down it, in 256-bit lanes with
/// fused multiply-adds on CPUs with AVX2 and FMA (results then differ from other CPUs in the
/// last bits).
pub fn cholupdate_columns(
    l: &mut [f64],
    n: usize,
    vs: &mut [f64],
    ld: usize,
    count: usize,
    sign: f64,
) -> Result<(), DowndateFailed> {
    cholupdate_columns_sized::<0>(l, n, vs, ld, count, sign)
}

/// [`cholupdate_columns`] for `n = N` (any `n` when `N` is 0): the block kernel is compiled
/// for `N` when `N` is one of its sizes (a multiple of four up to 24), so its column and
/// block loops unroll. Same operations, same results.
#[inline(always)]
pub(crate) fn cholupdate_columns_sized<const N: usize>(
    l: &mut [f64],
    n: usize,
    vs: &mut [f64],
    ld: usize,
    count: usize,
    sign: f64,
) -> Result<(), DowndateFailed> {
    debug_assert!(N == 0 || N == n);
    debug_assert!(l.len() >= n * n && ld >= n && vs.len() >= ld * count.saturating_sub(1) + n);
    if !n.is_multiple_of(LANES) {
        return if sign > 0.0 {
            rotate_columns::<true>(l, n, vs, ld, count)
        } else {
            rotate_columns::<false>(l, n, vs, ld, count)
        };
    }
    macro_rules! sized {
        ($($size:literal)*) => {
            match N {
                $($size => rotate_blocks_for::<$size>(l, n, vs, ld, count, sign),)*
                _ => rotate_blocks_for::<0>(l, n, vs, ld, count, sign),
            }
        };
    }
    sized!(4 8 12 16 20 24)
}

/// [`rotate_blocks`] for `n` a multiple of four (`N` as in [`cholupdate_columns_sized`]), with
/// 256-bit lanes and fused multiply-adds where the CPU has them.
fn rotate_blocks_for<const N: usize>(
    l: &mut [f64],
    n: usize,
    vs: &mut [f64],
    ld: usize,
    count: usize,
    sign: f64,
) -> Result<(), DowndateFailed> {
    #[cfg(target_arch = "x86_64")]
    if crate::lanes::cpu_has_avx2_fma() {
        #[allow(unsafe_code)]
        // SAFETY: the CPU reported AVX2 and FMA, all `rotate_blocks_avx2` requires
        return unsafe { rotate_blocks_avx2::<N>(l, n, vs, ld, count, sign) };
    }
    rotate_blocks::<N, false>(l, n, vs, ld, count, sign)
}

/// Rotations of column `k` by up to this many vectors are applied in one pass down the column.
const ROTATION_GROUP: usize = 4;

/// One rotation of a column of `L` by a vector: for an update (Givens)
/// `l ← c·l + s·v`, `v ← c·v − s·l`; for a downdate (hyperbolic) `l ← (l − s·v)·(1/c)`,
/// `v ← c·v − s·l` with the new `l`.
#[derive(Clone, Copy)]
struct Rotation {
    c: f64,
    s: f64,
    inv_c: f64,
}

impl Rotation {
    const IDENTITY: Rotation = Rotation {
        c: 1.0,
        s: 0.0,
        inv_c: 1.0,
    };

    /// The rotation that takes `(L[k,k], v[k]) = (l0, v0)` to `(r, 0)`, `r² = l0² ± v0²`, and
    /// `r`; `None` when `r²` is not positive and finite (or a downdate's pivot is not positive).
    #[inline(always)]
    fn new<const UP: bool>(l0: f64, v0: f64) -> Option<(Rotation, f64)> {
        let sign = if UP { 1.0 } else { -1.0 };
        let r2 = l0 * l0 + sign * v0 * v0;
        // not positive, or not finite (NaN fails both comparisons)
        if !(r2 > 0.0 && r2 <= f64::MAX) || (!UP && l0 <= 0.0) {
            return None;
        }
        // √r2 and 1/r2 are independent: 1/r = √r2 · (1/r2) keeps one long-latency
        // operation off the chain from one column to the next
        let r = r2.sqrt();
        let inv_r = r * (1.0 / r2);
        Some(if UP {
            // Givens rotation of [L[:,k], v]: defined for a zero pivot too
            (
                Rotation {
                    c: l0 * inv_r,
                    s: v0 * inv_r,
                    inv_c: f64::NAN, // not used
                },
                r,
            )
        } else {
            let inv_l = 1.0 / l0;
            (
                Rotation {
                    c: r * inv_l,
                    s: v0 * inv_l,
                    inv_c: l0 * inv_r,
                },
                r,
            )
        })
    }

    /// The rotation of one entry pair `(l, v)`.
    #[inline(always)]
    fn apply_one<const UP: bool, const FUSED: bool>(&self, l: f64, v: f64) -> (f64, f64) {
        let (c, s) = (self.c, self.s);
        if UP {
            (madd::<FUSED>(s, v, c * l), madd::<FUSED>(-s, l, c * v))
        } else {
            let l2 = madd::<FUSED>(-s, v, l) * self.inv_c;
            (l2, madd::<FUSED>(-s, l2, c * v))
        }
    }

    /// [`Rotation::apply_one`] on four entry pairs, whole blocks loaded before and stored
    /// after (so that the four lanes are one vector operation each).
    #[inline(always)]
    fn apply<const UP: bool, const FUSED: bool>(&self, lb: &mut Lanes, vb: &mut Lanes) {
        let (l, v) = (*lb, *vb);
        let r: [(f64, f64); LANES] =
            std::array::from_fn(|t| self.apply_one::<UP, FUSED>(l[t], v[t]));
        *lb = std::array::from_fn(|t| r[t].0);
        *vb = std::array::from_fn(|t| r[t].1);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn rotate_blocks_avx2<const N: usize>(
    l: &mut [f64],
    n: usize,
    vs: &mut [f64],
    ld: usize,
    count: usize,
    sign: f64,
) -> Result<(), DowndateFailed> {
    rotate_blocks::<N, true>(l, n, vs, ld, count, sign)
}

/// [`cholupdate_columns`] for `n` a multiple of four, the vectors taken [`ROTATION_GROUP`] at
/// a time: per column `k`, the group's rotations are found one after the other on the
/// diagonal (they chain through `L[k,k]` only), then applied together in one pass down the
/// column, four rows at a time from the block that holds row `k + 1`, so every entry below the
/// diagonal sees the same rotations in the same order as with one vector at a time. Rows above
/// `k` in that block hold zeros in `L` and (cleared after their own column) in every `v`,
/// which the rotations keep exact zeros; row `k` takes the new pivot afterwards.
#[inline(always)]
fn rotate_blocks<const N: usize, const FUSED: bool>(
    l: &mut [f64],
    n: usize,
    vs: &mut [f64],
    ld: usize,
    count: usize,
    sign: f64,
) -> Result<(), DowndateFailed> {
    for first in (0..count).step_by(ROTATION_GROUP) {
        let vs = &mut vs[first * ld..];
        macro_rules! group {
            ($($g:literal),*) => {
                match ROTATION_GROUP.min(count - first) {
                    $($g if sign > 0.0 => rotate_group::<N, $g, true, FUSED>(l, n, vs, ld),)*
                    $($g => rotate_group::<N, $g, false, FUSED>(l, n, vs, ld),)*
                    _ => unreachable!("groups of 1 to ROTATION_GROUP vectors"),
                }
            };
        }
        group!(1, 2, 3, 4)?;
    }
    Ok(())
}

/// One group of `G` vectors (columns `0, ld, …` of `vs`) of [`rotate_blocks`].
#[inline(always)]
fn rotate_group<const N: usize, const G: usize, const UP: bool, const FUSED: bool>(
    l: &mut [f64],
    n: usize,
    vs: &mut [f64],
    ld: usize,
) -> Result<(), DowndateFailed> {
    let n = if N == 0 { n } else { N };
    let mut rest = vs;
    // each vector as blocks of four rows
    let mut vcols: [&mut [Lanes]; G] = std::array::from_fn(|g| {
        let taken = std::mem::take(&mut rest);
        let (head, tail) = taken.split_at_mut(if g + 1 < G { ld } else { n });
        rest = tail;
        head[..n].as_chunks_mut::<LANES>().0
    });
    for (k, col) in l[..n * n].chunks_exact_mut(n).enumerate() {
        let (kb, kt) = (k / LANES, k % LANES);
        let col = col.as_chunks_mut::<LANES>().0;
        let mut rot = [Rotation::IDENTITY; G];
        let (mut pivot, mut any) = (col[kb][kt], false);
        for (rot, v) in rot.iter_mut().zip(vcols.iter()) {
            let v0 = v[kb][kt];
            if v0 == 0.0 {
                continue; // nothing to rotate into this column
            }
            let (r, diag) = Rotation::new::<UP>(pivot, v0).ok_or(DowndateFailed { column: k })?;
            (*rot, pivot, any) = (r, diag, true);
        }
        if !any {
            continue;
        }
        let start = (k + 1) / LANES;
        for (b, lb) in col.iter_mut().enumerate().skip(start) {
            for (rot, v) in rot.iter().zip(vcols.iter_mut()) {
                rot.apply::<UP, FUSED>(lb, &mut v[b]);
            }
        }
        col[kb][kt] = pivot;
        for v in vcols.iter_mut() {
            v[kb][kt] = 0.0;
        }
    }
    Ok(())
}

/// [`cholupdate_columns`] for one sign (`UP`: update), the branch on it hoisted: any `n`,
/// one vector at a time per column, scalar.
#[inline(always)]
fn rotate_columns<const UP: bool>(
    l: &mut [f64],
    n: usize,
    vs: &mut [f64],
    ld: usize,
    count: usize,
) -> Result<(), DowndateFailed> {
    for (k, col) in l[..n * n].chunks_exact_mut(n).enumerate() {
        let (lkk, head) = col[k..].split_first_mut().expect("k < n");
        for m in 0..count {
            let (vk, tail) = vs[m * ld + k..m * ld + n].split_first_mut().expect("k < n");
            if *vk == 0.0 {
                continue; // nothing to rotate into this column
            }
            let (rot, r) = Rotation::new::<UP>(*lkk, *vk).ok_or(DowndateFailed { column: k })?;
            *lkk = r;
            for (li, vi) in head.iter_mut().zip(tail.iter_mut()) {
                (*li, *vi) = rot.apply_one::<UP, false>(*li, *vi);
            }
        }
    }
    Ok(())
}

/// Rows of an [`lq_lower`] workspace: `n` rounded up to whole SIMD lanes.
pub const fn padded(n: usize) -> usize {
    n.div_ceil(LANES) * LANES
}

/// Lower factor `L` (`n × n`, column-major, non-negative diagonal) with `L·Lᵀ = A·Aᵀ`: the
/// transpose of `R` in the QR decomposition of `Aᵀ`, i.e. the square root that the filter's
/// `qr([√W·(χ − x̂), √Q])` stands for. `a` is `n × cols`, column-major with leading dimension
/// [`padded`]`(n)` whose padding rows are zero; it is destroyed. Columns `dense..cols` must
/// form a lower-triangular block (column `dense + t` zero above row `t`: the square root of a
/// noise covariance), whose known zeros the reflections skip. `w` is scratch of length
/// [`padded`]`(n)`.
///
/// Householder reflections from the right, one per row. Each column is one weighted
/// deviation (as the sigma points are stored), so a reflection runs down contiguous columns a
/// SIMD block at a time with no horizontal sums, and the product `A·x` with the row `x` is
/// formed before the row's norm is known (`A·v = A·x − α·A·e_k`), so the square root and the
/// division overlap with it instead of waiting in line. The norm itself is the row's own entry
/// of `A·x`. Up to 24 rows the columns are fixed-size arrays, with 256-bit lanes and fused
/// multiply-adds when the CPU has AVX2 and FMA (the same operations with one rounding per
/// multiply-add, so results differ from the portable build in the last bits); larger `n`
/// runs block by block.
pub fn lq_lower(a: &mut [f64], n: usize, cols: usize, dense: usize, w: &mut [f64], l: &mut [f64]) {
    let ld = padded(n);
    assert!(
        a.len() >= ld * cols && l.len() >= n * n && dense <= cols && w.len() >= ld,
        "lq_lower: workspace too small"
    );
    macro_rules! fixed {
        ($($ld:literal => $chains:literal),*) => {
            match ld {
                $($ld => {
                    #[cfg(target_arch = "x86_64")]
                    if crate::lanes::cpu_has_avx2_fma() {
                        #[allow(unsafe_code)]
                        // SAFETY: the CPU reported AVX2 and FMA, all `lq_fixed_avx2` requires
                        unsafe { lq_fixed_avx2::<$ld, $chains>(a, n, cols, dense, l) };
                        return;
                    }
                    lq_fixed::<$ld, $chains, false>(a, n, cols, dense, l)
                })*
                _ => lq_blocks(a, n, cols, dense, w, l),
            }
        };
    }
    // independent accumulator chains: as many as the 16 vector registers allow next to the
    // reflection being applied (12 rows: 2 chains of 3 blocks, measured faster than 4)
    fixed!(4 => 4, 8 => 4, 12 => 2, 16 => 2, 20 => 2, 24 => 2);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn lq_fixed_avx2<const LD: usize, const C: usize>(
    a: &mut [f64],
    n: usize,
    cols: usize,
    dense: usize,
    l: &mut [f64],
) {
    lq_fixed::<LD, C, true>(a, n, cols, dense, l);
}

/// The reflection of row `k` from `s2 = |x|²` and `x_k`: `(α, 1/(vᵀv/2))` with
/// `v = x − α·e_k`, `α = −sign(x_k)·|x|`; `vᵀv = 2·|x|·(|x| + |x_k|)` (no cancellation).
#[inline(always)]
fn reflector(s2: f64, xk: f64) -> (f64, f64) {
    let norm = s2.sqrt();
    let alpha = if xk > 0.0 { -norm } else { norm };
    (alpha, 1.0 / (norm * (norm + xk.abs())))
}

/// `L[i, k] = sign_k · A[i, k]` for `i ≥ k` (zero columns past the last reflection).
#[inline(always)]
fn extract_lower(a: &[f64], ld: usize, n: usize, steps: usize, l: &mut [f64]) {
    for (k, col) in l[..n * n].chunks_exact_mut(n).enumerate() {
        if k >= steps {
            col.fill(0.0);
            continue;
        }
        let sgn = if a[k + k * ld] < 0.0 { -1.0 } else { 1.0 };
        // one pass with a select, not a copy and a short fill (a library call per column)
        for (i, (li, v)) in col.iter_mut().zip(&a[k * ld..k * ld + n]).enumerate() {
            *li = if i < k { 0.0 } else { sgn * v };
        }
    }
}

/// [`lq_lower`] with padded columns (`LD` rows) in registers. Rows are finished four at a
/// time: a finished block of four rows influences no other row (and what rounding leaves right
/// of a finished row's diagonal is never read), so each reflection runs over the window of the
/// last `R` rows only, from the block that holds row `k` down (`R = LD − 4·⌊k/4⌋`).
///
/// The product `A·x` that reflection `k + 1` needs is summed in the pass that applies
/// reflection `k`, from each column as it leaves the update (one pass over the columns per
/// row, and the sum does not wait for a second pass to load what the first just stored).
#[inline(always)]
fn lq_fixed<const LD: usize, const C: usize, const FUSED: bool>(
    a: &mut [f64],
    n: usize,
    cols: usize,
    dense: usize,
    l: &mut [f64],
) {
    let steps = n.min(cols);
    // row k is non-zero in columns k..end only: a tail column dense + t is untouched (and
    // zero in row k) while t > k
    let end = |k: usize| (dense + k + 1).min(cols);
    let mut ax = [0.0; LD];
    if steps > 0 {
        row_products::<LD, LD, C, FUSED>(a, 0, end(0), &mut ax);
    }
    for k in 0..steps {
        // the next row's product is summed in this reflection's pass
        let next = (k + 1 < steps).then(|| end(k + 1));
        macro_rules! window {
            ($($r:literal),*) => {
                match LD - 4 * (k / 4) {
                    $($r => reflect_row::<LD, $r, C, FUSED>(a, k, end(k), next, &mut ax),)*
                    _ => unreachable!("LD is a multiple of 4 up to 24"),
                }
            };
        }
        window!(4, 8, 12, 16, 20, 24);
    }
    extract_lower(a, LD, n, steps, l);
}

/// `A·x` for the row `x = A[k, k..end]` on the last `R` rows, over columns `k..end` with `C`
/// accumulator chains (column `j` in chain `(j − k) mod C`), into `ax` (rows `LD − R..`).
#[inline(always)]
fn row_products<const LD: usize, const R: usize, const C: usize, const FUSED: bool>(
    a: &[f64],
    k: usize,
    end: usize,
    ax: &mut [f64; LD],
) {
    if R > LD {
        return;
    }
    let (block, _) = a[k * LD..end * LD].as_chunks::<LD>();
    let mut acc = [[0.0; R]; C];
    let (groups, rest) = block.as_chunks::<C>();
    for group in groups {
        for (acc, col) in acc.iter_mut().zip(group) {
            accumulate::<LD, R, FUSED>(acc, col, k);
        }
    }
    for (acc, col) in acc.iter_mut().zip(rest) {
        accumulate::<LD, R, FUSED>(acc, col, k);
    }
    sum_chains(&acc, ax);
}

/// `acc += A[row, j]·A[:, j]` on the last `R` rows of column `j` (one term of `A·x`).
#[inline(always)]
fn accumulate<const LD: usize, const R: usize, const FUSED: bool>(
    acc: &mut [f64; R],
    col: &[f64; LD],
    row: usize,
) {
    let (off, xj) = (LD - R, col[row]);
    for r in 0..R {
        acc[r] = madd::<FUSED>(xj, col[off + r], acc[r]);
    }
}

/// The `C` chains of `A·x` summed ([`chain_sum`]) into the last `R` rows of `ax`.
#[inline(always)]
fn sum_chains<const LD: usize, const R: usize, const C: usize>(
    acc: &[[f64; R]; C],
    ax: &mut [f64; LD],
) {
    for r in 0..R {
        ax[LD - R + r] = chain_sum(std::array::from_fn::<f64, C, _>(|c| acc[c][r]));
    }
}

/// The reflection of row `k` over columns `k..end`, on the last `R` rows of each column,
/// from `ax` = `A·x` of row `k`; with `next = Some(next_end)`, `ax` becomes `A·x` of row
/// `k + 1` over columns `k + 1..next_end` (`next_end ≤ end + 1`: a column past `end` is a tail
/// column, zero in row `k`, that this reflection leaves as it is), summed as [`row_products`]
/// would. Products and sums fused when `FUSED`.
#[inline(always)]
fn reflect_row<const LD: usize, const R: usize, const C: usize, const FUSED: bool>(
    a: &mut [f64],
    k: usize,
    end: usize,
    next: Option<usize>,
    ax: &mut [f64; LD],
) {
    if R > LD {
        return; // not a window of this LD (the match above never picks it)
    }
    let off = LD - R;
    assert!(k >= off && k - off < R, "row k lies in the window");
    let next_end = next.unwrap_or(end);
    assert!(next_end <= end + 1, "one tail column more at most");
    assert!(next.is_none() || k + 1 < LD, "row k + 1 lies in the window");
    let s2 = ax[k];
    // whole columns as arrays: indices `off + r` need no checks, `k` is checked once above
    let (block, _) = a[k * LD..next_end * LD].as_chunks_mut::<LD>();
    if s2 == 0.0 {
        // row k is zero already: L[k,k] = 0, the columns stay as they are
        if next.is_some() {
            row_products::<LD, R, C, FUSED>(a, k + 1, next_end, ax);
        }
        return;
    }
    let (first, others) = block.split_first_mut().expect("k < end");
    let xk = first[k];
    let (alpha, scale) = reflector(s2, xk);
    // w = scale·A·v = scale·(A·x − α·A[:,k]); A ← A − w·vᵀ, v_j read before column j changes
    let w: [f64; R] =
        std::array::from_fn(|r| scale * madd::<FUSED>(-alpha, first[off + r], ax[off + r]));
    let vk = alpha - xk; // −v_k
    for r in 0..R {
        first[off + r] = madd::<FUSED>(vk, w[r], first[off + r]);
    }
    // row k is now α·e_kᵀ up to rounding; the rounding right of the diagonal is never read
    // and is not cleared (a scalar store there would stall the next vector loads)
    first[k] = alpha;
    if next.is_none() {
        let (groups, rest) = others.as_chunks_mut::<4>();
        for group in groups {
            for col in group {
                reflect_column::<LD, R, FUSED>(col, k, &w);
            }
        }
        for col in rest {
            reflect_column::<LD, R, FUSED>(col, k, &w);
        }
        return;
    }
    // the column past `end` is zero in row k, so the update leaves it as it is (v_j = 0)
    let mut acc = [[0.0; R]; C];
    let (groups, rest) = others.as_chunks_mut::<C>();
    for group in groups {
        for (acc, col) in acc.iter_mut().zip(group) {
            reflect_column::<LD, R, FUSED>(col, k, &w);
            accumulate::<LD, R, FUSED>(acc, col, k + 1);
        }
    }
    for (acc, col) in acc.iter_mut().zip(rest) {
        reflect_column::<LD, R, FUSED>(col, k, &w);
        accumulate::<LD, R, FUSED>(acc, col, k + 1);
    }
    sum_chains(&acc, ax);
}

/// `A[:, j] −= v_j·w` on the last `R` rows of column `j`, `v_j = A[k, j]` (a function, not
/// a closure: a closure would not inherit the caller's target features).
#[inline(always)]
fn reflect_column<const LD: usize, const R: usize, const FUSED: bool>(
    col: &mut [f64; LD],
    k: usize,
    w: &[f64; R],
) {
    let off = LD - R;
    let vj = -col[k];
    for r in 0..R {
        col[off + r] = madd::<FUSED>(vj, w[r], col[off + r]);
    }
}

/// Sum of the chains in a fixed tree order: `((c₀ + c₁) + (c₂ + c₃))`.
#[inline(always)]
fn chain_sum<const C: usize>(c: [f64; C]) -> f64 {
    match C {
        1 => c[0],
        2 => c[0] + c[1],
        4 => (c[0] + c[1]) + (c[2] + c[3]),
        _ => c.iter().sum(),
    }
}

/// [`lq_lower`] for any size, `LANES` rows at a time with four chains (`w` holds `A·x`).
fn lq_blocks(a: &mut [f64], n: usize, cols: usize, dense: usize, w: &mut [f64], l: &mut [f64]) {
    let ld = padded(n);
    let steps = n.min(cols);
    for k in 0..steps {
        let end = (dense + k + 1).min(cols);
        let blk = |a: &[f64], j: usize, r0: usize| -> Lanes {
            a[j * ld + r0..j * ld + r0 + LANES]
                .try_into()
                .expect("LANES")
        };
        for r0 in (0..ld).step_by(LANES) {
            let mut acc = [[0.0; LANES]; 4];
            for j in k..end {
                let (c, xj) = (blk(a, j, r0), a[k + j * ld]);
                let acc = &mut acc[(j - k) % 4];
                for t in 0..LANES {
                    acc[t] += xj * c[t];
                }
            }
            for t in 0..LANES {
                w[r0 + t] = chain_sum([acc[0][t], acc[1][t], acc[2][t], acc[3][t]]);
            }
        }
        let s2 = w[k];
        if s2 == 0.0 {
            continue;
        }
        let xk = a[k + k * ld];
        let (alpha, scale) = reflector(s2, xk);
        for r in 0..ld {
            w[r] = scale * (w[r] - alpha * a[r + k * ld]);
        }
        for j in k..end {
            let vj = if j == k { xk - alpha } else { a[k + j * ld] };
            let col = &mut a[j * ld..(j + 1) * ld];
            for (c, wr) in col.iter_mut().zip(&w[..ld]) {
                *c -= vj * wr;
            }
        }
        a[k + k * ld] = alpha;
    }
    extract_lower(a, ld, n, steps, l);
}

/// Solve `L·x = b` in place (`L` lower, `n × n` column-major). A zero pivot gives ±inf/NaN:
/// callers check finiteness.
pub fn solve_lower(l: &[f64], n: usize, b: &mut [f64]) {
    for j in 0..n {
        b[j] /= l[j + j * n];
        let bj = b[j];
        for i in j + 1..n {
            b[i] -= l[i + j * n] * bj;
        }
    }
}

/// Solve `Lᵀ·x = b` in place (`L` lower, `n × n` column-major).
pub fn solve_lower_transpose(l: &[f64], n: usize, b: &mut [f64]) {
    for j in (0..n).rev() {
        let mut s = b[j];
        for i in j + 1..n {
            s -= l[i + j * n] * b[i];
        }
        b[j] = s / l[j + j * n];
    }
}

/// Cholesky factor (lower, column-major) of a symmetric positive semi-definite matrix `p`
/// (`n × n`, column-major; only the lower triangle is read). Zero pivots are accepted when the
/// rest of their column is zero too (a state without noise); returns the failing row otherwise.
pub fn cholesky_psd(p: &[f64], n: usize) -> Result<Vec<f64>, usize> {
    let mut l = vec![0.0; n * n];
    for j in 0..n {
        let pjj = p[j + j * n];
        // pivots are judged against their own diagonal entry, so a well-posed but badly scaled
        // covariance (angles in 1e-10 rad², stiffness in 1e8 (N/m)²) is not called singular
        let tiny = 1e-13 * pjj.abs();
        let mut d = pjj;
        for k in 0..j {
            d -= l[j + k * n] * l[j + k * n];
        }
        if !d.is_finite() || d < -tiny {
            return Err(j);
        }
        if d <= tiny {
            // semi-definite direction: the column below must vanish too
            for i in j + 1..n {
                let mut s = p[i + j * n];
                for k in 0..j {
                    s -= l[i + k * n] * l[j + k * n];
                }
                let scale = (p[i + i * n].abs() * pjj.abs()).sqrt();
                if s.abs() > 1e-7 * scale {
                    return Err(j);
                }
            }
            continue;
        }
        let djj = d.sqrt();
        l[j + j * n] = djj;
        for i in j + 1..n {
            let mut s = p[i + j * n];
            for k in 0..j {
                s -= l[i + k * n] * l[j + k * n];
            }
            l[i + j * n] = s / djj;
        }
    }
    Ok(l)
}

/// The nearest (Frobenius) symmetric positive definite matrix to `p` with eigenvalues at least
/// `floor_rel` of the largest one, returned as its lower Cholesky factor. The recovery path of a
/// failed downdate: allocates, never fails for finite input.
pub fn nearest_spd_factor(p: &[f64], n: usize, floor_rel: f64) -> Vec<f64> {
    let m = DMatrix::from_fn(n, n, |i, j| 0.5 * (p[i + j * n] + p[j + i * n]));
    let eig = SymmetricEigen::new(m);
    let top = eig.eigenvalues.iter().fold(0.0_f64, |a, &b| a.max(b.abs()));
    let floor = (floor_rel * top).max(f64::MIN_POSITIVE.sqrt());
    let lam = eig.eigenvalues.map(|v| v.max(floor));
    let q = &eig.eigenvectors;
    let rebuilt = q * DMatrix::from_diagonal(&lam) * q.transpose();
    let flat: Vec<f64> = (0..n * n).map(|k| rebuilt[(k % n, k / n)]).collect();
    // the clipped matrix is positive definite by construction; guard against rounding anyway
    cholesky_psd(&flat, n).unwrap_or_else(|_| {
        let mut l = vec![0.0; n * n];
        for i in 0..n {
            l[i + i * n] = floor.sqrt();
        }
        l
    })
}

/// The factor of `saved·savedᵀ + Σ signᵢ·vᵢ·vᵢᵀ`, projected onto the positive definite cone:
/// the repair after a failed [`cholupdate`] (allocates).
pub fn repaired_factor(saved: &[f64], n: usize, updates: &[(&[f64], f64)]) -> Vec<f64> {
    let mut pm = outer_lower(saved, n);
    for (v, sign) in updates {
        for j in 0..n {
            for i in 0..n {
                pm[i + j * n] += sign * v[i] * v[j];
            }
        }
    }
    nearest_spd_factor(&pm, n, 1e-12)
}

/// [`cholupdate`] that repairs instead of failing (offline paths; allocates a copy): returns
/// whether a repair was needed.
pub fn cholupdate_or_repair(l: &mut [f64], n: usize, v: &mut [f64], sign: f64) -> bool {
    let (saved, keep) = (l[..n * n].to_vec(), v[..n].to_vec());
    if cholupdate(l, n, v, sign).is_ok() {
        return false;
    }
    l[..n * n].copy_from_slice(&repaired_factor(&saved, n, &[(&keep, sign)]));
    true
}

/// `P = L·Lᵀ` (column-major, full).
pub fn outer_lower(l: &[f64], n: usize) -> Vec<f64> {
    let mut p = vec![0.0; n * n];
    for j in 0..n {
        for i in 0..n {
            let mut s = 0.0;
            for k in 0..=i.min(j) {
                s += l[i + k * n] * l[j + k * n];
            }
            p[i + j * n] = s;
        }
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn spd(n: usize, seed: u64) -> Vec<f64> {
        // A·Aᵀ + n·I from a deterministic pseudo-random A
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let a: Vec<f64> = (0..n * n).map(|_| next()).collect();
        let mut p = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                p[i + j * n] = (0..n).map(|k| a[i + k * n] * a[j + k * n]).sum::<f64>();
            }
            p[i + i * n] += n as f64 * 0.1;
        }
        p
    }

    #[test]
    #[allow(clippy::float_cmp)] // the upper triangle must stay exactly zero
    fn cholupdate_matches_refactorisation_both_ways() {
        // multiples of four take the block kernel (fused on AVX2+FMA CPUs), the others the
        // general loops; `rotate_blocks::<false>` is the portable build of the former
        for n in [3, 4, 6, 8, 12, 13, 16, 24] {
            let p = spd(n, 3);
            let l = cholesky_psd(&p, n).unwrap();
            let v: Vec<f64> = (0..n).map(|i| 0.1 * (i as f64 + 1.0).sin()).collect();
            for sign in [1.0, -1.0] {
                let mut p2 = p.clone();
                for i in 0..n {
                    for j in 0..n {
                        p2[i + j * n] += sign * v[i] * v[j];
                    }
                }
                let want = cholesky_psd(&p2, n).unwrap();
                let mut got = vec![];
                let (mut l2, mut w) = (l.clone(), v.clone());
                cholupdate(&mut l2, n, &mut w, sign).unwrap();
                got.push(l2);
                if n % 4 == 0 {
                    let (mut l2, mut w) = (l.clone(), v.clone());
                    rotate_blocks::<0, false>(&mut l2, n, &mut w, n, 1, sign).unwrap();
                    got.push(l2);
                }
                for l2 in got {
                    for j in 0..n {
                        for i in 0..n {
                            let k = i + j * n;
                            if i < j {
                                assert_eq!(l2[k], 0.0, "n = {n}: upper triangle stays zero");
                            } else {
                                assert_relative_eq!(l2[k], want[k], epsilon = 1e-12);
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn downdate_that_loses_definiteness_is_reported() {
        for n in [3, 4, 8] {
            let mut l = vec![0.0; n * n];
            for i in 0..n {
                l[i + i * n] = 1.0;
            }
            let mut v = vec![0.0; n];
            v[1] = 2.0;
            assert_eq!(
                cholupdate(&mut l, n, &mut v, -1.0),
                Err(DowndateFailed { column: 1 }),
                "n = {n}"
            );
        }
    }

    fn lq_of(a: &[f64], n: usize, cols: usize, dense: usize) -> Vec<f64> {
        let ld = padded(n);
        let mut work = vec![0.0; ld * cols];
        for j in 0..cols {
            work[j * ld..j * ld + n].copy_from_slice(&a[j * n..(j + 1) * n]);
        }
        let mut w = vec![f64::NAN; ld];
        let mut l = vec![f64::NAN; n * n];
        lq_lower(&mut work, n, cols, dense, &mut w, &mut l);
        l
    }

    #[test]
    fn lq_lower_is_the_cholesky_factor_of_the_gram_matrix() {
        // every remainder of the row blocks and of the column pairs, wide and narrow
        for (n, cols) in [
            (4, 9),
            (5, 11),
            (7, 21),
            (12, 36),
            (3, 27),
            (6, 4),
            (1, 3),
            (15, 47),
            (21, 60),
            (30, 70),
        ] {
            let a: Vec<f64> = (0..n * cols)
                .map(|k| ((k * 7 + 3) % 11) as f64 - 5.0 + 0.01 * k as f64)
                .collect();
            let mut gram = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..n {
                    gram[i + j * n] = (0..cols).map(|c| a[i + c * n] * a[j + c * n]).sum();
                }
            }
            let l = lq_of(&a, n, cols, cols);
            let back = outer_lower(&l, n);
            for k in 0..n * n {
                let scale = (gram[k % n * (n + 1)] * gram[k / n * (n + 1)]).sqrt();
                assert!(
                    (back[k] - gram[k]).abs() <= 1e-13 * scale,
                    "n={n} cols={cols} k={k}: {} vs {}",
                    back[k],
                    gram[k]
                );
            }
            if cols >= n {
                let want = cholesky_psd(&gram, n).unwrap();
                for k in 0..n * n {
                    assert_relative_eq!(l[k], want[k], epsilon = 1e-10, max_relative = 1e-10);
                }
            }
            for i in 0..n {
                assert!(l[i * (n + 1)] >= 0.0);
                for j in i + 1..n {
                    assert!(l[i + j * n].to_bits() == 0, "upper triangle");
                }
            }
        }
    }

    #[test]
    fn lq_lower_skips_the_zeros_of_a_triangular_tail() {
        for (n, dense) in [(4, 8), (12, 24), (3, 24), (6, 3), (18, 36), (29, 58)] {
            let cols = dense + n;
            let mut a: Vec<f64> = (0..n * cols)
                .map(|k| ((k * 5 + 1) % 13) as f64 - 6.0)
                .collect();
            for t in 0..n {
                for i in 0..t {
                    a[i + (dense + t) * n] = 0.0; // lower-triangular tail
                }
            }
            let (l0, l1) = (lq_of(&a, n, cols, cols), lq_of(&a, n, cols, dense));
            for k in 0..n * n {
                assert_relative_eq!(l0[k], l1[k], epsilon = 1e-12, max_relative = 1e-12);
            }
            // and a tail that is not triangular is not what the skipping version computes
            a[(dense + n - 1) * n] = 3.0;
            let (l0, l1) = (lq_of(&a, n, cols, cols), lq_of(&a, n, cols, dense));
            assert!(l0.iter().zip(&l1).any(|(x, y)| (x - y).abs() > 1e-6));
        }
    }

    #[test]
    fn lq_lower_reads_only_its_columns_of_a_longer_workspace() {
        // columns past `cols` (here NaN) are neither read nor written, with and without a
        // triangular tail
        for (n, dense, cols) in [(12, 24, 36), (4, 8, 12), (7, 5, 12), (6, 10, 10)] {
            let ld = padded(n);
            let mut a = vec![0.0; ld * cols];
            for j in 0..cols {
                for i in 0..n {
                    a[i + j * ld] = if j >= dense && i < j - dense {
                        0.0
                    } else {
                        ((i * 3 + j * 7) % 11) as f64 - 5.0
                    };
                }
            }
            let mut long = a.clone();
            long.extend(std::iter::repeat_n(f64::NAN, 3 * ld));
            let (mut w, mut l0, mut l1) = (vec![0.0; ld], vec![0.0; n * n], vec![0.0; n * n]);
            lq_lower(&mut a, n, cols, dense, &mut w, &mut l0);
            lq_lower(&mut long, n, cols, dense, &mut w, &mut l1);
            assert_eq!(l0, l1, "n = {n}");
            assert!(long[ld * cols..].iter().all(|v| v.is_nan()));
        }
    }

    #[test]
    fn many_updates_equal_one_at_a_time_bit_for_bit() {
        // six vectors: more than one rotation group of the fixed-size kernel
        for (n, ld) in [(7, 8), (8, 8), (12, 13)] {
            let l = cholesky_psd(&spd(n, 5), n).unwrap();
            let count = 6;
            let vs: Vec<f64> = (0..ld * count)
                .map(|k| 0.02 * ((k * 3 + 1) as f64).sin())
                .collect();
            for sign in [1.0, -1.0] {
                let (mut one, mut many) = (l.clone(), l.clone());
                let mut w = vs.clone();
                cholupdate_columns(&mut many, n, &mut w, ld, count, sign).unwrap();
                for m in 0..count {
                    let mut v = vs[m * ld..m * ld + n].to_vec();
                    cholupdate(&mut one, n, &mut v, sign).unwrap();
                }
                assert_eq!(one, many, "n = {n}");
            }
        }
    }

    #[test]
    fn triangular_solves_invert_the_factor() {
        let n = 5;
        let l = cholesky_psd(&spd(n, 9), n).unwrap();
        let x: Vec<f64> = (0..n).map(|i| i as f64 - 2.0).collect();
        let mut b = vec![0.0; n];
        for i in 0..n {
            b[i] = (0..=i).map(|k| l[i + k * n] * x[k]).sum();
        }
        solve_lower(&l, n, &mut b);
        for i in 0..n {
            assert_relative_eq!(b[i], x[i], epsilon = 1e-12);
        }
        for i in 0..n {
            b[i] = (i..n).map(|k| l[k + i * n] * x[k]).sum();
        }
        solve_lower_transpose(&l, n, &mut b);
        for i in 0..n {
            assert_relative_eq!(b[i], x[i], epsilon = 1e-12);
        }
    }

    #[test]
    fn nearest_spd_repairs_an_indefinite_matrix() {
        let n = 2;
        let p = vec![1.0, 2.0, 2.0, 1.0]; // eigenvalues 3, −1
        let l = nearest_spd_factor(&p, n, 1e-9);
        let back = outer_lower(&l, n);
        // projection: eigenvalue −1 → ~0, so P ≈ 1.5·[1 1; 1 1]
        assert_relative_eq!(back[0], 1.5, epsilon = 1e-6);
        assert_relative_eq!(back[1], 1.5, epsilon = 1e-6);
        assert!(l[0] > 0.0 && l[3] > 0.0);
    }
}
