//! Model classes: `Model` (base, shared evaluation methods) and one subclass per core model.

use cable_core::check;
use cable_core::dynamics::{self as core, AnyModel, Model as _};
use cable_core::estimate::{with_named_params, TransmissionParam};
use cable_core::friction::Dahl;
use cable_core::integrate::jacobian_rows;
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use std::sync::{Mutex, MutexGuard};

use cable_core::integrate::Rk4;

use crate::convert::{
    out_vector, spec_dict, spec_values, to_matrix, to_vector, vector, vector_into,
};
use crate::errors::guarded;

/// Base class of every cablekit model: sizes, names, and single evaluations of `f`, `h` and RK4.
#[pyclass(subclass, frozen, module = "cablekit._cablekit")]
pub struct Model {
    pub inner: AnyModel,
    /// Buffers of the calls with `out=` (a controller's loop): taken while a call runs, so a
    /// second thread's call meanwhile takes fresh ones.
    work: Mutex<Work>,
}

/// [`Model`]'s buffers for its allocation-free calls.
#[derive(Debug)]
struct Work {
    rk4: Rk4,
    x: Vec<f64>,
    u: Vec<f64>,
    u_next: Vec<f64>,
    scratch: Vec<f64>,
}

impl Work {
    fn new(model: &AnyModel) -> Self {
        let (n, m) = (model.n_states(), model.n_inputs());
        Self {
            rk4: Rk4::for_model(model),
            x: vec![0.0; n],
            u: vec![0.0; m],
            u_next: vec![0.0; m],
            scratch: Vec::with_capacity(n.max(model.n_outputs())),
        }
    }
}

#[pymethods]
impl Model {
    /// Number of states.
    #[getter]
    fn n_states(&self) -> usize {
        self.inner.n_states()
    }
    /// Number of inputs.
    #[getter]
    fn n_inputs(&self) -> usize {
        self.inner.n_inputs()
    }
    /// Number of outputs.
    #[getter]
    fn n_outputs(&self) -> usize {
        self.inner.n_outputs()
    }
    /// Names of the states, in order.
    #[getter]
    fn state_names(&self) -> Vec<String> {
        self.inner.state_names()
    }
    /// Names of the inputs, in order.
    #[getter]
    fn input_names(&self) -> Vec<String> {
        self.inner.input_names()
    }
    /// Names of the outputs, in order.
    #[getter]
    fn output_names(&self) -> Vec<String> {
        self.inner.output_names()
    }
    /// The model's state at rest (its equilibrium with zero input where it has one).
    fn rest_state<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_vector(py, self.inner.rest_state())
    }

    /// `f(x, u)`: the state derivative.
    fn derivative<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (x, u) = self.point(x, u)?;
        let (n, m) = (self.n_states(), self.n_inputs());
        let out = guarded(|| {
            check::evaluate(&[("x", &x, n), ("u", &u, m)], "derivative", n, |out| {
                self.inner.derivative(&x, &u, out)
            })
        })?;
        Ok(to_vector(py, out))
    }

    /// `h(x, u)`: the outputs. With `out` `(p,)` (a writable float64 array) they are written
    /// into it and `out` is returned: no allocation (a controller's loop); on an error `out` is
    /// left as it was.
    #[pyo3(signature = (x, u, out = None))]
    fn output<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (n, m, p) = (self.n_states(), self.n_inputs(), self.n_outputs());
        if let Some(obj) = out.filter(|o| !o.is_none()) {
            let mut work = self.work();
            let w = &mut *work;
            vector_into(x, "x", &mut w.x)?;
            vector_into(u, "u", &mut w.u)?;
            let mut rw = out_vector(obj, "out", p)?;
            let dst = rw.as_slice_mut()?;
            guarded(|| {
                check::evaluate_into(
                    &[("x", &w.x, n), ("u", &w.u, m)],
                    "output",
                    dst,
                    &mut w.scratch,
                    |o| self.inner.output(&w.x, &w.u, o),
                )
            })?;
            return Ok(obj.clone().cast_into::<PyArray1<f64>>()?);
        }
        let (x, u) = self.point(x, u)?;
        let out = guarded(|| {
            check::evaluate(&[("x", &x, n), ("u", &u, m)], "output", p, |out| {
                self.inner.output(&x, &u, out)
            })
        })?;
        Ok(to_vector(py, out))
    }

    /// One sample interval `dt` of RK4 in `substeps` steps from `x` (inputs held at `u`, or
    /// linear towards `u_next`). With `out` `(n,)` (a writable float64 array, which may be `x`
    /// itself) the state is written into it and `out` is returned: no allocation (the model
    /// keeps its RK4 workspace; a controller's loop); on an error `out` is left as it was.
    #[pyo3(signature = (x, u, dt, substeps = 1, u_next = None, out = None))]
    #[allow(clippy::too_many_arguments)]
    fn rk4_step<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
        dt: f64,
        substeps: usize,
        u_next: Option<&Bound<'py, PyAny>>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        if let Some(obj) = out.filter(|o| !o.is_none()) {
            return self.rk4_step_into(py, (x, u, u_next), dt, substeps, obj);
        }
        let (x, u) = self.point(x, u)?;
        let u_b = match u_next {
            Some(obj) => vector(obj, "u_next", self.n_inputs())?,
            None => u.clone(),
        };
        let out = py.detach(|| {
            guarded(|| {
                cable_core::with_model!(&self.inner, m => cable_core::integrate::rk4_interval(m, &x, &u, &u_b, dt, substeps))
            })
        })?;
        Ok(to_vector(py, out))
    }

    /// Jacobian `∂f/∂x` at `(x, u)` by central differences.
    fn jacobian<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let (x, u) = self.point(x, u)?;
        let n = self.n_states();
        let rows = guarded(|| jacobian_rows(&self.inner, &x, &u))?;
        Ok(to_matrix(py, rows, n, n))
    }

    fn __repr__(&self) -> String {
        match &self.inner {
            AnyModel::Transmission(t) => format!("CableTransmission(n_links={})", t.n_links()),
            AnyModel::Antagonistic(_) => "AntagonisticJoint(...)".to_owned(),
            AnyModel::Dahl(d) => format!(
                "DahlElement(sigma0={}, coulomb={}, exponent={})",
                d.dahl.sigma0, d.dahl.coulomb, d.dahl.exponent
            ),
            AnyModel::Winch(w) => format!(
                "WinchDrive(setup={:?}, lpf={}, pretension={}, current_limit={})",
                w.setup, w.lpf, w.pretension, w.current_limit
            ),
            AnyModel::Cdpr(p) => {
                format!("CdprPlant(robot={:?}, home={:?})", p.robot().name, p.home())
            }
            AnyModel::Network(n) => format!(
                "CableNetwork(joints={:?}, cables={:?}, motors={:?})",
                n.joint_names(),
                n.cable_names(),
                n.motor_names()
            ),
        }
    }
}

