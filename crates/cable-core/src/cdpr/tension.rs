//! Tension distribution: cable tensions `f` with `Aᵀ·f + w = 0` and `f_min ≤ f ≤ f_max`.
//!
//! * [`minimum_norm`]: `f = −A⁺ᵀ·w`, the least-norm solution (seed 003 eq. 8), bounds ignored;
//! * [`closed_form`]: `f = f_ref − A⁺ᵀ·(w + Aᵀ·f_ref)` with `f_ref = (f_min + f_max)/2` (seed 002
//!   eq. 10), the solution nearest the middle of the tension range;
//! * [`improved_closed_form`]: the closed form, and while a tension is out of bounds the most
//!   violating cable is set to its bound and removed (its force moves into the wrench), down to
//!   the square case (Pott's improved closed-form method).
//!
//! All work in fixed-size stack buffers: no allocation per pose. `A⁺ᵀ = A·(AᵀA)⁻¹` comes from a
//! Cholesky factor of the `n × n` matrix `Aᵀ(Aᵀ)ᵀ`; a structure matrix without full row rank is
//! an error (the geometry is degenerate at that pose: the cables cannot hold every wrench).

use super::kinematics::solve_spd;
use super::robot::MAX_CABLES;
use crate::error::{check, CableError, Result};

/// Bound tolerance (N, relative to `f_max`) within which a tension counts as inside its bounds.
pub const BOUND_TOLERANCE: f64 = 1e-9;

/// Which method produced a distribution.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Least-norm solution, bounds ignored.
    MinimumNorm,
    /// Closed form about the middle of the range.
    ClosedForm,
    /// Improved closed form.
    ImprovedClosedForm,
    /// Quadratic programme (clarabel), polished.
    Qp,
    /// Least wrench error within the bounds (no feasible tensions exist).
    LeastWrenchError,
    /// The fallback chain: improved closed form, then the QP, then the least wrench error
    /// (a distribution reports the method that answered, never this one).
    Auto,
}

impl Method {
    /// Its name (`"minimum_norm"`, `"closed_form"`, `"improved_closed_form"`).
    pub fn name(self) -> &'static str {
        match self {
            Self::MinimumNorm => "minimum_norm",
            Self::ClosedForm => "closed_form",
            Self::ImprovedClosedForm => "improved_closed_form",
            Self::Qp => "qp",
            Self::LeastWrenchError => "least_wrench_error",
            Self::Auto => "auto",
        }
    }

    /// From its name.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "minimum_norm" => Ok(Self::MinimumNorm),
            "closed_form" => Ok(Self::ClosedForm),
            "improved_closed_form" => Ok(Self::ImprovedClosedForm),
            "qp" => Ok(Self::Qp),
            "least_wrench_error" => Ok(Self::LeastWrenchError),
            "auto" => Ok(Self::Auto),
            other => Err(CableError::InvalidOption {
                name: "method".into(),
                value: other.into(),
                allowed: "auto, minimum_norm, closed_form, improved_closed_form, qp, \
                          least_wrench_error"
                    .into(),
            }),
        }
    }
}

/// A tension distribution at one pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distribution {
    /// Tensions (N), the first `m` entries.
    pub f: [f64; MAX_CABLES],
    /// Cables `m`.
    pub m: usize,
    /// The method that answered.
    pub method: Method,
    /// Whether `f` satisfies the equilibrium and the bounds.
    pub feasible: bool,
    /// `‖Aᵀ·f + w‖₂` (N and N·m mixed, as the wrench is).
    pub residual: f64,
}

impl Distribution {
    /// The tensions.
    pub fn tensions(&self) -> &[f64] {
        &self.f[..self.m]
    }
}

/// The structure matrix restricted to the cables in `cols`, row-major `n × k`.
pub(super) fn columns(at: &[f64], n: usize, m: usize, cols: &[usize], out: &mut [f64]) {
    let k = cols.len();
    for r in 0..n {
        for (c, &j) in cols.iter().enumerate() {
            out[r * k + c] = at[r * m + j];
        }
    }
}

