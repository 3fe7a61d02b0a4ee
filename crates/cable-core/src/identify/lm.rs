//! Bounded Levenberg–Marquardt for grey-box least squares through a simulator.
//!
//! Minimises `½‖r(θ)‖²` over the box `lower ≤ θ ≤ upper`. The Jacobian is taken by forward
//! differences (the residual is a whole simulation, no derivatives available), its columns
//! evaluated in parallel on rayon's pool. Each step solves the damped problem
//!
//! ```text
//! min ‖ [J; √λ·D] δ + [r; 0] ‖²,   D = diag(‖J_j‖)    (⇔ (JᵀJ + λ·diag(JᵀJ)) δ = −Jᵀr)
//! ```
//!
//! in parameter units scaled by `scale` (so a stiffness in kN/m and a lag in ms are comparable),
//! the MINPACK way: one QR of the tall Jacobian augmented by the residual, `[J | r] = Q·[R c; 0 ρ]`
//! (faer's blocked Householder), per Jacobian; then, for every trial `λ`, a QR of the small
//! `[R; √λ·D]` and a back substitution. Forming `JᵀJ` (the earlier normal equations solved by
//! Cholesky) squares the Jacobian's condition number: with nearly collinear columns (two
//! parameters that trade against each other, the regime where grey-box fits stall) the step
//! lost every digit and the Cholesky failed outright. The step is then projected onto the box.
//! `λ` follows Nielsen's rule: shrink by `max(1/3, 1 − (2ρ − 1)³)` on a successful step, double
//! (then more) on a failed one. A residual evaluation that fails (for example a trial parameter
//! makes the simulation diverge) counts as a failed step.

use faer::Mat;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::error::{check, CableError, Result};

/// Options of [`least_squares`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmOptions {
    /// Maximum number of accepted-or-rejected iterations.
    pub max_iter: usize,
    /// Stop when the relative cost reduction of an accepted step is below this.
    pub ftol: f64,
    /// Stop when two accepted steps in a row each reduce the cost by less than this (absolute,
    /// in the cost's units; 0 = off): with residuals in noise units, a change no decision
    /// resolves, where a relative tolerance keeps a crawl over a large, slowly falling cost going.
    pub atol: f64,
    /// Stop when the scaled step is below this (relative to the scaled parameters + 1).
    pub xtol: f64,
    /// Forward-difference step relative to `max(|θ_i|, scale_i)`.
    pub fd_step: f64,
    /// Parallel Jacobian columns (1 = serial; more = rayon's pool takes the columns).
    pub threads: usize,
}

impl LmOptions {
    /// Checked options: tolerances finite and ≥ 0, the finite-difference step finite and > 0,
    /// at most 100000 iterations (every loop is bounded) and at least one thread.
    pub fn validate(&self) -> Result<()> {
        check::non_negative("ftol", self.ftol)?;
        check::non_negative("atol", self.atol)?;
        check::non_negative("xtol", self.xtol)?;
        check::positive("fd_step", self.fd_step)?;
        let count = |name: &str, v: usize, range: std::ops::RangeInclusive<usize>, words| {
            if range.contains(&v) {
                Ok(())
            } else {
                Err(CableError::InvalidParameter {
                    name: name.into(),
                    value: v as f64,
                    requirement: words,
                })
            }
        };
        count("max_iter", self.max_iter, 0..=100_000, "in 0 ..= 100000")?;
        count("threads", self.threads, 1..=1024, "in 1 ..= 1024")
    }
}

impl Default for LmOptions {
    fn default() -> Self {
        Self {
            max_iter: 60,
            ftol: 1e-8,
            atol: 0.0,
            xtol: 1e-8,
            fd_step: 1e-6,
            threads: 1,
        }
    }
}