impl Model {
    /// `rk4_step`'s form with `out`: `(x, u, u_next)` read into the model's buffers, the step
    /// integrated in its workspace and written into `obj`.
    fn rk4_step_into<'py>(
        &self,
        py: Python<'py>,
        (x, u, u_next): (
            &Bound<'py, PyAny>,
            &Bound<'py, PyAny>,
            Option<&Bound<'py, PyAny>>,
        ),
        dt: f64,
        substeps: usize,
        obj: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let mut work = self.work();
        let w = &mut *work;
        vector_into(x, "x", &mut w.x)?;
        vector_into(u, "u", &mut w.u)?;
        match u_next.filter(|o| !o.is_none()) {
            Some(v) => vector_into(v, "u_next", &mut w.u_next)?,
            None => w.u_next.copy_from_slice(&w.u),
        }
        let mut rw = out_vector(obj, "out", self.n_states())?;
        let dst = rw.as_slice_mut()?;
        py.detach(|| {
            guarded(|| {
                cable_core::with_model!(&self.inner, m => cable_core::integrate::rk4_interval_into(
                    m, &w.x, &w.u, &w.u_next, dt, substeps, dst, &mut w.rk4,
                ))
            })
        })?;
        Ok(obj.clone().cast_into::<PyArray1<f64>>()?)
    }

    /// The buffers of the `out=` calls, or fresh ones while another thread's call holds them.
    fn work(&self) -> WorkGuard<'_> {
        match self.work.try_lock() {
            Ok(g) => WorkGuard::Shared(g),
            Err(std::sync::TryLockError::Poisoned(p)) => WorkGuard::Shared(p.into_inner()),
            Err(std::sync::TryLockError::WouldBlock) => {
                WorkGuard::Own(Box::new(Work::new(&self.inner)))
            }
        }
    }

    /// Validated `(x, u)` evaluation point.
    fn point(&self, x: &Bound<'_, PyAny>, u: &Bound<'_, PyAny>) -> PyResult<(Vec<f64>, Vec<f64>)> {
        let x = vector(x, "x", self.n_states())?;
        let u = vector(u, "u", self.n_inputs())?;
        Ok((x, u))
    }
}

