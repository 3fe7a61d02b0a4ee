//! `Jtdo`: the forceps' joint torque disturbance observer and clamping-force estimator.

use std::sync::Mutex;

use cable_core::forceps::drive;
use cable_core::forceps::physics::{self, Losses, PhysicsObserver as CorePhysics};
use cable_core::forceps::twin::{self, Segment};
use cable_core::forceps::{self as core, ClampLog, Geometry};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;

use crate::convert::{matrix, opt_tuples, to_matrix, tuples, vector, vector_into};
use crate::errors::{core_error, guarded, lock};

const BIAS: &str = "a pair (A, B) of forces in N";

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
    #[pyo3(signature = (*, r2, arm_a, arm_b, threshold = core::SEED_THRESHOLD, bias = None))]
    fn new(
        r2: f64,
        arm_a: f64,
        arm_b: f64,
        threshold: f64,
        bias: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let geometry = Geometry { r2, arm_a, arm_b };
        let bias: [f64; 2] = opt_tuples(bias, "bias", BIAS)?.unwrap_or_default();
        let inner = guarded(|| core::Jtdo::new(geometry, threshold, bias))?;
        Ok(Self { inner })
    }

    /// The same observer with another `bias` `(A, B)` (N).
    fn with_bias(&self, bias: &Bound<'_, PyAny>) -> PyResult<Self> {
        let bias: [f64; 2] = tuples(bias, "bias", BIAS)?;
        let inner = guarded(|| self.inner.with_bias(bias))?;
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
    /// The collision threshold on the external force (N).
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
        Ok(guarded(|| self.inner.estimate(&m, &f))?.into())
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
        Ok(clamp_run(py, log, t))
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

impl From<core::Clamp> for ClampStep {
    fn from(c: core::Clamp) -> Self {
        Self {
            disturbance: c.disturbance.into(),
            torque: c.torque.into(),
            external: c.external.into(),
            clamping: c.clamping,
            contact: c.contact.into(),
        }
    }
}

fn clamp_run(py: Python<'_>, log: ClampLog, t: usize) -> ClampRun {
    let contact = numpy::ndarray::Array2::from_shape_vec((t, 2), log.contact)
        .expect("buffer length matches the shape by construction");
    ClampRun {
        disturbance: to_matrix(py, log.disturbance, t, 4).unbind(),
        torque: to_matrix(py, log.torque, t, 2).unbind(),
        external: to_matrix(py, log.external, t, 2).unbind(),
        clamping: log.clamping.into_pyarray(py).unbind(),
        contact: contact.into_pyarray(py).unbind(),
    }
}

/// Seed 000's two-forceps bench as a twin (see `cable_core::forceps::twin`): jaws `a`, `b` as
/// `(17,)` parameter arrays in `JAW_NAMES` order, sensor noise (N) with its `seed`, the
/// sampling period (s) and RK4 steps per sample. Immutable.
#[pyclass(frozen, module = "cablekit._cablekit")]
pub struct Twin {
    inner: twin::Twin,
}

#[pymethods]
impl Twin {
    #[classattr]
    const JAW_NAMES: [&'static str; twin::N_JAW] = twin::JAW_NAMES;
    #[classattr]
    const SEED_SPEEDS: [f64; 5] = twin::SEED_SPEEDS;

    #[new]
    #[pyo3(signature = (a, b, *, tension_noise, pressure_noise, seed, sample_time, substeps))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        a: &Bound<'_, PyAny>,
        b: &Bound<'_, PyAny>,
        tension_noise: f64,
        pressure_noise: f64,
        seed: u64,
        sample_time: f64,
        substeps: usize,
    ) -> PyResult<Self> {
        let (a, b) = (vector(a, "a", twin::N_JAW)?, vector(b, "b", twin::N_JAW)?);
        let inner = guarded(|| {
            let tw = twin::Twin {
                a: twin::Jaw::from_array(&a, "a")?,
                b: twin::Jaw::from_array(&b, "b")?,
                noise: twin::Noise {
                    tension: tension_noise,
                    pressure: pressure_noise,
                    seed,
                },
                sample_time,
                substeps,
            };
            tw.validate().map(|()| tw)
        })?;
        Ok(Self { inner })
    }

    /// Seed 000's bench with the core's documented values.
    #[staticmethod]
    fn seed() -> Self {
        Self {
            inner: twin::Twin::seed(),
        }
    }

    /// Jaw `a` or `b`'s parameters `(17,)` in `JAW_NAMES` order.
    #[getter]
    fn a<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.a.to_array().to_vec().into_pyarray(py)
    }
    #[getter]
    fn b<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.b.to_array().to_vec().into_pyarray(py)
    }
    /// `(tension_noise, pressure_noise, seed, sample_time, substeps)`.
    #[getter]
    fn bench(&self) -> (f64, f64, u64, f64, usize) {
        let t = &self.inner;
        (
            t.noise.tension,
            t.noise.pressure,
            t.noise.seed,
            t.sample_time,
            t.substeps,
        )
    }

    /// Seed 000 §3.1's free motion: close and open over the whole range at each of `speeds`
    /// (m/s), block removed (GIL released).
    #[pyo3(signature = (speeds = twin::SEED_SPEEDS.to_vec(), pause = 0.2))]
    fn free_motion(&self, py: Python<'_>, speeds: Vec<f64>, pause: f64) -> PyResult<TwinRun> {
        let run = py.detach(|| guarded(|| self.inner.free_motion(&speeds, pause)))?;
        Ok(twin_run(py, run))
    }

    /// Seed 000 §3.3's clamping on the block: `steps = 1` continuous to `peak` N (Fig. 7),
    /// `steps > 1` stair loading in equal increments (Figs 8–9), each load held `dwell` s.
    fn clamp(
        &self,
        py: Python<'_>,
        speed: f64,
        peak: f64,
        steps: usize,
        dwell: f64,
    ) -> PyResult<TwinRun> {
        let run = py.detach(|| guarded(|| self.inner.clamp(speed, peak, steps, dwell)))?;
        Ok(twin_run(py, run))
    }

    /// Any motor programs: `start_*` (m) and `program_*` lists of `("move", to_m, speed_m_s)`
    /// or `("hold", seconds)`, with or without the `block`.
    fn run(
        &self,
        py: Python<'_>,
        start_a: f64,
        program_a: Vec<Bound<'_, PyAny>>,
        start_b: f64,
        program_b: Vec<Bound<'_, PyAny>>,
        block: bool,
    ) -> PyResult<TwinRun> {
        let (pa, pb) = (segments(&program_a)?, segments(&program_b)?);
        let run = py.detach(|| {
            guarded(|| {
                let a = twin::Profile::new(start_a, &pa, twin::RAMP, twin::PULSE)?;
                let b = twin::Profile::new(start_b, &pb, twin::RAMP, twin::PULSE)?;
                self.inner.run(&a, &b, block)
            })
        })?;
        Ok(twin_run(py, run))
    }
}

