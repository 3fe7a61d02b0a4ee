//! Trajectory simulation and step advice (GIL released for the integration).

use cable_core::control::{simulate_closed_loop_into, ClosedLoopMut, MotorPd};
use cable_core::dynamics::{AnyModel, Model as _};
use cable_core::integrate::{propose_step, simulate_into, InputHold, SimOptions, TrajectoryMut};
use cable_core::with_model;
use numpy::{PyArray2, PyArrayMethods};
use pyo3::prelude::*;

use crate::convert::{matrix, vector};
use crate::dynamics::{CableTransmission, Model};
use crate::errors::guarded;

type Arrays<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>);
type Arrays3<'py> = (
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<f64>>,
);

/// Simulate `model` on inputs `(T, m)`; returns `(states (T, n), outputs (T, p))`.
#[pyfunction]
#[pyo3(signature = (model, inputs, dt, x0 = None, substeps = 1, hold = "zoh"))]
pub fn simulate_arrays<'py>(
    py: Python<'py>,
    model: PyRef<'py, Model>,
    inputs: &Bound<'py, PyAny>,
    dt: f64,
    x0: Option<&Bound<'py, PyAny>>,
    substeps: usize,
    hold: &str,
) -> PyResult<Arrays<'py>> {
    let inner: AnyModel = model.inner.clone();
    let (n, m, p) = (inner.n_states(), inner.n_inputs(), inner.n_outputs());
    let (u_arr, t_len) = matrix(inputs, "inputs", Some(m))?;
    let u = u_arr.as_slice()?;
    let x0 = x0.map(|o| vector(o, "x0", n)).transpose()?;
    let x0 = x0.unwrap_or_else(|| inner.rest_state());
    let hold = guarded(|| InputHold::from_name(hold))?;
    // numpy-owned outputs: numpy recycles large buffers (and asks for huge pages), which saves
    // the first-touch page faults a fresh Rust allocation pays on every call.
    let states = PyArray2::<f64>::zeros(py, [t_len, n], false);
    let outputs = PyArray2::<f64>::zeros(py, [t_len, p], false);
    {
        let (mut sw, mut ow) = (states.readwrite(), outputs.readwrite());
        let out = TrajectoryMut {
            states: sw.as_slice_mut()?,
            outputs: ow.as_slice_mut()?,
        };
        py.detach(|| {
            guarded(|| {
                let opts = SimOptions::new(dt, substeps, hold)?;
                with_model!(&inner, mm => simulate_into(mm, u, &x0, &opts, out))
            })
        })?;
    }
    Ok((states, outputs))
}

/// The optional `(T, nl)` external torques of a servo run as a flat row-major vector (empty:
/// none).
fn external_torques(external: Option<&Bound<'_, PyAny>>, nl: usize) -> PyResult<Vec<f64>> {
    let Some(e) = external else {
        return Ok(Vec::new());
    };
    let (m, _) = matrix(e, "external", Some(nl))?;
    Ok(m.as_slice()?.to_vec())
}

/// Closed-loop simulation under a motor-space PD servo; returns `(states, outputs, inputs)`.
#[pyfunction]
#[pyo3(signature = (model, references, dt, *, kp, kd, torque_limit, external = None, x0 = None, substeps = 1))]
pub fn simulate_servo_arrays<'py>(
    py: Python<'py>,
    model: PyRef<'py, CableTransmission>,
    references: &Bound<'py, PyAny>,
    dt: f64,
    kp: Vec<f64>,
    kd: Vec<f64>,
    torque_limit: Vec<f64>,
    external: Option<&Bound<'py, PyAny>>,
    x0: Option<&Bound<'py, PyAny>>,
    substeps: usize,
) -> PyResult<Arrays3<'py>> {
    let t = guarded(|| model.as_super().inner.transmission("the servo").cloned())?;
    let nl = t.n_links();
    let (refs, t_len) = matrix(references, "references", Some(2 * nl))?;
    let (refs, ext) = (refs.as_slice()?, external_torques(external, nl)?);
    let x0 = x0.map_or_else(|| Ok(t.rest_state()), |o| vector(o, "x0", t.n_states()))?;
    let [states, outputs, inputs] = [t.n_states(), t.n_outputs(), t.n_inputs()]
        .map(|w| PyArray2::<f64>::zeros(py, [t_len, w], false));
    {
        let (mut sw, mut ow, mut iw) =
            (states.readwrite(), outputs.readwrite(), inputs.readwrite());
        let out = ClosedLoopMut {
            trajectory: TrajectoryMut {
                states: sw.as_slice_mut()?,
                outputs: ow.as_slice_mut()?,
            },
            inputs: iw.as_slice_mut()?,
        };
        py.detach(|| {
            guarded(|| {
                let pd = MotorPd::new(kp, kd, torque_limit)?;
                let opts = SimOptions::new(dt, substeps, InputHold::Zoh)?;
                simulate_closed_loop_into(&t, &pd, refs, &ext, &x0, &opts, out)
            })
        })?;
    }
    Ok((states, outputs, inputs))
}

/// Step advice: `(max_stable_step, (re, im), substeps)`.
#[pyfunction]
#[pyo3(signature = (model, dt, x = None, u = None, safety = 0.9))]
pub fn propose_step_raw(
    model: PyRef<'_, Model>,
    dt: f64,
    x: Option<&Bound<'_, PyAny>>,
    u: Option<&Bound<'_, PyAny>>,
    safety: f64,
) -> PyResult<(f64, (f64, f64), usize)> {
    let inner = &model.inner;
    let (n, m) = (inner.n_states(), inner.n_inputs());
    let x = x.map(|o| vector(o, "x", n)).transpose()?;
    let x = x.unwrap_or_else(|| inner.rest_state());
    let u = u
        .map(|o| vector(o, "u", m))
        .transpose()?
        .unwrap_or(vec![0.0; m]);
    let adv = guarded(|| propose_step(inner, &x, &u, dt, safety))?;
    Ok((adv.max_stable_step, adv.stiffest_eigenvalue, adv.substeps))
}

/// Add this file's classes and functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(simulate_arrays, m)?)?;
    m.add_function(wrap_pyfunction!(simulate_servo_arrays, m)?)?;
    m.add_function(wrap_pyfunction!(propose_step_raw, m)?)?;
    Ok(())
}
