//! The filter's inner kernels: sigma points, means, the square root of a spread, the
//! closed-form spread of a linear measurement, and the triangular solves of the gain.

use super::super::linalg::{lq_lower, padded};
use super::super::models::LinearRows;
use crate::lanes::LANES;

/// The state count of a filter specialised for `N` states, `n` itself when `N` is 0 (the
/// general build). The specialised builds ([`SrUkf::step`] picks one by `n`) see every
/// length as a constant: their loops unroll and vectorise whole, with no remainder code or
/// bounds checks.
#[inline(always)]
pub(super) const fn dim<const N: usize>(n: usize) -> usize {
    if N == 0 {
        n
    } else {
        N
    }
}

/// Sigma points `[x, x + γ·S_j, x − γ·S_j]` (eq 3.11) into `chi`, one point per `n` values.
#[inline(always)]
pub(super) fn sigma_points<const N: usize>(x: &[f64], s: &[f64], gamma: f64, chi: &mut [f64]) {
    let n = dim::<N>(x.len());
    let x = &x[..n];
    let (c0, rest) = chi.split_at_mut(n);
    c0.copy_from_slice(x);
    let (plus, minus) = rest.split_at_mut(n * n);
    if N > 0 {
        // whole columns through local copies: no stores between loads that might alias
        let x: [f64; N] = x.try_into().expect("N values");
        let (plus, minus) = (plus.as_chunks_mut::<N>().0, minus.as_chunks_mut::<N>().0);
        for ((sj, p), m) in s.as_chunks::<N>().0.iter().zip(plus).zip(minus) {
            let sj = *sj;
            *p = std::array::from_fn(|r| x[r] + gamma * sj[r]);
            *m = std::array::from_fn(|r| x[r] - gamma * sj[r]);
        }
        return;
    }
    for ((sj, p), m) in s[..n * n]
        .chunks_exact(n)
        .zip(plus.chunks_exact_mut(n))
        .zip(minus.chunks_exact_mut(n))
    {
        for (((p, m), x), s) in p.iter_mut().zip(m.iter_mut()).zip(x).zip(sj) {
            *p = x + gamma * s;
            *m = x - gamma * s;
        }
    }
}

/// The mean of sigma points (eq 3.13) as `χ₀ + w·Σᵢ(χᵢ − χ₀)` into `mean` (the weights sum
/// to one, and this form does not cancel the ±1e6-weighted terms of the seed's α = 1e-3,
/// `W₀ ≈ −n/(α²n)`); `points` holds `χ₀` first, `w` is the weight of the others.
#[inline(always)]
pub(super) fn sigma_mean<const N: usize>(points: &[f64], w: f64, mean: &mut [f64]) {
    let n = dim::<N>(mean.len());
    let mean = &mut mean[..n];
    let (c0, rest) = points.split_at(n);
    if N > 0 {
        let c0: &[f64; N] = c0.try_into().expect("N values");
        let mut acc = [0.0; N];
        for col in rest.as_chunks::<N>().0 {
            for r in 0..N {
                acc[r] += col[r] - c0[r];
            }
        }
        for r in 0..N {
            mean[r] = c0[r] + w * acc[r];
        }
        return;
    }
    mean.fill(0.0);
    for col in rest.chunks_exact(n) {
        for ((acc, v), z) in mean.iter_mut().zip(col).zip(c0) {
            *acc += v - z;
        }
    }
    for (m, z) in mean.iter_mut().zip(c0) {
        *m = z + w * *m;
    }
}

/// `out = a·(v − m)` over the first `n = m.len()` entries.
#[inline(always)]
pub(super) fn scaled_difference<const N: usize>(a: f64, v: &[f64], m: &[f64], out: &mut [f64]) {
    let n = dim::<N>(m.len());
    for ((o, v), m) in out[..n].iter_mut().zip(&v[..n]).zip(&m[..n]) {
        *o = a * (v - m);
    }
}

