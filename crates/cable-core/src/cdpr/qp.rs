//! Tension distribution as a quadratic programme solved by clarabel: `min ½‖f − f_ref‖²_W`
//! subject to `Aᵀ·f + w = 0` and `f_min ≤ f ≤ f_max`, and, when that has no solution, the
//! least wrench error `min ‖Aᵀ·f + w‖² + ε‖f − f_ref‖²_W` within the bounds.
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

/// A tension below or above its bound by at most this (N, relative) is set on the bound.
const POLISH_BAND: f64 = 1e-7;

fn settings() -> Result<DefaultSettings<f64>> {
    DefaultSettingsBuilder::default()
        .verbose(false)
        .presolve_enable(false)
        .input_sparse_dropzeros(false)
        .max_iter(QP_MAX_ITER)
        .tol_gap_abs(1e-10)
        .tol_gap_rel(1e-10)
        .tol_feas(1e-10)
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

/// `[I; −I]` (bounds only), CSC.
fn bounds_matrix(m: usize) -> CscMatrix<f64> {
    let colptr = (0..=m).map(|j| 2 * j).collect();
    let rowval = (0..m).flat_map(|j| [j, m + j]).collect();
    let nzval = (0..m).flat_map(|_| [1.0, -1.0]).collect();
    CscMatrix::new(2 * m, m, colptr, rowval, nzval)
}

/// The upper triangle of a dense symmetric `m × m` matrix, CSC (all entries structural).
fn upper_dense(m: usize) -> (Vec<usize>, Vec<usize>) {
    let mut colptr = vec![0];
    let mut rowval = Vec::new();
    for j in 0..m {
        rowval.extend(0..=j);
        colptr.push(rowval.len());
    }
    (colptr, rowval)
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
    p_vals: Vec<f64>,
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
            p_vals: Vec::new(),
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
                let s = DefaultSolver::new(&p, &self.q, &a, &self.b, &cones, settings()?)
                    .map_err(|e| solver_error("qp", e))?;
                self.qp.insert(s)
            }
        };
        solver.solve();
        let status = solver.solution.status;
        if matches!(status, SolverStatus::Solved | SolverStatus::AlmostSolved) {
            let mut f = [0.0; MAX_CABLES];
            f[..m].copy_from_slice(&solver.solution.x[..m]);
            if let Some(d) = polish(at, n, m, w, f_min, f_max, f)? {
                if d.feasible {
                    return Ok(d);
                }
            }
        }
        self.least_error(at, w, f_min, f_max)
    }

    /// `min ‖Aᵀ·f + w‖² + ε‖f − f_ref‖²_W` within the bounds (reported infeasible).
    fn least_error(
        &mut self,
        at: &[f64],
        w: &[f64],
        f_min: &[f64],
        f_max: &[f64],
    ) -> Result<Distribution> {
        let (n, m) = (self.n, self.m);
        let eps = LEAST_ERROR_REGULARISATION;
        // P = 2(A·Aᵀ + εW) (upper triangle, column by column), q = 2(A·w − εW·f_ref)
        self.p_vals.clear();
        for j in 0..m {
            for i in 0..=j {
                let g: f64 = (0..n).map(|r| at[r * m + i] * at[r * m + j]).sum();
                let reg = if i == j { eps * self.weights[i] } else { 0.0 };
                self.p_vals.push(2.0 * (g + reg));
            }
        }
        self.q.clear();
        for i in 0..m {
            let aw: f64 = (0..n).map(|r| at[r * m + i] * w[r]).sum();
            let f_ref = 0.5 * (f_min[i] + f_max[i]);
            self.q.push(2.0 * (aw - eps * self.weights[i] * f_ref));
        }
        self.b.clear();
        self.b.extend_from_slice(f_max);
        self.b.extend(f_min.iter().map(|v| -v));
        let solver = match self.least.as_mut() {
            Some(s) => {
                s.update_P(&self.p_vals)
                    .map_err(|e| solver_error("least error", e))?;
                s.update_q(&self.q)
                    .map_err(|e| solver_error("least error", e))?;
                s.update_b(&self.b)
                    .map_err(|e| solver_error("least error", e))?;
                s
            }
            None => {
                let (colptr, rowval) = upper_dense(m);
                let p = CscMatrix::new(m, m, colptr, rowval, self.p_vals.clone());
                let a = bounds_matrix(m);
                let cones = [NonnegativeConeT(2 * m)];
                let s = DefaultSolver::new(&p, &self.q, &a, &self.b, &cones, settings()?)
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

/// Tensions within [`POLISH_BAND`] of a bound set on it, the others moved by the least-norm
/// correction of the equilibrium (`None` if the free cables cannot carry it).
fn polish(
    at: &[f64],
    n: usize,
    m: usize,
    w: &[f64],
    f_min: &[f64],
    f_max: &[f64],
    mut f: [f64; MAX_CABLES],
) -> Result<Option<Distribution>> {
    let mut free = [0usize; MAX_CABLES];
    let mut k = 0;
    for i in 0..m {
        let band = POLISH_BAND * (1.0 + f_max[i].abs());
        if f[i] <= f_min[i] + band {
            f[i] = f_min[i];
        } else if f[i] >= f_max[i] - band {
            f[i] = f_max[i];
        } else {
            free[k] = i;
            k += 1;
        }
    }
    if k >= n {
        // residual r = Aᵀf + w; correct the free tensions by −M⁺ᵀ·r (M: the free columns)
        let mut r = [0.0; 6];
        for a in 0..n {
            r[a] = w[a] + (0..m).map(|i| at[a * m + i] * f[i]).sum::<f64>();
        }
        let mut sub = [0.0; 6 * MAX_CABLES];
        for a in 0..n {
            for (c, &j) in free[..k].iter().enumerate() {
                sub[a * k + c] = at[a * m + j];
            }
        }
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
        for (c, &j) in free[..k].iter().enumerate() {
            f[j] += delta[c];
        }
    }
    tension::finish(at, n, m, w, f, Method::Qp, Some((f_min, f_max))).map(Some)
}