fn segments(program: &[Bound<'_, PyAny>]) -> PyResult<Vec<Segment>> {
    let bad = |item: &Bound<'_, PyAny>| {
        core_error(cable_core::CableError::InvalidOption {
            name: "program segment".into(),
            value: item.repr().map(|r| r.to_string()).unwrap_or_default(),
            allowed: "(\"move\", to, speed) or (\"hold\", seconds)".into(),
        })
    };
    let segment = |item: &Bound<'_, PyAny>| match item.extract::<(String, f64, f64)>() {
        Ok((kind, to, speed)) if kind == "move" => Ok(Segment::Move { to, speed }),
        Ok(_) => Err(bad(item)),
        Err(_) => match item.extract::<(String, f64)>() {
            Ok((kind, duration)) if kind == "hold" => Ok(Segment::Hold { duration }),
            _ => Err(bad(item)),
        },
    };
    program.iter().map(segment).collect()
}

/// A twin run, one row per sample: `time` `(T,)`; `motors` `(T, 4)` `[x_a, v_a, x_b, v_b]`;
/// motor-side tensions `measured` (noisy) and `tensions` `(T, 4)`; `joint_tensions` `(T, 4)`;
/// pad forces `external` (pressure sensors, noisy) and `external_true` `(T, 2)`; jaw `angles`
/// `(T, 2)` (rad, closing from fully open).
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct TwinRun {
    time: Py<PyArray1<f64>>,
    motors: Py<PyArray2<f64>>,
    measured: Py<PyArray2<f64>>,
    tensions: Py<PyArray2<f64>>,
    joint_tensions: Py<PyArray2<f64>>,
    external: Py<PyArray2<f64>>,
    external_true: Py<PyArray2<f64>>,
    angles: Py<PyArray2<f64>>,
}

