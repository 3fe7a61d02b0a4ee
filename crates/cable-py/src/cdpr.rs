//! `Robot`: a cable-driven parallel robot, its kinematics and tension distribution.

use std::sync::Mutex;

use cable_core::cdpr::{
    self as core, KinematicsMut, Margins, Method, Motion, Platform, Requirement, TensionsMut,
};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;

use crate::convert::{
    any_vector, matrix, opt_tuples, out_vector, to_matrix, to_vector, vector, vector_into,
};
use crate::errors::{guarded, lock};
use crate::results::{Capacity, CapacityBuffers, Kinematics, PathRun, Step, Tensions};

/// `(cable, radius, axis)` of each pulley.
type Pulleys = Vec<(usize, f64, [f64; 3])>;

/// The optional `wrenches` `(T, n)` argument, copied out (`None` when absent or `None`).
fn optional_wrenches(wrenches: Option<&Bound<'_, PyAny>>, n: usize) -> PyResult<Option<Vec<f64>>> {
    wrenches
        .filter(|w| !w.is_none())
        .map(|w| Ok(matrix(w, "wrenches", Some(n))?.0.as_slice()?.to_vec()))
        .transpose()
}

/// A cable-driven parallel robot (seeds 002, 003): `motion` `"planar"` (pose `[x, y, θ]`) or
/// `"spatial"` (pose `[x, y, z, roll, pitch, yaw]`), per cable an anchor and a platform
/// attachment `(m, 3)`, tension bounds and axial stiffness `E·A` `(m,)`, optional pulleys
/// `(cable, radius, axis)`, the platform's mass, centre of mass `(3,)` and inertia `(3, 3)`, and
/// gravity `(3,)`. Immutable; calls on many poses release the GIL and run in parallel.
#[pyclass(subclass, frozen, module = "cablekit._cablekit")]
pub struct Robot {
    pub(crate) inner: core::Robot,
}

