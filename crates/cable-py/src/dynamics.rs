//! Model classes: `Model` (base, shared evaluation methods) and one subclass per core model.

use cable_core::check;
use cable_core::dynamics::{self as core, Model as _};
use cable_core::estimate::{with_named_params, TransmissionParam};
use cable_core::friction::Dahl;
use cable_core::integrate::jacobian_rows;
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyFloat, PyInt};

use crate::convert::{to_matrix, to_vector, vector};
use crate::errors::{guarded, Class};

/// The core models behind the Python classes.
#[derive(Debug, Clone)]
pub enum AnyModel {
    /// Coupled cable transmission.
    Transmission(core::CableTransmission),
    /// Antagonistic joint.
    Antagonistic(core::AntagonisticJoint),
    /// Dahl friction element.
    Dahl(core::DahlElement),
}

/// Evaluate `$body` with `$m` bound to the concrete core model (monomorphised per variant).
macro_rules! with_model {
    ($any:expr, $m:ident => $body:expr) => {
        match $any {
            $crate::dynamics::AnyModel::Transmission($m) => $body,
            $crate::dynamics::AnyModel::Antagonistic($m) => $body,
            $crate::dynamics::AnyModel::Dahl($m) => $body,
        }
    };
}
pub(crate) use with_model;

/// Base class of every cablekit model: sizes, names, and single evaluations of `f`, `h` and RK4.
#[pyclass(subclass, frozen, module = "cablekit._cablekit")]
pub struct Model {
    pub inner: AnyModel,
}

