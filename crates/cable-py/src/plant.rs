//! `CdprPlant`: a cable-driven parallel robot with winches and pulleys as a `Model`, and its
//! closed loop (`cable_core::dynamics::CdprPlant`, `cable_core::control::closed_loop`).

use cable_core::cdpr::{Method, PathFriction, PathLaw};
use cable_core::control::{self as control, Feedback, LoopOptions};
use cable_core::dynamics;
use cable_core::dynamics::AnyModel;
use numpy::PyArray2;
use pyo3::prelude::*;

use crate::cdpr::Robot;
use crate::convert::{any_vector, matrix, opt_tuples, to_matrix, to_vector};
use crate::dynamics::{wrap, Model};
use crate::errors::guarded;
use crate::nn::Mlp;
use crate::winch::Winch;

/// Pulley friction on one side of the winch-side sensor, per cable (`(m,)`) or shared
/// (`(1,)`): coefficient μ, viscous σ_v (N·s/m), guide pulleys' wrap (rad), and the law
/// `"coulomb"` (`smoothing` m/s) or `"dahl"` (`presliding` m, `exponent`); see
/// `Robot.path_friction`.
#[pyclass(frozen, module = "cablekit._cablekit")]
pub struct PulleyFriction {
    coefficient: Vec<f64>,
    viscous: Vec<f64>,
    guide_wrap: Vec<f64>,
    law: PathLaw,
}

#[pymethods]
impl PulleyFriction {
    #[new]
    #[pyo3(signature = (coefficient, viscous, guide_wrap, *, law = None, smoothing = None, presliding = None, exponent = None))]
    pub(crate) fn new(
        coefficient: &Bound<'_, PyAny>,
        viscous: &Bound<'_, PyAny>,
        guide_wrap: &Bound<'_, PyAny>,
        law: Option<&str>,
        smoothing: Option<f64>,
        presliding: Option<f64>,
        exponent: Option<f64>,
    ) -> PyResult<Self> {
        let coefficient = any_vector(coefficient, "coefficient")?;
        let viscous = any_vector(viscous, "viscous")?;
        let guide_wrap = any_vector(guide_wrap, "guide_wrap")?;
        let law = guarded(|| {
            let law = PathLaw::named(law, smoothing, presliding, exponent)?;
            // validated now for a shared or per-cable count: whichever the lengths allow
            let m = coefficient.len().max(viscous.len()).max(guide_wrap.len());
            PathFriction::per_cable(&coefficient, &viscous, &guide_wrap, law, m)?;
            Ok(law)
        })?;
        Ok(Self {
            coefficient,
            viscous,
            guide_wrap,
            law,
        })
    }
}

impl PulleyFriction {
    pub(crate) fn paths(&self, m: usize) -> cable_core::error::Result<Vec<PathFriction>> {
        PathFriction::per_cable(
            &self.coefficient,
            &self.viscous,
            &self.guide_wrap,
            self.law,
            m,
        )
    }
}

/// A cable-driven parallel robot as a `Model` (`cable_core::dynamics::CdprPlant`): the platform
/// (Newton–Euler), elastic one-sided cables, one `winch` (default `Winch.seed003()`) per cable
/// under its PID, and pulley friction between the drum and the winch-side sensor
/// (`drum_side`) and between the sensor and the platform (`platform_side`). At α = 0 it rests
/// at `home` holding `home_tensions` (default: the tension distribution of its weight).
/// `creep=(ratio, time_constant)` (`(m,)` or `(1,)` each): polymer-cable creep, settled
/// stretch `1 + ratio` times the elastic one, reached with time constant (s).
/// `drum_friction` `(m,)`: each winch's static friction as a multiple of the winch's.
/// State `[q, v, α, α̇, z, D, z_drum, z_platform, creep]`, input `[α_ref, α̇_ref, i_ff, w_ext]`, output
/// `[q, T_EE, T_PUL, i, T̂, α]` (see `state_names`, `input_names`, `output_names`).
#[pyclass(extends = Model, frozen, module = "cablekit._cablekit")]
pub struct CdprPlant;

fn plant<'a>(slf: &'a PyRef<'_, CdprPlant>) -> &'a dynamics::CdprPlant {
    match &slf.as_super().inner {
        AnyModel::Cdpr(p) => p,
        _ => unreachable!("CdprPlant always wraps a plant"),
    }
}

