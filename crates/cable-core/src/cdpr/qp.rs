//! Tension distribution as a quadratic programme solved by clarabel: `min ½‖f − f_ref‖²_W`
//! subject to `Aᵀ·f + w = 0` and `f_min ≤ f ≤ f_max`, and, when that has no solution, the
//! least wrench error `min ‖Aᵀ·f + w‖² + ε‖f − f_ref‖²_W` within the bounds (the error as
//! its own variable).
//!
//! A [`QpDistributor`] keeps both clarabel solvers between poses: the first pose builds them
//! (clarabel's setup: equilibration, symbolic factorisation, allocation), later poses only
//! overwrite the numbers of `Aᵀ`, `w` and the bounds (clarabel's data updating; the sparsity
//! pattern is fixed, dense `Aᵀ` with structural zeros kept). Clarabel is an interior-point
//! method, so the iterations are not warm-started; the saving is the setup.
//!
//! The interior-point answer is polished: tensions within `1e-7` of a bound are set on it and
//! the others are moved by the least-norm correction that makes `Aᵀ·f + w = 0` hold to
//! rounding, so a solution reported feasible satisfies the equality to ≤ 1e-9 and the bounds
//! exactly.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus,
    SupportedConeT::{NonnegativeConeT, ZeroConeT},
};

use super::robot::MAX_CABLES;
use super::tension::{self, Distribution, Method};
use crate::error::{check, CableError, Result};

/// Interior-point iteration cap per solve.
pub const QP_MAX_ITER: u32 = 100;

/// Weight `ε` of the tension term in the least-wrench-error fallback (it makes that problem
/// strictly convex, so its answer is unique and continuous along a trajectory).
pub const LEAST_ERROR_REGULARISATION: f64 = 1e-6;

/// Bands (relative to `1 + f_max`) within which an interior-point tension is taken to sit on
/// its bound; each gives a candidate active set, and the feasible candidate of least objective
/// is the answer (the optimum lies on the face of the true active set, and every other
/// feasible candidate is a feasible point, so it cannot do better).
const POLISH_BANDS: [f64; 4] = [1e-8, 1e-6, 1e-4, 1e-2];

/// Clarabel's settings: data updates allowed; `tight` asks for 1e-10 gaps (the QP, whose
/// answer is then polished), else clarabel's defaults (the least-error fallback).
fn settings(tight: bool) -> Result<DefaultSettings<f64>> {
    let tol = if tight { 1e-10 } else { 1e-8 };
    DefaultSettingsBuilder::default()
        .verbose(false)
        .presolve_enable(false)
        .input_sparse_dropzeros(false)
        .max_iter(QP_MAX_ITER)
        .tol_gap_abs(tol)
        .tol_gap_rel(tol)
        .tol_feas(tol)
        .build()
        .map_err(|e| CableError::InvalidOption {
            name: "clarabel settings".into(),
            value: e.to_string(),
            allowed: "valid settings".into(),
        })
}

fn solver_error(what: &str, e: impl std::fmt::Display) -> CableError {
    CableError::InvalidOption {
        name: what.into(),
        value: e.to_string(),
        allowed: "a problem clarabel accepts".into(),
    }
}

/// `[Aᵀ; I; −I]` column by column (the nonzero values in clarabel's CSC order).
fn constraint_values(at: &[f64], n: usize, m: usize, out: &mut Vec<f64>) {
    out.clear();
    for j in 0..m {
        out.extend((0..n).map(|r| at[r * m + j]));
        out.extend([1.0, -1.0]);
    }
}

/// `[Aᵀ; I; −I]` as a CSC matrix of `n + 2m` rows.
fn constraint_matrix(at: &[f64], n: usize, m: usize) -> CscMatrix<f64> {
    let mut colptr = vec![0];
    let mut rowval = Vec::with_capacity(m * (n + 2));
    for j in 0..m {
        rowval.extend(0..n);
        rowval.extend([n + j, n + m + j]);
        colptr.push(rowval.len());
    }
    let mut nzval = Vec::new();
    constraint_values(at, n, m, &mut nzval);
    CscMatrix::new(n + 2 * m, m, colptr, rowval, nzval)
}