fn twin_run(py: Python<'_>, r: twin::TwinRun) -> TwinRun {
    let t = r.len;
    TwinRun {
        time: r.time.into_pyarray(py).unbind(),
        motors: to_matrix(py, r.motors, t, 4).unbind(),
        measured: to_matrix(py, r.measured, t, 4).unbind(),
        tensions: to_matrix(py, r.tensions, t, 4).unbind(),
        joint_tensions: to_matrix(py, r.joint_tensions, t, 4).unbind(),
        external: to_matrix(py, r.external, t, 2).unbind(),
        external_true: to_matrix(py, r.external_true, t, 2).unbind(),
        angles: to_matrix(py, r.angles, t, 2).unbind(),
    }
}

/// The physics-informed clamping-force estimator (`cable_core::forceps::physics`): per forceps
/// the capstan and joint friction of its cable loop with rate-independent direction states,
/// from motor motion and measured tensions only. Loss parameters `(9,)` in `LOSS_NAMES` order
/// (`None`: a neutral start for `calibrated`).
/// `step` keeps the direction states between calls (`reset` forgets them; a second thread in
/// a call raises `ConcurrentUseError`); `estimate` runs a log from reset states.
#[pyclass(module = "cablekit._cablekit")]
pub struct PhysicsObserver {
    inner: Mutex<CorePhysics>,
}

/// Loss parameters from `(9,)`, or the core's neutral start for `None`.
fn losses(obj: Option<&Bound<'_, PyAny>>, name: &str) -> PyResult<Losses> {
    let Some(obj) = obj else {
        return Ok(Losses::START);
    };
    let v = vector(obj, name, physics::N_LOSSES)?;
    guarded(|| Losses::from_array(&v, name))
}

#[pymethods]
impl PhysicsObserver {
    #[classattr]
    const LOSS_NAMES: [&'static str; physics::N_LOSSES] = physics::LOSS_NAMES;

    #[new]
    #[pyo3(signature = (*, r2, arm_a, arm_b, losses_a = None, losses_b = None, threshold = core::SEED_THRESHOLD))]
    fn new(
        r2: f64,
        arm_a: f64,
        arm_b: f64,
        losses_a: Option<&Bound<'_, PyAny>>,
        losses_b: Option<&Bound<'_, PyAny>>,
        threshold: f64,
    ) -> PyResult<Self> {
        let l = [losses(losses_a, "losses_a")?, losses(losses_b, "losses_b")?];
        let inner = guarded(|| CorePhysics::new(Geometry { r2, arm_a, arm_b }, l, threshold))?;
        Ok(Self {
            inner: Mutex::new(inner),
        })
    }

    /// Fits each forceps' losses to one calibration run: `motors`, `measured` `(T, 4)` and the
    /// known `external` forces `(T, 2)` (N; zeros for free motion), from `start` (this
    /// observer's losses, e.g. another instrument's). Returns the fitted observer and the two
    /// `PhysicsCalibration`s (GIL released).
    fn calibrated(
        &self,
        py: Python<'_>,
        motors: &Bound<'_, PyAny>,
        measured: &Bound<'_, PyAny>,
        external: &Bound<'_, PyAny>,
    ) -> PyResult<(Self, (PhysicsCalibration, PhysicsCalibration))> {
        let (m, _) = matrix(motors, "motors", Some(4))?;
        let (f, _) = matrix(measured, "measured", Some(4))?;
        let (e, _) = matrix(external, "external", Some(2))?;
        let (m, f, e) = (m.as_slice()?, f.as_slice()?, e.as_slice()?);
        let me = *lock(&self.inner, "PhysicsObserver")?;
        let (obs, [ca, cb]) = py.detach(|| {
            guarded(|| CorePhysics::calibrate(me.geometry(), me.threshold(), me.losses(), m, f, e))
        })?;
        Ok((
            Self {
                inner: Mutex::new(obs),
            },
            (ca.into(), cb.into()),
        ))
    }

    /// `(2, 9)` loss parameters of A and B.
    #[getter]
    fn losses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let l = lock(&self.inner, "PhysicsObserver")?.losses();
        let v = [l[0].to_array(), l[1].to_array()].concat();
        Ok(to_matrix(py, v, 2, physics::N_LOSSES))
    }
    /// `(r2, arm_a, arm_b)` (m).
    #[getter]
    fn geometry(&self) -> PyResult<(f64, f64, f64)> {
        let g = lock(&self.inner, "PhysicsObserver")?.geometry();
        Ok((g.r2, g.arm_a, g.arm_b))
    }
    /// The collision threshold on the external force (N).
    #[getter]
    fn threshold(&self) -> PyResult<f64> {
        Ok(lock(&self.inner, "PhysicsObserver")?.threshold())
    }