/// Result of [`least_squares`].
#[derive(Debug, Clone, PartialEq)]
pub struct LmReport {
    /// Fitted parameters.
    pub params: Vec<f64>,
    /// `½‖r‖²` at the fitted parameters.
    pub cost: f64,
    /// `½‖r‖²` at the start.
    pub initial_cost: f64,
    /// Residuals at the fitted parameters.
    pub residuals: Vec<f64>,
    /// Jacobian at the fitted parameters, row-major `(m, p)`.
    pub jacobian: Vec<f64>,
    /// Iterations taken.
    pub iterations: usize,
    /// Residual evaluations (including the Jacobian's).
    pub evaluations: usize,
    /// Whether a tolerance (not the iteration limit) stopped the search.
    pub converged: bool,
    /// Which parameters ended on a bound.
    pub at_bound: Vec<bool>,
}

/// Minimise `½‖f(θ)‖²` over a box; `f(θ, r)` writes `m` residuals into `r`.
///
/// `scale` gives each parameter's typical magnitude (> 0). Errors: shape or bound problems, or
/// a residual evaluation failing at the starting point.
pub fn least_squares<F>(
    f: F,
    x0: &[f64],
    lower: &[f64],
    upper: &[f64],
    scale: &[f64],
    m: usize,
    opts: &LmOptions,
) -> Result<LmReport>
where
    F: Fn(&[f64], &mut [f64]) -> Result<()> + Sync,
{
    opts.validate()?;
    let p = x0.len();
    for (what, v) in [("lower", lower), ("upper", upper), ("scale", scale)] {
        if v.len() != p {
            return Err(CableError::Shape {
                what: format!("least_squares {what}"),
                expected: format!("({p},)"),
                got: format!("({},)", v.len()),
            });
        }
    }
    for i in 0..p {
        let ordered = lower[i] <= upper[i] && scale[i] > 0.0;
        if !ordered || !x0[i].is_finite() {
            return Err(CableError::InvalidParameter {
                name: format!("least_squares parameter {i}"),
                value: x0[i],
                requirement: "finite, with lower <= upper and scale > 0",
            });
        }
    }
    let mut x: Vec<f64> = (0..p).map(|i| x0[i].clamp(lower[i], upper[i])).collect();
    let mut r = vec![0.0; m];
    f(&x, &mut r)?;
    let mut evaluations = 1;
    let mut cost = half_sq(&r);
    let initial_cost = cost;
    if !cost.is_finite() {
        return Err(CableError::InvalidParameter {
            name: "least_squares initial cost".into(),
            value: cost,
            requirement: "finite at the starting point",
        });
    }
    let mut jac = jacobian(&f, &x, &r, lower, upper, scale, opts, &mut evaluations);
    let mut lambda = 1e-3;
    let mut nu = 2.0;
    let mut converged = p == 0;
    let mut iterations = 0;
    let mut small_steps = 0;
    let mut trial = vec![0.0; p];
    let mut r_trial = vec![0.0; m];
    while iterations < opts.max_iter && !converged {
        iterations += 1;
        // the tall QR once per Jacobian: R (p×p) and c = Qᵀr
        let js = DMatrix::from_fn(m, p, |i, j| jac[i * p + j] * scale[j]);
        let (rr, qtr) = tall_qr(&js, &r);
        let g = rr.transpose() * &qtr; // = Jsᵀ r
        if g.amax() <= 1e-300 {
            converged = true;
            break;
        }
        // D² = diag(JsᵀJs) = the squared column norms of R, floored for empty columns
        let d2: Vec<f64> = (0..p).map(|j| rr.column(j).norm_squared()).collect();
        let d2_max = d2.iter().copied().fold(0.0_f64, f64::max).max(1e-300);
        let d: Vec<f64> = d2.iter().map(|v| v.max(1e-12 * d2_max).sqrt()).collect();
        let step = match damped_step(&rr, &qtr, &d, lambda) {
            Some(s) => s,
            None => {
                lambda *= nu;
                nu *= 2.0;
                if lambda > 1e16 {
                    converged = true;
                    break;
                }
                continue;
            }
        };
        for j in 0..p {
            trial[j] = (x[j] + step[j] * scale[j]).clamp(lower[j], upper[j]);
        }
        let actual_step: f64 = (0..p)
            .map(|j| ((trial[j] - x[j]) / scale[j]).powi(2))
            .sum::<f64>()
            .sqrt();
        let x_norm: f64 = (0..p)
            .map(|j| (x[j] / scale[j]).powi(2))
            .sum::<f64>()
            .sqrt();
        if actual_step <= opts.xtol * (x_norm + opts.xtol) {
            converged = true;
            break;
        }
        evaluations += 1;
        let new_cost = match f(&trial, &mut r_trial) {
            Ok(()) => half_sq(&r_trial),
            Err(_) => f64::INFINITY,
        };
        // predicted reduction of the linear model for the projected step
        let ds = DVector::from_fn(p, |j, _| (trial[j] - x[j]) / scale[j]);
        let jd = &rr * &ds; // ‖Js·δ‖ = ‖R·δ‖
        let predicted = -(g.dot(&ds) + 0.5 * jd.norm_squared());
        let rho = if predicted > 0.0 {
            (cost - new_cost) / predicted
        } else {
            -1.0
        };
        if new_cost.is_finite() && new_cost < cost {
            let rel = (cost - new_cost) / cost.max(1e-300);
            small_steps = if cost - new_cost < opts.atol {
                small_steps + 1
            } else {
                0
            };
            x.copy_from_slice(&trial);
            std::mem::swap(&mut r, &mut r_trial);
            cost = new_cost;
            lambda *= (1.0 - (2.0 * rho.clamp(0.0, 1.0) - 1.0).powi(3)).max(1.0 / 3.0);
            nu = 2.0;
            if rel < opts.ftol || small_steps >= 2 {
                converged = true;
            }
            jac = jacobian(&f, &x, &r, lower, upper, scale, opts, &mut evaluations);
        } else {
            lambda *= nu;
            nu *= 2.0;
            if lambda > 1e16 {
                converged = true; // no descent direction left within the box
            }
        }
    }
    let at_bound = (0..p)
        .map(|j| x[j] <= lower[j] || x[j] >= upper[j])
        .collect();
    Ok(LmReport {
        params: x,
        cost,
        initial_cost,
        residuals: r,
        jacobian: jac,
        iterations,
        evaluations,
        converged,
        at_bound,
    })
}