/// Tension distribution for one robot by any [`Method`], keeping the clarabel solvers warm.
pub struct Distributor {
    n: usize,
    m: usize,
    weights: Vec<f64>,
    qp: Option<DefaultSolver<f64>>,
    least: Option<DefaultSolver<f64>>,
    a_vals: Vec<f64>,
    b: Vec<f64>,
    q: Vec<f64>,
    /// Solves since construction (cold ones included).
    pub solves: u64,
}

impl std::fmt::Debug for Distributor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Distributor")
            .field("n", &self.n)
            .field("m", &self.m)
            .field("weights", &self.weights)
            .field("warm", &self.qp.is_some())
            .finish()
    }
}

impl Distributor {
    /// Distributor for `n` DOF and `m` cables with objective weights `W = diag(weights)`
    /// (`None`: all 1).
    pub fn new(n: usize, m: usize, weights: Option<&[f64]>) -> Result<Self> {
        if !(1..=6).contains(&n) || m < n || m > MAX_CABLES {
            return Err(CableError::Shape {
                what: "structure matrix".into(),
                expected: format!("(n, m) with 1 <= n <= 6 and n <= m <= {MAX_CABLES}"),
                got: format!("({n}, {m})"),
            });
        }
        let weights = match weights {
            Some(w) => {
                check::len("weights", w, m)?;
                for (i, v) in w.iter().enumerate() {
                    check::positive(&format!("weights[{i}]"), *v)?;
                }
                w.to_vec()
            }
            None => vec![1.0; m],
        };
        Ok(Self {
            n,
            m,
            weights,
            qp: None,
            least: None,
            a_vals: Vec::new(),
            b: Vec::new(),
            q: Vec::new(),
            solves: 0,
        })
    }

    /// Whether the solvers are built (the next solve is warm).
    pub fn is_warm(&self) -> bool {
        self.qp.is_some()
    }

    /// Forget the built solvers (the next solve is cold).
    pub fn reset(&mut self) {
        self.qp = None;
        self.least = None;
    }

    /// Tensions at the pose of structure matrix `at` (`n × m`, row-major) for wrench `w` by
    /// `method`. The QP answers `feasible = false` with the least-wrench-error tensions when no
    /// tensions within the bounds hold the wrench; `Auto` tries the improved closed form first.
    pub fn distribute(
        &mut self,
        at: &[f64],
        w: &[f64],
        f_min: &[f64],
        f_max: &[f64],
        method: Method,
    ) -> Result<Distribution> {
        let (n, m) = (self.n, self.m);
        match method {
            Method::MinimumNorm => tension::minimum_norm(at, n, m, w),
            Method::ClosedForm => tension::closed_form(at, n, m, w, f_min, f_max),
            Method::ImprovedClosedForm => tension::improved_closed_form(at, n, m, w, f_min, f_max),
            Method::Qp => self.qp(at, w, f_min, f_max),
            Method::LeastWrenchError => {
                tension::checked(at, n, m, w)?;
                tension::bounds_checked(m, f_min, f_max)?;
                self.least_error(at, w, f_min, f_max)
            }
            Method::Auto => {
                let d = tension::improved_closed_form(at, n, m, w, f_min, f_max)?;
                if d.feasible {
                    return Ok(d);
                }
                self.qp(at, w, f_min, f_max)
            }
        }
    }

