//! Seed 003's tension sensors (`cable_core::cdpr::sensors`): the load-cell pulley, the linear
//! calibration, the HX711-and-link signal chain.

use cable_core::cdpr::sensors as core;
use numpy::PyArray1;
use pyo3::prelude::*;

use crate::convert::{any_vector, to_vector};
use crate::errors::guarded;

/// A load cell pushed by a pulley deflecting the cable by `angle_1`, `angle_2` (rad, in
/// `(0, π/2]`): `push(T) = T·(sin α₁ + sin α₂)` (eq. 31); `tension_range(rating)` the largest
/// tension a cell rated `rating` N measures (eq. 32 read with eq. 31). Immutable.
#[pyclass(frozen, module = "cablekit._cablekit")]
pub struct LoadCellPulley {
    inner: core::LoadCellPulley,
}

#[pymethods]
impl LoadCellPulley {
    #[new]
    fn new(angle_1: f64, angle_2: f64) -> PyResult<Self> {
        let inner = guarded(|| core::LoadCellPulley::new(angle_1, angle_2))?;
        Ok(Self { inner })
    }
    /// `sin α₁ + sin α₂`.
    #[getter]
    fn ratio(&self) -> f64 {
        self.inner.ratio()
    }
    /// The force on the load cell (N) at cable tension `tension` (N), eq. 31.
    fn push(&self, tension: f64) -> PyResult<f64> {
        guarded(|| self.inner.push(tension))
    }
    /// The largest tension (N) a cell rated `rating` N measures (eqs 31–32).
    fn tension_range(&self, rating: f64) -> PyResult<f64> {
        guarded(|| self.inner.tension_range(rating))
    }
}

/// A linear calibration `R = gain·T + offset` (eq. 33); `Calibration.fit` from loading and
/// unloading runs. Immutable.
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct Calibration {
    gain: f64,
    offset: f64,
}

impl From<core::Calibration> for Calibration {
    fn from(c: core::Calibration) -> Self {
        Self {
            gain: c.gain,
            offset: c.offset,
        }
    }
}

#[pymethods]
impl Calibration {
    #[new]
    fn new(gain: f64, offset: f64) -> PyResult<Self> {
        Ok(guarded(|| core::Calibration::new(gain, offset))?.into())
    }

    /// Tensions (N) of readings `(T,)`.
    fn tension<'py>(
        &self,
        py: Python<'py>,
        readings: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let c = core::Calibration {
            gain: self.gain,
            offset: self.offset,
        };
        let r = any_vector(readings, "readings")?;
        Ok(to_vector(py, guarded(|| c.tensions(&r))?))
    }

    /// The line through loading `(loads N, readings)` and unloading runs by least squares, with
    /// its correlation, residuals and hysteresis: a `CalibrationFit`.
    #[staticmethod]
    fn fit(
        py: Python<'_>,
        loading_loads: &Bound<'_, PyAny>,
        loading_readings: &Bound<'_, PyAny>,
        unloading_loads: &Bound<'_, PyAny>,
        unloading_readings: &Bound<'_, PyAny>,
    ) -> PyResult<CalibrationFit> {
        let [lt, lr, ut, ur] = [
            (loading_loads, "loading_loads"),
            (loading_readings, "loading_readings"),
            (unloading_loads, "unloading_loads"),
            (unloading_readings, "unloading_readings"),
        ]
        .map(|(a, name)| any_vector(a, name));
        let (lt, lr, ut, ur) = (lt?, lr?, ut?, ur?);
        let f = guarded(|| core::Calibration::fit((&lt, &lr), (&ut, &ur)))?;
        Ok(CalibrationFit {
            calibration: Py::new(py, Calibration::from(f.calibration))?,
            correlation: f.correlation,
            residual_rms: f.residual_rms,
            residual_max: f.residual_max,
            hysteresis: f.hysteresis,
            hysteresis_fraction: f.hysteresis_fraction,
        })
    }

    fn __repr__(&self) -> String {
        format!("Calibration(gain={}, offset={})", self.gain, self.offset)
    }
}

/// `Calibration.fit`: the `calibration`, the `correlation` of readings and loads, the tension
/// residuals' `residual_rms` and `residual_max` (N), and the `hysteresis` (N; unloading minus
/// loading at a load met both ways) and its `hysteresis_fraction` of the span.
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct CalibrationFit {
    calibration: Py<Calibration>,
    correlation: f64,
    residual_rms: f64,
    residual_max: f64,
    hysteresis: f64,
    hysteresis_fraction: f64,
}

/// The path from the gauge to the controller: an integrating converter of `conversion_time`
/// (s; the HX711 at 10 samples/s: 0.1), a sample-and-hold, and a `latency` (s; BLE: ≥ 0.03).
/// Immutable.
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct SignalChain {
    conversion_time: f64,
    latency: f64,
}

#[pymethods]
impl SignalChain {
    #[new]
    fn new(conversion_time: f64, latency: f64) -> PyResult<Self> {
        let c = guarded(|| core::SignalChain::new(conversion_time, latency))?;
        Ok(Self {
            conversion_time: c.conversion_time,
            latency: c.latency,
        })
    }

    /// The HX711 at 10 samples/s behind a BLE link (0.1 s, 0.03 s).
    #[staticmethod]
    fn hx711_ble() -> Self {
        let c = core::SignalChain::hx711_ble();
        Self {
            conversion_time: c.conversion_time,
            latency: c.latency,
        }
    }

    /// What the controller sees at the times `t` `(T,)` (strictly increasing, s) of a signal
    /// `(T,)` sampled there (GIL released).
    fn apply<'py>(
        &self,
        py: Python<'py>,
        t: &Bound<'py, PyAny>,
        signal: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (t, s) = (any_vector(t, "t")?, any_vector(signal, "signal")?);
        let chain = core::SignalChain {
            conversion_time: self.conversion_time,
            latency: self.latency,
        };
        let out = py.detach(|| guarded(|| chain.apply(&t, &s)))?;
        Ok(to_vector(py, out))
    }
}

/// Add this file's classes and functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<LoadCellPulley>()?;
    m.add_class::<Calibration>()?;
    m.add_class::<CalibrationFit>()?;
    m.add_class::<SignalChain>()?;
    Ok(())
}