    /// One sample: `motors` `[x_a, v_a, x_b, v_b]` and `measured` `(4,)` → a `ClampStep`
    /// (`disturbance` holds the tension losses `F_f`).
    fn step(&self, motors: &Bound<'_, PyAny>, measured: &Bound<'_, PyAny>) -> PyResult<ClampStep> {
        let (mut m, mut f) = ([0.0; 4], [0.0; 4]);
        vector_into(motors, "motors", &mut m)?;
        vector_into(measured, "measured", &mut f)?;
        let mut me = lock(&self.inner, "PhysicsObserver")?;
        Ok(guarded(|| me.step(&m, &f))?.into())
    }

    /// Forget the direction states (a new run starts).
    fn reset(&self) -> PyResult<()> {
        lock(&self.inner, "PhysicsObserver")?.reset();
        Ok(())
    }

    /// A whole log `(T, 4)` each from reset states → a `ClampRun` (GIL released).
    fn estimate(
        &self,
        py: Python<'_>,
        motors: &Bound<'_, PyAny>,
        measured: &Bound<'_, PyAny>,
    ) -> PyResult<ClampRun> {
        let (m, t) = matrix(motors, "motors", Some(4))?;
        let (f, _) = matrix(measured, "measured", Some(4))?;
        let (m, f) = (m.as_slice()?, f.as_slice()?);
        let me = *lock(&self.inner, "PhysicsObserver")?;
        let log = py.detach(|| guarded(|| me.estimate_log(m, f)))?;
        Ok(clamp_run(py, log, t))
    }
}

/// One forceps' calibration: fitted `losses` `(9,)`, the external-force RMS error on the
/// calibration run at the start and after the fit (`rmse_start`, `rmse`, N), LM `iterations`
/// and whether a tolerance stopped it (`converged`).
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct PhysicsCalibration {
    losses: Vec<f64>,
    rmse_start: f64,
    rmse: f64,
    iterations: usize,
    converged: bool,
}

impl From<physics::Calibration> for PhysicsCalibration {
    fn from(c: physics::Calibration) -> Self {
        Self {
            losses: c.losses.to_array().to_vec(),
            rmse_start: c.rmse_start,
            rmse: c.rmse,
            iterations: c.iterations,
            converged: c.converged,
        }
    }
}

/// Jaw torque from drive-side signals (`cable_core::forceps::drive`): a transmission with
/// Maxwell-slip friction driven by the motor angle (and optionally by the spindle's), fitted by least squares on runs with a
/// measured jaw, inverted per sample. A run is a `(T, 5)` array of `[spindle_angle (rad),
/// spindle_torque (N·m), motor_angle (rad), jaw_torque (N·m), jaw_angle (rad)]` sampled every
/// `dt` s (for `estimate` the jaw columns may be absent: `(T, 3)`). Immutable.
#[pyclass(frozen, module = "cablekit._cablekit")]
pub struct DriveModel {
    inner: drive::DriveModel,
}

