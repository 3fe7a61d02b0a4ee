//! `Winch`: seed 003's actuator linearised — transfer functions, zeros and poles, root locus.

use cable_core::cdpr::winch::{self as core, Complex, Setup};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;

use crate::convert::{to_matrix, vector};
use crate::errors::guarded;

/// Seed 003's winch (DC motor, gearbox, drum, elastic cable to the EE held by an antagonist,
/// PID position loop) linearised about a working point; parameters `(16,)` in `NAMES` order
/// (SI). `setup` is `"fixed"` (Setup 1: the antagonist holds still) or `"synchronized"`
/// (Setup 2, eq. 27); `lpf` adds the derivative's low-pass filter (eq. 13). Complex numbers
/// come as `(n, 2)` arrays of `[re, im]`. Immutable.
#[pyclass(frozen, module = "cablekit._cablekit")]
pub struct Winch {
    inner: core::Winch,
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
