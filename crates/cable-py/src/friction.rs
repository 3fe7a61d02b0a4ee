//! Vectorised friction and cable-law functions (for plotting curves and for the reference tests).

use cable_core::cable::{CableLaw, CableRun};
use cable_core::friction::{self as f, Dahl, StaticFriction};
use numpy::PyArray1;
use pyo3::prelude::*;

use cable_core::check;

use crate::convert::{any_vector, to_vector};
use crate::errors::guarded;

fn map1<'py>(
    py: Python<'py>,
    v: &Bound<'py, PyAny>,
    name: &str,
    result: &str,
    g: impl Fn(f64) -> f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let v = any_vector(v, name)?;
    Ok(to_vector(
        py,
        guarded(|| check::finite_map(name, &v, result, g))?,
    ))
}

fn map2<'py>(
    py: Python<'py>,
    a: (&Bound<'py, PyAny>, &str),
    b: (&Bound<'py, PyAny>, &str),
    result: &str,
    g: impl Fn(f64, f64) -> f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let va = any_vector(a.0, a.1)?;
    let vb = crate::convert::vector(b.0, b.1, va.len())?;
    Ok(to_vector(
        py,
        guarded(|| check::finite_map2((a.1, b.1), &va, &vb, result, g))?,
    ))
}

/// Coulomb friction `F_c·v/sqrt(v² + ε²)` at each velocity.
#[pyfunction]
#[pyo3(signature = (v, *, coulomb, smoothing))]
pub fn coulomb_friction<'py>(
    py: Python<'py>,
    v: &Bound<'py, PyAny>,
    coulomb: f64,
    smoothing: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let law = guarded(|| StaticFriction::coulomb_viscous("friction", coulomb, 0.0, smoothing))?;
    map1(py, v, "v", "friction", |x| law.force(x))
}

/// Stribeck + Coulomb + viscous friction at each velocity.
#[pyfunction]
#[pyo3(signature = (v, *, coulomb, static_level, stribeck_velocity, exponent = 2.0, viscous = 0.0, smoothing))]
pub fn stribeck_friction<'py>(
    py: Python<'py>,
    v: &Bound<'py, PyAny>,
    coulomb: f64,
    static_level: f64,
    stribeck_velocity: f64,
    exponent: f64,
    viscous: f64,
    smoothing: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let law = guarded(|| {
        StaticFriction::stribeck(
            "friction",
            coulomb,
            static_level,
            stribeck_velocity,
            exponent,
            viscous,
            smoothing,
        )
    })?;
    map1(py, v, "v", "friction", |x| law.force(x))
}

/// Capstan ratio `T_out/T_in = exp(−μφ·σ_ε(v))` at each cable velocity.
#[pyfunction]
#[pyo3(signature = (v, *, mu, wrap, smoothing))]
pub fn capstan_ratio<'py>(
    py: Python<'py>,
    v: &Bound<'py, PyAny>,
    mu: f64,
    wrap: f64,
    smoothing: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    guarded(|| {
        check::non_negative("mu", mu)?;
        check::non_negative("wrap", wrap)?;
        check::positive("smoothing", smoothing)
    })?;
    map1(py, v, "v", "capstan_ratio", |x| {
        f::capstan_ratio(mu, wrap, x, smoothing)
    })
}

/// Dahl rate `dF/dt` at friction states `force` and velocities `v` (same length).
#[pyfunction]
#[pyo3(signature = (force, v, *, sigma0, coulomb, exponent = 1.0))]
pub fn dahl_rate<'py>(
    py: Python<'py>,
    force: &Bound<'py, PyAny>,
    v: &Bound<'py, PyAny>,
    sigma0: f64,
    coulomb: f64,
    exponent: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let dahl = guarded(|| Dahl::new(sigma0, coulomb, exponent))?;
    map2(py, (force, "force"), (v, "v"), "dahl_rate", |a, b| {
        dahl.rate(a, b)
    })
}

/// Cable-run tension `max(0, T₀ + F(s) + c·ṡ)` at each stretch and stretch rate.
#[pyfunction]
#[pyo3(signature = (stretch, stretch_rate, *, stiffness, damping = 0.0, pretension = 0.0, law = "linear", length_scale = 1.0))]
pub fn cable_tension<'py>(
    py: Python<'py>,
    stretch: &Bound<'py, PyAny>,
    stretch_rate: &Bound<'py, PyAny>,
    stiffness: f64,
    damping: f64,
    pretension: f64,
    law: &str,
    length_scale: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let run = guarded(|| {
        CableRun::new(
            CableLaw::from_name(law, stiffness, length_scale, "cable")?,
            damping,
            pretension,
            "cable",
        )
    })?;
    map2(
        py,
        (stretch, "stretch"),
        (stretch_rate, "stretch_rate"),
        "tension",
        |a, b| run.tension(a, b),
    )
}

/// Add this file's classes and functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(coulomb_friction, m)?)?;
    m.add_function(wrap_pyfunction!(stribeck_friction, m)?)?;
    m.add_function(wrap_pyfunction!(capstan_ratio, m)?)?;
    m.add_function(wrap_pyfunction!(dahl_rate, m)?)?;
    m.add_function(wrap_pyfunction!(cable_tension, m)?)?;
    Ok(())
}