#[pymethods]
impl Robot {
    #[new]
    #[pyo3(signature = (*, name, motion, anchors, attachments, f_min, f_max, ea, mass, com, inertia, gravity, pulleys = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        name: &str,
        motion: &str,
        anchors: &Bound<'_, PyAny>,
        attachments: &Bound<'_, PyAny>,
        f_min: &Bound<'_, PyAny>,
        f_max: &Bound<'_, PyAny>,
        ea: &Bound<'_, PyAny>,
        mass: f64,
        com: &Bound<'_, PyAny>,
        inertia: &Bound<'_, PyAny>,
        gravity: &Bound<'_, PyAny>,
        pulleys: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let (a, _) = matrix(anchors, "anchors", Some(3))?;
        let (b, _) = matrix(attachments, "attachments", Some(3))?;
        let bounds = (any_vector(f_min, "f_min")?, any_vector(f_max, "f_max")?);
        let ea = any_vector(ea, "ea")?;
        let (j, _) = matrix(inertia, "inertia", Some(3))?;
        let platform = Platform {
            mass,
            com: xyz(com, "com")?,
            inertia: j.as_slice()?.try_into().map_err(|_| shape("inertia"))?,
        };
        let gravity = xyz(gravity, "gravity")?;
        let (a, b) = (a.as_slice()?, b.as_slice()?);
        let what = "a list of (cable, radius, axis (3,)) triples";
        let pulleys: Pulleys = opt_tuples(pulleys, "pulleys", what)?.unwrap_or_default();
        let inner = guarded(|| {
            let columns = (bounds.0.as_slice(), bounds.1.as_slice(), ea.as_slice());
            let motion = Motion::from_name(motion)?;
            core::Robot::from_columns(name, motion, a, b, columns, &pulleys, platform, gravity)
        })?;
        Ok(Self { inner })
    }

    /// The robot's name (from its file, or empty).
    #[getter]
    fn name(&self) -> &str {
        &self.inner.name
    }
    #[getter]
    fn motion(&self) -> &'static str {
        self.inner.motion.name()
    }
    /// Degrees of freedom `n`.
    #[getter]
    fn dof(&self) -> usize {
        self.inner.dof()
    }
    /// Cables `m`.
    #[getter]
    fn n_cables(&self) -> usize {
        self.inner.n_cables()
    }
    /// The platform's mass (kg).
    #[getter]
    fn mass(&self) -> f64 {
        self.inner.platform.mass
    }
    /// Axial stiffness `E·A` per cable (N).
    #[getter]
    fn ea<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_vector(py, self.inner.cables.iter().map(|c| c.ea).collect())
    }
    /// `(f_min, f_max)` per cable (N).
    #[getter]
    fn bounds<'py>(
        &self,
        py: Python<'py>,
    ) -> (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>) {
        let c = &self.inner.cables;
        let lo = c.iter().map(|c| c.f_min).collect();
        (
            to_vector(py, lo),
            to_vector(py, c.iter().map(|c| c.f_max).collect()),
        )
    }

    /// Inverse kinematics of poses `(T, n)`: a `Kinematics` with cable lengths `(T, m)` and
    /// structure matrices `Aᵀ` `(T, n, m)` (GIL released, parallel for many poses).
    fn inverse_kinematics(&self, py: Python<'_>, poses: &Bound<'_, PyAny>) -> PyResult<Kinematics> {
        let (n, m) = (self.inner.dof(), self.inner.n_cables());
        let (p, t) = matrix(poses, "poses", Some(n))?;
        let (mut length, mut structure) = (vec![0.0; t * m], vec![0.0; t * n * m]);
        let out = KinematicsMut {
            length: &mut length,
            structure: &mut structure,
        };
        let p = p.as_slice()?;
        py.detach(|| guarded(|| core::inverse_kinematics_batch(&self.inner, p, out)))?;
        Ok(Kinematics::new(py, length, structure, (t, n, m)))
    }

    /// The winch-side (sensor) tensions along a trajectory: poses `(T, n)` every `dt` s, the
    /// platform-side tensions `ee` `(T, m)`, and each cable's path friction (seed 002 eqs 7–8):
    /// `coefficient` μ, `viscous` σ_v (N·s/m), `guide_wrap` (rad) as `(m,)` or `(1,)` arrays,
    /// `law` `"dahl"` (`presliding` m, `exponent`) or `"coulomb"` (`smoothing` m/s). A
    /// `PathRun` (GIL released).
    #[pyo3(signature = (poses, ee, dt, coefficient, viscous, guide_wrap, *, law = None, smoothing = None, presliding = None, exponent = None))]
    #[allow(clippy::too_many_arguments)]
    fn path_friction(
        &self,
        py: Python<'_>,
        poses: &Bound<'_, PyAny>,
        ee: &Bound<'_, PyAny>,
        dt: f64,
        coefficient: &Bound<'_, PyAny>,
        viscous: &Bound<'_, PyAny>,
        guide_wrap: &Bound<'_, PyAny>,
        law: Option<&str>,
        smoothing: Option<f64>,
        presliding: Option<f64>,
        exponent: Option<f64>,
    ) -> PyResult<PathRun> {
        let (n, m) = (self.inner.dof(), self.inner.n_cables());
        let (p, t) = matrix(poses, "poses", Some(n))?;
        let (e, _) = matrix(ee, "ee", Some(m))?;
        let friction = crate::plant::PulleyFriction::new(
            coefficient,
            viscous,
            guide_wrap,
            law,
            smoothing,
            presliding,
            exponent,
        )?;
        let paths = guarded(|| friction.paths(m))?;
        let (p, e) = (p.as_slice()?, e.as_slice()?);
        let run = py.detach(|| guarded(|| core::path_friction(&self.inner, p, e, dt, &paths)))?;
        Ok(PathRun::new(py, run, (t, m)))
    }

    /// Measured tensions `(T, m)` moved to the nearest tensions that hold the platform at the
    /// poses `(T, n)` against the external `wrenches` `(T, n)` and the weight (unless
    /// `gravity=False`): seed 002 eq. 10 with the measurement as `f_ref` (GIL released).
    #[pyo3(signature = (poses, tensions, wrenches = None, *, gravity = true))]
    fn project_tensions<'py>(
        &self,
        py: Python<'py>,
        poses: &Bound<'py, PyAny>,
        tensions: &Bound<'py, PyAny>,
        wrenches: Option<&Bound<'py, PyAny>>,
        gravity: bool,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let (n, m) = (self.inner.dof(), self.inner.n_cables());
        let (p, t) = matrix(poses, "poses", Some(n))?;
        let (f, _) = matrix(tensions, "tensions", Some(m))?;
        let ext = optional_wrenches(wrenches, n)?;
        let (p, f) = (p.as_slice()?, f.as_slice()?);
        let out = py.detach(|| {
            guarded(|| core::equilibrium_projection(&self.inner, p, f, ext.as_deref(), gravity))
        })?;
        Ok(to_matrix(py, out, t, m))
    }

    /// Tensions at poses `(T, n)` holding the platform's weight (unless `gravity=False`) plus
    /// the external `wrenches` `(T, n)`, by `method` (`"auto"`: improved closed form → QP →
    /// least wrench error; or one of `"minimum_norm"`, `"closed_form"`,
    /// `"improved_closed_form"`, `"qp"`): a `Tensions` (GIL released, parallel).
    #[pyo3(signature = (poses, wrenches = None, *, method = "auto", gravity = true))]
    fn distribute(
        &self,
        py: Python<'_>,
        poses: &Bound<'_, PyAny>,
        wrenches: Option<&Bound<'_, PyAny>>,
        method: &str,
        gravity: bool,
    ) -> PyResult<Tensions> {
        let (n, m) = (self.inner.dof(), self.inner.n_cables());
        let method = guarded(|| Method::from_name(method))?;
        let (p, t) = matrix(poses, "poses", Some(n))?;
        let ext = optional_wrenches(wrenches, n)?;
        let mut f = vec![0.0; t * m];
        let (mut used, mut feasible, mut residual) =
            (vec![Method::Auto; t], vec![false; t], vec![0.0; t]);
        let out = TensionsMut {
            f: &mut f,
            method: &mut used,
            feasible: &mut feasible,
            residual: &mut residual,
        };
        let p = p.as_slice()?;
        py.detach(|| {
            guarded(|| core::distribute_batch(&self.inner, p, ext.as_deref(), gravity, method, out))
        })?;
        Ok(Tensions::new(py, f, (t, m), &used, feasible, residual))
    }

    /// Capacity margins at poses `(T, n)`: the required wrench set is the platform's weight
    /// (unless `gravity=False`) plus the box `wrench ± half_width` `(n,)` each; moments count
    /// in the distance divided by `moment_length` (m). A `Capacity` (GIL released, parallel);
    /// a grid of poses gives the static or wrench-feasible workspace. `margins="inside"` stops
    /// an outside pose's scan at the first crossed facet (its margin is then an upper bound).
    #[pyo3(signature = (poses, wrench = None, half_width = None, *, gravity = true, moment_length = 1.0, margins = "everywhere"))]
    #[allow(clippy::too_many_arguments)]
    fn capacity(
        &self,
        py: Python<'_>,
        poses: &Bound<'_, PyAny>,
        wrench: Option<&Bound<'_, PyAny>>,
        half_width: Option<&Bound<'_, PyAny>>,
        gravity: bool,
        moment_length: f64,
        margins: &str,
    ) -> PyResult<Capacity> {
        let n = self.inner.dof();
        let (p, t) = matrix(poses, "poses", Some(n))?;
        let req = requirement(n, wrench, half_width, gravity, moment_length, margins)?;
        let p = p.as_slice()?;
        let mut buf = CapacityBuffers::new(t, n);
        py.detach(|| guarded(|| core::capacity_batch(&self.inner, p, &req, buf.out())))?;
        Ok(Capacity::new(py, buf, (t, n)))
    }

    /// A `TensionController` for this robot: one pose per call, the solver kept warm.
    #[pyo3(signature = (method = "auto", *, gravity = true))]
    fn controller(&self, method: &str, gravity: bool) -> PyResult<TensionController> {
        let inner =
            guarded(|| core::Controller::new(&self.inner, Method::from_name(method)?, gravity))?;
        Ok(TensionController {
            inner: Mutex::new(inner),
        })
    }

    /// The pose whose cable lengths are `lengths` `(m,)`, from `seed` `(n,)` (damped
    /// Gauss–Newton): `(pose, rms_error, iterations, converged)`.
    #[pyo3(signature = (lengths, seed, tolerance = 1e-10))]
    fn forward_kinematics<'py>(
        &self,
        py: Python<'py>,
        lengths: &Bound<'py, PyAny>,
        seed: &Bound<'py, PyAny>,
        tolerance: f64,
    ) -> PyResult<(Bound<'py, PyArray1<f64>>, f64, usize, bool)> {
        let l = vector(lengths, "lengths", self.inner.n_cables())?;
        let s = vector(seed, "seed", self.inner.dof())?;
        let fk = guarded(|| core::forward_kinematics(&self.inner, &l, &s, tolerance))?;
        Ok((
            to_vector(py, fk.pose),
            fk.rms_error,
            fk.iterations,
            fk.converged,
        ))
    }

    /// The platform's weight as a wrench `(n,)` at `pose`.
    fn gravity_wrench<'py>(
        &self,
        py: Python<'py>,
        pose: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let q = vector(pose, "pose", self.inner.dof())?;
        let p = guarded(|| core::Pose::from_coordinates(self.inner.motion, &q))?;
        let mut w = [0.0; 6];
        self.inner.gravity_wrench(&p.rotation, &mut w);
        Ok(to_vector(py, w[..self.inner.dof()].to_vec()))
    }

    /// Anchors and attachments `(m, 3)` as given.
    fn points<'py>(
        &self,
        py: Python<'py>,
    ) -> (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>) {
        let c = &self.inner.cables;
        let m = c.len();
        let a = c.iter().flat_map(|c| c.anchor).collect();
        let b = c.iter().flat_map(|c| c.attachment).collect();
        (
            crate::convert::to_matrix(py, a, m, 3),
            crate::convert::to_matrix(py, b, m, 3),
        )
    }

    fn __repr__(&self) -> String {
        let r = &self.inner;
        format!(
            "Robot(name={:?}, motion={:?}, cables={})",
            r.name,
            r.motion.name(),
            r.n_cables()
        )
    }
}