#[pymethods]
impl Model {
    #[getter]
    fn n_states(&self) -> usize {
        with_model!(&self.inner, m => m.n_states())
    }
    #[getter]
    fn n_inputs(&self) -> usize {
        with_model!(&self.inner, m => m.n_inputs())
    }
    #[getter]
    fn n_outputs(&self) -> usize {
        with_model!(&self.inner, m => m.n_outputs())
    }
    #[getter]
    fn state_names(&self) -> Vec<String> {
        with_model!(&self.inner, m => m.state_names())
    }
    #[getter]
    fn input_names(&self) -> Vec<String> {
        with_model!(&self.inner, m => m.input_names())
    }
    #[getter]
    fn output_names(&self) -> Vec<String> {
        with_model!(&self.inner, m => m.output_names())
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
            check::evaluate(
                &[("x", &x, n), ("u", &u, m)],
                "derivative",
                n,
                |out| with_model!(&self.inner, mm => mm.derivative(&x, &u, out)),
            )
        })?;
        Ok(to_vector(py, out))
    }

    /// `h(x, u)`: the outputs.
    fn output<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (x, u) = self.point(x, u)?;
        let (n, m, p) = (self.n_states(), self.n_inputs(), self.n_outputs());
        let out = guarded(|| {
            check::evaluate(
                &[("x", &x, n), ("u", &u, m)],
                "output",
                p,
                |out| with_model!(&self.inner, mm => mm.output(&x, &u, out)),
            )
        })?;
        Ok(to_vector(py, out))
    }

    /// One sample interval `dt` of RK4 in `substeps` steps from `x` (inputs held at `u`, or
    /// linear towards `u_next`).
    #[pyo3(signature = (x, u, dt, substeps = 1, u_next = None))]
    fn rk4_step<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
        dt: f64,
        substeps: usize,
        u_next: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (x, u) = self.point(x, u)?;
        let u_b = match u_next {
            Some(obj) => vector(obj, "u_next", self.n_inputs())?,
            None => u.clone(),
        };
        let out = py.detach(|| {
            guarded(|| {
                with_model!(&self.inner, m => cable_core::integrate::rk4_interval(m, &x, &u, &u_b, dt, substeps))
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
        let rows = guarded(|| with_model!(&self.inner, m => jacobian_rows(m, &x, &u)))?;
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
        }
    }
}

impl Model {
    /// Validated `(x, u)` evaluation point.
    fn point(&self, x: &Bound<'_, PyAny>, u: &Bound<'_, PyAny>) -> PyResult<(Vec<f64>, Vec<f64>)> {
        let x = vector(x, "x", self.n_states())?;
        let u = vector(u, "u", self.n_inputs())?;
        Ok((x, u))
    }
}

/// Initializer of a `Model` subclass wrapping `inner`.
fn wrap<S: pyo3::PyClass<BaseType = Model>>(inner: AnyModel, sub: S) -> PyClassInitializer<S> {
    PyClassInitializer::from(Model { inner }).add_subclass(sub)
}

/// A float (one value for every link) or a sequence of floats (one per link).
fn per_link(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<f64>> {
    if obj.is_instance_of::<PyFloat>() || obj.is_instance_of::<PyInt>() {
        return Ok(vec![obj.extract::<f64>()?]);
    }
    obj.extract().map_err(|_| {
        crate::errors::raise(
            Class::Parameter,
            format!("{name} must be a float or a sequence of floats (one per link)"),
            &[],
        )
    })
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
    #[new]
    #[pyo3(signature = (
        *, motor_inertia, gear_ratio, capstan_radius, joint_radius, link_inertia, cable_stiffness,
        cable_damping = None, pretension = None, cable_law = "linear", length_scale = 1.0,
        joint_kind = None, motor_coulomb = None, motor_viscous = None, motor_smoothing = None,
        link_coulomb = None, link_viscous = None, link_smoothing = None,
        gravity_amplitude = None, gravity_offset = None, coupling = None
    ))]
    fn new(
        motor_inertia: &Bound<'_, PyAny>,
        gear_ratio: &Bound<'_, PyAny>,
        capstan_radius: &Bound<'_, PyAny>,
        joint_radius: &Bound<'_, PyAny>,
        link_inertia: &Bound<'_, PyAny>,
        cable_stiffness: &Bound<'_, PyAny>,
        cable_damping: Option<&Bound<'_, PyAny>>,
        pretension: Option<&Bound<'_, PyAny>>,
        cable_law: &str,
        length_scale: f64,
        joint_kind: Option<Vec<String>>,
        motor_coulomb: Option<&Bound<'_, PyAny>>,
        motor_viscous: Option<&Bound<'_, PyAny>>,
        motor_smoothing: Option<&Bound<'_, PyAny>>,
        link_coulomb: Option<&Bound<'_, PyAny>>,
        link_viscous: Option<&Bound<'_, PyAny>>,
        link_smoothing: Option<&Bound<'_, PyAny>>,
        gravity_amplitude: Option<&Bound<'_, PyAny>>,
        gravity_offset: Option<&Bound<'_, PyAny>>,
        coupling: Option<Vec<Vec<f64>>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let named = [
            ("motor_inertia", Some(motor_inertia)),
            ("gear_ratio", Some(gear_ratio)),
            ("capstan_radius", Some(capstan_radius)),
            ("joint_radius", Some(joint_radius)),
            ("link_inertia", Some(link_inertia)),
            ("cable_stiffness", Some(cable_stiffness)),
            ("cable_damping", cable_damping),
            ("pretension", pretension),
            ("motor_coulomb", motor_coulomb),
            ("motor_viscous", motor_viscous),
            ("motor_smoothing", motor_smoothing),
            ("link_coulomb", link_coulomb),
            ("link_viscous", link_viscous),
            ("link_smoothing", link_smoothing),
            ("gravity_amplitude", gravity_amplitude),
            ("gravity_offset", gravity_offset),
        ];
        let mut spec = core::TransmissionSpec {
            cable_law: cable_law.to_owned(),
            length_scale,
            joint_kind: joint_kind.unwrap_or_default(),
            coupling: coupling.unwrap_or_default(),
            ..Default::default()
        };
        for (name, obj) in named {
            if let Some(obj) = obj {
                spec.values.insert(name.to_owned(), per_link(obj, name)?);
            }
        }
        let model = guarded(|| spec.build())?;
        Ok(wrap(AnyModel::Transmission(model), CableTransmission))
    }

    /// The Raven-II parameter set for the first `links` axes (1 to 3).
    #[staticmethod]
    #[pyo3(signature = (links = 3))]
    fn raven2(py: Python<'_>, links: usize) -> PyResult<Py<CableTransmission>> {
        let model = guarded(|| core::raven2(links))?;
        Py::new(py, wrap(AnyModel::Transmission(model), CableTransmission))
    }

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
        let spec = core::TransmissionSpec::of(&transmission(&slf));
        let d = PyDict::new(slf.py());
        for (name, values) in &spec.values {
            d.set_item(name, values)?;
        }
        d.set_item("cable_law", spec.cable_law)?;
        d.set_item("length_scale", spec.length_scale)?;
        d.set_item("joint_kind", spec.joint_kind)?;
        d.set_item("coupling", spec.coupling)?;
        Ok(d)
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
    #[new]
    #[pyo3(signature = (
        *, radius, stiffness, inertia, damping = 0.0, pretension = 0.0,
        stiffness_return = None, damping_return = None, pretension_return = None,
        cable_law = "linear", length_scale = 1.0,
        viscous = 0.0, coulomb = 0.0, smoothing = 0.05,
        static_friction = None, stribeck_velocity = 1.0, stribeck_exponent = 2.0,
        capstan_mu = 0.0, capstan_wrap = 0.0, capstan_smoothing = 1e-3,
        contact_angle = None, contact_stiffness = None, contact_damping = 0.0, contact_lever_arm = None,
        dahl_coulomb = None, dahl_sigma0 = None, dahl_exponent = 1.0,
        creep_fraction = None, creep_time_constant = None
    ))]
    fn new(
        radius: f64,
        stiffness: f64,
        inertia: f64,
        damping: f64,
        pretension: f64,
        stiffness_return: Option<f64>,
        damping_return: Option<f64>,
        pretension_return: Option<f64>,
        cable_law: &str,
        length_scale: f64,
        viscous: f64,
        coulomb: f64,
        smoothing: f64,
        static_friction: Option<f64>,
        stribeck_velocity: f64,
        stribeck_exponent: f64,
        capstan_mu: f64,
        capstan_wrap: f64,
        capstan_smoothing: f64,
        contact_angle: Option<f64>,
        contact_stiffness: Option<f64>,
        contact_damping: f64,
        contact_lever_arm: Option<f64>,
        dahl_coulomb: Option<f64>,
        dahl_sigma0: Option<f64>,
        dahl_exponent: f64,
        creep_fraction: Option<f64>,
        creep_time_constant: Option<f64>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let given = [
            ("radius", Some(radius)),
            ("stiffness", Some(stiffness)),
            ("inertia", Some(inertia)),
            ("damping", Some(damping)),
            ("pretension", Some(pretension)),
            ("stiffness_return", stiffness_return),
            ("damping_return", damping_return),
            ("pretension_return", pretension_return),
            ("length_scale", Some(length_scale)),
            ("viscous", Some(viscous)),
            ("coulomb", Some(coulomb)),
            ("smoothing", Some(smoothing)),
            ("static_friction", static_friction),
            ("stribeck_velocity", Some(stribeck_velocity)),
            ("stribeck_exponent", Some(stribeck_exponent)),
            ("capstan_mu", Some(capstan_mu)),
            ("capstan_wrap", Some(capstan_wrap)),
            ("capstan_smoothing", Some(capstan_smoothing)),
            ("contact_angle", contact_angle),
            ("contact_stiffness", contact_stiffness),
            ("contact_damping", Some(contact_damping)),
            ("contact_lever_arm", contact_lever_arm),
            ("dahl_coulomb", dahl_coulomb),
            ("dahl_sigma0", dahl_sigma0),
            ("dahl_exponent", Some(dahl_exponent)),
            ("creep_fraction", creep_fraction),
            ("creep_time_constant", creep_time_constant),
        ];
        let spec = core::JointSpec {
            values: given
                .into_iter()
                .filter_map(|(k, v)| v.map(|v| (k.to_owned(), v)))
                .collect(),
            cable_law: cable_law.to_owned(),
        };
        let joint = guarded(|| spec.build())?;
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
        let spec = core::JointSpec::of(&antagonistic(&slf));
        let d = PyDict::new(slf.py());
        for (name, value) in &spec.values {
            d.set_item(name, value)?;
        }
        d.set_item("cable_law", spec.cable_law)?;
        Ok(d)
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