/// `Z ← Z·L⁻ᵀ` for the `n × q` column-major `Z` (`n = z.len() / q`) and the lower `q × q`
/// `L`: each row of `Z` solves `L·zᵀ = rowᵀ` as [`solve_lower`] would, all rows at once
/// down the columns (eq 3.22's `P_xy / S_yᵀ`).
#[inline(always)]
pub(super) fn solve_rows_lower_transpose<const N: usize>(l: &[f64], q: usize, z: &mut [f64]) {
    if N > 0 {
        let z = z.as_chunks_mut::<N>().0;
        for j in 0..q {
            let d = l[j + j * q];
            let zj = z[j].map(|v| v / d);
            z[j] = zj;
            for (i, zi) in z[j + 1..q].iter_mut().enumerate() {
                let f = l[j + 1 + i + j * q];
                let mut v = *zi;
                for r in 0..N {
                    v[r] -= f * zj[r];
                }
                *zi = v;
            }
        }
        return;
    }
    let n = z.len() / q;
    for j in 0..q {
        let (done, rest) = z.split_at_mut((j + 1) * n);
        let zj = &mut done[j * n..];
        let d = l[j + j * q];
        for v in zj.iter_mut() {
            *v /= d;
        }
        for (i, zi) in rest.chunks_exact_mut(n).enumerate() {
            let f = l[j + 1 + i + j * q];
            for (a, b) in zi.iter_mut().zip(zj.iter()) {
                *a -= f * b;
            }
        }
    }
}

/// `x += Z·c` for the `n × q` column-major `Z` (`n = x.len()`), the sum formed first
/// (from zero, column by column) in `acc` (`n` long).
#[inline(always)]
pub(super) fn add_combination<const N: usize>(
    z: &[f64],
    c: &[f64],
    x: &mut [f64],
    acc: &mut [f64],
) {
    if N > 0 {
        let mut sum = [0.0; N];
        for (zc, rc) in z.as_chunks::<N>().0.iter().zip(c) {
            for r in 0..N {
                sum[r] += zc[r] * rc;
            }
        }
        for (x, a) in x[..N].iter_mut().zip(sum) {
            *x += a;
        }
        return;
    }
    let n = x.len();
    let acc = &mut acc[..n];
    acc.fill(0.0);
    for (zc, rc) in z.chunks_exact(n).zip(c) {
        for (a, v) in acc.iter_mut().zip(zc) {
            *a += v * rc;
        }
    }
    for (x, a) in x.iter_mut().zip(acc.iter()) {
        *x += a;
    }
}

/// `L = qr([√w·(pᵢ − mean)ᵢ, noise])ᵀ`, the square root of `w·Σᵢ(pᵢ − m)(pᵢ − m)ᵀ + N·Nᵀ`
/// (eqs 3.14 and 3.19): `points` are the consecutive non-central sigma points (`d` values
/// each, `d = mean.len()`), `noise` the lower `d × d` square root of the additive noise. The
/// compound is laid out one column per deviation in `comp` (see [`lq_lower`]).
#[inline(always)]
pub(super) fn square_root_of_spread<const D: usize>(
    comp: &mut [f64],
    points: &[f64],
    mean: &[f64],
    w_sqrt: f64,
    noise: &[f64],
    scratch: &mut [f64],
    l: &mut [f64],
) {
    let d = dim::<D>(mean.len());
    let mean = &mean[..d];
    let (ld, dense) = (padded(d), points.len() / d);
    let cols = dense + d;
    if D > 0 {
        // whole columns through local copies (as in `sigma_points`)
        let mean: [f64; D] = mean.try_into().expect("D values");
        let (dev, tail) = comp[..ld * cols].split_at_mut(ld * dense);
        for (col, p) in dev.chunks_exact_mut(ld).zip(points.as_chunks::<D>().0) {
            let p = *p;
            let c: [f64; D] = std::array::from_fn(|r| w_sqrt * (p[r] - mean[r]));
            col[..D].copy_from_slice(&c);
            col[D..].fill(0.0);
        }
        for (col, q) in tail.chunks_exact_mut(ld).zip(noise.as_chunks::<D>().0) {
            let q = *q;
            col[..D].copy_from_slice(&q);
            col[D..].fill(0.0);
        }
        lq_lower(&mut comp[..ld * cols], d, cols, dense, scratch, l);
        return;
    }
    for (i, col) in comp[..ld * cols].chunks_exact_mut(ld).enumerate() {
        let (col, pad) = col.split_at_mut(d);
        if i < dense {
            for ((c, v), m) in col.iter_mut().zip(&points[i * d..(i + 1) * d]).zip(mean) {
                *c = w_sqrt * (v - m);
            }
        } else {
            col.copy_from_slice(&noise[(i - dense) * d..(i - dense + 1) * d]);
        }
        pad.fill(0.0);
    }
    lq_lower(&mut comp[..ld * cols], d, cols, dense, scratch, l);
}