fn shape(name: &str) -> PyErr {
    crate::errors::arg_error(
        crate::errors::Class::Shape,
        name,
        format!("{name} must have shape (3, 3)"),
    )
}

fn xyz(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<[f64; 3]> {
    let v = vector(obj, name, 3)?;
    Ok([v[0], v[1], v[2]])
}

/// Tension distribution at a controller's rate (`Robot.controller`): `step(pose, wrench, out)`
/// distributes for one pose, keeping the QP's face warm between calls; with `out` `(m,)` the
/// tensions are written in place. A call while another thread's is running raises
/// `ConcurrentUseError`.
#[pyclass(frozen, module = "cablekit._cablekit")]
pub struct TensionController {
    inner: Mutex<core::Controller>,
}

#[pymethods]
impl TensionController {
    /// Tensions at `pose` `(n,)` against the weight plus `wrench` `(n,)`: a `Step` (tensions,
    /// method, feasible, residual, and the largest change since the last step).
    #[pyo3(signature = (pose, wrench = None, out = None))]
    fn step<'py>(
        &self,
        py: Python<'py>,
        pose: &Bound<'py, PyAny>,
        wrench: Option<&Bound<'py, PyAny>>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Step> {
        let mut ctl = lock(&self.inner, "TensionController")?;
        let (n, m) = (ctl.robot().dof(), ctl.robot().n_cables());
        let (mut q, mut w) = ([0.0; 6], [0.0; 6]);
        vector_into(pose, "pose", &mut q[..n])?;
        let wrench = wrench.filter(|v| !v.is_none());
        if let Some(v) = wrench {
            vector_into(v, "wrench", &mut w[..n])?;
        }
        let mut out = out
            .filter(|v| !v.is_none())
            .map(|o| out_vector(o, "out", m).map(|rw| (o.clone(), rw)))
            .transpose()?;
        let s = guarded(|| ctl.step(&q[..n], wrench.map(|_| &w[..n])))?;
        let d = s.distribution;
        let f = match out.as_mut() {
            Some((obj, rw)) => {
                rw.as_slice_mut()?.copy_from_slice(d.tensions());
                obj.clone().cast_into::<PyArray1<f64>>()?
            }
            None => to_vector(py, d.tensions().to_vec()),
        };
        Ok(Step::new(f, d.method, d.feasible, d.residual, s.jump))
    }

    /// Forget the warm solver, its face and the last tensions.
    fn reset(&self) -> PyResult<()> {
        lock(&self.inner, "TensionController")?.reset();
        Ok(())
    }

    /// The tension distribution method in use.
    #[getter]
    fn method(&self) -> PyResult<&'static str> {
        Ok(lock(&self.inner, "TensionController")?.method().name())
    }

    fn __repr__(&self) -> PyResult<String> {
        let c = lock(&self.inner, "TensionController")?;
        Ok(format!(
            "TensionController(robot={:?}, method={:?})",
            c.robot().name,
            c.method().name()
        ))
    }
}

/// The required wrench set of `Robot.capacity` from its arguments (`n` the robot's DOF).
fn requirement(
    n: usize,
    wrench: Option<&Bound<'_, PyAny>>,
    half_width: Option<&Bound<'_, PyAny>>,
    gravity: bool,
    moment_length: f64,
    margins: &str,
) -> PyResult<Requirement> {
    let mut req = Requirement {
        gravity,
        moment_length,
        margins: guarded(|| Margins::from_name(margins))?,
        ..Requirement::default()
    };
    for (arg, name, into) in [
        (wrench, "wrench", &mut req.center),
        (half_width, "half_width", &mut req.half_width),
    ] {
        if let Some(v) = arg.filter(|v| !v.is_none()) {
            vector_into(v, name, &mut into[..n])?;
        }
    }
    Ok(req)
}

/// Add this file's classes and functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Robot>()?;
    m.add_class::<TensionController>()?;
    Ok(())
}
