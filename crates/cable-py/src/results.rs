//! Typed results (numpy arrays as read-only attributes), converted from the core's
//! `FilterRun`, `DualRun`, `Health` and `LmReport`.

use cable_core::cdpr::CapacityMut;
use cable_core::estimate::{DualRun as CoreDualRun, FilterRun as CoreFilterRun, Health};
use cable_core::identify::LmReport;
use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::convert::to_matrix;

fn cube(py: Python<'_>, data: Vec<f64>, t: usize, n: usize) -> Py<PyArray3<f64>> {
    Array3::from_shape_vec((t, n, n), data)
        .expect("buffer length matches the shape by construction")
        .into_pyarray(py)
        .unbind()
}

/// A filtered log (`SrUkf.run`): `x` `(T, n)` means, `S` `(T, n, n)` lower square roots of the
/// covariances, per row `nis`, `condition`, `recovered` downdates, `measured` channels and
/// `gated` (rejected by the innovation gate); with `smooth=True` also `x_smooth`, `S_smooth`.
#[pyclass(frozen, module = "cablekit._cablekit")]
pub struct FilterRun {
    #[pyo3(get)]
    x: Py<PyArray2<f64>>,
    #[pyo3(get, name = "S")]
    s: Py<PyArray3<f64>>,
    #[pyo3(get)]
    nis: Py<PyArray1<f64>>,
    #[pyo3(get)]
    condition: Py<PyArray1<f64>>,
    #[pyo3(get)]
    recovered: Py<PyArray1<u32>>,
    #[pyo3(get)]
    measured: Py<PyArray1<u64>>,
    #[pyo3(get)]
    gated: Py<PyArray1<bool>>,
    #[pyo3(get)]
    x_smooth: Option<Py<PyArray2<f64>>>,
    #[pyo3(get, name = "S_smooth")]
    s_smooth: Option<Py<PyArray3<f64>>>,
}

impl FilterRun {
    pub fn new(py: Python<'_>, run: CoreFilterRun) -> Self {
        let (t, n) = (run.len, run.n);
        let (x_smooth, s_smooth) = match run.smoothed {
            Some((xs, ss)) => (
                Some(to_matrix(py, xs, t, n).unbind()),
                Some(cube(py, ss, t, n)),
            ),
            None => (None, None),
        };
        let measured: Vec<u64> = run.measured.iter().map(|&q| q as u64).collect();
        Self {
            x: to_matrix(py, run.x, t, n).unbind(),
            s: cube(py, run.s, t, n),
            nis: run.nis.into_pyarray(py).unbind(),
            condition: run.condition.into_pyarray(py).unbind(),
            recovered: run.recovered.into_pyarray(py).unbind(),
            measured: measured.into_pyarray(py).unbind(),
            gated: run.gated.into_pyarray(py).unbind(),
            x_smooth,
            s_smooth,
        }
    }
}

#[pymethods]
impl FilterRun {
    fn __repr__(&self, py: Python<'_>) -> String {
        let shape = self.x.bind(py).shape().to_vec();
        format!(
            "FilterRun(T={}, n={}, smoothed={})",
            shape[0],
            shape[1],
            self.x_smooth.is_some()
        )
    }
}

/// A dual-filtered log (`DualSrUkf.run`): state means `x` `(T, n)`, parameter means `theta`
/// `(T, p)` and their standard deviations `theta_std` `(T, p)`.
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct DualRun {
    x: Py<PyArray2<f64>>,
    theta: Py<PyArray2<f64>>,
    theta_std: Py<PyArray2<f64>>,
}

impl DualRun {
    pub fn new(py: Python<'_>, run: CoreDualRun, n: usize, p: usize) -> Self {
        let t = run.len;
        Self {
            x: to_matrix(py, run.x, t, n).unbind(),
            theta: to_matrix(py, run.theta, t, p).unbind(),
            theta_std: to_matrix(py, run.theta_std, t, p).unbind(),
        }
    }
}

/// Health of a filter's last step (`SrUkf.health`).
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct FilterHealth {
    /// Normalised innovation squared of the last update (NaN without one).
    nis: f64,
    /// Channels measured in the last update.
    measured: usize,
    /// Condition estimate of the covariance.
    condition: f64,
    /// Downdates recovered in the last step.
    recovered: u32,
    /// Downdates recovered since construction.
    recoveries_total: u64,
    /// Whether the last update was rejected by the innovation gate.
    gated: bool,
    /// Updates rejected by the gate since construction.
    rejected_total: u64,
    /// Steps since construction or the last reset.
    steps: u64,
}

impl From<Health> for FilterHealth {
    fn from(h: Health) -> Self {
        Self {
            nis: h.nis,
            measured: h.measured,
            condition: h.condition,
            recovered: h.recovered,
            recoveries_total: h.recoveries_total,
            gated: h.gated,
            rejected_total: h.rejected_total,
            steps: h.steps,
        }
    }
}

#[pymethods]
impl FilterHealth {
    fn __repr__(&self) -> String {
        format!(
            "FilterHealth(nis={}, measured={}, condition={:.3e}, recovered={}, \
             recoveries_total={}, gated={}, rejected_total={}, steps={})",
            self.nis,
            self.measured,
            self.condition,
            self.recovered,
            self.recoveries_total,
            self.gated,
            self.rejected_total,
            self.steps
        )
    }
}

