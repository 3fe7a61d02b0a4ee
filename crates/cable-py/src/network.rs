//! `CableNetwork`: a cable network from a model file (issue #39 §1); the file's document,
//! kinematics and dynamics are the core's (`cable_core::dynamics::network`).

use cable_core::check;
use cable_core::dynamics::network::{Network, NetworkSpec};
use cable_core::dynamics::{AnyModel, Model as _};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;

use crate::convert::{to_matrix, to_vector, vector};
use crate::dynamics::{wrap, AntagonisticJoint, CableTransmission, Model};
use crate::errors::guarded;

/// A cable network: joints, pulleys, cables with their routing, motors and sensors.
#[pyclass(extends = Model, frozen, module = "cablekit._cablekit")]
pub struct CableNetwork;

fn network<'a>(slf: &'a PyRef<'_, CableNetwork>) -> &'a Network {
    match &slf.as_super().inner {
        AnyModel::Network(n) => n,
        _ => unreachable!("CableNetwork always wraps a network"),
    }
}

fn built(py: Python<'_>, spec: PyResult<NetworkSpec>) -> PyResult<Py<CableNetwork>> {
    let spec = spec?;
    let net = py.detach(|| guarded(|| Network::new(&spec)))?;
    Py::new(py, wrap(AnyModel::Network(net), CableNetwork))
}

#[pymethods]
impl CableNetwork {
    /// The network a model file's parsed document describes, given as JSON text.
    #[staticmethod]
    fn from_json(py: Python<'_>, text: &str) -> PyResult<Py<CableNetwork>> {
        built(py, guarded(|| NetworkSpec::from_json(text)))
    }

    /// The antagonistic joint as a network (joint "joint", cables "drive" and "return").
    #[staticmethod]
    fn from_joint(
        py: Python<'_>,
        joint: PyRef<'_, AntagonisticJoint>,
    ) -> PyResult<Py<CableNetwork>> {
        let j = match &joint.as_super().inner {
            AnyModel::Antagonistic(j) => *j,
            _ => unreachable!("AntagonisticJoint always wraps a joint"),
        };
        built(py, guarded(|| NetworkSpec::from_joint(&j)))
    }

    /// The coupled transmission as a network (per link: motor, joint, drive and return cable).
    #[staticmethod]
    fn from_transmission(
        py: Python<'_>,
        transmission: PyRef<'_, CableTransmission>,
    ) -> PyResult<Py<CableNetwork>> {
        let spec = match &transmission.as_super().inner {
            AnyModel::Transmission(t) => guarded(|| NetworkSpec::from_transmission(t)),
            _ => unreachable!("CableTransmission always wraps a transmission"),
        };
        built(py, spec)
    }

    /// Joint names, in order.
    #[getter]
    fn joint_names(slf: PyRef<'_, Self>) -> Vec<String> {
        network(&slf).joint_names().to_vec()
    }

    /// Cable names, in order.
    #[getter]
    fn cable_names(slf: PyRef<'_, Self>) -> Vec<String> {
        network(&slf).cable_names().to_vec()
    }

    /// Motor names, in order.
    #[getter]
    fn motor_names(slf: PyRef<'_, Self>) -> Vec<String> {
        network(&slf).motor_names().to_vec()
    }

    /// Measured signals it reads besides its motors (input columns after the motors').
    #[getter]
    fn signal_names(slf: PyRef<'_, Self>) -> Vec<String> {
        network(&slf).signal_names().to_vec()
    }

    /// The sensors: (channel name, index in `output_names`).
    #[getter]
    fn sensors(slf: PyRef<'_, Self>) -> Vec<(String, usize)> {
        network(&slf).sensor_outputs().to_vec()
    }

    /// The moment-arm (coupling) matrix `J = −∂l/∂q`, shape `(cables, joints)`.
    #[getter]
    fn moment_arms<'py>(slf: PyRef<'py, Self>) -> Bound<'py, PyArray2<f64>> {
        let n = network(&slf);
        to_matrix(
            slf.py(),
            n.moment_arms().to_vec(),
            n.n_cables(),
            n.n_joints(),
        )
    }

    /// Change of every cable's path length from `q = 0` (m): `−J·q`.
    fn length_change<'py>(
        slf: PyRef<'py, Self>,
        q: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let n = network(&slf);
        let q = vector(q, "q", n.n_joints())?;
        Ok(to_vector(slf.py(), guarded(|| n.length_change(&q))?))
    }

    /// Joint torques of the cable tensions (N·m or N): `Jᵀ·T`.
    fn joint_torques<'py>(
        slf: PyRef<'py, Self>,
        tensions: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let n = network(&slf);
        let t = vector(tensions, "tensions", n.n_cables())?;
        Ok(to_vector(slf.py(), guarded(|| n.joint_torques(&t))?))
    }

    /// Tension closure: the torque-free cable tensions (summing to 1) with the largest smallest
    /// share `s`; `(s, tensions)`, `s > 0` when every cable can be pretensioned, `s ≤ 0` when a
    /// torque-free state needs a cable to push.
    fn tension_closure<'py>(slf: PyRef<'py, Self>) -> PyResult<(f64, Bound<'py, PyArray1<f64>>)> {
        let n = network(&slf);
        let (s, t) = slf.py().detach(|| guarded(|| n.tension_closure()))?;
        Ok((s, to_vector(slf.py(), t)))
    }

    /// Mechanical energy (J) at state `x` and input `u`: kinetic, cable (taut), gravity.
    fn energy(slf: PyRef<'_, Self>, x: &Bound<'_, PyAny>, u: &Bound<'_, PyAny>) -> PyResult<f64> {
        let n = network(&slf);
        let (ns, ni) = (n.n_states(), n.n_inputs());
        let (x, u) = (vector(x, "x", ns)?, vector(u, "u", ni)?);
        let e = guarded(|| {
            check::evaluate(&[("x", &x, ns), ("u", &u, ni)], "energy", 1, |e| {
                e[0] = n.energy(&x, &u)
            })
        })?;
        Ok(e[0])
    }
}
