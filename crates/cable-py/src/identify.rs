//! Grey-box identification for the diagnosis: `JointProblem` and the effect catalogue.

use cable_core::control::MotorPd;
use cable_core::identify::{self as core, Candidate, Effect, LmOptions};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::convert::{any_vector, to_matrix, to_vector};
use crate::dynamics::{AnyModel, Model};
use crate::errors::{guarded, raise, Class};
use crate::results::{FitReport, ParamSpec};

/// The candidate effects: a list of dicts `name, stage, has_state, description`.
#[pyfunction]
pub fn effect_catalogue(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    let out = PyList::empty(py);
    for e in Effect::ALL {
        let d = PyDict::new(py);
        d.set_item("name", e.name())?;
        d.set_item(
            "stage",
            match e.stage() {
                core::Stage::Input => "input",
                core::Stage::Plant => "plant",
                core::Stage::Sensor => "sensor",
            },
        )?;
        d.set_item("has_state", e.has_state())?;
        d.set_item("description", e.description())?;
        out.append(d)?;
    }
    Ok(out)
}

type Gains = (Vec<f64>, Vec<f64>, Vec<f64>);

fn plant_of(model: &Bound<'_, Model>, servo: Option<Gains>) -> PyResult<core::Plant> {
    match &model.get().inner {
        AnyModel::Antagonistic(j) => Ok(core::Plant::Joint(*j)),
        AnyModel::Transmission(t) => match servo {
            None => Ok(core::Plant::Transmission(t.clone())),
            Some((kp, kd, lim)) => {
                let pd = guarded(|| MotorPd::new(kp, kd, lim))?;
                Ok(core::Plant::Servo(t.clone(), pd))
            }
        },
        AnyModel::Dahl(_) => Err(raise(
            Class::Parameter,
            "the diagnosis needs an AntagonisticJoint or a CableTransmission, not a DahlElement"
                .into(),
            &[],
        )),
    }
}

/// An ndarray of any rank as its row-major float64 values (`DTypeError` for anything else).
fn flat(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<f64>> {
    crate::convert::ndim_of(obj, name)?;
    any_vector(&obj.call_method0("ravel")?, name)
}

fn run_from(obj: &Bound<'_, PyAny>, i: usize, q: usize, width: usize) -> PyResult<core::JointRun> {
    let d = obj.cast::<PyDict>().map_err(|_| {
        raise(
            Class::Data,
            format!(
                "runs[{i}] must be a dict with keys dt, input (or x_m), measured, coupled, external, x0, start"
            ),
            &[],
        )
    })?;
    let get = |k: &str| -> PyResult<Bound<'_, PyAny>> {
        d.get_item(k)?
            .ok_or_else(|| raise(Class::Data, format!("runs[{i}] has no key {k:?}"), &[]))
    };
    let dt: f64 = get("dt")?.extract()?;
    let input_obj = match d.get_item("input")? {
        Some(v) => v,
        None => get("x_m")?,
    };
    let input = flat(&input_obj, &format!("runs[{i}].input"))?;
    let t = input.len() / width.max(1);
    let measured = flat(&get("measured")?, &format!("runs[{i}].measured"))?;
    if measured.len() != t * q || input.len() != t * width {
        return Err(raise(
            Class::Shape,
            format!(
                "runs[{i}]: input must have shape (T, {width}) and measured (T, {q}); got {} and {} values",
                input.len(),
                measured.len()
            ),
            &[],
        ));
    }
    let optional = |k: &str| -> PyResult<Vec<f64>> {
        match d.get_item(k)? {
            Some(c) if !c.is_none() => flat(&c, &format!("runs[{i}].{k}")),
            _ => Ok(vec![]),
        }
    };
    let x0 = optional("x0")?;
    let coupled = optional("coupled")?;
    let external = optional("external")?;
    let start: usize = match d.get_item("start")? {
        Some(s) => s.extract()?,
        None => 0,
    };
    Ok(core::JointRun {
        dt,
        input,
        width,
        x0,
        coupled,
        external,
        measured,
        start,
    })
}