/// Initializer of a `Model` subclass wrapping `inner`.
pub(crate) fn wrap<S: pyo3::PyClass<BaseType = Model>>(
    inner: AnyModel,
    sub: S,
) -> PyClassInitializer<S> {
    let work = Mutex::new(Work::new(&inner));
    PyClassInitializer::from(Model { inner, work }).add_subclass(sub)
}

/// [`Model::work`]'s buffers: the model's own, or fresh ones.
enum WorkGuard<'a> {
    Shared(MutexGuard<'a, Work>),
    Own(Box<Work>),
}

impl std::ops::Deref for WorkGuard<'_> {
    type Target = Work;
    fn deref(&self) -> &Work {
        match self {
            WorkGuard::Shared(g) => g,
            WorkGuard::Own(w) => w,
        }
    }
}

impl std::ops::DerefMut for WorkGuard<'_> {
    fn deref_mut(&mut self) -> &mut Work {
        match self {
            WorkGuard::Shared(g) => g,
            WorkGuard::Own(w) => w,
        }
    }
}

/// Cable-driven transmission with 1–3 coupled links (seed 001 eqs 2.3–2.8).
#[pyclass(extends = Model, frozen, module = "cablekit._cablekit")]
pub struct CableTransmission;

fn transmission(slf: &PyRef<'_, CableTransmission>) -> core::CableTransmission {
    match &slf.as_super().inner {
        AnyModel::Transmission(t) => t.clone(),
        _ => unreachable!("CableTransmission always wraps a transmission"),
    }
}

#[pymethods]
impl CableTransmission {
    /// Keywords as in `params()`: per-link values (a float applies to every link),
    /// `cable_law`, `length_scale`, `joint_kind`, `coupling`; defaults and validation are the
    /// core's `TransmissionSpec`.
    #[new]
    #[pyo3(signature = (**params))]
    fn new(params: Option<&Bound<'_, PyDict>>) -> PyResult<PyClassInitializer<Self>> {
        let named = spec_values(params)?;
        let model = guarded(|| core::TransmissionSpec::from_named(named)?.build())?;
        Ok(wrap(AnyModel::Transmission(model), CableTransmission))
    }

    /// The Raven-II parameter set for the first `links` axes (1 to 3).
    #[staticmethod]
    #[pyo3(signature = (links = 3))]
    fn raven2(py: Python<'_>, links: usize) -> PyResult<Py<CableTransmission>> {
        let model = guarded(|| core::raven2(links))?;
        Py::new(py, wrap(AnyModel::Transmission(model), CableTransmission))
    }

    /// Number of links.
    #[getter]
    fn n_links(slf: PyRef<'_, Self>) -> usize {
        transmission(&slf).n_links()
    }

