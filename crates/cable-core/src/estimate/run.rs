//! Whole logs through the filters: the batch loops, their results, and errors that name the
//! row of the log (the bindings only convert).
//!
//! A log is `T` rows: inputs `U` `(T, m)` (row `k` acting over the period that ends at sample
//! `k`), measurements `Y` `(T, p)`, and an optional mask `(T, p)` (true = measured). Row `k`
//! is one [`SrUkf::step`]. On an error the filter is left as it was after row `k − 1`.

use super::models::{Observe, Process};
use super::params::DualSrUkf;
use super::srukf::SrUkf;
use crate::error::{check, CableError, Result};

/// A filtered (and optionally smoothed) log. Row-major arrays; factors are lower-triangular.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterRun {
    /// Rows `T`.
    pub len: usize,
    /// States `n`.
    pub n: usize,
    /// Filtered means `(T, n)`.
    pub x: Vec<f64>,
    /// Filtered square-root covariances `(T, n, n)`, row-major per sample.
    pub s: Vec<f64>,
    /// Normalised innovation squared per row (NaN where nothing was measured).
    pub nis: Vec<f64>,
    /// Condition estimate of the covariance per row.
    pub condition: Vec<f64>,
    /// Recovered downdates per row.
    pub recovered: Vec<u32>,
    /// Measured channels per row.
    pub measured: Vec<usize>,
    /// Whether the row's update was rejected by the innovation gate.
    pub gated: Vec<bool>,
    /// Smoothed means `(T, n)` and factors `(T, n, n)` (square-root URTS), when asked for.
    pub smoothed: Option<(Vec<f64>, Vec<f64>)>,
}

/// A dual (state + parameter) filtered log.
#[derive(Debug, Clone, PartialEq)]
pub struct DualRun {
    /// Rows `T`.
    pub len: usize,
    /// State means `(T, n)`.
    pub x: Vec<f64>,
    /// Parameter means `(T, p)`.
    pub theta: Vec<f64>,
    /// Parameter standard deviations `(T, p)`: the square roots of the diagonal of `S·Sᵀ`.
    pub theta_std: Vec<f64>,
}

/// The rows `T` of a log: `Y` `(T, p)`, `U` `(T, m)` finite, `mask` `(T, p)` if given.
pub(crate) fn log_rows(
    us: &[f64],
    ys: &[f64],
    mask: Option<&[bool]>,
    m: usize,
    p: usize,
) -> Result<usize> {
    let t = ys.len() / p.max(1);
    rows("U", us, t, m)?;
    check::len("Y", ys, t * p)?;
    match mask {
        Some(mk) if mk.len() != t * p => Err(CableError::Shape {
            what: "mask".into(),
            expected: format!("({t}, {p})"),
            got: format!("{} values", mk.len()),
        }),
        _ => Ok(t),
    }
}

/// `(T, width)` rows of `data` (`width` 0 allows an empty array for any `T`), finite.
fn rows(what: &str, data: &[f64], t: usize, width: usize) -> Result<()> {
    if data.len() != t * width {
        return Err(CableError::Shape {
            what: what.into(),
            expected: format!("({t}, {width})"),
            got: format!("{} values", data.len()),
        });
    }
    check::all_finite(what, data, width)
}

/// The error of row `k`'s step, located in the log: a NaN measurement by its row and column, a
/// divergence by its row.
pub(crate) fn at_row(e: CableError, k: usize, p: usize) -> CableError {
    match e {
        CableError::FilterDiverged { .. } => CableError::FilterDiverged { step: k },
        CableError::NotFinite { index, value, .. } => CableError::NotFinite {
            what: "Y (mask the missing entries instead)".into(),
            index: k * p + index,
            value,
            location: format!(" (row {k}, column {index})"),
        },
        other => other,
    }
}

/// Column-major `n × n` factor → row-major, into `out`.
fn row_major(s: &[f64], n: usize, out: &mut [f64]) {
    for i in 0..n {
        for j in 0..n {
            out[i * n + j] = s[i + j * n];
        }
    }
}