fn half_sq(r: &[f64]) -> f64 {
    0.5 * r.iter().map(|v| v * v).sum::<f64>()
}

/// `R` (p×p, upper triangular) and `c = Qᵀr` (first p rows) of the thin QR `Js = Q·R`, from one
/// faer QR of the augmented `[Js | r]` (m × (p + 1)): its last column carries `Qᵀr`, so `Q` is
/// never formed. With fewer rows than `p + 1` the missing rows of `R` are zero.
fn tall_qr(js: &DMatrix<f64>, r: &[f64]) -> (DMatrix<f64>, DVector<f64>) {
    let (m, p) = js.shape();
    let aug = Mat::<f64>::from_fn(m, p + 1, |i, j| if j < p { js[(i, j)] } else { r[i] });
    let qr = aug.qr();
    let big_r = qr.thin_R();
    let rows = big_r.nrows().min(p);
    let mut rr = DMatrix::zeros(p, p);
    let mut c = DVector::zeros(p);
    for i in 0..rows {
        for j in i..p {
            rr[(i, j)] = big_r[(i, j)];
        }
        c[i] = big_r[(i, p)];
    }
    (rr, c)
}

/// The Levenberg–Marquardt step `δ = argmin ‖[R; √λ·D] δ + [c; 0]‖` by a QR of the stacked
/// (2p × p) matrix and a back substitution; `None` when the stacked matrix is numerically
/// singular (then `λ` grows).
fn damped_step(
    rr: &DMatrix<f64>,
    c: &DVector<f64>,
    d: &[f64],
    lambda: f64,
) -> Option<DVector<f64>> {
    let p = rr.nrows();
    let sl = lambda.sqrt();
    let stacked = Mat::<f64>::from_fn(2 * p, p + 1, |i, j| match (i < p, j < p) {
        (true, true) => rr[(i, j)],
        (true, false) => c[i],
        (false, true) => {
            if i - p == j {
                sl * d[j]
            } else {
                0.0
            }
        }
        (false, false) => 0.0,
    });
    let qr = stacked.qr();
    let r2 = qr.thin_R();
    let scale = (0..p).map(|j| r2[(j, j)].abs()).fold(0.0_f64, f64::max);
    let mut x = DVector::zeros(p);
    for i in (0..p).rev() {
        let piv = r2[(i, i)];
        if piv.abs().partial_cmp(&(1e-14 * scale)) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let mut acc = -r2[(i, p)];
        for j in i + 1..p {
            acc -= r2[(i, j)] * x[j];
        }
        x[i] = acc / piv;
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Forward-difference Jacobian (row-major `(m, p)`), columns in parallel. A column whose
/// perturbed evaluation fails is tried with the step in the other direction, then left zero.
#[allow(clippy::too_many_arguments)]
fn jacobian<F>(
    f: &F,
    x: &[f64],
    r0: &[f64],
    lower: &[f64],
    upper: &[f64],
    scale: &[f64],
    opts: &LmOptions,
    evaluations: &mut usize,
) -> Vec<f64>
where
    F: Fn(&[f64], &mut [f64]) -> Result<()> + Sync,
{
    let (m, p) = (r0.len(), x.len());
    let column = |j: usize| -> (Vec<f64>, usize) {
        let mut col = vec![0.0; m];
        let mut xp = x.to_vec();
        let mut evals = 0;
        let base = opts.fd_step * x[j].abs().max(scale[j]);
        for h in [base, -base] {
            let h = if x[j] + h > upper[j] || x[j] + h < lower[j] {
                continue;
            } else {
                h
            };
            xp[j] = x[j] + h;
            evals += 1;
            if f(&xp, &mut col).is_ok() && col.iter().all(|v| v.is_finite()) {
                for i in 0..m {
                    col[i] = (col[i] - r0[i]) / h;
                }
                return (col, evals);
            }
        }
        (vec![0.0; m], evals)
    };
    let cols: Vec<(Vec<f64>, usize)> = if opts.threads <= 1 || p <= 1 {
        (0..p).map(column).collect()
    } else {
        (0..p).into_par_iter().map(column).collect()
    };
    let mut jac = vec![0.0; m * p];
    for (j, (col, evals)) in cols.into_iter().enumerate() {
        *evaluations += evals;
        for i in 0..m {
            jac[i * p + j] = col[i];
        }
    }
    jac
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // a parameter clamped to its bound is exactly the bound
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// Exponential decay fit `y = a·exp(−b·t) + c`: a classic nonlinear least-squares test.
    fn decay(t: &[f64], a: f64, b: f64, c: f64) -> Vec<f64> {
        t.iter().map(|&t| a * (-b * t).exp() + c).collect()
    }

    #[test]
    fn recovers_exponential_decay_parameters() {
        let t: Vec<f64> = (0..200).map(|k| k as f64 * 0.05).collect();
        let y = decay(&t, 2.5, 1.3, 0.4);
        let f = |th: &[f64], r: &mut [f64]| {
            let m = decay(&t, th[0], th[1], th[2]);
            for i in 0..r.len() {
                r[i] = m[i] - y[i];
            }
            Ok(())
        };
        for threads in [1, 2] {
            let opts = LmOptions {
                threads,
                ..LmOptions::default()
            };
            let rep = least_squares(
                f,
                &[1.0, 0.2, 0.0],
                &[-10.0, 0.0, -10.0],
                &[10.0, 10.0, 10.0],
                &[1.0, 1.0, 1.0],
                t.len(),
                &opts,
            )
            .unwrap();
            assert!(rep.converged);
            assert_relative_eq!(rep.params[0], 2.5, max_relative = 1e-6);
            assert_relative_eq!(rep.params[1], 1.3, max_relative = 1e-6);
            assert_relative_eq!(rep.params[2], 0.4, max_relative = 1e-6);
            assert!(rep.cost < 1e-12 && rep.initial_cost > 1.0);
        }
    }

    #[test]
    fn an_absolute_tolerance_stops_a_crawl_a_relative_one_does_not() {
        // a noisy decay: the cost settles at the noise floor (~0.5·Σn²), which a relative
        // tolerance of 0 never accepts as converged; two steps in a row below `atol` do, within
        // a few `atol` of the tight optimum and in fewer iterations
        let t: Vec<f64> = (0..400).map(|k| k as f64 * 0.025).collect();
        let clean = decay(&t, 2.5, 1.3, 0.4);
        let y: Vec<f64> = clean
            .iter()
            .enumerate()
            .map(|(i, v)| v + 0.05 * ((i as f64 * 12.9898).sin() * 43_758.545_3).fract())
            .collect();
        let f = |th: &[f64], r: &mut [f64]| {
            let m = decay(&t, th[0], th[1], th[2]);
            for i in 0..r.len() {
                r[i] = m[i] - y[i];
            }
            Ok(())
        };
        let run = |atol: f64| {
            let opts = LmOptions {
                max_iter: 200,
                ftol: 0.0,
                xtol: 0.0,
                atol,
                ..LmOptions::default()
            };
            least_squares(
                f,
                &[0.5, 5.0, -1.0],
                &[-10.0, 0.0, -10.0],
                &[10.0, 10.0, 10.0],
                &[1.0, 1.0, 1.0],
                t.len(),
                &opts,
            )
            .unwrap()
        };
        let tight = run(0.0);
        let loose = run(1e-3);
        assert!(loose.converged);
        assert!(
            loose.iterations < tight.iterations,
            "{} vs {}",
            loose.iterations,
            tight.iterations
        );
        assert!(
            loose.cost <= tight.cost + 4e-3,
            "{} vs {}",
            loose.cost,
            tight.cost
        );
        let bad = LmOptions {
            atol: -1.0,
            ..LmOptions::default()
        };
        assert!(least_squares(
            f,
            &[1.0, 1.0, 0.0],
            &[-10.0; 3],
            &[10.0; 3],
            &[1.0; 3],
            t.len(),
            &bad
        )
        .is_err());
    }

    #[test]
    fn respects_bounds_and_reports_them() {
        // the unconstrained optimum b = 1.3 lies above the bound 1.0
        let t: Vec<f64> = (0..100).map(|k| k as f64 * 0.05).collect();
        let y = decay(&t, 2.5, 1.3, 0.0);
        let f = |th: &[f64], r: &mut [f64]| {
            let m = decay(&t, th[0], th[1], 0.0);
            for i in 0..r.len() {
                r[i] = m[i] - y[i];
            }
            Ok(())
        };
        let rep = least_squares(
            f,
            &[1.0, 0.5],
            &[0.0, 0.0],
            &[10.0, 1.0],
            &[1.0, 1.0],
            t.len(),
            &LmOptions::default(),
        )
        .unwrap();
        assert_eq!(rep.params[1], 1.0);
        assert_eq!(rep.at_bound, vec![false, true]);
    }

    #[test]
    fn badly_scaled_parameters_converge_with_scale() {
        // a stiffness of 3e4 and a time constant of 2e-3 in one fit
        let t: Vec<f64> = (0..300).map(|k| k as f64 * 1e-4).collect();
        let model = |k: f64, tau: f64| -> Vec<f64> {
            t.iter()
                .map(|&t| k * 1e-4 * (1.0 - (-t / tau).exp()))
                .collect()
        };
        let y = model(3e4, 2e-3);
        let f = |th: &[f64], r: &mut [f64]| {
            let m = model(th[0], th[1]);
            for i in 0..r.len() {
                r[i] = m[i] - y[i];
            }
            Ok(())
        };
        let rep = least_squares(
            f,
            &[1e4, 5e-3],
            &[0.0, 1e-5],
            &[1e6, 1.0],
            &[1e4, 1e-3],
            t.len(),
            &LmOptions::default(),
        )
        .unwrap();
        assert_relative_eq!(rep.params[0], 3e4, max_relative = 1e-6);
        assert_relative_eq!(rep.params[1], 2e-3, max_relative = 1e-6);
    }

    #[test]
    fn the_step_keeps_its_digits_where_normal_equations_lose_them() {
        // a degree-13 polynomial in monomials on [0, 1]: the Jacobian's condition number is 4e9,
        // JᵀJ's 2e19 — beyond double precision. For a consistent system J·δ* = −r the undamped
        // step is δ*: the QR step recovers it to about cond·ε, the normal equations do not
        let (m, p) = (400, 14);
        let js = DMatrix::from_fn(m, p, |i, j| (i as f64 / (m - 1) as f64).powi(j as i32));
        let want = DVector::from_element(p, 1.0);
        let r: Vec<f64> = (-(&js * &want)).iter().copied().collect();
        let (rr, c) = tall_qr(&js, &r);
        let d = vec![1.0; p];
        let step = damped_step(&rr, &c, &d, 1e-300).unwrap();
        let qr_err = (&step - &want).amax();
        assert!(qr_err < 1e-4, "QR step error {qr_err:e}");
        let g = -(js.transpose() * DVector::from_column_slice(&r));
        let normal_err = match (js.transpose() * &js).cholesky() {
            Some(ch) => (ch.solve(&g) - &want).amax(),
            None => f64::INFINITY,
        };
        assert!(
            normal_err > 1e3 * qr_err,
            "normal equations {normal_err:e} vs QR {qr_err:e}"
        );
    }

    #[test]
    fn damped_step_matches_the_normal_equations_when_well_conditioned() {
        let rr = DMatrix::from_row_slice(3, 3, &[2.0, 0.5, -1.0, 0.0, 1.5, 0.3, 0.0, 0.0, 0.7]);
        let c = DVector::from_column_slice(&[0.3, -1.2, 0.8]);
        let d = [1.1, 0.9, 2.0];
        for lambda in [1e-6, 0.1, 10.0] {
            let step = damped_step(&rr, &c, &d, lambda).unwrap();
            let mut a = rr.transpose() * &rr;
            for j in 0..3 {
                a[(j, j)] += lambda * d[j] * d[j];
            }
            let want = a.cholesky().unwrap().solve(&(-(rr.transpose() * &c)));
            assert_relative_eq!(step, want, max_relative = 1e-10);
        }
        // the tall QR reproduces R and Qᵀr: RᵀR = JᵀJ and Rᵀc = Jᵀr
        let js = DMatrix::from_fn(50, 3, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0 + j as f64);
        let r: Vec<f64> = (0..50).map(|i| (i as f64).sin()).collect();
        let (big_r, qtr) = tall_qr(&js, &r);
        assert_relative_eq!(
            big_r.transpose() * &big_r,
            js.transpose() * &js,
            max_relative = 1e-12
        );
        assert_relative_eq!(
            big_r.transpose() * qtr,
            js.transpose() * DVector::from_column_slice(&r),
            max_relative = 1e-12
        );
    }

    #[test]
    fn failing_trial_points_are_rejected_not_fatal() {
        // the residual fails for b > 2: the search must stay below and still converge
        let t: Vec<f64> = (0..50).map(|k| k as f64 * 0.1).collect();
        let y = decay(&t, 1.0, 1.5, 0.0);
        let f = |th: &[f64], r: &mut [f64]| {
            if th[1] > 2.0 {
                return Err(CableError::Diverged {
                    step: 0,
                    time_s: 0.0,
                });
            }
            let m = decay(&t, th[0], th[1], 0.0);
            for i in 0..r.len() {
                r[i] = m[i] - y[i];
            }
            Ok(())
        };
        let rep = least_squares(
            f,
            &[0.1, 0.1],
            &[0.0, 0.0],
            &[10.0, 10.0],
            &[1.0, 1.0],
            t.len(),
            &LmOptions::default(),
        )
        .unwrap();
        assert_relative_eq!(rep.params[1], 1.5, max_relative = 1e-6);
        assert!(least_squares(
            f,
            &[1.0, 3.0],
            &[0.0; 2],
            &[9.0; 2],
            &[1.0; 2],
            50,
            &LmOptions::default()
        )
        .is_err());
    }
}