    /// Transmission matrix `T` of eq. (2.8), shape `(n, n)`.
    #[getter]
    fn transmission_matrix<'py>(slf: PyRef<'py, Self>) -> Bound<'py, PyArray2<f64>> {
        let t = transmission(&slf);
        let n = t.n_links();
        to_matrix(slf.py(), t.transmission_matrix(), n, n)
    }

    /// All parameters as a dict of per-link lists (the constructor's keywords).
    fn params<'py>(slf: PyRef<'py, Self>) -> PyResult<Bound<'py, PyDict>> {
        let named = core::TransmissionSpec::of(&transmission(&slf)).named();
        spec_dict(slf.py(), named)
    }

    /// Values of named parameters (`"cable_stiffness[1]"`, `"coupling[2][0]"`, …: the
    /// keyword names with 0-based indices).
    fn parameter_values<'py>(
        slf: PyRef<'py, Self>,
        names: Vec<String>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let t = transmission(&slf);
        let params = guarded(|| TransmissionParam::parse_all(&names, t.n_links()))?;
        Ok(to_vector(
            slf.py(),
            params.iter().map(|p| p.get(&t)).collect(),
        ))
    }

    /// This model with the named parameters set to `values` (validated like the constructor).
    fn with_parameter_values(
        slf: PyRef<'_, Self>,
        names: Vec<String>,
        values: &Bound<'_, PyAny>,
    ) -> PyResult<Py<CableTransmission>> {
        let values = vector(values, "values", names.len())?;
        let t = transmission(&slf);
        let model = guarded(|| with_named_params(&t, &names, &values))?;
        Py::new(
            slf.py(),
            wrap(AnyModel::Transmission(model), CableTransmission),
        )
    }

    /// Rigid-cable kinematics `q_m = T·q_l`.
    fn joint_to_motor<'py>(
        slf: PyRef<'py, Self>,
        q_l: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let t = transmission(&slf);
        let (q, n) = (vector(q_l, "q_l", t.n_links())?, t.n_links());
        let out = guarded(|| {
            check::evaluate(&[("q_l", &q, n)], "q_m", n, |out| t.joint_to_motor(&q, out))
        })?;
        Ok(to_vector(slf.py(), out))
    }

    /// Transmission-kinematics joint estimate `q_l = T⁻¹·q_m`: `(n,)` or row by row `(T, n)`.
    fn motor_to_joint<'py>(
        slf: PyRef<'py, Self>,
        q_m: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let t = transmission(&slf);
        let n = t.n_links();
        if crate::convert::ndim_of(q_m, "q_m")? == 1 {
            let q = vector(q_m, "q_m", n)?;
            let out = guarded(|| t.motor_to_joint_rows(&q))?;
            return Ok(to_vector(slf.py(), out).into_any());
        }
        let (arr, rows) = crate::convert::matrix(q_m, "q_m", Some(n))?;
        let q = arr.as_slice()?;
        let out = slf.py().detach(|| guarded(|| t.motor_to_joint_rows(q)))?;
        Ok(to_matrix(slf.py(), out, rows, n).into_any())
    }

    /// Mechanical energy (J) at state `x` (kinetic + taut cable + gravity).
    fn energy(slf: PyRef<'_, Self>, x: &Bound<'_, PyAny>) -> PyResult<f64> {
        let t = transmission(&slf);
        let (x, n) = (vector(x, "x", t.n_states())?, t.n_states());
        let e = guarded(|| check::evaluate(&[("x", &x, n)], "energy", 1, |e| e[0] = t.energy(&x)))?;
        Ok(e[0])
    }
}

/// Antagonistic cable-driven joint (seed 000 forceps jaw, or a pulley board).
#[pyclass(extends = Model, frozen, module = "cablekit._cablekit")]
pub struct AntagonisticJoint;

fn antagonistic(slf: &PyRef<'_, AntagonisticJoint>) -> core::AntagonisticJoint {
    match &slf.as_super().inner {
        AnyModel::Antagonistic(j) => *j,
        _ => unreachable!("AntagonisticJoint always wraps an antagonistic joint"),
    }
}

#[pymethods]
impl AntagonisticJoint {
    /// Keywords as in `params()`; defaults and validation are the core's `JointSpec`.
    #[new]
    #[pyo3(signature = (**params))]
    fn new(params: Option<&Bound<'_, PyDict>>) -> PyResult<PyClassInitializer<Self>> {
        let named = spec_values(params)?;
        let joint = guarded(|| core::JointSpec::from_named(named)?.build())?;
        Ok(wrap(AnyModel::Antagonistic(joint), AntagonisticJoint))
    }

    /// The illustrative EndoWrist-like forceps jaw used by `cablekit simulate --example forceps`.
    #[staticmethod]
    fn forceps_example(py: Python<'_>) -> PyResult<Py<AntagonisticJoint>> {
        Py::new(
            py,
            wrap(
                AnyModel::Antagonistic(core::AntagonisticJoint::forceps_example()),
                AntagonisticJoint,
            ),
        )
    }

    /// All parameters as a dict (the constructor's keywords).
    fn params<'py>(slf: PyRef<'py, Self>) -> PyResult<Bound<'py, PyDict>> {
        spec_dict(slf.py(), core::JointSpec::of(&antagonistic(&slf)).named())
    }
}

/// Dahl friction element: state `[F]`, input `[v]`, output `[F]` (seed 002 eq. 8).
#[pyclass(extends = Model, frozen, module = "cablekit._cablekit")]
pub struct DahlElement;

#[pymethods]
impl DahlElement {
    #[new]
    #[pyo3(signature = (*, sigma0, coulomb, exponent = 1.0))]
    fn new(sigma0: f64, coulomb: f64, exponent: f64) -> PyResult<PyClassInitializer<Self>> {
        let dahl = guarded(|| Dahl::new(sigma0, coulomb, exponent))?;
        Ok(wrap(
            AnyModel::Dahl(core::DahlElement { dahl }),
            DahlElement,
        ))
    }
}

/// Add this file's classes and functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Model>()?;
    m.add_class::<CableTransmission>()?;
    m.add_class::<AntagonisticJoint>()?;
    m.add_class::<DahlElement>()?;
    m.add_class::<crate::network::CableNetwork>()?;
    Ok(())
}
