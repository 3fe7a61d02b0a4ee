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
/// its bound; each gives a candidate face, tried tightest first.
const POLISH_BANDS: [f64; 4] = [1e-8, 1e-6, 1e-4, 1e-2];

/// Clarabel's settings: data updates allowed; `tight` asks for 1e-10 gaps (the QP, whose
/// answer is then polished), else clarabel's defaults (the least-error fallback).
fn settings(tight: bool) -> Result<DefaultSettings<f64>> {
    let tol = if tight { 1e-8 } else { 1e-7 };
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
    /// The last QP answer's face (which cables sat on which bound): the warm start.
    face: Option<Face>,
    /// Interior-point solves since construction.
    pub solves: u64,
    /// QP answers found on the previous answer's face, without an interior-point solve.
    pub warm_hits: u64,
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
            face: None,
            solves: 0,
            warm_hits: 0,
        })
    }

    /// Whether the solvers are built (the next solve is warm).
    pub fn is_warm(&self) -> bool {
        self.qp.is_some()
    }

    /// Forget the built solvers and the last face (the next solve is cold).
    pub fn reset(&mut self) {
        self.qp = None;
        self.least = None;
        self.face = None;
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
            Method::MinimumNorm => {
                // `feasible` means one thing for every method: equilibrium *and* the bounds
                // (the minimum-norm tensions ignore the bounds but are judged by them)
                tension::bounds_checked(m, f_min, f_max)?;
                let mut d = tension::minimum_norm(at, n, m, w)?;
                d.feasible &= (0..m).all(|i| d.f[i] >= f_min[i] && d.f[i] <= f_max[i]);
                Ok(d)
            }
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
        // warm path: the previous answer's face, if its exact optimum passes the KKT test here
        // (neighbouring poses of a trajectory share a face), is this pose's optimum
        if let Some(face) = self.face {
            if let Some(f) = solve_on_face(at, n, m, w, (f_min, f_max), &self.weights, &face) {
                let d = tension::finish(at, n, m, w, f, Method::Qp, Some((f_min, f_max)))?;
                if d.feasible {
                    self.warm_hits += 1;
                    return Ok(d);
                }
            }
        }
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
            if let Some(d) = polish(at, n, m, w, (f_min, f_max), &self.weights, f)? {
                if d.feasible {
                    self.face = Some(face_of(d.tensions(), f_min, f_max));
                    return Ok(d);
                }
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
        // in units of the largest force involved (an interior point misjudges feasibility
        // when the error and the tensions differ by orders of magnitude)
        let scale = w.iter().chain(f_max).fold(1.0_f64, |a, v| a.max(v.abs()));
        let mid = |i: usize| 0.5 * (f_min[i] + f_max[i]) / scale;
        self.q.clear();
        self.q
            .extend((0..m).map(|i| -eps * self.weights[i] * mid(i)));
        self.q.extend(std::iter::repeat_n(0.0, n));
        self.b.clear();
        self.b.extend(w.iter().map(|v| -v / scale));
        self.b.extend(f_max.iter().map(|v| v / scale));
        self.b.extend(f_min.iter().map(|v| -v / scale));
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
        // the fallback's answer is reported infeasible with its residual, so an interior point
        // stopped early (iteration cap, slow progress) still serves if it is finite
        let usable = matches!(
            solver.solution.status,
            SolverStatus::Solved
                | SolverStatus::AlmostSolved
                | SolverStatus::MaxIterations
                | SolverStatus::InsufficientProgress
        ) && solver.solution.x[..m].iter().all(|v| v.is_finite());
        if !usable {
            return Err(CableError::NotConverged {
                what: "least-wrench-error tension distribution".into(),
                limit: QP_MAX_ITER as usize,
                hint: "the structure matrix or the wrench is badly scaled",
            });
        }
        let mut f = [0.0; MAX_CABLES];
        for i in 0..m {
            f[i] = (scale * solver.solution.x[i]).clamp(f_min[i], f_max[i]);
        }
        // the interior point stops at its tolerance, up to ~0.5 N of wrench error above the
        // optimum: the exact optimum on the face it found (then its neighbours) replaces it
        // whenever it is at least as good
        let objective =
            |f: &[f64]| least_error_objective(at, n, m, w, f, (f_min, f_max), &self.weights, eps);
        if let Some(exact) = polish_least_error(at, n, m, w, (f_min, f_max), &self.weights, eps, &f)
        {
            if objective(&exact[..m]) <= objective(&f[..m]) {
                f = exact;
            }
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

/// `½‖Aᵀf + w‖² + ½ε Σ wᵢ (fᵢ − f_mid,i)²`: the least-wrench-error objective (the
/// regularisation picks one answer among equally good ones, towards the middle of the range).
#[allow(clippy::too_many_arguments)]
fn least_error_objective(
    at: &[f64],
    n: usize,
    m: usize,
    w: &[f64],
    f: &[f64],
    (f_min, f_max): (&[f64], &[f64]),
    weights: &[f64],
    eps: f64,
) -> f64 {
    let err: f64 = wrench_residual(at, n, m, w, f)[..n]
        .iter()
        .map(|r| r * r)
        .sum();
    let reg: f64 = (0..m)
        .map(|i| weights[i] * (f[i] - 0.5 * (f_min[i] + f_max[i])).powi(2))
        .sum();
    0.5 * err + 0.5 * eps * reg
}

/// `Aᵀf + w` (the first `n` entries).
fn wrench_residual(at: &[f64], n: usize, m: usize, w: &[f64], f: &[f64]) -> [f64; 6] {
    let mut r = [0.0; 6];
    for (a, ra) in r.iter_mut().enumerate().take(n) {
        *ra = (0..m).map(|i| at[a * m + i] * f[i]).sum::<f64>() + w[a];
    }
    r
}

/// The exact minimiser of the least-wrench-error objective within the bounds, by a primal
/// active set started from `start` (the interior point's answer): the free tensions solve the
/// objective's normal equations with the held ones at their bounds; a free tension past a bound
/// is held there, a held one whose gradient points into the box is freed; at most `4m + 4`
/// changes of the face. `None` if it does not settle (the interior point's answer then stands).
#[allow(clippy::too_many_arguments)]
fn polish_least_error(
    at: &[f64],
    n: usize,
    m: usize,
    w: &[f64],
    (f_min, f_max): (&[f64], &[f64]),
    weights: &[f64],
    eps: f64,
    start: &[f64; MAX_CABLES],
) -> Option<[f64; MAX_CABLES]> {
    let band = |i: usize| 1e-6 * (1.0 + f_max[i].abs());
    let mut face: Face = [0; MAX_CABLES];
    for i in 0..m {
        if start[i] <= f_min[i] + band(i) {
            face[i] = -1;
        } else if start[i] >= f_max[i] - band(i) {
            face[i] = 1;
        }
    }
    let mid = |i: usize| 0.5 * (f_min[i] + f_max[i]);
    for _ in 0..4 * m + 4 {
        let mut f = [0.0; MAX_CABLES];
        let free: Vec<usize> = (0..m).filter(|&i| face[i] == 0).collect();
        for i in 0..m {
            f[i] = match face[i] {
                -1 => f_min[i],
                1 => f_max[i],
                _ => 0.0,
            };
        }
        if !free.is_empty() {
            // residual of the held cables: r_H = A_Hᵀ f_H + w
            let r_held = wrench_residual(at, n, m, w, &f[..m]);
            let k = free.len();
            let h = nalgebra::DMatrix::from_fn(k, k, |p, q| {
                let (i, j) = (free[p], free[q]);
                let mut v: f64 = (0..n).map(|a| at[a * m + i] * at[a * m + j]).sum();
                if p == q {
                    v += eps * weights[i];
                }
                v
            });
            let rhs = nalgebra::DVector::from_fn(k, |p, _| {
                let i = free[p];
                -(0..n).map(|a| at[a * m + i] * r_held[a]).sum::<f64>() + eps * weights[i] * mid(i)
            });
            let x = h.cholesky()?.solve(&rhs);
            for (p, &i) in free.iter().enumerate() {
                f[i] = x[p];
            }
        }
        if f[..m].iter().any(|v| !v.is_finite()) {
            return None;
        }
        // the free tension furthest past a bound is held there
        let worst = free
            .iter()
            .map(|&i| {
                let past = (f_min[i] - f[i]).max(f[i] - f_max[i]);
                (i, past / (1.0 + f_max[i].abs()))
            })
            .filter(|&(_, past)| past > 1e-12)
            .max_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((i, _)) = worst {
            face[i] = if f[i] < f_min[i] { -1 } else { 1 };
            continue;
        }
        // a held tension whose gradient points into the box is freed (the most negative
        // multiplier first)
        let r = wrench_residual(at, n, m, w, &f[..m]);
        let scale = 1.0 + r[..n].iter().map(|v| v.abs()).fold(0.0, f64::max);
        let release = (0..m)
            .filter(|&i| face[i] != 0)
            .map(|i| {
                let g = (0..n).map(|a| at[a * m + i] * r[a]).sum::<f64>()
                    + eps * weights[i] * (f[i] - mid(i));
                // held low: a multiplier −g·(−1) ≥ 0 means g ≥ 0; held high: g ≤ 0
                (i, f64::from(face[i]) * g / scale)
            })
            .filter(|&(_, lam)| lam > 1e-12)
            .max_by(|a, b| a.1.total_cmp(&b.1));
        match release {
            Some((i, _)) => face[i] = 0,
            None => return Some(f),
        }
    }
    None
}

fn diagonal(weights: &[f64]) -> CscMatrix<f64> {
    let m = weights.len();
    CscMatrix::new(m, m, (0..=m).collect(), (0..m).collect(), weights.to_vec())
}

/// Per cable: `-1` held at `f_min`, `1` at `f_max`, `0` free.
type Face = [i8; MAX_CABLES];

/// The exact optimum of `min ½‖f − f_ref‖²_W, Aᵀf + w = 0` with the cables of `face` held at
/// their bounds, if it satisfies every KKT condition of the bounded problem — the free
/// tensions within their bounds and the held cables' multipliers non-negative — and is then
/// the QP's global optimum (the problem is convex). `None` otherwise.
fn solve_on_face(
    at: &[f64],
    n: usize,
    m: usize,
    w: &[f64],
    (f_min, f_max): (&[f64], &[f64]),
    weights: &[f64],
    face: &Face,
) -> Option<[f64; MAX_CABLES]> {
    let mut f = [0.0; MAX_CABLES];
    let mut free = [0usize; MAX_CABLES];
    let k = hold(face, (f_min, f_max), &mut f[..m], &mut free);
    if k < n {
        return None;
    }
    let free = &free[..k];
    let mut sub = [0.0; 6 * MAX_CABLES];
    tension::columns(at, n, m, free, &mut sub);
    // w_eff = w + the held cables' forces; scaled variables g = W^½·f make the weighted
    // problem the plain closed form (multipliers unchanged)
    let mut w_eff = [0.0; 6];
    for a in 0..n {
        w_eff[a] = w[a]
            + (0..m)
                .filter(|&i| face[i] != 0)
                .map(|i| at[a * m + i] * f[i])
                .sum::<f64>();
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
    let y = tension::project(&sub[..n * k], n, k, &w_eff[..n], &g_ref[..k], &mut g[..k]).ok()?;
    for (c, &j) in free.iter().enumerate() {
        f[j] = g[c] * weights[j].sqrt().recip();
        if f[j] < f_min[j] || f[j] > f_max[j] {
            return None;
        }
    }
    // held cables: W_j(f_j − r_j) + a_jᵀy is the lower bound's multiplier (≥ 0), its negative
    // the upper bound's
    for i in (0..m).filter(|&i| face[i] != 0) {
        let r = 0.5 * (f_min[i] + f_max[i]);
        let grad = weights[i] * (f[i] - r) + (0..n).map(|a| at[a * m + i] * y[a]).sum::<f64>();
        let tol = 1e-9 * (1.0 + weights[i] * (f_max[i] - f_min[i]));
        if f64::from(face[i]) * grad > tol {
            return None;
        }
    }
    Some(f)
}

/// Set the held cables of `face` on their bounds in `f`; the free cables' indices go to `free`,
/// and their count is returned.
fn hold(face: &Face, (f_min, f_max): (&[f64], &[f64]), f: &mut [f64], free: &mut [usize]) -> usize {
    let mut k = 0;
    for (i, v) in f.iter_mut().enumerate() {
        match face[i] {
            -1 => *v = f_min[i],
            1 => *v = f_max[i],
            _ => {
                free[k] = i;
                k += 1;
            }
        }
    }
    k
}

/// The face of a distribution: the cables exactly at a bound.
fn face_of(f: &[f64], f_min: &[f64], f_max: &[f64]) -> Face {
    let mut face = [0; MAX_CABLES];
    for (i, v) in f.iter().enumerate() {
        face[i] = if *v <= f_min[i] {
            -1
        } else if *v >= f_max[i] {
            1
        } else {
            0
        };
    }
    face
}

/// The interior-point answer made exact: for each band, the tensions within it of a bound are
/// held there, and the first such face whose exact optimum passes the KKT test
/// ([`solve_on_face`]) is the answer. If none does, the interior-point answer gets the
/// least-norm equilibrium correction on its free cables instead. `None` if the free cables
/// cannot hold the wrench.
fn polish(
    at: &[f64],
    n: usize,
    m: usize,
    w: &[f64],
    bounds: (&[f64], &[f64]),
    weights: &[f64],
    ipm: [f64; MAX_CABLES],
) -> Result<Option<Distribution>> {
    let (f_min, f_max) = bounds;
    let face_at = |band: f64| {
        let mut face = [0; MAX_CABLES];
        for i in 0..m {
            let b = band * (1.0 + f_max[i].abs());
            face[i] = if ipm[i] <= f_min[i] + b {
                -1
            } else if ipm[i] >= f_max[i] - b {
                1
            } else {
                0
            };
        }
        face
    };
    for band in POLISH_BANDS {
        if let Some(f) = solve_on_face(at, n, m, w, bounds, weights, &face_at(band)) {
            return tension::finish(at, n, m, w, f, Method::Qp, Some(bounds)).map(Some);
        }
    }
    // no face passed: correct the interior-point answer's equilibrium by least norm
    let face = face_at(POLISH_BANDS[0]);
    let mut f = ipm;
    let mut free = [0usize; MAX_CABLES];
    let k = hold(&face, (f_min, f_max), &mut f[..m], &mut free);
    if k >= n {
        let mut r = [0.0; 6];
        for a in 0..n {
            r[a] = w[a] + (0..m).map(|i| at[a * m + i] * f[i]).sum::<f64>();
        }
        let mut sub = [0.0; 6 * MAX_CABLES];
        tension::columns(at, n, m, &free[..k], &mut sub);
        let mut delta = [0.0; MAX_CABLES];
        let zero = [0.0; MAX_CABLES];
        if tension::project(&sub[..n * k], n, k, &r[..n], &zero[..k], &mut delta[..k]).is_err() {
            return Ok(None);
        }
        for (c, &j) in free[..k].iter().enumerate() {
            f[j] += delta[c];
        }
    }
    tension::finish(at, n, m, w, f, Method::Qp, Some(bounds)).map(Some)
}