    /// The QP, falling back to the least wrench error.
    fn qp(&mut self, at: &[f64], w: &[f64], f_min: &[f64], f_max: &[f64]) -> Result<Distribution> {
        let (n, m) = (self.n, self.m);
        tension::checked(at, n, m, w)?;
        tension::bounds_checked(m, f_min, f_max)?;
        // b = [−w; f_max; −f_min], q = −W·f_ref
        self.b.clear();
        self.b.extend(w.iter().map(|v| -v));
        self.b.extend_from_slice(f_max);
        self.b.extend(f_min.iter().map(|v| -v));
        self.q.clear();
        self.q
            .extend((0..m).map(|i| -self.weights[i] * 0.5 * (f_min[i] + f_max[i])));
        constraint_values(at, n, m, &mut self.a_vals);
        self.solves += 1;
        let solver = match self.qp.as_mut() {
            Some(s) => {
                s.update_A(&self.a_vals)
                    .map_err(|e| solver_error("qp", e))?;
                s.update_b(&self.b).map_err(|e| solver_error("qp", e))?;
                s.update_q(&self.q).map_err(|e| solver_error("qp", e))?;
                s
            }
            None => {
                let p = diagonal(&self.weights);
                let a = constraint_matrix(at, n, m);
                let cones = [ZeroConeT(n), NonnegativeConeT(2 * m)];
                let s = DefaultSolver::new(&p, &self.q, &a, &self.b, &cones, settings(true)?)
                    .map_err(|e| solver_error("qp", e))?;
                self.qp.insert(s)
            }
        };
        solver.solve();
        let status = solver.solution.status;
        if matches!(status, SolverStatus::Solved | SolverStatus::AlmostSolved) {
            let mut f = [0.0; MAX_CABLES];
            f[..m].copy_from_slice(&solver.solution.x[..m]);
            let objective = |d: &Distribution| -> f64 {
                let t = d.tensions();
                (0..m)
                    .map(|i| self.weights[i] * (t[i] - 0.5 * (f_min[i] + f_max[i])).powi(2))
                    .sum()
            };
            let mut best: Option<(f64, Distribution)> = None;
            for band in POLISH_BANDS {
                let Some(d) = polish(at, n, m, w, (f_min, f_max), &self.weights, f, band)? else {
                    continue;
                };
                let obj = objective(&d);
                if d.feasible && best.as_ref().is_none_or(|(b, _)| obj < *b) {
                    best = Some((obj, d));
                }
            }
            if let Some((_, d)) = best {
                return Ok(d);
            }
        }
        self.least_error(at, w, f_min, f_max)
    }

    /// `min ½‖e‖² + ½ε‖f − f_ref‖²_W` subject to `Aᵀ·f + w = e` and the bounds: the least
    /// wrench error `e` (reported infeasible). The error as its own variable keeps the problem
    /// well conditioned (`P = diag(εW, I)`).
    fn least_error(
        &mut self,
        at: &[f64],
        w: &[f64],
        f_min: &[f64],
        f_max: &[f64],
    ) -> Result<Distribution> {
        let (n, m) = (self.n, self.m);
        let eps = LEAST_ERROR_REGULARISATION;
        self.q.clear();
        self.q
            .extend((0..m).map(|i| -eps * self.weights[i] * 0.5 * (f_min[i] + f_max[i])));
        self.q.extend(std::iter::repeat_n(0.0, n));
        self.b.clear();
        self.b.extend(w.iter().map(|v| -v));
        self.b.extend_from_slice(f_max);
        self.b.extend(f_min.iter().map(|v| -v));
        constraint_values(at, n, m, &mut self.a_vals);
        self.a_vals.extend(std::iter::repeat_n(-1.0, n));
        let solver = match self.least.as_mut() {
            Some(s) => {
                s.update_A(&self.a_vals)
                    .map_err(|e| solver_error("least error", e))?;
                s.update_b(&self.b)
                    .map_err(|e| solver_error("least error", e))?;
                s.update_q(&self.q)
                    .map_err(|e| solver_error("least error", e))?;
                s
            }
            None => {
                let mut diag: Vec<f64> = self.weights.iter().map(|v| eps * v).collect();
                diag.extend(std::iter::repeat_n(1.0, n));
                let p = diagonal(&diag);
                let mut a = constraint_matrix(at, n, m);
                // the error columns: −I on the equality rows
                a.n += n;
                for r in 0..n {
                    a.rowval.push(r);
                    a.nzval.push(-1.0);
                    a.colptr.push(a.rowval.len());
                }
                let cones = [ZeroConeT(n), NonnegativeConeT(2 * m)];
                let s = DefaultSolver::new(&p, &self.q, &a, &self.b, &cones, settings(false)?)
                    .map_err(|e| solver_error("least error", e))?;
                self.least.insert(s)
            }
        };
        solver.solve();
        if !matches!(
            solver.solution.status,
            SolverStatus::Solved | SolverStatus::AlmostSolved
        ) {
            return Err(CableError::NotConverged {
                what: "least-wrench-error tension distribution".into(),
                limit: QP_MAX_ITER as usize,
                hint: "the structure matrix or the wrench is badly scaled",
            });
        }
        let mut f = [0.0; MAX_CABLES];
        for i in 0..m {
            f[i] = solver.solution.x[i].clamp(f_min[i], f_max[i]);
        }
        let mut d = tension::finish(
            at,
            n,
            m,
            w,
            f,
            Method::LeastWrenchError,
            Some((f_min, f_max)),
        )?;
        d.feasible = false;
        Ok(d)
    }
}

