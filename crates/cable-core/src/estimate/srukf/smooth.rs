//! The square-root unscented Rauch–Tung–Striebel smoother over a filtered run.

use super::super::linalg::{cholupdate_or_repair, lq_lower, padded, solve_lower};
use super::super::models::{Observe, Process};
use super::kernels::square_root_of_spread;
use super::SrUkf;
use crate::error::{check, CableError, Result};

impl<P: Process, H: Observe> SrUkf<P, H> {
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
                super::super::linalg::solve_lower_transpose(&sp, n, &mut row);
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
}
