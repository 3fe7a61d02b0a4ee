//! The square-root unscented Kalman filter of van der Merwe (seed 001, eqs 3.9–3.25).

use super::linalg::{
    cholesky_psd, cholupdate, cholupdate_columns_sized, cholupdate_or_repair, lq_lower,
    nearest_spd_factor, outer_lower, padded, repaired_factor, solve_lower,
};
use super::models::{LinearRows, Observe, Process};
use crate::error::{check, CableError, Result};
use crate::lanes::{cpu_has_avx2, Aligned, LANES};

/// Sigma-point scaling (seed 001: α = 1e-3, β = 2, κ = 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SigmaScaling {
    /// Spread of the sigma points around the mean, `0 < α ≤ 1`.
    pub alpha: f64,
    /// Prior knowledge of the distribution (2 is optimal for Gaussians).
    pub beta: f64,
    /// Secondary scaling, `n + κ > 0`.
    pub kappa: f64,
}

impl Default for SigmaScaling {
    fn default() -> Self {
        Self {
            alpha: 1e-3,
            beta: 2.0,
            kappa: 0.0,
        }
    }
}

/// The scaled unscented transform's weights for `n` states.
#[derive(Debug, Clone, PartialEq)]
pub struct Weights {
    /// `γ = √(n + λ)`.
    pub gamma: f64,
    /// Mean weights `W(m)_0`, `W(m)_i` (i ≥ 1).
    pub wm: (f64, f64),
    /// Covariance weights `W(c)_0` (negative for small α), `W(c)_i`.
    pub wc: (f64, f64),
}

impl Weights {
    /// Merwe's scaled weights: `λ = α²(n + κ) − n`.
    pub fn new(n: usize, s: SigmaScaling) -> Result<Self> {
        if !(s.alpha > 0.0 && s.alpha <= 1.0) {
            return Err(CableError::InvalidParameter {
                name: "alpha".into(),
                value: s.alpha,
                requirement: "in (0, 1]",
            });
        }
        check::finite("beta", s.beta)?;
        let nf = n as f64;
        if nf + s.kappa <= 0.0 || !s.kappa.is_finite() {
            return Err(CableError::InvalidParameter {
                name: "kappa".into(),
                value: s.kappa,
                requirement: "finite with n + kappa > 0",
            });
        }
        let lambda = s.alpha * s.alpha * (nf + s.kappa) - nf;
        let wi = 1.0 / (2.0 * (nf + lambda));
        let wm0 = lambda / (nf + lambda);
        Ok(Self {
            gamma: (nf + lambda).sqrt(),
            wm: (wm0, wi),
            wc: (wm0 + 1.0 - s.alpha * s.alpha + s.beta, wi),
        })
    }
}

/// Health of the last step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Health {
    /// Normalised innovation squared `νᵀ·P_yy⁻¹·ν` of the last update (NaN without one); its
    /// mean is the number of measured channels when the filter is consistent.
    pub nis: f64,
    /// Measured channels in the last update.
    pub measured: usize,
    /// Estimate of the state covariance's condition number, `(max Sᵢᵢ / min Sᵢᵢ)²`.
    pub condition: f64,
    /// Failed Cholesky downdates recovered in the last step.
    pub recovered: u32,
    /// Failed downdates recovered since construction.
    pub recoveries_total: u64,
    /// Whether the last update was rejected by the innovation gate (its NIS above
    /// [`SrUkf::set_nis_gate`]'s threshold): the state is the prediction.
    pub gated: bool,
    /// Updates rejected by the gate since construction.
    pub rejected_total: u64,
    /// Steps since construction or [`SrUkf::reset`] (a failed step does not count).
    pub steps: u64,
}

/// Square-root UKF over a [`Process`] and an [`Observe`] model. `x` and the lower-triangular
/// `S` (`P = S·Sᵀ`) are the state; `step(u, y, mask)` predicts over one period with `u` and
/// updates with the measured entries of `y`. Stepping allocates nothing unless a downdate
/// fails (then `P` is rebuilt and projected onto the positive definite cone).
#[derive(Debug, Clone)]
pub struct SrUkf<P: Process, H: Observe> {
    /// Process model.
    pub process: P,
    /// Measurement model.
    pub observe: H,
    n: usize,
    p: usize,
    w: Weights,
    x: Aligned,
    s: Aligned,
    sq: Aligned,
    r_full: Aligned,
    sr: Aligned,
    health: Health,
    // workspaces
    chi: Aligned,
    ysig: Aligned,
    comp: Aligned,
    lqv: Aligned,
    ucols: Aligned,
    dev: Aligned,
    /// The 0th point's pending downdate vector (see [`SrUkf::step`]).
    v0: Aligned,
    s_saved: Aligned,
    vsave: Aligned,
    sy: Aligned,
    sr_obs: Aligned,
    pxy: Aligned,
    yhat: Aligned,
    nu: Aligned,
    obs: Vec<usize>,
    last_mask: Vec<bool>,
    /// `(x, S)` before the running step, restored when it fails.
    x_prev: Aligned,
    s_prev: Aligned,
    /// NIS above which an update is rejected (+∞: never).
    gate: f64,
    avx2: bool,
}

/// The state count of a filter specialised for `N` states, `n` itself when `N` is 0 (the
/// general build). The specialised builds ([`SrUkf::step`] picks one by `n`) see every
/// length as a constant: their loops unroll and vectorise whole, with no remainder code or
/// bounds checks.
#[inline(always)]
const fn dim<const N: usize>(n: usize) -> usize {
    if N == 0 {
        n
    } else {
        N
    }
}