/// `H·S` (`S` is `n × n`) into the first `n` columns of the compound (column `j`: row `a` is
/// `h_s(obs[a], j, S[:, j])`), a SIMD block of rows at a time with the padding zeros (a
/// short fill of runtime length would be a library call per column).
#[inline(always)]
pub(super) fn fill_h_s(
    comp: &mut [f64],
    ld: usize,
    n: usize,
    s: &[f64],
    obs: &[usize],
    h_s: impl Fn(usize, usize, &[f64]) -> f64,
) {
    let q = obs.len();
    for (j, (col, sj)) in comp[..ld * n]
        .chunks_exact_mut(ld)
        .zip(s.chunks_exact(n))
        .enumerate()
    {
        for (b, block) in col.as_chunks_mut::<LANES>().0.iter_mut().enumerate() {
            *block = std::array::from_fn(|t| {
                let a = b * LANES + t;
                if a < q {
                    h_s(obs[a], j, sj)
                } else {
                    0.0
                }
            });
        }
    }
}

/// `ŷ`, `S_y` and `P_xy` of a linear measurement `y = H·x` in closed form, for the rows
/// `obs` of `H`. Sigma points `x̂ ± γ·S_j` through `H` give `Yᵢ − ŷ = ±γ·(H·S)_j` and
/// `Y₀ − ŷ = 0` (eqs 3.16–3.18), so with `2·W_c·γ² = 1` the compound of eq 3.19 holds each
/// column of `H·S` twice, scaled by `±1/√2`: `S_y = qr([H·S, √R])` (eq 3.20's 0th point adds
/// nothing) and `P_xy = S·(H·S)ᵀ` (eq 3.21). Exact arithmetic gives the sigma-point result;
/// rounding is smaller (no `±γ` deviations from `x̂` to subtract).
#[inline(always)]
pub(super) fn linear_spread<const N: usize>(
    lin: LinearRows<'_>,
    obs: &[usize],
    x: &[f64],
    s: &[f64],
    sr: &[f64],
    comp: &mut [f64],
    scratch: &mut [f64],
    yhat: &mut [f64],
    sy: &mut [f64],
    pxy: &mut [f64],
) {
    let (n, q) = (dim::<N>(x.len()), obs.len());
    let ld = padded(q);
    // H·S (column j: row a = H[obs[a], :]·S[:, j])
    match lin.pick {
        Some(pick) => fill_h_s(comp, ld, n, s, obs, |k, _, sj| sj[pick[k]]),
        None => fill_h_s(comp, ld, n, s, obs, |k, j, sj| {
            (j..n).map(|i| lin.h[k * n + i] * sj[i]).sum()
        }),
    }
    for (a, &k) in obs.iter().enumerate() {
        yhat[a] = lin.row_times(k, x);
    }
    // P_xy = S·(H·S)ᵀ, column-major n × q, over whole columns of S (the zeros above its
    // diagonal add exact zeros); exact zeros of H·S (a selected state's row right of its
    // diagonal) are skipped. For N states each column is summed in a local array.
    if N > 0 {
        let s = s.as_chunks::<N>().0;
        for (a, p) in pxy[..N * q].as_chunks_mut::<N>().0.iter_mut().enumerate() {
            let mut acc = [0.0; N];
            for (j, sj) in s.iter().enumerate() {
                let h = comp[a + j * ld];
                if h == 0.0 {
                    continue;
                }
                for r in 0..N {
                    acc[r] += sj[r] * h;
                }
            }
            *p = acc;
        }
    } else {
        for (a, p) in pxy.chunks_exact_mut(n).enumerate() {
            p.fill(0.0);
            for (j, sj) in s.chunks_exact(n).enumerate() {
                let h = comp[a + j * ld];
                if h == 0.0 {
                    continue;
                }
                for (p, v) in p.iter_mut().zip(sj) {
                    *p += v * h;
                }
            }
        }
    }
    for (t, col) in comp[ld * n..ld * (n + q)].chunks_exact_mut(ld).enumerate() {
        let src = &sr[t * q..(t + 1) * q];
        for (b, block) in col.as_chunks_mut::<LANES>().0.iter_mut().enumerate() {
            *block = std::array::from_fn(|r| src.get(b * LANES + r).copied().unwrap_or(0.0));
        }
    }
    lq_lower(&mut comp[..ld * (n + q)], q, n + q, n, scratch, sy);
}