/// `f = f_ref − Mᵀ·y` with `y = (M·Mᵀ)⁻¹·(w + M·f_ref)` for `M` `n × k` row-major (`f_ref = 0`:
/// least norm); returns `y`, the equality's multipliers.
pub(super) fn project(
    mat: &[f64],
    n: usize,
    k: usize,
    w: &[f64],
    f_ref: &[f64],
    f: &mut [f64],
) -> Result<[f64; 6]> {
    let mut mmt = [0.0; 36];
    let mut r = [0.0; 6];
    for a in 0..n {
        let ra = &mat[a * k..(a + 1) * k];
        for b in 0..=a {
            let rb = &mat[b * k..(b + 1) * k];
            let s: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
            mmt[a * n + b] = s;
            mmt[b * n + a] = s;
        }
        r[a] = w[a] + ra.iter().zip(f_ref).map(|(x, y)| x * y).sum::<f64>();
    }
    let y = solve_spd(&mmt, &r, n).ok_or_else(|| CableError::InvalidParameter {
        name: "structure matrix".into(),
        value: (0..n).map(|i| mmt[i * n + i]).fold(f64::INFINITY, f64::min),
        requirement: "of full row rank (degenerate geometry: the cables cannot hold every \
                      wrench at this pose)",
    })?;
    for c in 0..k {
        f[c] = f_ref[c] - (0..n).map(|a| mat[a * k + c] * y[a]).sum::<f64>();
    }
    Ok(y)
}

pub(super) fn checked(at: &[f64], n: usize, m: usize, w: &[f64]) -> Result<()> {
    if !(1..=6).contains(&n) || m < n || m > MAX_CABLES {
        return Err(CableError::Shape {
            what: "structure matrix".into(),
            expected: format!("(n, m) with 1 <= n <= 6 and n <= m <= {MAX_CABLES}"),
            got: format!("({n}, {m})"),
        });
    }
    check::len("structure matrix", at, n * m)?;
    check::all_finite("structure matrix", at, m)?;
    check::len("wrench", w, n)?;
    check::all_finite("wrench", w, 1)
}

pub(super) fn bounds_checked(m: usize, f_min: &[f64], f_max: &[f64]) -> Result<()> {
    check::len("f_min", f_min, m)?;
    check::len("f_max", f_max, m)?;
    // names are built only for an error: the check allocates nothing on the controller path
    for i in 0..m {
        let (lo, hi) = (f_min[i], f_max[i]);
        if !(lo.is_finite() && lo >= 0.0) {
            check::non_negative(&format!("f_min[{i}]"), lo)?;
        }
        if !hi.is_finite() {
            check::finite(&format!("f_max[{i}]"), hi)?;
        }
        if hi < lo {
            return Err(CableError::InvalidParameter {
                name: format!("f_max[{i}]"),
                value: hi,
                requirement: "at least f_min",
            });
        }
    }
    Ok(())
}

fn within(f: f64, lo: f64, hi: f64) -> bool {
    let tol = BOUND_TOLERANCE * (1.0 + hi.abs());
    f >= lo - tol && f <= hi + tol
}

pub(super) fn finish(
    at: &[f64],
    n: usize,
    m: usize,
    w: &[f64],
    f: [f64; MAX_CABLES],
    method: Method,
    bounds: Option<(&[f64], &[f64])>,
) -> Result<Distribution> {
    let mut f = f;
    if let Some((lo, hi)) = bounds {
        // a tension within the tolerance of its bound is put on it (bounds hold exactly)
        for i in 0..m {
            if f[i] < lo[i] && within(f[i], lo[i], hi[i]) {
                f[i] = lo[i];
            } else if f[i] > hi[i] && within(f[i], lo[i], hi[i]) {
                f[i] = hi[i];
            }
        }
    }
    // ‖Aᵀ·f + w‖ scaled by its largest entry, so that a wrench near the float range (1e154
    // per component) gives its finite norm, not an overflowed square
    let mut e = [0.0; 6];
    for a in 0..n {
        e[a] = w[a] + (0..m).map(|i| at[a * m + i] * f[i]).sum::<f64>();
    }
    check::result_finite(
        "tensions",
        &f[..m],
        1,
        "the wrench or the geometry is too extreme",
    )?;
    let largest = e[..n].iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    let residual = if largest > 0.0 && largest.is_finite() {
        largest
            * e[..n]
                .iter()
                .map(|v| (v / largest).powi(2))
                .sum::<f64>()
                .sqrt()
    } else {
        largest
    };
    check::result_finite(
        "residual wrench",
        &[residual],
        1,
        "the wrench or the geometry is too extreme",
    )?;
    let scale = 1.0
        + w.iter().map(|v| v.abs()).fold(0.0, f64::max)
        + f[..m].iter().map(|v| v.abs()).fold(0.0, f64::max);
    let feasible = residual <= 1e-9 * scale
        && bounds.is_none_or(|(lo, hi)| (0..m).all(|i| f[i] >= lo[i] && f[i] <= hi[i]));
    Ok(Distribution {
        f,
        m,
        method,
        feasible,
        residual,
    })
}

