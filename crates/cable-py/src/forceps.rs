//! `Jtdo`: the forceps' joint torque disturbance observer and clamping-force estimator.

use cable_core::forceps::{self as core, Geometry};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;

use crate::convert::{matrix, to_matrix, vector_into};
use crate::errors::guarded;

/// Joint torque disturbance observer of a two-forceps end-effector (seed 000 eqs 8, 15–17):
/// from the measured cable tensions `F_M` and the free-motion tensions `F̂_E` (N, columns
/// `[A drive, A return, B drive, B return]`) it estimates the joint torque disturbances, the
/// external force on each forceps (less `bias`, a calibration group's mean errors), the
/// clamping force and contact above `threshold` (N). `r2`, `arm_a`, `arm_b` in m. Immutable.
#[pyclass(frozen, module = "cablekit._cablekit")]
pub struct Jtdo {
    inner: core::Jtdo,
}

#[pymethods]
impl Jtdo {
    #[new]
    #[pyo3(signature = (*, r2, arm_a, arm_b, threshold = core::SEED_THRESHOLD, bias = (0.0, 0.0)))]
    fn new(r2: f64, arm_a: f64, arm_b: f64, threshold: f64, bias: (f64, f64)) -> PyResult<Self> {
        let geometry = Geometry { r2, arm_a, arm_b };
        let inner = guarded(|| core::Jtdo::new(geometry, threshold, [bias.0, bias.1]))?;
        Ok(Self { inner })
    }

    /// The same observer with another `bias` `(A, B)` (N).
    fn with_bias(&self, bias: (f64, f64)) -> PyResult<Self> {
        let inner = guarded(|| self.inner.with_bias([bias.0, bias.1]))?;
        Ok(Self { inner })
    }

    /// The same observer with the bias of a calibration group: the mean errors of its external
    /// forces without bias on `measured`, `free` `(T, 4)` against the known `external` `(T, 2)`.
    fn calibrated(
        &self,
        measured: &Bound<'_, PyAny>,
        free: &Bound<'_, PyAny>,
        external: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let (m, _) = matrix(measured, "measured", Some(4))?;
        let (f, _) = matrix(free, "free", Some(4))?;
        let (e, _) = matrix(external, "external", Some(2))?;
        let (m, f, e) = (m.as_slice()?, f.as_slice()?, e.as_slice()?);
        let inner = guarded(|| self.inner.calibrated(m, f, e))?;
        Ok(Self { inner })
    }

    /// `(r2, arm_a, arm_b)` (m).
    #[getter]
    fn geometry(&self) -> (f64, f64, f64) {
        let g = self.inner.geometry();
        (g.r2, g.arm_a, g.arm_b)
    }
    #[getter]
    fn threshold(&self) -> f64 {
        self.inner.threshold()
    }
    #[getter]
    fn bias(&self) -> (f64, f64) {
        let b = self.inner.bias();
        (b[0], b[1])
    }

    /// One sample: `measured` and `free` `(4,)` → a `ClampStep`. No numpy allocation.
    fn step(&self, measured: &Bound<'_, PyAny>, free: &Bound<'_, PyAny>) -> PyResult<ClampStep> {
        let (mut m, mut f) = ([0.0; 4], [0.0; 4]);
        vector_into(measured, "measured", &mut m)?;
        vector_into(free, "free", &mut f)?;
        let c = guarded(|| self.inner.estimate(&m, &f))?;
        Ok(ClampStep {
            disturbance: c.disturbance.into(),
            torque: c.torque.into(),
            external: c.external.into(),
            clamping: c.clamping,
            contact: c.contact.into(),
        })
    }

    /// A whole log: `measured` and `free` `(T, 4)` → a `ClampRun` (GIL released).
    fn estimate(
        &self,
        py: Python<'_>,
        measured: &Bound<'_, PyAny>,
        free: &Bound<'_, PyAny>,
    ) -> PyResult<ClampRun> {
        let (m, t) = matrix(measured, "measured", Some(4))?;
        let (f, _) = matrix(free, "free", Some(4))?;
        let (m, f) = (m.as_slice()?, f.as_slice()?);
        let log = py.detach(|| guarded(|| self.inner.estimate_log(m, f)))?;
        let contact = numpy::ndarray::Array2::from_shape_vec((t, 2), log.contact)
            .expect("buffer length matches the shape by construction");
        Ok(ClampRun {
            disturbance: to_matrix(py, log.disturbance, t, 4).unbind(),
            torque: to_matrix(py, log.torque, t, 2).unbind(),
            external: to_matrix(py, log.external, t, 2).unbind(),
            clamping: log.clamping.into_pyarray(py).unbind(),
            contact: contact.into_pyarray(py).unbind(),
        })
    }

    fn __repr__(&self) -> String {
        let (g, b) = (self.inner.geometry(), self.inner.bias());
        format!(
            "Jtdo(r2={}, arm_a={}, arm_b={}, threshold={}, bias=({}, {}))",
            g.r2,
            g.arm_a,
            g.arm_b,
            self.inner.threshold(),
            b[0],
            b[1]
        )
    }
}

/// One `Jtdo.step`: tension `disturbance` (4), joint `torque` disturbances (2, N·m),
/// `external` forces (2, N), the `clamping` force (N) and `contact` per forceps.
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct ClampStep {
    disturbance: (f64, f64, f64, f64),
    torque: (f64, f64),
    external: (f64, f64),
    clamping: f64,
    contact: (bool, bool),
}

/// A `Jtdo.estimate` log: `disturbance` `(T, 4)`, `torque` `(T, 2)`, `external` `(T, 2)`,
/// `clamping` `(T,)` and `contact` `(T, 2)`.
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct ClampRun {
    disturbance: Py<PyArray2<f64>>,
    torque: Py<PyArray2<f64>>,
    external: Py<PyArray2<f64>>,
    clamping: Py<PyArray1<f64>>,
    contact: Py<PyArray2<bool>>,
}