#[pymethods]
impl CdprPlant {
    #[new]
    #[pyo3(signature = (robot, home, winch = None, *, lpf = None, current_limit = None, friction_smoothing = None, cable_damping = None, drum_side = None, platform_side = None, home_tensions = None, creep = None, drum_friction = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        robot: PyRef<'_, Robot>,
        home: &Bound<'_, PyAny>,
        winch: Option<PyRef<'_, Winch>>,
        lpf: Option<bool>,
        current_limit: Option<f64>,
        friction_smoothing: Option<f64>,
        cable_damping: Option<f64>,
        drum_side: Option<PyRef<'_, PulleyFriction>>,
        platform_side: Option<PyRef<'_, PulleyFriction>>,
        home_tensions: Option<&Bound<'_, PyAny>>,
        creep: Option<&Bound<'_, PyAny>>,
        drum_friction: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let r = &robot.inner;
        let home = any_vector(home, "home")?;
        let home_tensions = home_tensions
            .map(|h| any_vector(h, "home_tensions"))
            .transpose()?;
        let drum_friction =
            drum_friction.map_or(Ok(Vec::new()), |h| any_vector(h, "drum_friction"))?;
        let (d, m) = (dynamics::PlantOptions::default(), r.n_cables());
        let creep = creep_of(creep, m)?;
        let p = guarded(|| {
            let options = dynamics::PlantOptions {
                lpf: lpf.unwrap_or(d.lpf),
                current_limit: current_limit.unwrap_or(d.current_limit),
                friction_smoothing: friction_smoothing.unwrap_or(d.friction_smoothing),
                cable_damping: cable_damping.unwrap_or(d.cable_damping),
                drum_side: drum_side.map_or(Ok(Vec::new()), |f| f.paths(m))?,
                platform_side: platform_side.map_or(Ok(Vec::new()), |f| f.paths(m))?,
                home_tensions,
                creep,
                drum_friction,
            };
            let w = winch.map_or_else(cable_core::cdpr::winch::Winch::seed003, |w| w.inner);
            dynamics::CdprPlant::new(r, w, &home, options)
        })?;
        Ok(wrap(AnyModel::Cdpr(p), CdprPlant))
    }

    /// The home pose.
    #[getter]
    fn home<'py>(slf: PyRef<'py, Self>) -> Bound<'py, numpy::PyArray1<f64>> {
        let py = slf.py();
        to_vector(py, plant(&slf).home().to_vec())
    }
    /// Tensions at home (N).
    #[getter]
    fn home_tensions<'py>(slf: PyRef<'py, Self>) -> Bound<'py, numpy::PyArray1<f64>> {
        let py = slf.py();
        to_vector(py, plant(&slf).home_tensions().to_vec())
    }
    /// Unstretched cable lengths at α = 0 (m).
    #[getter]
    fn rest_length<'py>(slf: PyRef<'py, Self>) -> Bound<'py, numpy::PyArray1<f64>> {
        let py = slf.py();
        to_vector(py, plant(&slf).rest_length().to_vec())
    }
    /// `k_φ·r_gb/r` (N/A): the motor-current tension estimate per ampere.
    #[getter]
    fn tension_per_ampere(slf: PyRef<'_, Self>) -> f64 {
        plant(&slf).tension_per_ampere()
    }
    /// The winch (every cable's).
    #[getter]
    fn winch(slf: PyRef<'_, Self>) -> Winch {
        Winch {
            inner: *plant(&slf).winch(),
        }
    }

    /// Run the trajectory controller (`cable_core::control::closed_loop`) over desired `poses`
    /// `(T, n)` every `dt` s, from rest at home: the tension distribution (`method`) of weight
    /// and inertia gives `f_d`; the force loop `f_u = gain·(f_d − f̂)` feeds back `feedback`
    /// (`"open"`: none, `"platform"`, `"sensor"` with `sensor_noise` `(T, m)` N added, or
    /// `"network"`: `network`'s estimate from the desired position, velocity and the sensor),
    /// measured `sensor_delay` periods before the last one;
    /// the drums take the lengths and the current of `f_d + tension_offset + f_u`
    /// (`tension_offset` `(T, m)` N: an excitation). A `LoopRun` (GIL released).
    #[pyo3(signature = (poses, dt, *, substeps = 5, method = "auto", gain = 0.0, feedback = "open", sensor_delay = 0, current_feedforward = true, sensor_noise = None, tension_offset = None, network = None))]
    #[allow(clippy::too_many_arguments)]
    fn closed_loop(
        slf: PyRef<'_, Self>,
        poses: &Bound<'_, PyAny>,
        dt: f64,
        substeps: usize,
        method: &str,
        gain: f64,
        feedback: &str,
        sensor_delay: usize,
        current_feedforward: bool,
        sensor_noise: Option<&Bound<'_, PyAny>>,
        tension_offset: Option<&Bound<'_, PyAny>>,
        network: Option<PyRef<'_, Mlp>>,
    ) -> PyResult<LoopRun> {
        let py = slf.py();
        let p = plant(&slf);
        let (n, m) = (p.robot().dof(), p.robot().n_cables());
        let (q, _) = matrix(poses, "poses", Some(n))?;
        let noise = per_cable(sensor_noise, "sensor_noise", m)?;
        let offset = per_cable(tension_offset, "tension_offset", m)?;
        let opts = guarded(|| {
            Ok(LoopOptions {
                substeps,
                method: Method::from_name(method)?,
                gain,
                feedback: Feedback::from_name(feedback)?,
                sensor_delay,
                current_feedforward,
                ..LoopOptions::new(dt)
            })
        })?;
        let q = q.as_slice()?;
        let net = network.as_ref().map(|n| &n.inner);
        let run = py.detach(|| {
            guarded(|| control::closed_loop(p, q, &opts, noise.as_deref(), offset.as_deref(), net))
        })?;
        Ok(LoopRun::new(py, run, n, m))
    }
}

