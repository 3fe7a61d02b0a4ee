//! The square-root unscented Kalman filter of van der Merwe (seed 001, eqs 3.9–3.25): the
//! filter and its steps here, the sigma-point and square-root kernels in `kernels`, the
//! URTS smoother in `smooth`.

mod kernels;
mod smooth;

use kernels::{
    add_combination, dim, linear_spread, scaled_difference, sigma_mean, sigma_points,
    solve_rows_lower_transpose, square_root_of_spread,
};

use super::linalg::{
    cholesky_psd, cholupdate, cholupdate_columns_sized, nearest_spd_factor, outer_lower, padded,
    repaired_factor, solve_lower,
};
use super::models::{Observe, Process};
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
    /// mean is the number of measured channels when the filter is consistent. An NIS beyond
    /// the float range is reported as `f64::MAX` and its update rejected (`gated`).
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
    /// Every sigma point's whole measurement, `ns × p` (the mask picks from it).
    yall: Aligned,
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
            yall: Aligned::zeros(p * ns),
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
    /// Input dimension.
    pub fn n_inputs(&self) -> usize {
        self.process.n_inputs()
    }
    /// Current mean.
    pub fn x(&self) -> &[f64] {
        &self.x
    }
    /// Current lower-triangular square root of the covariance (column-major `n × n`).
    pub fn sqrt_covariance(&self) -> &[f64] {
        &self.s
    }
    /// [`sqrt_covariance`](Self::sqrt_covariance) row-major (the layout of a front end's
    /// arrays).
    pub fn sqrt_covariance_rows(&self) -> Vec<f64> {
        let n = self.n;
        (0..n * n).map(|k| self.s[(k % n) * n + k / n]).collect()
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
        // a model that could not be evaluated (a user's callback raised) fails the step too
        let failed = self.process.failed() || self.observe.failed();
        let done = if failed {
            Err(CableError::FilterDiverged { step: 0 })
        } else {
            done
        };
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
        self.observe
            .observe_many(&self.chi[..ns * n], u, &mut self.yall[..ns * p]);
        for i in 0..ns {
            for (a, &k) in self.obs.iter().enumerate() {
                self.ysig[a + i * q] = self.yall[k + i * p];
            }
        }
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
        let nis: f64 = row[..q].iter().map(|v| v * v).sum();
        // an innovation whose NIS overflows is an outlier by any gate: rejected, and its NIS
        // reported as the largest float (it is at least that)
        let overflow = !nis.is_finite();
        self.health.nis = if overflow { f64::MAX } else { nis };
        if overflow || self.health.nis > self.gate {
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
mod tests;