/// A bounded Levenberg–Marquardt fit (`JointProblem.fit`): fitted `params` `(p,)`, `cost` and
/// `initial_cost` (½‖r‖²), `iterations`, `evaluations`, `converged` (a tolerance, not the
/// iteration cap, stopped it), `at_bound` `(p,)`, `jacobian` `(m, p)` and `residuals` `(m,)` at
/// the fitted parameters.
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct FitReport {
    params: Py<PyArray1<f64>>,
    cost: f64,
    initial_cost: f64,
    iterations: usize,
    evaluations: usize,
    converged: bool,
    at_bound: Py<PyArray1<bool>>,
    jacobian: Py<PyArray2<f64>>,
    residuals: Py<PyArray1<f64>>,
}

impl FitReport {
    pub fn new(py: Python<'_>, rep: LmReport) -> Self {
        let (m, p) = (rep.residuals.len(), rep.params.len());
        Self {
            params: rep.params.into_pyarray(py).unbind(),
            cost: rep.cost,
            initial_cost: rep.initial_cost,
            iterations: rep.iterations,
            evaluations: rep.evaluations,
            converged: rep.converged,
            at_bound: rep.at_bound.into_pyarray(py).unbind(),
            jacobian: to_matrix(py, rep.jacobian, m, p).unbind(),
            residuals: rep.residuals.into_pyarray(py).unbind(),
        }
    }
}

#[pymethods]
impl FitReport {
    fn __repr__(&self) -> String {
        format!(
            "FitReport(cost={:.6e}, initial_cost={:.6e}, iterations={}, converged={})",
            self.cost, self.initial_cost, self.iterations, self.converged
        )
    }
}

/// One fitted parameter of a candidate (`JointProblem.param_specs`): the candidate `effect`
/// id, `name` and `unit`, the `reference` value at which the effect is off, the `initial`
/// value, the bounds `lower`/`upper`, the typical `scale`, whether it is found by `grid`
/// search, and further `starts` tried before the local search.
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct ParamSpec {
    effect: String,
    name: String,
    unit: String,
    reference: f64,
    initial: f64,
    lower: f64,
    upper: f64,
    scale: f64,
    grid: bool,
    starts: Vec<f64>,
}

impl ParamSpec {
    pub fn new(effect: String, s: cable_core::identify::ParamSpec) -> Self {
        Self {
            effect,
            name: s.name,
            unit: s.unit.to_owned(),
            reference: s.reference,
            initial: s.initial,
            lower: s.lower,
            upper: s.upper,
            scale: s.scale,
            grid: s.grid,
            starts: s.starts,
        }
    }
}

/// The constructor's arguments: `(effect, name, unit, reference, initial, lower, upper, scale,
/// grid, starts)`.
type ParamSpecArgs = (
    String,
    String,
    String,
    f64,
    f64,
    f64,
    f64,
    f64,
    bool,
    Vec<f64>,
);

#[pymethods]
impl ParamSpec {
    /// A spec from its fields (for pickling across processes, e.g. Ray workers).
    #[new]
    #[allow(clippy::too_many_arguments)]
    fn py_new(
        effect: String,
        name: String,
        unit: String,
        reference: f64,
        initial: f64,
        lower: f64,
        upper: f64,
        scale: f64,
        grid: bool,
        starts: Vec<f64>,
    ) -> Self {
        Self {
            effect,
            name,
            unit,
            reference,
            initial,
            lower,
            upper,
            scale,
            grid,
            starts,
        }
    }

    fn __getnewargs__(&self) -> ParamSpecArgs {
        (
            self.effect.clone(),
            self.name.clone(),
            self.unit.clone(),
            self.reference,
            self.initial,
            self.lower,
            self.upper,
            self.scale,
            self.grid,
            self.starts.clone(),
        )
    }

    fn __repr__(&self) -> String {
        format!(
            "ParamSpec({}:{} = {} {} in [{}, {}])",
            self.effect, self.name, self.initial, self.unit, self.lower, self.upper
        )
    }
}

/// Inverse kinematics of `T` poses (`Robot.inverse_kinematics`): cable `length` `(T, m)` (m)
/// and the structure matrices `structure` `(T, n, m)` (`Aᵀ`).
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct Kinematics {
    length: Py<PyArray2<f64>>,
    structure: Py<PyArray3<f64>>,
}

impl Kinematics {
    pub fn new(
        py: Python<'_>,
        length: Vec<f64>,
        structure: Vec<f64>,
        (t, n, m): (usize, usize, usize),
    ) -> Self {
        let structure = Array3::from_shape_vec((t, n, m), structure)
            .expect("buffer length matches the shape by construction")
            .into_pyarray(py)
            .unbind();
        Self {
            length: to_matrix(py, length, t, m).unbind(),
            structure,
        }
    }
}