/// `CdprPlant(creep=(ratio, time_constant))` per cable of `m` (empty: no creep).
fn creep_of(creep: Option<&Bound<'_, PyAny>>, m: usize) -> PyResult<Vec<dynamics::Creep>> {
    let what = "a pair (ratio, time_constant) of (m,) or (1,) arrays";
    let creep: Option<(Bound<'_, PyAny>, Bound<'_, PyAny>)> = opt_tuples(creep, "creep", what)?;
    let Some((ratio, tau)) = creep else {
        return Ok(Vec::new());
    };
    let (ratio, tau) = (any_vector(&ratio, "creep")?, any_vector(&tau, "creep")?);
    guarded(|| dynamics::Creep::per_cable(&ratio, &tau, m))
}

/// An optional `(T, m)` per-cable signal of `closed_loop` as a flat row-major vector.
fn per_cable(s: Option<&Bound<'_, PyAny>>, name: &str, m: usize) -> PyResult<Option<Vec<f64>>> {
    s.filter(|s| !s.is_none())
        .map(|s| Ok(matrix(s, name, Some(m))?.0.as_slice()?.to_vec()))
        .transpose()
}

/// `CdprPlant.closed_loop`: per controller period (rows) the platform `pose` `(T, n)`, the
/// desired tensions `desired`, platform-side tensions `ee`, winch-side `sensor` (with noise),
/// the fed-back `feedback`, motor `current` (A) and drum angles `alpha` (rad) `(T, m)`; the
/// cable wrenches `(T, n)`: `wrench_desired` (`Aᵀ·f_d`), `wrench_ee` (the actual one),
/// `wrench_sensor` and `wrench_feedback` (at the desired pose); the number of periods whose
/// `f_d` was `infeasible`; and the plant's `inputs` `(T, 3m + n)` (held over each period) and
/// `initial_state`, which replay the run through `simulate` or an sr-UKF.
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct LoopRun {
    pose: Py<PyArray2<f64>>,
    desired: Py<PyArray2<f64>>,
    ee: Py<PyArray2<f64>>,
    sensor: Py<PyArray2<f64>>,
    feedback: Py<PyArray2<f64>>,
    current: Py<PyArray2<f64>>,
    alpha: Py<PyArray2<f64>>,
    wrench_desired: Py<PyArray2<f64>>,
    wrench_ee: Py<PyArray2<f64>>,
    wrench_sensor: Py<PyArray2<f64>>,
    wrench_feedback: Py<PyArray2<f64>>,
    infeasible: usize,
    inputs: Py<PyArray2<f64>>,
    initial_state: Py<numpy::PyArray1<f64>>,
}

impl LoopRun {
    fn new(py: Python<'_>, r: control::LoopRun, n: usize, m: usize) -> Self {
        let t = r.samples;
        let mat = |v: Vec<f64>, c: usize| to_matrix(py, v, t, c).unbind();
        Self {
            pose: mat(r.pose, n),
            desired: mat(r.desired, m),
            ee: mat(r.ee, m),
            sensor: mat(r.sensor, m),
            feedback: mat(r.feedback, m),
            current: mat(r.current, m),
            alpha: mat(r.alpha, m),
            wrench_desired: mat(r.wrench_desired, n),
            wrench_ee: mat(r.wrench_ee, n),
            wrench_sensor: mat(r.wrench_sensor, n),
            wrench_feedback: mat(r.wrench_feedback, n),
            infeasible: r.infeasible,
            inputs: mat(r.inputs, 3 * m + n),
            initial_state: to_vector(py, r.initial_state).unbind(),
        }
    }
}

/// Add this file's classes and functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<CdprPlant>()?;
    m.add_class::<PulleyFriction>()?;
    m.add_class::<LoopRun>()?;
    Ok(())
}