fn candidates_from(problem: &core::JointProblem, ids: &[String]) -> PyResult<Vec<Candidate>> {
    guarded(|| ids.iter().map(|n| problem.parse_candidate(n)).collect())
}

fn candidate_dict<'py>(
    py: Python<'py>,
    problem: &core::JointProblem,
    c: &Candidate,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("id", problem.candidate_id(c))?;
    d.set_item("effect", c.effect.name())?;
    d.set_item("site", c.site.name(&|i| problem.channel_name(i)))?;
    d.set_item("form", c.form.name())?;
    d.set_item("sentence", problem.candidate_sentence(c))?;
    d.set_item("parameters", c.params(problem.scales()).len())?;
    d.set_item(
        "plant",
        !matches!(c.site, core::Site::Sensor(_) | core::Site::ForceSensors),
    )?;
    Ok(d)
}

/// Grey-box least-squares problem of a nominal model (an `AntagonisticJoint` or a
/// `CableTransmission`) with a set of candidate effects.
///
/// `channels` is a list of `(output_index, weight, is_force_sensor)`; joint output indices are
/// `[T_m1, T_m2, T_j1, T_j2, theta, contact_force, T_m1 - T_m2]`, transmission ones the model's
/// outputs (5 per link). `runs` is a list of dicts with `dt` (s), `input` (joint: `x_m` (T,) in m,
/// also accepted as key `x_m`; transmission: motor torques (T, n)), `measured` (T, q), optional
/// `coupled` (T,), optional `external` joint torques (T,) or (T, n), optional `x0` (initial
/// state) and `start` (first sample counted). With `servo = (kp, kd, torque_limit)` a transmission
/// is replayed in closed loop under its motor PD servo: `input` is then the recorded references
/// `[q_m_ref (n), dq_m_ref (n)]` and the outputs gain the applied motor torques (n) at the end.
/// The joint's sample intervals with a kink (slack, contact, reversal) are integrated with
/// `kink_refine` times the substeps (1: none). Immutable; safe to use from several threads
/// (calls release the GIL).
#[pyclass(frozen, module = "cablekit._cablekit")]
pub struct JointProblem {
    inner: core::JointProblem,
}

#[pymethods]
impl JointProblem {
    #[new]
    #[pyo3(signature = (model, channels, runs, effects, substeps = 1, servo = None, kink_refine = 8))]
    fn new(
        model: &Bound<'_, Model>,
        channels: Vec<(usize, f64, bool)>,
        runs: &Bound<'_, PyList>,
        effects: Vec<String>,
        substeps: usize,
        servo: Option<Gains>,
        kink_refine: usize,
    ) -> PyResult<Self> {
        let q = channels.len();
        let plant = plant_of(model, servo)?;
        let width = plant.input_width();
        let runs = runs
            .iter()
            .enumerate()
            .map(|(i, r)| run_from(&r, i, q, width))
            .collect::<PyResult<Vec<_>>>()?;
        let channels = channels
            .into_iter()
            .map(|(output, weight, sensor)| core::Channel {
                output,
                weight,
                sensor,
            })
            .collect();
        let bare = guarded(|| core::JointProblem::new(plant, channels, runs, vec![], substeps))?
            .with_kink_refine(kink_refine);
        let candidates = candidates_from(&bare, &effects)?;
        let inner = if candidates.is_empty() {
            bare
        } else {
            guarded(|| bare.with_candidates(candidates, substeps))?
        };
        Ok(Self { inner })
    }

    /// The same data with other candidates (ids `effect`, `effect@site` or
    /// `effect@site/form`; an effect alone is its classic site).
    #[pyo3(signature = (effects, substeps = None))]
    fn with_effects(&self, effects: Vec<String>, substeps: Option<usize>) -> PyResult<Self> {
        let candidates = candidates_from(&self.inner, &effects)?;
        let sub = substeps.unwrap_or(self.inner_substeps());
        Ok(Self {
            inner: guarded(|| self.inner.with_candidates(candidates, sub))?,
        })
    }

    /// Active candidate ids (sorted in canonical order).
    #[getter]
    fn effects(&self) -> Vec<String> {
        self.inner
            .candidates()
            .iter()
            .map(|c| self.inner.candidate_id(c))
            .collect()
    }

