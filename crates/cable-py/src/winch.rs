//! `Winch`: seed 003's actuator linearised — transfer functions, zeros and poles, root locus.

use cable_core::cdpr::winch::{self as core, Complex, Setup};
use cable_core::dynamics::{self as dynamics, AnyModel};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;

use crate::convert::{to_matrix, vector};
use crate::dynamics::{wrap, Model};
use crate::errors::guarded;

/// Seed 003's winch (DC motor, gearbox, drum, elastic cable to the EE held by an antagonist,
/// PID position loop) linearised about a working point; parameters `(16,)` in `NAMES` order
/// (SI). `setup` is `"fixed"` (Setup 1: the antagonist holds still) or `"synchronized"`
/// (Setup 2, eq. 27); `lpf` adds the derivative's low-pass filter (eq. 13). Complex numbers
/// come as `(n, 2)` arrays of `[re, im]`. Immutable.
#[pyclass(frozen, module = "cablekit._cablekit")]
pub struct Winch {
    pub(crate) inner: core::Winch,
}

type Pair<'py, A> = (Bound<'py, A>, Bound<'py, A>);
type Dominant = Option<((f64, f64), f64, f64)>;

fn pairs(py: Python<'_>, z: Vec<Complex>) -> Bound<'_, PyArray2<f64>> {
    let n = z.len();
    to_matrix(
        py,
        z.into_iter().flat_map(|(re, im)| [re, im]).collect(),
        n,
        2,
    )
}

#[pymethods]
impl Winch {
    #[classattr]
    const NAMES: [&'static str; core::N_WINCH] = core::WINCH_NAMES;

    #[new]
    fn new(values: &Bound<'_, PyAny>) -> PyResult<Self> {
        let v = vector(values, "values", core::N_WINCH)?;
        Ok(Self {
            inner: guarded(|| core::Winch::from_array(&v))?,
        })
    }

    /// Seed 003's actuator, cable and controller (Tables 1–4, Appendices A–B; see docs/cdpr.md).
    #[staticmethod]
    fn seed003() -> Self {
        Self {
            inner: core::Winch::seed003(),
        }
    }

    /// The parameters `(16,)`.
    #[getter]
    fn values<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.to_array().to_vec().into_pyarray(py)
    }

    /// `(J_l, B_l)` at the drum (kg·m², N·m·s/rad), eq. 17.
    #[getter]
    fn load(&self) -> (f64, f64) {
        (self.inner.load_inertia(), self.inner.load_viscous())
    }

    /// Open loop `PID·plant` with `K_p = 1`: `(num, den)`, highest power first.
    fn open_loop<'py>(
        &self,
        py: Python<'py>,
        setup: &str,
        lpf: bool,
    ) -> PyResult<Pair<'py, PyArray1<f64>>> {
        let tf = guarded(|| self.inner.open_loop(Setup::from_name(setup)?, lpf))?;
        Ok((tf.num.into_pyarray(py), tf.den.into_pyarray(py)))
    }

    /// `(zeros, poles)` of the open loop (seed 003 Table 5), `(n, 2)` each.
    fn zeros_and_poles<'py>(
        &self,
        py: Python<'py>,
        setup: &str,
        lpf: bool,
    ) -> PyResult<Pair<'py, PyArray2<f64>>> {
        let (z, p) = guarded(|| self.inner.zeros_and_poles(Setup::from_name(setup)?, lpf))?;
        Ok((pairs(py, z), pairs(py, p)))
    }

    /// Closed-loop poles at each gain of `kps` (A/rad): `(K, n, 2)`.
    fn root_locus<'py>(
        &self,
        py: Python<'py>,
        setup: &str,
        lpf: bool,
        kps: Vec<f64>,
    ) -> PyResult<Bound<'py, numpy::PyArray3<f64>>> {
        let rows = guarded(|| self.inner.root_locus(Setup::from_name(setup)?, lpf, &kps))?;
        let n = rows.first().map_or(0, Vec::len);
        let flat: Vec<f64> = rows
            .into_iter()
            .flatten()
            .flat_map(|(re, im)| [re, im])
            .collect();
        let arr = numpy::ndarray::Array3::from_shape_vec((kps.len(), n, 2), flat)
            .expect("every gain has the same number of poles");
        Ok(arr.into_pyarray(py))
    }

    /// The dominant closed-loop pair at `kp`: `((re, im), ω_d rad/s, t_p s)`, or `None` when
    /// every pole is real.
    fn dominant(&self, setup: &str, lpf: bool, kp: f64) -> PyResult<Dominant> {
        guarded(|| self.inner.dominant(Setup::from_name(setup)?, lpf, kp))
    }
}