/// The views of `(5, T)` or `(3, T)` signal arrays as core runs.
fn drive_runs<'a>(
    data: &'a [(numpy::ndarray::Array2<f64>, usize)],
    dt: f64,
) -> Vec<drive::DriveRun<'a>> {
    data.iter()
        .map(|(a, cols)| {
            let col = |j: usize| {
                a.row(j)
                    .to_slice()
                    .expect("rows of a standard-layout copy are contiguous")
            };
            drive::DriveRun {
                spindle_angle: col(0),
                spindle_torque: col(1),
                motor_angle: col(2),
                jaw_torque: (*cols == 5).then(|| col(3)),
                jaw_angle: (*cols == 5).then(|| col(4)),
                dt,
            }
        })
        .collect()
}

/// A run's columns as the rows of a `(columns, T)` copy, so each signal is one slice.
fn drive_array(
    obj: &Bound<'_, PyAny>,
    name: &str,
    jaw: bool,
) -> PyResult<(numpy::ndarray::Array2<f64>, usize)> {
    let (m, _) = matrix(obj, name, None)?;
    let v = m.as_array();
    let cols = v.ncols();
    if cols != 5 && (jaw || cols != 3) {
        let expected = if jaw { "5 columns" } else { "3 or 5 columns" };
        return Err(core_error(cable_core::CableError::Shape {
            what: name.into(),
            expected: format!("(T, {expected}): spindle angle, spindle torque, motor angle[, jaw torque, jaw angle]"),
            got: format!("{:?}", v.shape()),
        }));
    }
    Ok((v.t().as_standard_layout().into_owned(), cols))
}

