//! Grey-box identification for the diagnosis: `JointProblem` and the effect catalogue.

use cable_core::identify::{self as core, Candidate, Effect, LmOptions};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::convert::{any_vector, ndim_of, rows, to_matrix, to_vector, tuples};
use crate::dynamics::Model;
use crate::errors::guarded;
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

/// An ndarray of any rank as its row-major float64 values and its columns (1 for 1-D).
fn flat(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<(Vec<f64>, usize)> {
    if ndim_of(obj, name)? == 1 {
        return Ok((any_vector(obj, name)?, 1));
    }
    let (values, rows) = rows(obj, name)?;
    let width = values.len() / rows;
    Ok((values, width))
}

fn optional(obj: Option<&Bound<'_, PyAny>>, name: &str) -> PyResult<Vec<f64>> {
    match obj {
        Some(o) if !o.is_none() => Ok(flat(o, name)?.0),
        _ => Ok(Vec::new()),
    }
}

/// One recorded run of a `JointProblem`: sample interval `dt` (s); `input` (joint: `x_m` `(T,)`
/// in m; transmission: motor torques `(T, n)`; under a servo the references `[q_m_ref, dq_m_ref]`
/// `(T, 2n)`); `measured` `(T, q)`; optional `coupled` `(T,)`, `external` joint torques `(T,)` or
/// `(T, n)`, initial state `x0`, the first sample counted, `start`, and `commands` `(T,)` or
/// `(T, c)`: recorded commands that are not the plant's input (the torque of a motor replayed
/// from its measured angle, held in a derived load channel: a channel's `command`). Checked
/// against the plant when the problem is built.
#[pyclass(frozen, module = "cablekit._cablekit")]
#[derive(Clone)]
pub struct JointRun {
    inner: core::JointRun,
}

#[pymethods]
impl JointRun {
    #[new]
    #[pyo3(signature = (dt, input, measured, *, coupled = None, external = None, x0 = None, start = 0, commands = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        dt: f64,
        input: &Bound<'_, PyAny>,
        measured: &Bound<'_, PyAny>,
        coupled: Option<&Bound<'_, PyAny>>,
        external: Option<&Bound<'_, PyAny>>,
        x0: Option<&Bound<'_, PyAny>>,
        start: usize,
        commands: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let (input, width) = flat(input, "input")?;
        let inner = core::JointRun {
            dt,
            input,
            width,
            x0: optional(x0, "x0")?,
            coupled: optional(coupled, "coupled")?,
            external: optional(external, "external")?,
            measured: flat(measured, "measured")?.0,
            commands: optional(commands, "commands")?,
            start,
        };
        Ok(Self { inner })
    }

    /// The same run with other measurements `(T, q)`.
    fn with_measured(&self, measured: &Bound<'_, PyAny>) -> PyResult<Self> {
        let mut inner = self.inner.clone();
        inner.measured = flat(measured, "measured")?.0;
        Ok(Self { inner })
    }

    /// Sample interval, s.
    #[getter]
    fn dt(&self) -> f64 {
        self.inner.dt
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }
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
    d.set_item("site", problem.site_name(c.site))?;
    d.set_item("form", c.form.name())?;
    d.set_item("sentence", problem.candidate_sentence(c))?;
    d.set_item("parameters", c.params(problem.scales()).len())?;
    d.set_item(
        "plant",
        !matches!(c.site, core::Site::Sensor(_) | core::Site::ForceSensors),
    )?;
    Ok(d)
}

/// A channel as Python gives it: `(output, weight, sensor)`, with the residual's averaging
/// window `(output, weight, sensor, window)`, or with the run's command column it holds
/// `(output, weight, sensor, window, command)` (`command` None: none).
#[derive(FromPyObject)]
enum ChannelTuple {
    Commanded((usize, f64, bool, usize, Option<usize>)),
    Windowed((usize, f64, bool, usize)),
    Plain((usize, f64, bool)),
}

impl ChannelTuple {
    fn channel(self) -> core::Channel {
        match self {
            Self::Plain((o, w, s)) => core::Channel::new(o, w, s),
            Self::Windowed((o, w, s, n)) => core::Channel::new(o, w, s).with_window(n),
            Self::Commanded((o, w, s, n, None)) => core::Channel::new(o, w, s).with_window(n),
            Self::Commanded((o, w, s, n, Some(j))) => {
                core::Channel::new(o, w, s).with_window(n).with_command(j)
            }
        }
    }
}

/// Grey-box least-squares problem of a nominal model (an `AntagonisticJoint` or a
/// `CableTransmission`) with a set of candidate effects.
///
/// `channels` is a list of `(output_index, weight, is_force_sensor)`, or `(output_index,
/// weight, is_force_sensor, window)` with the odd width of a centred moving average applied to
/// the channel's residual before weighting (1: none; for a channel whose noise is blue, such as a
/// load derived from an encoder's second difference), or `(..., window, command)` with the
/// column of each run's `commands` the channel's measurement holds as recorded (a late command,
/// `time_delay@input`, then acts on that part and not on the measured motor angle that drives
/// the plant); joint output indices are
/// `[T_m1, T_m2, T_j1, T_j2, theta, contact_force, T_m1 - T_m2]`, transmission ones the model's
/// outputs (5 per link). `runs` is a list of `JointRun`. With `servo = (kp, kd, torque_limit)` a
/// transmission is replayed in closed loop under its motor PD servo: each run's `input` is then
/// the recorded references `[q_m_ref (n), dq_m_ref (n)]` and the outputs gain the applied motor
/// torques (n) at the end.
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
        channels: &Bound<'_, PyAny>,
        runs: Vec<PyRef<'_, JointRun>>,
        effects: Vec<String>,
        substeps: usize,
        servo: Option<Gains>,
        kink_refine: usize,
    ) -> PyResult<Self> {
        let plant = guarded(|| core::Plant::of(&model.get().inner, servo))?;
        let runs = runs.iter().map(|r| r.inner.clone()).collect();
        let what =
            "a list of (output, weight, sensor), (output, weight, sensor, window) or (output, \
                    weight, sensor, window, command) tuples";
        let channels: Vec<ChannelTuple> = tuples(channels, "channels", what)?;
        let channels = channels.into_iter().map(ChannelTuple::channel).collect();
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
    #[pyo3(signature = (theta0 = None, *, max_iter = 60, threads = 1, ftol = 1e-8, xtol = 1e-8, atol = 0.0))]
    #[allow(clippy::too_many_arguments)]
    fn fit<'py>(
        &self,
        py: Python<'py>,
        theta0: Option<&Bound<'py, PyAny>>,
        max_iter: usize,
        threads: usize,
        ftol: f64,
        xtol: f64,
        atol: f64,
    ) -> PyResult<FitReport> {
        let theta0 = theta0.map(|t| any_vector(t, "theta0")).transpose()?;
        let opts = LmOptions {
            max_iter,
            ftol,
            atol,
            xtol,
            threads,
            ..LmOptions::default()
        };
        let rep = py.detach(|| guarded(|| self.inner.fit(theta0.as_deref(), &opts)))?;
        Ok(FitReport::new(py, rep))
    }

    /// The same problem on the first `seconds` of every run (after its warm-up), or None when
    /// every run is shorter than twice that: a cheap objective for screening fits.
    fn head(&self, seconds: f64) -> PyResult<Option<Self>> {
        Ok(guarded(|| self.inner.head(seconds))?.map(|inner| Self { inner }))
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

/// Add this file's classes and functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<JointProblem>()?;
    m.add_class::<JointRun>()?;
    m.add_function(wrap_pyfunction!(effect_catalogue, m)?)?;
    Ok(())
}