/// Tensions at `T` poses (`Robot.distribute`): `f` `(T, m)` (N), per pose the `method` that
/// answered, whether the tensions are `feasible` (equilibrium and bounds) and the `residual`
/// wrench norm `‖Aᵀf + w‖`.
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct Tensions {
    f: Py<PyArray2<f64>>,
    method: Vec<&'static str>,
    feasible: Py<PyArray1<bool>>,
    residual: Py<PyArray1<f64>>,
}

impl Tensions {
    pub fn new(
        py: Python<'_>,
        f: Vec<f64>,
        (t, m): (usize, usize),
        method: &[cable_core::cdpr::Method],
        feasible: Vec<bool>,
        residual: Vec<f64>,
    ) -> Self {
        Self {
            f: to_matrix(py, f, t, m).unbind(),
            method: method.iter().map(|k| k.name()).collect(),
            feasible: feasible.into_pyarray(py).unbind(),
            residual: residual.into_pyarray(py).unbind(),
        }
    }
}

/// Capacity margins at `T` poses (`Robot.capacity`): the `margin` `(T,)` (N, moments divided
/// by the moment length; `≥ 0` inside the workspace, the radius of the largest extra wrench
/// ball), whether each pose is `feasible`, `degenerate` poses (rank-deficient `Aᵀ`, margin 0)
/// and the `weakest` external wrench direction `(T, n)`.
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct Capacity {
    margin: Py<PyArray1<f64>>,
    feasible: Py<PyArray1<bool>>,
    degenerate: Py<PyArray1<bool>>,
    weakest: Py<PyArray2<f64>>,
}

/// The owned arrays a capacity batch writes into, before they become a [`Capacity`].
pub struct CapacityBuffers {
    margin: Vec<f64>,
    feasible: Vec<bool>,
    degenerate: Vec<bool>,
    weakest: Vec<f64>,
}

impl CapacityBuffers {
    /// Zeroed arrays for `t` poses of an `n`-DOF robot.
    pub fn new(t: usize, n: usize) -> Self {
        Self {
            margin: vec![0.0; t],
            feasible: vec![false; t],
            degenerate: vec![false; t],
            weakest: vec![0.0; t * n],
        }
    }

    /// The core's view of them.
    pub fn out(&mut self) -> CapacityMut<'_> {
        CapacityMut {
            margin: &mut self.margin,
            feasible: &mut self.feasible,
            degenerate: &mut self.degenerate,
            weakest: &mut self.weakest,
        }
    }
}

impl Capacity {
    pub fn new(py: Python<'_>, b: CapacityBuffers, (t, n): (usize, usize)) -> Self {
        Self {
            margin: b.margin.into_pyarray(py).unbind(),
            feasible: b.feasible.into_pyarray(py).unbind(),
            degenerate: b.degenerate.into_pyarray(py).unbind(),
            weakest: to_matrix(py, b.weakest, t, n).unbind(),
        }
    }
}

/// One `TensionController.step`: tensions `f` `(m,)` (the `out` array when one was given),
/// the `method` that answered, `feasible`, the `residual` wrench norm and the `jump`, the
/// largest tension change since the previous step (N).
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct Step {
    f: Py<PyArray1<f64>>,
    method: &'static str,
    feasible: bool,
    residual: f64,
    jump: f64,
}

impl Step {
    pub fn new(
        f: Bound<'_, PyArray1<f64>>,
        method: cable_core::cdpr::Method,
        feasible: bool,
        residual: f64,
        jump: f64,
    ) -> Self {
        Self {
            f: f.unbind(),
            method: method.name(),
            feasible,
            residual,
            jump,
        }
    }
}

#[pymethods]
impl Step {
    fn __repr__(&self) -> String {
        format!(
            "Step(method={:?}, feasible={}, residual={:.3e}, jump={:.3})",
            self.method, self.feasible, self.residual, self.jump
        )
    }
}

/// `Robot.path_friction`: per sample and cable `(T, m)` the winch-side tension `pul` (N), the
/// `friction` `pul − ee` (N), the cable `speed` towards the winch (m/s) and the exit pulley's
/// `wrap` (rad).
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct PathRun {
    pul: Py<PyArray2<f64>>,
    friction: Py<PyArray2<f64>>,
    speed: Py<PyArray2<f64>>,
    wrap: Py<PyArray2<f64>>,
}

impl PathRun {
    pub fn new(py: Python<'_>, run: cable_core::cdpr::PathRun, (t, m): (usize, usize)) -> Self {
        Self {
            pul: to_matrix(py, run.pul, t, m).unbind(),
            friction: to_matrix(py, run.friction, t, m).unbind(),
            speed: to_matrix(py, run.speed, t, m).unbind(),
            wrap: to_matrix(py, run.wrap, t, m).unbind(),
        }
    }
}

/// Add this file's classes and functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<FilterRun>()?;
    m.add_class::<DualRun>()?;
    m.add_class::<FilterHealth>()?;
    m.add_class::<FitReport>()?;
    m.add_class::<ParamSpec>()?;
    m.add_class::<Kinematics>()?;
    m.add_class::<Tensions>()?;
    m.add_class::<Capacity>()?;
    m.add_class::<PathRun>()?;
    m.add_class::<Step>()?;
    Ok(())
}