/// Sigma points `[x, x + γ·S_j, x − γ·S_j]` (eq 3.11) into `chi`, one point per `n` values.
#[inline(always)]
fn sigma_points<const N: usize>(x: &[f64], s: &[f64], gamma: f64, chi: &mut [f64]) {
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
fn sigma_mean<const N: usize>(points: &[f64], w: f64, mean: &mut [f64]) {
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
fn scaled_difference<const N: usize>(a: f64, v: &[f64], m: &[f64], out: &mut [f64]) {
    let n = dim::<N>(m.len());
    for ((o, v), m) in out[..n].iter_mut().zip(&v[..n]).zip(&m[..n]) {
        *o = a * (v - m);
    }
}

/// `Z ← Z·L⁻ᵀ` for the `n × q` column-major `Z` (`n = z.len() / q`) and the lower `q × q`
/// `L`: each row of `Z` solves `L·zᵀ = rowᵀ` as [`solve_lower`] would, all rows at once
/// down the columns (eq 3.22's `P_xy / S_yᵀ`).
#[inline(always)]
fn solve_rows_lower_transpose<const N: usize>(l: &[f64], q: usize, z: &mut [f64]) {
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
fn add_combination<const N: usize>(z: &[f64], c: &[f64], x: &mut [f64], acc: &mut [f64]) {
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
fn square_root_of_spread<const D: usize>(
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
fn fill_h_s(
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
fn linear_spread<const N: usize>(
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

fn square(name: &str, m: &[f64], n: usize) -> Result<()> {
    check::len(name, m, n * n)?;
    check::all_finite(name, m, n)
}

/// Lower Cholesky factor of a symmetric (row- or column-major alike) covariance.
fn factor(name: &str, m: &[f64], n: usize, definite: bool) -> Result<Vec<f64>> {
    square(name, m, n)?;
    for i in 0..n {
        for j in 0..i {
            let (a, b) = (m[i + j * n], m[j + i * n]);
            if (a - b).abs() > 1e-9 * (a.abs() + b.abs()).max(1e-300) {
                return Err(CableError::InvalidParameter {
                    name: format!("{name}[{i}][{j}]"),
                    value: a,
                    requirement: "symmetric (equal to its transpose)",
                });
            }
        }
    }
    let l = cholesky_psd(m, n).map_err(|row| CableError::InvalidParameter {
        name: format!("{name} (Cholesky pivot at row {row})"),
        value: m[row + row * n],
        requirement: "positive semi-definite",
    })?;
    if definite {
        if let Some(i) = (0..n).find(|&i| l[i + i * n] <= 0.0) {
            return Err(CableError::InvalidParameter {
                name: format!("{name} (Cholesky pivot at row {i})"),
                value: m[i + i * n],
                requirement: "positive definite",
            });
        }
    }
    Ok(l)
}

impl<P: Process, H: Observe> SrUkf<P, H> {
    /// A filter at mean `x0` with covariance `p0` (positive definite), process noise
    /// covariance `q` (positive semi-definite) and measurement noise covariance `r` (positive
    /// definite); matrices `n × n` / `p × p`, symmetric, in either storage order.
    pub fn new(
        process: P,
        observe: H,
        x0: &[f64],
        p0: &[f64],
        q: &[f64],
        r: &[f64],
        scaling: SigmaScaling,
    ) -> Result<Self> {
        let n = process.n_states();
        let p = observe.n_outputs();
        check::len("x0", x0, n)?;
        check::all_finite("x0", x0, 1)?;
        let s = factor("P0", p0, n, true)?;
        let sq = factor("Q", q, n, false)?;
        let sr = factor("R", r, p, true)?;
        let w = Weights::new(n, scaling)?;
        let ns = 2 * n + 1;
        let cols = 2 * n + n.max(p);
        Ok(Self {
            process,
            observe,
            n,
            p,
            w,
            x: Aligned::from_slice(x0),
            s: s.into(),
            sq: sq.into(),
            r_full: Aligned::from_slice(r),
            sr_obs: Aligned::from_slice(&sr),
            sr: sr.into(),
            health: Health {
                nis: f64::NAN,
                ..Health::default()
            },
            chi: Aligned::zeros(n * ns),
            ysig: Aligned::zeros(p * ns),
            comp: Aligned::zeros(padded(n.max(p)) * cols),
            lqv: Aligned::zeros(padded(n.max(p))),
            ucols: Aligned::zeros(n * (p + 1)),
            dev: Aligned::zeros(n.max(p)),
            v0: Aligned::zeros(n),
            s_saved: Aligned::zeros(n * n),
            vsave: Aligned::zeros(n.max(p)),
            sy: Aligned::zeros(p * p),
            pxy: Aligned::zeros(n * p),
            yhat: Aligned::zeros(p),
            nu: Aligned::zeros(p),
            obs: (0..p).collect(),
            last_mask: vec![true; p],
            x_prev: Aligned::zeros(n),
            s_prev: Aligned::zeros(n * n),
            gate: f64::INFINITY,
            avx2: cpu_has_avx2(),
        })
    }

    /// State dimension.
    pub fn n_states(&self) -> usize {
        self.n
    }
    /// Measurement dimension.
    pub fn n_outputs(&self) -> usize {
        self.p
    }
    /// Current mean.
    pub fn x(&self) -> &[f64] {
        &self.x
    }
    /// Current lower-triangular square root of the covariance (column-major `n × n`).
    pub fn sqrt_covariance(&self) -> &[f64] {
        &self.s
    }
    /// Current covariance `S·Sᵀ` (column-major; symmetric).
    pub fn covariance(&self) -> Vec<f64> {
        outer_lower(&self.s, self.n)
    }
    /// Weights in use.
    pub fn weights(&self) -> &Weights {
        &self.w
    }
    /// Health of the last step.
    pub fn health(&self) -> Health {
        self.health
    }

    /// Replace mean and covariance (e.g. to restart); `p` must be positive definite.
    pub fn reset(&mut self, x: &[f64], p: &[f64]) -> Result<()> {
        check::len("x", x, self.n)?;
        check::all_finite("x", x, 1)?;
        self.s.copy_from_slice(&factor("P", p, self.n, true)?);
        self.x.copy_from_slice(x);
        self.health.steps = 0;
        Ok(())
    }

    /// Sigma points of the current `(x, S)` into `chi` (column `i` = point `i`).
    #[inline(always)]
    fn sigma_points<const N: usize>(&mut self) {
        sigma_points::<N>(&self.x, &self.s, self.w.gamma, &mut self.chi);
    }

    /// Record a failed downdate and rebuild `S` from `S_saved·S_savedᵀ + Σ signᵢ·vᵢ·vᵢᵀ`.
    fn recover(&mut self, updates: &[(&[f64], f64)]) {
        let repaired = repaired_factor(&self.s_saved, self.n, updates);
        self.s.copy_from_slice(&repaired);
        self.health.recovered += 1;
        self.health.recoveries_total += 1;
    }

    /// Time update (eqs 3.11–3.15) with input `u` held over the period.
    pub fn predict(&mut self, u: &[f64]) -> Result<()> {
        check::len("u", u, self.process.n_inputs())?;
        check::all_finite("u", u, 1)?;
        self.save();
        self.health.recovered = 0;
        self.predict_unchecked::<0>(u);
        let done = self.check_state::<0>();
        self.settle(done)
    }

    /// Undo the last successful step (put back the `(x, S)` it started from): for a caller
    /// whose compound step failed after this filter's part (the dual filter).
    pub(crate) fn undo_last_step(&mut self) {
        self.x.copy_from_slice(&self.x_prev);
        self.s.copy_from_slice(&self.s_prev);
        self.health.steps = self.health.steps.saturating_sub(1);
    }

    /// Keep `(x, S)` so that a failing step can be undone ([`Self::settle`]).
    #[inline(always)]
    fn save(&mut self) {
        self.x_prev.copy_from_slice(&self.x);
        self.s_prev.copy_from_slice(&self.s);
    }

    /// After a step: count it, or put `(x, S)` back as they were before it and report the
    /// divergence with the step's number.
    #[inline(always)]
    fn settle(&mut self, done: Result<()>) -> Result<()> {
        match done {
            Ok(()) => {
                self.health.steps += 1;
                Ok(())
            }
            Err(_) => {
                self.x.copy_from_slice(&self.x_prev);
                self.s.copy_from_slice(&self.s_prev);
                Err(CableError::FilterDiverged {
                    step: self.health.steps as usize,
                })
            }
        }
    }

    /// Innovation gating: an update whose normalised innovation squared `νᵀP_yy⁻¹ν` exceeds
    /// `nis_max` is rejected (the state stays the prediction) and counted in [`Health`]
    /// (`gated`, `rejected_total`). The NIS of `q` consistent channels is χ²(q) distributed:
    /// e.g. 23.9 is its 1 − 1e-5 quantile for q = 3. `None` (the default) never gates.
    pub fn set_nis_gate(&mut self, nis_max: Option<f64>) -> Result<()> {
        self.gate = match nis_max {
            None => f64::INFINITY,
            Some(g) => check::positive("nis_gate", g)?,
        };
        Ok(())
    }

    /// The innovation gate's threshold (+∞ when off).
    pub fn nis_gate(&self) -> f64 {
        self.gate
    }

    #[inline(always)]
    fn predict_unchecked<const N: usize>(&mut self, u: &[f64]) {
        self.predict_spread::<N>(u);
        // 0th point, weight possibly negative: update or downdate (eq 3.15)
        let (n, wc0) = (dim::<N>(self.n), self.w.wc.0);
        if wc0 != 0.0 {
            scaled_difference::<N>(wc0.abs().sqrt(), &self.chi[..n], &self.x, &mut self.dev);
            self.rank_one::<N>(n, wc0.signum());
        }
    }

    /// The time update up to its 0th point: mean (eq 3.13) and `S` of eq 3.14.
    #[inline(always)]
    fn predict_spread<const N: usize>(&mut self, u: &[f64]) {
        let n = dim::<N>(self.n);
        let ns = 2 * n + 1;
        self.sigma_points::<N>();
        self.process.propagate_many(&mut self.chi[..ns * n], u);
        // mean (eq 3.13) as χ₀ + Σ Wᵢ(χᵢ − χ₀): the weights sum to one, and this form does not
        // cancel the ±1e6-weighted terms of the seed's α = 1e-3 (W₀ ≈ −n/(α²n))
        sigma_mean::<N>(&self.chi[..ns * n], self.w.wm.1, &mut self.x);
        self.process.project(&mut self.x);
        // S = qr([√Wc·(χ_1:2n − x̂), √Q]) (eq 3.14)
        let swc = self.w.wc.1.sqrt();
        square_root_of_spread::<N>(
            &mut self.comp,
            &self.chi[n..ns * n],
            &self.x,
            swc,
            &self.sq,
            &mut self.lqv,
            &mut self.s,
        );
    }

    /// `S ← cholupdate(S, dev[..n], sign)`, recovering from a failed downdate.
    #[inline(always)]
    fn rank_one<const N: usize>(&mut self, n: usize, sign: f64) {
        self.s_saved.copy_from_slice(&self.s);
        self.vsave[..n].copy_from_slice(&self.dev[..n]);
        if cholupdate_columns_sized::<N>(&mut self.s, n, &mut self.dev[..n], n, 1, sign).is_err() {
            let v = std::mem::take(&mut self.vsave);
            self.recover(&[(&v[..n], sign)]);
            self.vsave = v;
        }
    }

    /// Measurement update (eqs 3.16–3.25) with the entries of `y` where `mask` is true (all
    /// when `mask` is `None`); `u` is passed to the measurement model.
    pub fn update(&mut self, u: &[f64], y: &[f64], mask: Option<&[bool]>) -> Result<()> {
        self.check_measurement(y, mask)?;
        self.save();
        self.update_unchecked::<0>(u, y, mask);
        let done = self.check_state::<0>();
        self.settle(done)
    }

    /// `y` and `mask` of the right lengths, `y` finite where measured.
    fn check_measurement(&self, y: &[f64], mask: Option<&[bool]>) -> Result<()> {
        check::len("y", y, self.p)?;
        if let Some(m) = mask {
            if m.len() != self.p {
                return Err(CableError::Shape {
                    what: "mask".into(),
                    expected: format!("({},)", self.p),
                    got: format!("({},)", m.len()),
                });
            }
        }
        for i in 0..self.p {
            let on = mask.is_none_or(|m| m[i]);
            if on && !y[i].is_finite() {
                return Err(CableError::NotFinite {
                    what: "y (mask the missing channels instead)".into(),
                    index: i,
                    value: y[i],
                    location: String::new(),
                });
            }
        }
        Ok(())
    }

    fn set_mask(&mut self, mask: Option<&[bool]>) {
        let p = self.p;
        let same = match mask {
            None => self.last_mask.iter().all(|&b| b),
            Some(m) => m == self.last_mask.as_slice(),
        };
        if same {
            return;
        }
        match mask {
            None => self.last_mask.iter_mut().for_each(|b| *b = true),
            Some(m) => self.last_mask.copy_from_slice(m),
        }
        self.obs.clear();
        self.obs.extend((0..p).filter(|&i| self.last_mask[i]));
        let q = self.obs.len();
        if q == p {
            self.sr_obs.copy_from_slice(&self.sr);
            return;
        }
        // √R of the observed block: factor R[obs, obs] (allocates only when the mask changes)
        let mut sub = vec![0.0; q * q];
        for (a, &i) in self.obs.iter().enumerate() {
            for (b, &j) in self.obs.iter().enumerate() {
                sub[a + b * q] = self.r_full[i + j * p];
            }
        }
        let l = cholesky_psd(&sub, q).unwrap_or_else(|_| nearest_spd_factor(&sub, q, 1e-12));
        self.sr_obs[..q * q].copy_from_slice(&l);
    }

    /// `ŷ`, `S_y` and `P_xy` from the sigma points of the predicted `(x, S)` (eqs 3.16–3.21)
    /// for the observed channels `obs`.
    fn sigma_spread(&mut self, u: &[f64]) {
        let (n, p, q) = (self.n, self.p, self.obs.len());
        let ns = 2 * n + 1;
        // redraw sigma points from the predicted (x, S) (eq 3.16) and measure them (eq 3.17)
        self.sigma_points::<0>();
        let mut full = std::mem::take(&mut self.nu); // p-long scratch
        for i in 0..ns {
            self.observe
                .observe(&self.chi[i * n..(i + 1) * n], u, &mut full[..p]);
            for (a, &k) in self.obs.iter().enumerate() {
                self.ysig[a + i * q] = full[k];
            }
        }
        self.nu = full;
        let wmi = self.w.wm.1;
        for a in 0..q {
            let y0 = self.ysig[a];
            let mut acc = 0.0;
            for i in 1..ns {
                acc += self.ysig[a + i * q] - y0;
            }
            self.yhat[a] = y0 + wmi * acc; // eq 3.18, summed as the mean above
        }
        // S_y = qr([√Wc·(Y − ŷ), √R]) (eq 3.19), then the 0th point (eq 3.20)
        let swc = self.w.wc.1.sqrt();
        square_root_of_spread::<0>(
            &mut self.comp,
            &self.ysig[q..ns * q],
            &self.yhat[..q],
            swc,
            &self.sr_obs[..q * q],
            &mut self.lqv,
            &mut self.sy[..q * q],
        );
        let wc0 = self.w.wc.0;
        if wc0 != 0.0 {
            let a = wc0.abs().sqrt();
            for c in 0..q {
                self.dev[c] = a * (self.ysig[c] - self.yhat[c]);
            }
            let mut sy = std::mem::take(&mut self.sy);
            if cholupdate(&mut sy[..q * q], q, &mut self.dev[..q], wc0.signum()).is_err() {
                // rebuild P_yy from the deviations and repair it
                let mut pyy = vec![0.0; q * q];
                for i in 0..ns {
                    let wi = if i == 0 { wc0 } else { self.w.wc.1 };
                    for b in 0..q {
                        for a in 0..q {
                            pyy[a + b * q] += wi
                                * (self.ysig[a + i * q] - self.yhat[a])
                                * (self.ysig[b + i * q] - self.yhat[b]);
                        }
                    }
                }
                let sr2 = outer_lower(&self.sr_obs[..q * q], q);
                for k in 0..q * q {
                    pyy[k] += sr2[k];
                }
                sy[..q * q].copy_from_slice(&nearest_spd_factor(&pyy, q, 1e-12));
                self.health.recovered += 1;
                self.health.recoveries_total += 1;
            }
            self.sy = sy;
        }
        // P_xy (eq 3.21), column-major n × q: Σᵢ Wᵢ·(χᵢ − x̂)·(Yᵢ − ŷ)ᵀ, accumulated point by
        // point over contiguous columns
        let (wc0, wci) = self.w.wc;
        self.pxy[..n * q].fill(0.0);
        let dx = &mut self.ucols[..n]; // scratch until the downdate below
        for i in 0..ns {
            let w = if i == 0 { wc0 } else { wci };
            for ((d, xv), xm) in dx
                .iter_mut()
                .zip(&self.chi[i * n..(i + 1) * n])
                .zip(&self.x)
            {
                *d = w * (xv - xm);
            }
            for (c, col) in self.pxy[..n * q].chunks_exact_mut(n).enumerate() {
                let dy = self.ysig[c + i * q] - self.yhat[c];
                for (p, d) in col.iter_mut().zip(dx.iter()) {
                    *p += d * dy;
                }
            }
        }
    }

    #[inline(always)]
    fn update_unchecked<const N: usize>(&mut self, u: &[f64], y: &[f64], mask: Option<&[bool]>) {
        self.set_mask(mask);
        let q = self.obs.len();
        self.health.measured = q;
        self.health.gated = false;
        if q == 0 {
            self.health.nis = f64::NAN;
            return;
        }
        if !self.closed_form_spread::<N>() {
            self.sigma_spread(u);
        }
        self.finish_update::<N>(y, false);
    }

    /// `ŷ`, `S_y` and `P_xy` of a linear measurement from `(x, S)` ([`linear_spread`]);
    /// false (nothing done) when the measurement is not linear.
    #[inline(always)]
    fn closed_form_spread<const N: usize>(&mut self) -> bool {
        let Some(lin) = self.observe.linear() else {
            return false;
        };
        let (n, q) = (dim::<N>(self.n), self.obs.len());
        linear_spread::<N>(
            lin,
            &self.obs,
            &self.x,
            &self.s,
            &self.sr_obs[..q * q],
            &mut self.comp,
            &mut self.lqv,
            &mut self.yhat[..q],
            &mut self.sy[..q * q],
            &mut self.pxy[..n * q],
        );
        true
    }

    /// The measurement update of [`SrUkf::step`] when the time update's 0th point left its
    /// downdate `S⁻ = cholupdate(S', v₀, −1)` pending in `v0` (negative `W(c)_0`, linear
    /// measurement): `P⁻ = S'S'ᵀ − v₀v₀ᵀ`, so `S_y = cholupdate(qr([H·S', √R]), H·v₀, −1)`
    /// (a `q × q` downdate), `P_xy = S'·(H·S')ᵀ − v₀·(H·v₀)ᵀ`, and eq 3.25 becomes one
    /// downdate of `S'` by `[v₀, U]`, whose rotations run in one pass down `S'`. Exact
    /// arithmetic gives the update after the 0th point's downdate. When there is nothing to
    /// measure, or `S_y`'s downdate fails, the 0th point's downdate runs first as in
    /// [`SrUkf::predict`] and the update as in [`SrUkf::update`].
    #[inline(always)]
    fn update_folded<const N: usize>(&mut self, u: &[f64], y: &[f64], mask: Option<&[bool]>) {
        self.set_mask(mask);
        if self.obs.is_empty() || !self.folded_spread::<N>() {
            let n = dim::<N>(self.n);
            self.dev[..n].copy_from_slice(&self.v0[..n]);
            self.rank_one::<N>(n, -1.0);
            self.update_unchecked::<N>(u, y, mask);
            return;
        }
        self.health.measured = self.obs.len();
        self.health.gated = false;
        self.finish_update::<N>(y, true);
    }

    /// `ŷ`, `S_y` and `P_xy` of [`Self::update_folded`]; false when `S_y`'s downdate fails
    /// (`H·P⁻·Hᵀ + R` not positive definite in floating point).
    #[inline(always)]
    fn folded_spread<const N: usize>(&mut self) -> bool {
        let n = dim::<N>(self.n);
        let q = self.obs.len();
        let linear = self.closed_form_spread::<N>();
        debug_assert!(linear, "folded only for linear measurements");
        let lin = self.observe.linear().expect("a linear measurement");
        let (v0, hv) = (&self.v0[..n], &mut self.nu[..q]); // nu: scratch until the innovation
        for (a, &k) in self.obs.iter().enumerate() {
            hv[a] = lin.row_times(k, v0);
        }
        for (p, &h) in self.pxy[..n * q].chunks_exact_mut(n).zip(hv.iter()) {
            for (p, v) in p.iter_mut().zip(v0) {
                *p -= v * h;
            }
        }
        cholupdate(&mut self.sy[..q * q], q, hv, -1.0).is_ok()
    }

    /// Eqs 3.22–3.25 from `ŷ`, `S_y` and `P_xy`; `folded`: the 0th point's downdate `v0` is
    /// pending ([`Self::update_folded`]) and joins eq 3.25's.
    #[inline(always)]
    fn finish_update<const N: usize>(&mut self, y: &[f64], folded: bool) {
        let n = dim::<N>(self.n);
        let q = self.obs.len();
        // K = (P_xy / S_yᵀ) / S_y (eq 3.22): Z = P_xy·S_y⁻ᵀ, each row solving S_y·zᵀ = p_xyᵀ
        // as `solve_lower` would, all rows at once down the columns; then K = Z·S_y⁻¹
        let sy = &self.sy[..q * q];
        solve_rows_lower_transpose::<N>(sy, q, &mut self.pxy[..n * q]); // Z = U (eq 3.24: U = K·S_y)
        let mut row = std::mem::take(&mut self.dev);
        // innovation and NIS = |S_y⁻¹ν|²
        for (a, &k) in self.obs.iter().enumerate() {
            self.nu[a] = y[k] - self.yhat[a];
        }
        row[..q].copy_from_slice(&self.nu[..q]);
        solve_lower(sy, q, &mut row[..q]);
        self.health.nis = row[..q].iter().map(|v| v * v).sum();
        if self.health.nis > self.gate {
            // rejected: keep the prediction (with the 0th point's pending downdate applied)
            self.dev = row;
            self.health.gated = true;
            self.health.rejected_total += 1;
            if folded {
                self.dev[..n].copy_from_slice(&self.v0[..n]);
                self.rank_one::<N>(n, -1.0);
            }
            return;
        }
        // x += K·ν = Z·(S_y⁻¹ν)   (K·ν = Z·S_y⁻¹·ν), summed over the columns of Z
        add_combination::<N>(&self.pxy[..n * q], &row[..q], &mut self.x, &mut self.ucols);
        self.dev = row;
        self.process.project(&mut self.x);
        // S ← cholupdate(S, U, −1), the q columns of U interleaved (eq 3.25), after v₀
        // when folded
        self.s_saved.copy_from_slice(&self.s);
        let lead = if folded { n } else { 0 };
        self.ucols[..lead].copy_from_slice(&self.v0[..lead]);
        self.ucols[lead..lead + n * q].copy_from_slice(&self.pxy[..n * q]);
        let (cols, count) = (&mut self.ucols[..lead + n * q], q + usize::from(folded));
        if cholupdate_columns_sized::<N>(&mut self.s, n, cols, n, count, -1.0).is_err() {
            let cols: Vec<Vec<f64>> = (lead > 0)
                .then(|| self.v0[..n].to_vec())
                .into_iter()
                .chain((0..q).map(|c| self.pxy[c * n..(c + 1) * n].to_vec()))
                .collect();
            let ups: Vec<(&[f64], f64)> = cols.iter().map(|v| (v.as_slice(), -1.0)).collect();
            self.recover(&ups);
        }
    }

    /// Square-root unscented Rauch–Tung–Striebel smoother (Särkkä 2008, in square-root form)
    /// over a filtered run: `xs` `(T, n)` filtered means, `ss` `T` lower factors (column-major
    /// `n × n` each), `us` `(T, m)` the inputs, `us[k]` acting over the period that ends at
    /// sample `k` (as in [`SrUkf::step`]). Returns the smoothed means and factors in the same
    /// layouts and the number of recovered downdates. Uses this filter's process model,
    /// weights and process noise; the filter's own state is left as it is.
    ///
    /// Backwards from `k = T − 2`: sigma points of the filtered `(x_k, S_k)` are propagated with
    /// `u[k+1]`, giving the predicted `(x⁻, S⁻)` and the cross covariance `C`; the gain is
    /// `G = C·(S⁻S⁻ᵀ)⁻¹` by two triangular solves; `x̃_k = x_k + G(x̃_{k+1} − x⁻)` and
    /// `S̃_k = qr([√W(χ − x_k − G(χ⁻ − x⁻)), G·√Q, G·S̃_{k+1}])` updated with the 0th point
    /// (`P̃ = Σ W (dχ − G dχ⁻)(·)ᵀ + G Q Gᵀ + G P̃_{k+1} Gᵀ`).
    pub fn smooth(
        &mut self,
        xs: &[f64],
        ss: &[f64],
        us: &[f64],
    ) -> Result<(Vec<f64>, Vec<f64>, u64)> {
        let (n, m) = (self.n, self.process.n_inputs());
        if n == 0 || !xs.len().is_multiple_of(n) {
            return Err(CableError::Shape {
                what: "filtered means".into(),
                expected: format!("(T, {n})"),
                got: format!("{} values", xs.len()),
            });
        }
        let t = xs.len() / n;
        check::len("filtered factors", ss, t * n * n)?;
        check::len("inputs", us, t * m)?;
        check::all_finite("filtered means", xs, n)?;
        check::all_finite("filtered factors", ss, n * n)?;
        check::all_finite("inputs", us, m.max(1))?;
        let mut xo = xs.to_vec();
        let mut so = ss.to_vec();
        if t < 2 {
            return Ok((xo, so, 0));
        }
        let ns = 2 * n + 1;
        let g = self.w.gamma;
        let (wm1, (wc0, wc1)) = (self.w.wm.1, self.w.wc);
        let mut chi = vec![0.0; n * ns]; // sigma points of the filtered state
        let mut chp = vec![0.0; n * ns]; // propagated
        let mut xp = vec![0.0; n];
        let mut sp = vec![0.0; n * n];
        let mut gain = vec![0.0; n * n]; // column-major G
        let mut row = vec![0.0; n];
        let mut dv = vec![0.0; n];
        // LQ workspace: n rows (padded, the padding stays zero), up to 4n columns
        let ld = padded(n);
        let mut comp = vec![0.0; ld * 4 * n];
        let mut lqv = vec![0.0; ld];
        let mut recovered = 0u64;
        for k in (0..t - 1).rev() {
            let xk = &xs[k * n..(k + 1) * n];
            let sk = &ss[k * n * n..(k + 1) * n * n];
            let u = &us[(k + 1) * m..(k + 2) * m];
            chi[..n].copy_from_slice(xk);
            for j in 0..n {
                for i in 0..n {
                    chi[i + (1 + j) * n] = xk[i] + g * sk[i + j * n];
                    chi[i + (1 + n + j) * n] = xk[i] - g * sk[i + j * n];
                }
            }
            chp.copy_from_slice(&chi);
            self.process.propagate_many(&mut chp[..ns * n], u);
            // predicted mean and factor (as in the time update)
            for r in 0..n {
                let c0 = chp[r];
                let acc: f64 = (1..ns).map(|i| chp[r + i * n] - c0).sum();
                xp[r] = c0 + wm1 * acc;
            }
            let sw = wc1.sqrt();
            square_root_of_spread::<0>(&mut comp, &chp[n..], &xp, sw, &self.sq, &mut lqv, &mut sp);
            if wc0 != 0.0 {
                let a = wc0.abs().sqrt();
                for r in 0..n {
                    dv[r] = a * (chp[r] - xp[r]);
                }
                recovered += u64::from(cholupdate_or_repair(&mut sp, n, &mut dv, wc0.signum()));
            }
            // cross covariance C = Σ W (χ − x_k)(χ⁻ − x⁻)ᵀ, then G = C·S⁻⁻ᵀ·S⁻⁻¹ row by row
            gain.fill(0.0);
            for i in 0..ns {
                let w = if i == 0 { wc0 } else { wc1 };
                for c in 0..n {
                    let dy = w * (chp[c + i * n] - xp[c]);
                    for r in 0..n {
                        gain[r + c * n] += (chi[r + i * n] - xk[r]) * dy;
                    }
                }
            }
            for r in 0..n {
                for c in 0..n {
                    row[c] = gain[r + c * n];
                }
                solve_lower(&sp, n, &mut row);
                super::linalg::solve_lower_transpose(&sp, n, &mut row);
                for c in 0..n {
                    gain[r + c * n] = row[c];
                }
            }
            // smoothed mean
            let (head, tail) = xo.split_at_mut((k + 1) * n);
            let next = &tail[..n];
            for r in 0..n {
                let mut acc = 0.0;
                for c in 0..n {
                    acc += gain[r + c * n] * (next[c] - xp[c]);
                }
                head[k * n + r] = xk[r] + acc;
            }
            // smoothed factor: rows [√W(dχ − G dχ⁻) (2n), (G·√Q)ᵀ (n), (G·S̃_{k+1})ᵀ (n)]
            let snext: Vec<f64> = so[(k + 1) * n * n..(k + 2) * n * n].to_vec();
            let mut dev0 = vec![0.0; n];
            for i in 0..ns {
                for r in 0..n {
                    let mut gd = 0.0;
                    for c in 0..n {
                        gd += gain[r + c * n] * (chp[c + i * n] - xp[c]);
                    }
                    let d = (chi[r + i * n] - xk[r]) - gd;
                    if i == 0 {
                        dev0[r] = d;
                    } else {
                        comp[r + (i - 1) * ld] = sw * d;
                    }
                }
            }
            for (block, factor) in [(2 * n, &self.sq[..]), (3 * n, &snext[..])] {
                for j in 0..n {
                    for r in 0..n {
                        let mut acc = 0.0;
                        for c in 0..n {
                            acc += gain[r + c * n] * factor[c + j * n];
                        }
                        comp[r + (block + j) * ld] = acc;
                    }
                }
            }
            let mut snew = vec![0.0; n * n];
            lq_lower(
                &mut comp[..ld * 4 * n],
                n,
                4 * n,
                4 * n,
                &mut lqv,
                &mut snew,
            );
            if wc0 != 0.0 {
                let a = wc0.abs().sqrt();
                for v in &mut dev0 {
                    *v *= a;
                }
                recovered += u64::from(cholupdate_or_repair(&mut snew, n, &mut dev0, wc0.signum()));
            }
            so[k * n * n..(k + 1) * n * n].copy_from_slice(&snew);
        }
        let bad =
            |v: &[f64], width: usize| v.iter().position(|v| !v.is_finite()).map(|i| i / width);
        if let Some(step) = [bad(&xo, n), bad(&so, n * n)].into_iter().flatten().min() {
            return Err(CableError::FilterDiverged { step });
        }
        Ok((xo, so, recovered))
    }

    /// Predict with `u`, then update with `y` (entries where `mask` is true; all if `None`).
    /// Bad input is refused before anything changes. Filters of up to
    /// [`SPECIALISED_UP_TO`] states run a build specialised for their size (and for AVX2 + FMA
    /// CPUs, 256-bit lanes): same operations, same results. With a negative `W(c)_0` and a
    /// linear measurement the 0th sigma point's downdate is folded into the measurement's
    /// (one pass down `S` for both): the result equals [`SrUkf::predict`] then
    /// [`SrUkf::update`] in exact arithmetic, and to rounding in floating point.
    pub fn step(&mut self, u: &[f64], y: &[f64], mask: Option<&[bool]>) -> Result<()> {
        check::len("u", u, self.process.n_inputs())?;
        check::all_finite("u", u, 1)?;
        self.check_measurement(y, mask)?;
        self.save();
        macro_rules! sized {
            ($($n:literal)*) => {
                match self.n {
                    $($n => self.step_sized::<$n>(u, y, mask),)*
                    _ => self.step_unchecked::<0>(u, y, mask),
                }
            };
        }
        let done = sized!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24);
        self.settle(done)
    }

    /// [`Self::step_unchecked`] for `N = n` states, with 256-bit lanes where the CPU has them.
    fn step_sized<const N: usize>(
        &mut self,
        u: &[f64],
        y: &[f64],
        mask: Option<&[bool]>,
    ) -> Result<()> {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            #[allow(unsafe_code)]
            // SAFETY: `avx2` is set only when `cpu_has_avx2()` reported AVX2 on this CPU
            return unsafe { step_avx2::<P, H, N>(self, u, y, mask) };
        }
        self.step_unchecked::<N>(u, y, mask)
    }

    /// Predict and update, inputs already checked.
    #[inline(always)]
    fn step_unchecked<const N: usize>(
        &mut self,
        u: &[f64],
        y: &[f64],
        mask: Option<&[bool]>,
    ) -> Result<()> {
        self.health.recovered = 0;
        if self.w.wc.0 < 0.0 && self.observe.linear().is_some() {
            // the 0th point's downdate joins the measurement's (one pass down S for both)
            self.predict_spread::<N>(u);
            let n = dim::<N>(self.n);
            let swc0 = (-self.w.wc.0).sqrt();
            scaled_difference::<N>(swc0, &self.chi[..n], &self.x, &mut self.v0);
            self.update_folded::<N>(u, y, mask);
        } else {
            self.predict_unchecked::<N>(u);
            self.update_unchecked::<N>(u, y, mask);
        }
        self.check_state::<N>()
    }

    /// Refresh the condition estimate; a non-finite mean or factor is an error (the model
    /// diverged: smaller dt or more substeps).
    #[inline(always)]
    fn check_state<const N: usize>(&mut self) -> Result<()> {
        let n = dim::<N>(self.n);
        let (mut lo, mut hi) = (f64::INFINITY, 0.0_f64);
        for i in 0..n {
            let d = self.s[i + i * n].abs();
            lo = lo.min(d);
            hi = hi.max(d);
        }
        self.health.condition = if lo > 0.0 {
            (hi / lo).powi(2)
        } else {
            f64::INFINITY
        };
        // v·0 is ±0 for a finite v and NaN otherwise: one vectorisable sum for the whole state
        let probe = |m: &[f64]| {
            let mut acc = [0.0; LANES];
            let mut blocks = m.chunks_exact(LANES);
            for b in blocks.by_ref() {
                for l in 0..LANES {
                    acc[l] += b[l] * 0.0;
                }
            }
            acc.iter().sum::<f64>() + blocks.remainder().iter().map(|v| v * 0.0).sum::<f64>()
        };
        if !(probe(&self.x) + probe(&self.s)).is_finite() {
            // renumbered and undone by `settle`
            return Err(CableError::FilterDiverged { step: 0 });
        }
        Ok(())
    }
}

/// The largest state count with a specialised build of [`SrUkf::step`].
pub const SPECIALISED_UP_TO: usize = 24;

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn step_avx2<P: Process, H: Observe, const N: usize>(
    f: &mut SrUkf<P, H>,
    u: &[f64],
    y: &[f64],
    mask: Option<&[bool]>,
) -> Result<()> {
    f.step_unchecked::<N>(u, y, mask)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::{LinearObserve, LinearProcess};
    use approx::assert_relative_eq;

    /// Exact Kalman filter for `x' = A x + B u`, `y = H x` (row-major), covariances row-major.
    struct Kf {
        n: usize,
        x: Vec<f64>,
        p: nalgebra::DMatrix<f64>,
    }

    fn dm(r: usize, c: usize, v: &[f64]) -> nalgebra::DMatrix<f64> {
        nalgebra::DMatrix::from_row_slice(r, c, v)
    }

    /// `v·I` (`n × n`).
    fn diag(n: usize, v: f64) -> Vec<f64> {
        (0..n * n)
            .map(|k| if k % (n + 1) == 0 { v } else { 0.0 })
            .collect()
    }

    /// A slightly damped process matrix with cross-coupling of size `c` (row-major).
    fn coupled(n: usize, c: f64) -> Vec<f64> {
        (0..n * n)
            .map(|k| {
                let (i, j) = (k / n, k % n);
                if i == j {
                    0.98
                } else {
                    c * (((i * 7 + j * 3) % 5) as f64 - 2.0)
                }
            })
            .collect()
    }

    /// A linear measurement that does not tell the filter its matrix, so the filter runs the
    /// sigma-point update (eqs 3.16–3.21) on it.
    #[derive(Clone)]
    struct Opaque(LinearObserve);

    impl Observe for Opaque {
        fn n_outputs(&self) -> usize {
            self.0.n_outputs()
        }
        fn observe(&mut self, x: &[f64], u: &[f64], y: &mut [f64]) {
            self.0.observe(x, u, y)
        }
    }

    #[test]
    fn linear_measurement_in_closed_form_equals_the_sigma_point_update() {
        let n = 5;
        // a rotating, slightly damped process with cross-coupling
        let a = coupled(n, 0.05);
        let q: Vec<f64> = (0..n * n)
            .map(|k| if k % (n + 1) == 0 { 1e-4 } else { 0.0 })
            .collect();
        let p0: Vec<f64> = (0..n * n)
            .map(|k| if k % (n + 1) == 0 { 0.2 } else { 0.03 })
            .collect();
        let x0 = vec![0.3, -0.1, 0.2, 0.0, 0.5];
        let r = vec![1e-2, 1e-3, 0.0, 1e-3, 2e-2, 0.0, 0.0, 0.0, 5e-3];
        let dense = vec![
            1.0, 0.5, 0.0, -0.2, 0.0, //
            0.0, 0.0, 2.0, 0.0, 0.3, //
            0.1, 0.1, 0.1, 0.1, 0.1,
        ];
        let pick = vec![
            0.0, 0.0, 0.0, 1.0, 0.0, //
            1.0, 0.0, 0.0, 0.0, 0.0, //
            0.0, 0.0, 0.0, 0.0, 1.0,
        ];
        // (α, relative tolerance): at α = 1e-3 the sigma-point sums carry ~eps/γ² rounding
        for (alpha, tol) in [(0.5, 1e-12), (1e-3, 1e-8)] {
            for h in [&dense, &pick] {
                let scaling = SigmaScaling {
                    alpha,
                    ..SigmaScaling::default()
                };
                let process = LinearProcess::new(n, 0, a.clone(), vec![]).unwrap();
                let observe = LinearObserve::new(3, n, h.clone()).unwrap();
                assert!(observe.linear().is_some());
                let mut closed =
                    SrUkf::new(process.clone(), observe.clone(), &x0, &p0, &q, &r, scaling)
                        .unwrap();
                let mut sigma =
                    SrUkf::new(process, Opaque(observe), &x0, &p0, &q, &r, scaling).unwrap();
                for k in 0..60 {
                    let t = k as f64;
                    let y = [(0.3 * t).sin(), 0.2 * (0.1 * t).cos(), 0.05 * t.sqrt()];
                    // every fourth step drops the middle channel (the masked path)
                    let mask = [true, k % 4 != 0, true];
                    closed.step(&[], &y, Some(&mask)).unwrap();
                    sigma.step(&[], &y, Some(&mask)).unwrap();
                    let (pc, ps) = (closed.covariance(), sigma.covariance());
                    let scale = ps.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
                    for i in 0..n {
                        assert!(
                            (closed.x()[i] - sigma.x()[i]).abs() <= tol,
                            "x[{i}] step {k}"
                        );
                    }
                    for (c, s) in pc.iter().zip(&ps) {
                        assert!((c - s).abs() <= tol * scale, "P at step {k}");
                    }
                    assert!((closed.health().nis - sigma.health().nis).abs() <= tol * 1e3);
                }
            }
        }
    }

    #[test]
    fn a_state_that_overflows_is_a_divergence_error_not_a_nan() {
        // x' = 1e200·x: finite for one step from x = 1, infinite after two; P overflows first
        for (x0, p0) in [(1.0, 1e-300), (1e-300, 1.0)] {
            let n = 2;
            let a = vec![1e200, 0.0, 0.0, 1e200];
            let mut f = SrUkf::new(
                LinearProcess::new(n, 0, a, vec![]).unwrap(),
                LinearObserve::select(n, &[0]).unwrap(),
                &[x0, x0],
                &[p0, 0.0, 0.0, p0],
                &[0.0; 4],
                &[1e-2],
                SigmaScaling {
                    alpha: 0.5,
                    ..SigmaScaling::default()
                },
            )
            .unwrap();
            let mut outcome = Ok(());
            for _ in 0..4 {
                outcome = f.predict(&[]);
                if outcome.is_err() {
                    break;
                }
                assert!(f
                    .x()
                    .iter()
                    .chain(f.sqrt_covariance())
                    .all(|v| v.is_finite()));
            }
            assert!(
                matches!(outcome, Err(CableError::FilterDiverged { .. })),
                "{outcome:?}"
            );
            // the failed step is undone: the filter holds the last finite state
            assert!(f
                .x()
                .iter()
                .chain(f.sqrt_covariance())
                .all(|v| v.is_finite()));
        }
    }

    #[test]
    fn linear_system_equals_the_kalman_filter_with_negative_w0() {
        let (n, m, p) = (4, 1, 2);
        let dt = 0.01;
        let a = vec![
            1.0,
            dt,
            0.0,
            0.0, //
            -dt * 40.0,
            1.0 - dt * 0.5,
            dt * 10.0,
            0.0, //
            0.0,
            0.0,
            1.0,
            dt, //
            dt * 10.0,
            0.0,
            -dt * 30.0,
            1.0 - dt * 0.2,
        ];
        let b = vec![0.0, dt, 0.0, 0.0];
        let h = vec![1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let q: Vec<f64> = (0..n * n)
            .map(|k| if k % (n + 1) == 0 { 1e-6 } else { 0.0 })
            .collect();
        let r = vec![1e-4, 2e-5, 2e-5, 4e-4];
        let p0: Vec<f64> = (0..n * n)
            .map(|k| if k % (n + 1) == 0 { 0.1 } else { 0.01 })
            .collect();
        let x0 = vec![0.1, 0.0, -0.2, 0.0];
        let mut f = SrUkf::new(
            LinearProcess::new(n, m, a.clone(), b.clone()).unwrap(),
            LinearObserve::new(p, n, h.clone()).unwrap(),
            &x0,
            &p0,
            &q,
            &r,
            SigmaScaling::default(),
        )
        .unwrap();
        assert!(f.weights().wc.0 < 0.0, "seed α = 1e-3 gives a negative W0");
        let mut kf = Kf {
            n,
            x: x0.clone(),
            p: dm(n, n, &p0),
        };
        let (am, bm, hm, qm, rm) = (
            dm(n, n, &a),
            dm(n, m, &b),
            dm(p, n, &h),
            dm(n, n, &q),
            dm(p, p, &r),
        );
        for k in 0..300 {
            let u = [(k as f64 * 0.05).sin()];
            let y = [0.1 * (k as f64 * 0.03).cos(), -0.05 + 1e-3 * k as f64];
            f.step(&u, &y, None).unwrap();
            // exact KF
            let x = nalgebra::DVector::from_column_slice(&kf.x);
            let xp = &am * x + &bm * u[0];
            let pp = &am * &kf.p * am.transpose() + &qm;
            let s = &hm * &pp * hm.transpose() + &rm;
            let kgain = &pp * hm.transpose() * s.clone().try_inverse().unwrap();
            let innov = nalgebra::DVector::from_column_slice(&y) - &hm * &xp;
            let xn = &xp + &kgain * innov;
            kf.p = &pp - &kgain * s * kgain.transpose();
            kf.x = xn.as_slice().to_vec();
            let cov = f.covariance();
            for i in 0..kf.n {
                assert_relative_eq!(f.x()[i], kf.x[i], epsilon = 1e-9, max_relative = 1e-7);
                for j in 0..kf.n {
                    assert_relative_eq!(
                        cov[i + j * n],
                        kf.p[(i, j)],
                        epsilon = 1e-12,
                        max_relative = 1e-6
                    );
                }
            }
        }
        assert_eq!(f.health().recoveries_total, 0);
        assert!(f.health().nis.is_finite());
    }

    /// `x₀ ← x₀ + c·x₁²`, `x₁ ← x₁`: the sigma points' mean moves by `c·P₁₁`, so the 0th
    /// point's downdate is `|W(c)_0|·(c·P₁₁)² ≈ 1e6·c²` in `x₀`, as large as the spread it
    /// cancels.
    #[derive(Clone)]
    struct Quadratic(f64);

    impl Process for Quadratic {
        fn n_states(&self) -> usize {
            2
        }
        fn n_inputs(&self) -> usize {
            0
        }
        fn propagate(&mut self, x: &mut [f64], _u: &[f64]) {
            x[0] += self.0 * x[1] * x[1];
        }
    }

    #[test]
    fn the_folded_0th_point_gives_the_sequential_update() {
        // c = 1e-3: half of the predicted spread of x0 is cancelled by the 0th point; x0 is
        // measured, so S_y, P_xy and S all take the fold's corrections
        let mk = |observe| {
            SrUkf::new(
                Quadratic(1e-3),
                observe,
                &[0.0, 1.0],
                &[1.0, 0.0, 0.0, 1.0],
                &[0.0; 4],
                &[0.1],
                SigmaScaling::default(),
            )
            .unwrap()
        };
        for observe in [
            LinearObserve::select(2, &[0]).unwrap(),
            LinearObserve::new(1, 2, vec![1.0, 0.5]).unwrap(),
        ] {
            let (mut folded, mut split) = (mk(observe.clone()), mk(observe));
            assert!(folded.weights().wc.0 < -1e5);
            for k in 0..5 {
                let y = [0.3 * k as f64];
                // the cancelled spread: S' holds 1 + 1e6·c² ≈ 2 in x0, v0 ≈ 1
                if k == 0 {
                    folded.predict_spread::<0>(&[]);
                    let v0: f64 = folded.chi[0] - folded.x[0];
                    let w0 = -folded.weights().wc.0;
                    assert!((w0 * v0 * v0 - 1.0).abs() < 1e-3, "{}", w0 * v0 * v0);
                    folded.reset(&[0.0, 1.0], &[1.0, 0.0, 0.0, 1.0]).unwrap();
                }
                folded.step(&[], &y, None).unwrap();
                split.predict(&[]).unwrap();
                split.update(&[], &y, None).unwrap();
                // a fold that dropped a correction would be off by ~50 %
                for (a, b) in folded.x().iter().zip(split.x()) {
                    assert_relative_eq!(a, b, epsilon = 1e-12, max_relative = 1e-10);
                }
                for (a, b) in folded.covariance().iter().zip(&split.covariance()) {
                    assert_relative_eq!(a, b, epsilon = 1e-12, max_relative = 1e-10);
                }
                assert_relative_eq!(
                    folded.health().nis,
                    split.health().nis,
                    max_relative = 1e-10
                );
                assert_eq!(folded.health().recoveries_total, 0);
            }
        }
    }

    #[test]
    fn a_downdate_lost_to_rounding_is_recovered_and_counted() {
        // a near-perfect measurement of x0: the posterior variance 1e-30 is below the
        // resolution of the prior's 1.0, so the rank-one downdate fails in floating point
        let n = 2;
        let mut f = SrUkf::new(
            LinearProcess::new(n, 0, vec![1.0, 0.0, 0.0, 1.0], vec![]).unwrap(),
            LinearObserve::select(n, &[0]).unwrap(),
            &[0.0, 0.0],
            &[1.0, 0.0, 0.0, 1.0],
            &[0.0; 4],
            &[1e-30],
            SigmaScaling::default(),
        )
        .unwrap();
        f.step(&[], &[0.5], None).unwrap();
        let h = f.health();
        assert!(h.recovered >= 1 && h.recoveries_total >= 1);
        let cov = f.covariance();
        assert!(cov.iter().all(|v| v.is_finite()));
        assert!(
            cov[0] >= 0.0 && cov[0] < 1e-6,
            "x0 is now known: {}",
            cov[0]
        );
        assert_relative_eq!(cov[3], 1.0, epsilon = 1e-9);
        assert_relative_eq!(f.x()[0], 0.5, epsilon = 1e-9);
    }

    #[test]
    fn masked_channels_are_not_used_and_nan_is_refused_unless_masked() {
        let n = 2;
        let mk = || {
            SrUkf::new(
                LinearProcess::new(n, 0, vec![1.0, 0.0, 0.0, 1.0], vec![]).unwrap(),
                LinearObserve::select(n, &[0, 1]).unwrap(),
                &[0.0, 0.0],
                &[1.0, 0.0, 0.0, 1.0],
                &[0.0; 4],
                &[0.01, 0.0, 0.0, 0.01],
                SigmaScaling::default(),
            )
            .unwrap()
        };
        let mut f = mk();
        assert!(matches!(
            f.step(&[], &[1.0, f64::NAN], None),
            Err(CableError::NotFinite { index: 1, .. })
        ));
        let mut f = mk();
        f.step(&[], &[1.0, f64::NAN], Some(&[true, false])).unwrap();
        assert_relative_eq!(f.x()[0], 1.0 / 1.01, epsilon = 1e-9);
        assert!(f.x()[1].abs() < 1e-300);
        assert_relative_eq!(f.covariance()[3], 1.0, epsilon = 1e-12);
        assert_eq!(f.health().measured, 1);
    }

    #[test]
    fn bad_covariances_are_typed_errors() {
        let n = 2;
        let mk = |p0: &[f64], r: &[f64]| {
            SrUkf::new(
                LinearProcess::new(n, 0, vec![1.0, 0.0, 0.0, 1.0], vec![]).unwrap(),
                LinearObserve::select(n, &[0]).unwrap(),
                &[0.0, 0.0],
                p0,
                &[0.0; 4],
                r,
                SigmaScaling::default(),
            )
        };
        assert!(matches!(
            mk(&[1.0, 2.0, 2.0, 1.0], &[1.0]),
            Err(CableError::InvalidParameter { .. })
        ));
        assert!(matches!(
            mk(&[1.0, 0.5, 0.0, 1.0], &[1.0]),
            Err(CableError::InvalidParameter { .. })
        ));
        assert!(matches!(
            mk(&[1.0, 0.0, 0.0, 1.0], &[0.0]),
            Err(CableError::InvalidParameter { .. })
        ));
        assert!(matches!(
            mk(&[1.0, 0.0, 0.0], &[1.0]),
            Err(CableError::Shape { .. })
        ));
    }

    /// Largest `|xᵢ − x'ᵢ| / σᵢ` and `|Pᵢⱼ − P'ᵢⱼ| / (σᵢσⱼ)` between two filters (`σ` from `a`).
    fn gap<P: Process, H: Observe>(a: &SrUkf<P, H>, b: &SrUkf<P, H>) -> (f64, f64) {
        let n = a.n_states();
        let (pa, pb) = (a.covariance(), b.covariance());
        let sd = |i: usize| pa[i * (n + 1)].sqrt();
        let (mut gx, mut gp) = (0.0_f64, 0.0_f64);
        for i in 0..n {
            gx = gx.max((a.x()[i] - b.x()[i]).abs() / sd(i));
            for j in 0..n {
                gp = gp.max((pa[i + j * n] - pb[i + j * n]).abs() / (sd(i) * sd(j)));
            }
        }
        (gx, gp)
    }

    /// Runs `steps` steps five ways. `step()` (the build specialised for `n`, with the CPU's
    /// lanes), `step()` with the portable lanes and the general build of `step()` must agree
    /// bit for bit. `predict()` + `update()` runs the 0th point's downdate on its own where
    /// `step()` folds it into the measurement's: it must agree to rounding, i.e. be no further
    /// from `step()` (over the whole run) than ten times the distance between two sequential
    /// runs whose `P₀` differ by 4e-16 relative (with the seed's α = 1e-3, a filter's sums
    /// amplify rounding by up to ~1/α; a strongly nonlinear model more).
    fn three_builds_agree<P: Process + Clone, H: Observe + Clone>(
        f: SrUkf<P, H>,
        steps: usize,
        input: impl Fn(usize) -> Vec<f64>,
        measure: impl Fn(usize, &[f64]) -> (Vec<f64>, Option<Vec<bool>>),
    ) {
        let mut nudged = f.clone();
        let p0: Vec<f64> = f.covariance().iter().map(|v| v * (1.0 + 4e-16)).collect();
        nudged.reset(f.x(), &p0).unwrap();
        let (mut fast, mut portable, mut general, mut split) = (f.clone(), f.clone(), f.clone(), f);
        portable.avx2 = false;
        let (mut folded_gap, mut rounding_gap) = ((0.0_f64, 0.0_f64), (0.0_f64, 0.0_f64));
        for k in 0..steps {
            let u = input(k);
            let (y, mask) = measure(k, general.x());
            let mask = mask.as_deref();
            fast.step(&u, &y, mask).unwrap();
            portable.step(&u, &y, mask).unwrap();
            general.step_unchecked::<0>(&u, &y, mask).unwrap();
            for seq in [&mut split, &mut nudged] {
                seq.predict(&u).unwrap();
                seq.update(&u, &y, mask).unwrap();
            }
            for other in [&fast, &portable] {
                let bits = |v: &[f64]| v.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(other.x()), bits(general.x()), "x at step {k}");
                let (so, sg) = (other.sqrt_covariance(), general.sqrt_covariance());
                assert_eq!(bits(so), bits(sg), "S at step {k}");
                assert_eq!(other.health().nis.to_bits(), general.health().nis.to_bits());
            }
            let (g, r) = (gap(&split, &general), gap(&split, &nudged));
            folded_gap = (folded_gap.0.max(g.0), folded_gap.1.max(g.1));
            rounding_gap = (rounding_gap.0.max(r.0), rounding_gap.1.max(r.1));
        }
        assert!(general.x().iter().all(|v| v.is_finite()));
        let n = general.n_states();
        assert!(
            folded_gap.0 <= 10.0 * rounding_gap.0.max(1e-8)
                && folded_gap.1 <= 10.0 * rounding_gap.1.max(1e-11),
            "n = {n}: step() vs predict() + update() {folded_gap:?}, rounding {rounding_gap:?}"
        );
    }

    #[test]
    fn specialised_steps_equal_the_general_build_bit_for_bit() {
        use crate::dynamics::{raven2, Model};
        use crate::estimate::ModelProcess;
        // the Raven-II transmission (n = 12), motor encoders, every third step one masked
        let model = raven2(3).unwrap();
        let n = model.n_states();
        let mut x0 = vec![0.0; n];
        let mut q_m = [0.0; 3];
        model.joint_to_motor(&[0.2, 1.4, 0.3], &mut q_m);
        for i in 0..3 {
            x0[4 * i] = q_m[i];
            x0[4 * i + 2] = [0.2, 1.4, 0.3][i];
        }
        let f = SrUkf::new(
            ModelProcess::new(model, 1e-4, 1).unwrap(),
            LinearObserve::select(n, &[0, 4, 8]).unwrap(),
            &x0,
            &diag(n, 1e-6),
            &diag(n, 1e-9),
            &diag(3, 1e-8),
            SigmaScaling::default(),
        )
        .unwrap();
        let x_ref = x0.clone();
        three_builds_agree(
            f,
            60,
            |k| {
                let s = (k as f64 * 0.3).sin();
                vec![0.2 * s, -0.1 * s, 0.05 * s, 0.0, 0.0, 0.0]
            },
            |k, _| {
                let y = vec![x_ref[0] + 1e-4 * k as f64, x_ref[4], x_ref[8] - 1e-5];
                let mask = (k % 3 == 2).then(|| vec![true, false, true]);
                (y, mask)
            },
        );
        // linear processes of sizes with and without whole SIMD blocks, selections and a
        // general H (the sigma-point update through an opaque model), past the specialised
        // sizes too
        for n in [1, 3, 5, 8, 13, SPECIALISED_UP_TO, SPECIALISED_UP_TO + 1] {
            let a = coupled(n, 0.01);
            let p = n.min(3);
            let picks: Vec<usize> = (0..p).map(|i| (i * 5) % n).collect();
            let x0: Vec<f64> = (0..n).map(|i| 0.1 * i as f64).collect();
            fn mk<H: Observe>(
                n: usize,
                a: &[f64],
                x0: &[f64],
                p: usize,
                obs: H,
            ) -> SrUkf<LinearProcess, H> {
                SrUkf::new(
                    LinearProcess::new(n, 0, a.to_vec(), vec![]).unwrap(),
                    obs,
                    x0,
                    &diag(n, 0.5),
                    &diag(n, 1e-3),
                    &diag(p, 1e-2),
                    SigmaScaling::default(),
                )
                .unwrap()
            }
            let measure = |k: usize, _: &[f64]| {
                let y = (0..p).map(|i| (0.1 * (k + i) as f64).cos()).collect();
                (y, None)
            };
            let picked = LinearObserve::select(n, &picks).unwrap();
            three_builds_agree(mk(n, &a, &x0, p, picked.clone()), 20, |_| vec![], measure);
            let h: Vec<f64> = (0..p * n).map(|k| 0.3 + 0.1 * (k % 4) as f64).collect();
            let general_h = LinearObserve::new(p, n, h).unwrap();
            three_builds_agree(mk(n, &a, &x0, p, general_h), 20, |_| vec![], measure);
            three_builds_agree(mk(n, &a, &x0, p, Opaque(picked)), 20, |_| vec![], measure);
        }
    }
}