    /// Every candidate that can act on this plant with these channels: a list of dicts `id,
    /// effect, site, form, sentence, parameters, plant` (whether it changes the plant).
    fn candidate_library<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let out = PyList::empty(py);
        for c in Candidate::library(&self.inner.context()) {
            out.append(candidate_dict(py, &self.inner, &c)?)?;
        }
        Ok(out)
    }

    /// The candidate an id means on this problem (same dict as `candidate_library`).
    fn describe<'py>(&self, py: Python<'py>, id: &str) -> PyResult<Bound<'py, PyDict>> {
        let c = guarded(|| self.inner.parse_candidate(id))?;
        candidate_dict(py, &self.inner, &c)
    }

    /// Number of residuals.
    #[getter]
    fn n_residuals(&self) -> usize {
        self.inner.n_residuals()
    }

    /// Parameter specs of the active candidates, in parameter order (`ParamSpec`).
    fn param_specs(&self) -> Vec<ParamSpec> {
        let sc = self.inner.scales();
        let mut out = Vec::new();
        for c in self.inner.candidates() {
            let id = self.inner.candidate_id(c);
            out.extend(
                c.params(sc)
                    .into_iter()
                    .map(|s| ParamSpec::new(id.clone(), s)),
            );
        }
        out
    }

    /// Parameters at which every active effect is off.
    fn reference<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_vector(py, self.inner.reference())
    }

    /// Predicted measurements `(T, q)` of run `run` at `theta`.
    fn predict<'py>(
        &self,
        py: Python<'py>,
        theta: &Bound<'py, PyAny>,
        run: usize,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let theta = any_vector(theta, "theta")?;
        let q = self.n_channels();
        let pred = py.detach(|| guarded(|| self.inner.predict(&theta, run)))?;
        let t = pred.len() / q;
        Ok(to_matrix(py, pred, t, q))
    }

    /// Weighted residuals at `theta`.
    fn residuals<'py>(
        &self,
        py: Python<'py>,
        theta: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let theta = any_vector(theta, "theta")?;
        let r = py.detach(|| {
            guarded(|| {
                let mut r = vec![0.0; self.inner.n_residuals()];
                self.inner.residuals(&theta, &mut r)?;
                Ok(r)
            })
        })?;
        Ok(to_vector(py, r))
    }

    /// RK4 substeps the augmented model at `theta` needs.
    fn advised_substeps(&self, py: Python<'_>, theta: &Bound<'_, PyAny>) -> PyResult<usize> {
        let theta = any_vector(theta, "theta")?;
        py.detach(|| guarded(|| self.inner.advised_substeps(&theta)))
    }

    /// Fit the active effects (bounded Levenberg–Marquardt, GIL released): a `FitReport`.
    #[pyo3(signature = (theta0 = None, *, max_iter = 60, threads = 1, ftol = 1e-8, xtol = 1e-8))]
    fn fit<'py>(
        &self,
        py: Python<'py>,
        theta0: Option<&Bound<'py, PyAny>>,
        max_iter: usize,
        threads: usize,
        ftol: f64,
        xtol: f64,
    ) -> PyResult<FitReport> {
        let theta0 = theta0.map(|t| any_vector(t, "theta0")).transpose()?;
        let opts = LmOptions {
            max_iter,
            ftol,
            xtol,
            threads,
            ..LmOptions::default()
        };
        let rep = py.detach(|| guarded(|| self.inner.fit(theta0.as_deref(), &opts)))?;
        Ok(FitReport::new(py, rep))
    }

    /// Sample-and-hold `(period, phase)` read off the measured update instants of the first
    /// force channel, or None.
    fn hold_from_updates(&self) -> Option<(f64, f64)> {
        self.inner.hold_from_updates()
    }
}

impl JointProblem {
    fn n_channels(&self) -> usize {
        let r = &self.inner.runs()[0];
        r.measured.len() / r.len()
    }

    fn inner_substeps(&self) -> usize {
        self.inner.substeps()
    }
}