/// Least-norm tensions `f = −A⁺ᵀ·w` (seed 003 eq. 8; bounds ignored: here `feasible` only says
/// the equilibrium holds — a robot's `distribute` also judges them by its bounds). `at` is
/// `Aᵀ`, row-major `n × m`.
pub fn minimum_norm(at: &[f64], n: usize, m: usize, w: &[f64]) -> Result<Distribution> {
    checked(at, n, m, w)?;
    let mut f = [0.0; MAX_CABLES];
    project(at, n, m, w, &[0.0; MAX_CABLES][..m], &mut f[..m])?;
    finish(at, n, m, w, f, Method::MinimumNorm, None)
}

/// Closed-form tensions about the middle of the range (seed 002 eq. 10); `feasible` says
/// whether they also respect `[f_min, f_max]`.
pub fn closed_form(
    at: &[f64],
    n: usize,
    m: usize,
    w: &[f64],
    f_min: &[f64],
    f_max: &[f64],
) -> Result<Distribution> {
    checked(at, n, m, w)?;
    bounds_checked(m, f_min, f_max)?;
    let mut f_ref = [0.0; MAX_CABLES];
    for i in 0..m {
        f_ref[i] = 0.5 * (f_min[i] + f_max[i]);
    }
    let mut f = [0.0; MAX_CABLES];
    project(at, n, m, w, &f_ref[..m], &mut f[..m])?;
    finish(at, n, m, w, f, Method::ClosedForm, Some((f_min, f_max)))
}

/// The improved closed-form method: the closed form, then, while a tension violates its bounds,
/// the most violating cable is fixed at that bound and removed (its force joins the wrench),
/// until the tensions fit or only `n` cables are left (then `feasible = false`; the tensions
/// returned satisfy the equilibrium but not every bound — never a silent clamp).
pub fn improved_closed_form(
    at: &[f64],
    n: usize,
    m: usize,
    w: &[f64],
    f_min: &[f64],
    f_max: &[f64],
) -> Result<Distribution> {
    checked(at, n, m, w)?;
    bounds_checked(m, f_min, f_max)?;
    let mut f = [0.0; MAX_CABLES];
    let mut active = [0usize; MAX_CABLES];
    for (i, a) in active.iter_mut().enumerate().take(m) {
        *a = i;
    }
    let mut k = m;
    let mut w_eff = [0.0; 6];
    w_eff[..n].copy_from_slice(w);
    let mut sub = [0.0; 6 * MAX_CABLES];
    let mut f_ref = [0.0; MAX_CABLES];
    let mut fa = [0.0; MAX_CABLES];
    let mut last = f; // the last tensions that hold the wrench (fixed cables and the rest)
    loop {
        let cols = &active[..k];
        columns(at, n, m, cols, &mut sub);
        for (c, &j) in cols.iter().enumerate() {
            f_ref[c] = 0.5 * (f_min[j] + f_max[j]);
        }
        match project(&sub[..n * k], n, k, &w_eff[..n], &f_ref[..k], &mut fa[..k]) {
            Ok(_) => {}
            // the cables left after fixing some cannot hold the wrench: infeasible, and the
            // previous tensions still hold it
            Err(_) if k < m => {
                f = last;
                break;
            }
            Err(e) => return Err(e),
        }
        for (c, &j) in cols.iter().enumerate() {
            f[j] = fa[c];
        }
        last = f;
        // the most violating cable, if any
        let mut worst: Option<(usize, f64, f64)> = None; // (position in cols, violation, bound)
        for (c, &j) in cols.iter().enumerate() {
            let (v, bound) = if fa[c] < f_min[j] {
                (f_min[j] - fa[c], f_min[j])
            } else {
                (fa[c] - f_max[j], f_max[j])
            };
            if !within(fa[c], f_min[j], f_max[j]) && worst.is_none_or(|(_, wv, _)| v > wv) {
                worst = Some((c, v, bound));
            }
        }
        match worst {
            Some((c, _, bound)) if k > n => {
                let j = cols[c];
                f[j] = bound;
                for a in 0..n {
                    w_eff[a] += at[a * m + j] * bound;
                }
                active.copy_within(c + 1..k, c);
                k -= 1;
            }
            _ => break,
        }
    }
    finish(
        at,
        n,
        m,
        w,
        f,
        Method::ImprovedClosedForm,
        Some((f_min, f_max)),
    )
}