impl<P: Process, H: Observe> SrUkf<P, H> {
    /// Filter a whole log (see the module header); with `smooth`, the square-root URTS
    /// smoother then runs backwards over it.
    pub fn run(
        &mut self,
        us: &[f64],
        ys: &[f64],
        mask: Option<&[bool]>,
        smooth: bool,
    ) -> Result<FilterRun> {
        let (n, p, m) = (self.n_states(), self.n_outputs(), self.process.n_inputs());
        let t = log_rows(us, ys, mask, m, p)?;
        let mut out = FilterRun {
            len: t,
            n,
            x: vec![0.0; t * n],
            s: vec![0.0; t * n * n],
            nis: vec![0.0; t],
            condition: vec![0.0; t],
            recovered: vec![0; t],
            measured: vec![0; t],
            gated: vec![false; t],
            smoothed: None,
        };
        let mut factors = if smooth {
            vec![0.0; t * n * n]
        } else {
            Vec::new()
        };
        for k in 0..t {
            let mk = mask.map(|v| &v[k * p..(k + 1) * p]);
            self.step(&us[k * m..(k + 1) * m], &ys[k * p..(k + 1) * p], mk)
                .map_err(|e| at_row(e, k, p))?;
            out.x[k * n..(k + 1) * n].copy_from_slice(self.x());
            let s = self.sqrt_covariance();
            if smooth {
                factors[k * n * n..(k + 1) * n * n].copy_from_slice(s);
            }
            row_major(s, n, &mut out.s[k * n * n..(k + 1) * n * n]);
            let h = self.health();
            out.nis[k] = h.nis;
            out.condition[k] = h.condition;
            out.recovered[k] = h.recovered;
            out.measured[k] = h.measured;
            out.gated[k] = h.gated;
        }
        if smooth {
            let (xs, ss, _) = self.smooth(&out.x, &factors, us)?;
            let mut s_rows = vec![0.0; t * n * n];
            for k in 0..t {
                let r = k * n * n..(k + 1) * n * n;
                row_major(&ss[r.clone()], n, &mut s_rows[r]);
            }
            out.smoothed = Some((xs, s_rows));
        }
        Ok(out)
    }
}

impl DualRun {
    /// Row `k`: the state mean, the parameter mean and their standard deviations from the
    /// parameter filter's square root `s` (column-major).
    pub(crate) fn record(&mut self, k: usize, x: &[f64], theta: &[f64], s: &[f64]) {
        let (n, p) = (x.len(), theta.len());
        self.x[k * n..(k + 1) * n].copy_from_slice(x);
        self.theta[k * p..(k + 1) * p].copy_from_slice(theta);
        for i in 0..p {
            self.theta_std[k * p + i] = (0..p).map(|j| s[i + j * p].powi(2)).sum::<f64>().sqrt();
        }
    }
}

/// What the log runner needs of a dual filter (the transmission's and a user model's).
pub(crate) trait DualSteps {
    /// States `n`, measured channels `q`, inputs `m`.
    fn sizes(&self) -> (usize, usize, usize);
    /// One step (see [`DualSrUkf::step`]).
    fn step(&mut self, u: &[f64], y: &[f64], mask: Option<&[bool]>) -> Result<()>;
    /// The state filter's mean, the parameter filter's mean and square root.
    fn estimates(&self) -> (&[f64], &[f64], &[f64]);
}

/// Filter a whole log through both filters of `d`; a failing row's error names its row.
pub(crate) fn run_dual<D: DualSteps>(
    d: &mut D,
    us: &[f64],
    ys: &[f64],
    mask: Option<&[bool]>,
) -> Result<DualRun> {
    let (n, q, m) = d.sizes();
    let t = log_rows(us, ys, mask, m, q)?;
    let p = d.estimates().1.len();
    let mut out = DualRun {
        len: t,
        x: vec![0.0; t * n],
        theta: vec![0.0; t * p],
        theta_std: vec![0.0; t * p],
    };
    for k in 0..t {
        let mk = mask.map(|v| &v[k * q..(k + 1) * q]);
        d.step(&us[k * m..(k + 1) * m], &ys[k * q..(k + 1) * q], mk)
            .map_err(|e| at_row(e, k, q))?;
        let (x, theta, s) = d.estimates();
        out.record(k, x, theta, s);
    }
    Ok(out)
}

impl DualSteps for DualSrUkf {
    fn sizes(&self) -> (usize, usize, usize) {
        let (n, q) = (self.state.n_states(), self.state.n_outputs());
        (n, q, self.base_inputs())
    }
    fn step(&mut self, u: &[f64], y: &[f64], mask: Option<&[bool]>) -> Result<()> {
        DualSrUkf::step(self, u, y, mask)
    }
    fn estimates(&self) -> (&[f64], &[f64], &[f64]) {
        (
            self.state.x(),
            self.params.x(),
            self.params.sqrt_covariance(),
        )
    }
}

impl DualSrUkf {
    /// Filter a whole log through both filters (see the module header).
    pub fn run(&mut self, us: &[f64], ys: &[f64], mask: Option<&[bool]>) -> Result<DualRun> {
        run_dual(self, us, ys, mask)
    }
}