/// One `(T,)` array of sample weights per run of `data` (`DriveModel.fit`'s `weights`).
fn run_weights(
    ws: &[Bound<'_, PyAny>],
    data: &[(numpy::ndarray::Array2<f64>, usize)],
) -> PyResult<Vec<Vec<f64>>> {
    if ws.len() != data.len() {
        return Err(core_error(cable_core::CableError::Shape {
            what: "weights".into(),
            expected: format!("one array per run ({})", data.len()),
            got: ws.len().to_string(),
        }));
    }
    ws.iter()
        .zip(data)
        .enumerate()
        .map(|(i, (w, (a, _)))| vector(w, &format!("weights[{i}]"), a.ncols()))
        .collect()
}

/// `DriveModel.fit`'s `angle_friction`: `None` (the core's default), `"fitted"`, `"off"` or a
/// span `(lo, hi)` in rad.
fn angle_friction(obj: Option<&Bound<'_, PyAny>>) -> PyResult<drive::AngleFriction> {
    let Some(obj) = obj else {
        return Ok(drive::AngleFriction::default());
    };
    if let Ok(name) = obj.extract::<String>() {
        return match name.as_str() {
            "fitted" => Ok(drive::AngleFriction::FittedRange),
            "off" => Ok(drive::AngleFriction::Off),
            _ => Err(core_error(cable_core::CableError::InvalidOption {
                name: "angle_friction".into(),
                value: name,
                allowed: "'fitted', 'off' or a span (lo, hi) in rad".into(),
            })),
        };
    }
    // a (lo, hi) pair of numbers, or a (2,) float64 array
    if let Ok((lo, hi)) = obj.extract::<(f64, f64)>() {
        return Ok(drive::AngleFriction::Span([lo, hi]));
    }
    let span = vector(obj, "angle_friction", 2)?;
    Ok(drive::AngleFriction::Span([span[0], span[1]]))
}

#[pymethods]
impl DriveModel {
    /// Fits on `runs` (a list of `(T, 5)` arrays) with Maxwell-slip element `travels` (rad
    /// of motor angle), a causal velocity over `window` samples, skipping `warmup` s per run;
    /// `weights` (optional): one `(T,)` array of sample weights ≥ 0 per run (0 leaves a sample
    /// out of the fit, 2 counts it twice); `angle_friction`: the friction's dependence on the
    /// spindle angle — `"fitted"` (the default: held inside the fitted samples' range), `"off"`,
    /// or a span `(lo, hi)` in rad to hold it in (a calibration recording's range);
    /// `spindle_travels`: travels (rad of spindle angle) of Maxwell-slip elements driven by the
    /// spindle beside those driven by the motor (none by default).
    #[staticmethod]
    #[pyo3(signature = (runs, travels, *, dt = 1e-3, window = 20, warmup = 1.0, weights = None, angle_friction = None, spindle_travels = None))]
    #[allow(clippy::too_many_arguments)]
    fn fit(
        py: Python<'_>,
        runs: Vec<Bound<'_, PyAny>>,
        travels: Vec<f64>,
        dt: f64,
        window: usize,
        warmup: f64,
        weights: Option<Vec<Bound<'_, PyAny>>>,
        angle_friction: Option<Bound<'_, PyAny>>,
        spindle_travels: Option<Vec<f64>>,
    ) -> PyResult<Self> {
        let spindle_travels = spindle_travels.unwrap_or_default();
        let angle = self::angle_friction(angle_friction.as_ref())?;
        let data = runs
            .iter()
            .enumerate()
            .map(|(i, r)| drive_array(r, &format!("runs[{i}]"), true))
            .collect::<PyResult<Vec<_>>>()?;
        let weights = weights.map(|ws| run_weights(&ws, &data)).transpose()?;
        let inner = py.detach(|| {
            let views: Option<Vec<&[f64]>> = weights
                .as_ref()
                .map(|ws| ws.iter().map(Vec::as_slice).collect());
            guarded(|| {
                drive::DriveModel::fit_with(
                    &drive_runs(&data, dt),
                    views.as_deref(),
                    &travels,
                    window,
                    warmup,
                    angle,
                    &spindle_travels,
                )
            })
        })?;
        Ok(Self { inner })
    }

    /// The model adapted to a new instrument from one `(T, 5)` run or a list of them (their
    /// samples pooled): the offsets, and with `friction=True` also a common scale of the
    /// friction torques.
    #[pyo3(signature = (run, *, dt = 1e-3, friction = false))]
    fn recalibrated(&self, run: &Bound<'_, PyAny>, dt: f64, friction: bool) -> PyResult<Self> {
        let data = if let Ok(list) = run.cast::<pyo3::types::PyList>() {
            if list.is_empty() {
                return Err(core_error(cable_core::CableError::Shape {
                    what: "calibration runs".into(),
                    expected: "at least one run".into(),
                    got: "an empty list".into(),
                }));
            }
            list.iter()
                .enumerate()
                .map(|(i, r)| drive_array(&r, &format!("run[{i}]"), true))
                .collect::<PyResult<Vec<_>>>()?
        } else {
            vec![drive_array(run, "run", true)?]
        };
        let what = if friction {
            drive::Recalibrate::OffsetAndFriction
        } else {
            drive::Recalibrate::Offset
        };
        let inner = guarded(|| self.inner.recalibrated_on(&drive_runs(&data, dt), what))?;
        Ok(Self { inner })
    }

    /// Estimated jaw torque (N·m) and angle (rad) for a `(T, 3)` or `(T, 5)` run → `JawEstimate`
    /// (GIL released).
    #[pyo3(signature = (run, *, dt = 1e-3))]
    fn estimate(&self, py: Python<'_>, run: &Bound<'_, PyAny>, dt: f64) -> PyResult<JawEstimate> {
        let data = [drive_array(run, "run", false)?];
        let (torque, angle, outside) =
            py.detach(|| guarded(|| self.inner.estimate(&drive_runs(&data, dt)[0])))?;
        Ok(JawEstimate {
            torque: torque.into_pyarray(py).unbind(),
            angle: angle.into_pyarray(py).unbind(),
            outside_share: outside,
        })
    }

    /// A per-sample observer of this model for a controller (`JawObserver`).
    #[pyo3(signature = (*, dt = 1e-3))]
    fn observer(&self, dt: f64) -> PyResult<JawObserver> {
        let inner = guarded(|| drive::DriveObserver::new(self.inner.clone(), dt))?;
        Ok(JawObserver {
            inner: Mutex::new(inner),
        })
    }

    /// `[c₀, c_θ, c_ω, a₁..a_m, (e₁..e_m,) h₁..h_q, g, b₁..b_m]` (the `eᵢ` with angle-dependent
    /// friction, the `hₖ` with spindle-driven elements).
    #[getter]
    fn coefficients(&self) -> Vec<f64> {
        self.inner.coefficients().to_vec()
    }
    /// The span `(lo, hi)` (rad) of the angle-dependent friction, `None` when it is off.
    #[getter]
    fn angle_friction_span(&self) -> Option<(f64, f64)> {
        self.inner.angle_friction_span().map(|s| (s[0], s[1]))
    }
    /// `[p₀, p₁, p₂]` of the jaw angle.
    #[getter]
    fn angle_coefficients(&self) -> [f64; 3] {
        self.inner.angle_coefficients()
    }
    /// The Maxwell-slip elements' travels (rad of motor angle).
    #[getter]
    fn travels(&self) -> Vec<f64> {
        self.inner.travels().to_vec()
    }
    /// The spindle-driven Maxwell-slip elements' travels (rad of spindle angle; empty without).
    #[getter]
    fn spindle_travels(&self) -> Vec<f64> {
        self.inner.spindle_travels().to_vec()
    }
    /// Training ranges `[[min, max]]` of spindle angle, torque and velocity.
    #[getter]
    fn ranges(&self) -> [[f64; 2]; 3] {
        self.inner.ranges()
    }
}

/// `DriveModel.estimate`: jaw `torque` (N·m) and `angle` (rad) per sample, and the share of
/// samples outside the training ranges (`outside_share`).
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct JawEstimate {
    torque: Py<PyArray1<f64>>,
    angle: Py<PyArray1<f64>>,
    outside_share: f64,
}

/// `DriveModel.observer`: one sample per `step(spindle_angle, spindle_torque, motor_angle)`
/// (rad, N·m, rad) → `JawSample`; the friction states persist between calls, `reset` forgets
/// them. A second thread in a call raises `ConcurrentUseError`.
#[pyclass(module = "cablekit._cablekit")]
pub struct JawObserver {
    inner: Mutex<drive::DriveObserver>,
}

#[pymethods]
impl JawObserver {
    /// One sample: spindle angle (rad), spindle torque (N·m) and motor angle (rad) in, the jaw's
    /// `JawSample` out; the friction states carry over to the next call.
    fn step(
        &self,
        spindle_angle: f64,
        spindle_torque: f64,
        motor_angle: f64,
    ) -> PyResult<JawSample> {
        let mut obs = lock(&self.inner, "JawObserver")?;
        let e = guarded(|| obs.step(spindle_angle, spindle_torque, motor_angle))?;
        Ok(JawSample {
            torque: e.torque,
            angle: e.angle,
            outside: e.outside,
        })
    }

    /// Forget the friction states (a new run starts at rest).
    fn reset(&self) -> PyResult<()> {
        lock(&self.inner, "JawObserver")?.reset();
        Ok(())
    }
}

/// One `JawObserver.step`: jaw `torque` (N·m), `angle` (rad), and whether an input was
/// `outside` the training ranges.
#[pyclass(frozen, get_all, module = "cablekit._cablekit")]
pub struct JawSample {
    torque: f64,
    angle: f64,
    outside: bool,
}

/// Add this file's classes and functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Jtdo>()?;
    m.add_class::<ClampStep>()?;
    m.add_class::<ClampRun>()?;
    m.add_class::<Twin>()?;
    m.add_class::<TwinRun>()?;
    m.add_class::<PhysicsObserver>()?;
    m.add_class::<PhysicsCalibration>()?;
    m.add_class::<DriveModel>()?;
    m.add_class::<JawEstimate>()?;
    m.add_class::<JawObserver>()?;
    m.add_class::<JawSample>()?;
    Ok(())
}