/// Seed 003's winch as a nonlinear `Model` (see `cable_core::dynamics::WinchDrive`): state
/// `[alpha, alpha_dot, x_ee, x_ee_dot, error_integral, derivative_filtered]`, inputs
/// `[alpha_ref, alpha_ref_dot]`, outputs `[alpha, tension_a, tension_b, x_ee, current,
/// tension_from_current]`. Keywords left out take `WinchDrive.seed003()`'s values.
#[pyclass(extends = Model, frozen, module = "cablekit._cablekit")]
pub struct WinchDrive;

fn drive(slf: &PyRef<'_, WinchDrive>) -> dynamics::WinchDrive {
    match &slf.as_super().inner {
        AnyModel::Winch(w) => *w,
        _ => unreachable!("WinchDrive always wraps a winch drive"),
    }
}

#[pymethods]
impl WinchDrive {
    #[new]
    #[pyo3(signature = (winch = None, *, setup = None, lpf = None, pretension = None, current_limit = None, friction_smoothing = None, cable_damping = None, control = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        winch: Option<PyRef<'_, Winch>>,
        setup: Option<&str>,
        lpf: Option<bool>,
        pretension: Option<f64>,
        current_limit: Option<f64>,
        friction_smoothing: Option<f64>,
        cable_damping: Option<f64>,
        control: Option<&str>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let d = dynamics::WinchDrive::seed003();
        let model = guarded(|| {
            let control = control.map_or(Ok(d.control), dynamics::Control::from_name)?;
            dynamics::WinchDrive::new(
                winch.map_or(d.winch, |w| w.inner),
                setup.map_or(Ok(d.setup), Setup::from_name)?,
                lpf.unwrap_or(d.lpf),
                pretension.unwrap_or(d.pretension),
                current_limit.unwrap_or(d.current_limit),
                friction_smoothing.unwrap_or(d.friction_smoothing),
                cable_damping.unwrap_or(d.cable_damping),
            )
            .map(|m| m.with_control(control))
        })?;
        Ok(wrap(AnyModel::Winch(model), WinchDrive))
    }

    /// Seed 003's winch in Setup 1 with the LPF (`T₀ = 20 N`, `I_max = 10 A`: choices).
    #[staticmethod]
    fn seed003(py: Python<'_>) -> PyResult<Py<WinchDrive>> {
        let model = dynamics::WinchDrive::seed003();
        Py::new(py, wrap(AnyModel::Winch(model), WinchDrive))
    }

    /// The linear parameters (motor, gearbox, drum, cables, EE, PID) as a `Winch`.
    #[getter]
    fn winch(slf: PyRef<'_, Self>) -> Winch {
        Winch {
            inner: drive(&slf).winch,
        }
    }
    /// `"fixed"` (Setup 1) or `"synchronized"` (Setup 2).
    #[getter]
    fn setup(slf: PyRef<'_, Self>) -> &'static str {
        drive(&slf).setup.name()
    }
    /// Whether the PID's derivative goes through the low-pass filter (seed 003 eq. 13).
    #[getter]
    fn lpf(slf: PyRef<'_, Self>) -> bool {
        drive(&slf).lpf
    }
    /// `"position"` (the PID loop) or `"current"` (input `[current_ref]`, A).
    #[getter]
    fn control(slf: PyRef<'_, Self>) -> &'static str {
        drive(&slf).control.name()
    }
    /// `(pretension N, current_limit A, friction_smoothing rad/s, cable_damping N·s/m)`.
    #[getter]
    fn settings(slf: PyRef<'_, Self>) -> (f64, f64, f64, f64) {
        let d = drive(&slf);
        (
            d.pretension,
            d.current_limit,
            d.friction_smoothing,
            d.cable_damping,
        )
    }
}

/// Add this file's classes and functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<WinchDrive>()?;
    m.add_class::<Winch>()?;
    Ok(())
}