fn diagonal(weights: &[f64]) -> CscMatrix<f64> {
    let m = weights.len();
    CscMatrix::new(m, m, (0..=m).collect(), (0..m).collect(), weights.to_vec())
}

/// The interior-point answer made exact: tensions within `band` of a bound are set on it (the
/// active set), and the others are the exact optimum of the equality-constrained
/// problem on the free cables (the closed form with the active cables' forces in the wrench;
/// weighted by `W`). If that leaves the bounds (a wrong active set), the interior-point answer
/// gets the least-norm equilibrium correction instead. `None` if the free cables cannot hold
/// the wrench.
#[allow(clippy::too_many_arguments)]
fn polish(
    at: &[f64],
    n: usize,
    m: usize,
    w: &[f64],
    (f_min, f_max): (&[f64], &[f64]),
    weights: &[f64],
    ipm: [f64; MAX_CABLES],
    band: f64,
) -> Result<Option<Distribution>> {
    let mut f = ipm;
    let mut free = [0usize; MAX_CABLES];
    let mut k = 0;
    for i in 0..m {
        let band = band * (1.0 + f_max[i].abs());
        if f[i] <= f_min[i] + band {
            f[i] = f_min[i];
        } else if f[i] >= f_max[i] - band {
            f[i] = f_max[i];
        } else {
            free[k] = i;
            k += 1;
        }
    }
    if k < n {
        return tension::finish(at, n, m, w, f, Method::Qp, Some((f_min, f_max))).map(Some);
    }
    let free = &free[..k];
    let mut sub = [0.0; 6 * MAX_CABLES];
    tension::columns(at, n, m, free, &mut sub);
    // w_eff = w + the active cables' forces; scaled variables g = W^½·f make the weighted
    // problem the plain closed form
    let mut w_eff = [0.0; 6];
    for a in 0..n {
        let active: f64 = (0..m)
            .filter(|i| !free.contains(i))
            .map(|i| at[a * m + i] * f[i])
            .sum();
        w_eff[a] = w[a] + active;
    }
    let mut g_ref = [0.0; MAX_CABLES];
    for (c, &j) in free.iter().enumerate() {
        let s = weights[j].sqrt().recip();
        for a in 0..n {
            sub[a * k + c] *= s;
        }
        g_ref[c] = 0.5 * (f_min[j] + f_max[j]) / s;
    }
    let mut g = [0.0; MAX_CABLES];
    if tension::project(&sub[..n * k], n, k, &w_eff[..n], &g_ref[..k], &mut g[..k]).is_err() {
        return Ok(None);
    }
    let mut exact = f;
    for (c, &j) in free.iter().enumerate() {
        exact[j] = g[c] * weights[j].sqrt().recip();
    }
    let d = tension::finish(at, n, m, w, exact, Method::Qp, Some((f_min, f_max)))?;
    if d.feasible {
        return Ok(Some(d));
    }
    // a wrong active set: correct the interior-point answer's equilibrium by least norm
    let mut r = [0.0; 6];
    for a in 0..n {
        r[a] = w[a] + (0..m).map(|i| at[a * m + i] * f[i]).sum::<f64>();
    }
    tension::columns(at, n, m, free, &mut sub);
    let mut delta = [0.0; MAX_CABLES];
    if tension::project(
        &sub[..n * k],
        n,
        k,
        &r[..n],
        &[0.0; MAX_CABLES][..k],
        &mut delta[..k],
    )
    .is_err()
    {
        return Ok(None);
    }
    for (c, &j) in free.iter().enumerate() {
        f[j] += delta[c];
    }
    tension::finish(at, n, m, w, f, Method::Qp, Some((f_min, f_max))).map(Some)
}
