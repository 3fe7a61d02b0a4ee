//! Filters stated the way a front end states them: a model chosen at run time, a process kind,
//! a measurement kind and the initial moments. The Python constructors and any other front end
//! only convert their arguments into these and call [`filter`] or [`dual_filter`].

use crate::dynamics::AnyModel;
use crate::error::{CableError, Result};

use super::{
    DualSrUkf, InputStates, LinearObserve, LinearProcess, ModelOutputs, ModelProcess, Observe,
    ParamTransmission, Process, SigmaScaling, SrUkf, TransmissionParam,
};

/// A filter whose process and measurement are chosen at run time.
pub type DynSrUkf = SrUkf<Box<dyn Process + Send + Sync>, Box<dyn Observe + Send + Sync>>;

/// What the filter measures.
#[derive(Debug, Clone, PartialEq)]
pub enum Measure {
    /// The states at these indices.
    States(Vec<usize>),
    /// The model outputs at these indices (a model process only).
    Outputs(Vec<usize>),
    /// `H·x` with `H` `(rows, n)`, row-major.
    Matrix {
        /// Rows of `H` (measured channels).
        rows: usize,
        /// `H`, row-major.
        h: Vec<f64>,
    },
}

impl Measure {
    /// Exactly one of the three ways of stating a measurement (`H` as `(values, rows)`).
    pub fn one_of(
        states: Option<Vec<usize>>,
        outputs: Option<Vec<usize>>,
        h: Option<(Vec<f64>, usize)>,
    ) -> Result<Self> {
        let given: Vec<&str> = [
            ("states", states.is_some()),
            ("outputs", outputs.is_some()),
            ("H", h.is_some()),
        ]
        .iter()
        .filter_map(|(name, g)| g.then_some(*name))
        .collect();
        match (states, outputs, h) {
            (Some(s), None, None) => Ok(Self::States(s)),
            (None, Some(o), None) => Ok(Self::Outputs(o)),
            (None, None, Some((h, rows))) => Ok(Self::Matrix { rows, h }),
            _ => Err(CableError::InvalidOption {
                name: "measurement".into(),
                value: if given.is_empty() {
                    "none".into()
                } else {
                    given.join(" and ")
                },
                allowed: "states=[...], outputs=[...] or H=<(p, n) array> (give exactly one \
                          measurement)"
                    .into(),
            }),
        }
    }
}

/// The process model of a filter.
#[derive(Debug, Clone, PartialEq)]
pub enum ProcessKind {
    /// A model integrated by RK4 over `dt` in `substeps`, input held.
    Model {
        /// The model.
        model: AnyModel,
        /// Sample period, s.
        dt: f64,
        /// RK4 steps per period.
        substeps: usize,
    },
    /// A cable transmission with named parameters appended to the state as random walks
    /// (`"cable_stiffness[1]"`, ...), projected into `bounds`.
    Parameters {
        /// The model (a `CableTransmission`).
        model: AnyModel,
        /// Parameter names.
        names: Vec<String>,
        /// `(lower, upper)` per parameter, intersected with the physical ranges.
        bounds: Option<Vec<(f64, f64)>>,
        /// Sample period, s.
        dt: f64,
        /// RK4 steps per period.
        substeps: usize,
    },
    /// A model whose inputs `inputs` receive unknown random-walk offsets appended to the state.
    InputStates {
        /// The model.
        model: AnyModel,
        /// Indices of the inputs with unknown offsets.
        inputs: Vec<usize>,
        /// Sample period, s.
        dt: f64,
        /// RK4 steps per period.
        substeps: usize,
    },
    /// `x' = F·x + B·u`.
    Linear {
        /// `F` `(n, n)`, row-major.
        f: Vec<f64>,
        /// `B` `(n, m)`, row-major (empty: no inputs).
        b: Vec<f64>,
        /// States `n`.
        n: usize,
    },
}

/// The initial moments and noise of a filter, row-major or column-major symmetric matrices.
#[derive(Debug, Clone, PartialEq)]
pub struct Moments {
    /// Initial mean `(n,)`.
    pub x0: Vec<f64>,
    /// Initial covariance `(n, n)`.
    pub p0: Vec<f64>,
    /// Process noise covariance `(n, n)`.
    pub q: Vec<f64>,
    /// Measurement noise covariance `(p, p)`.
    pub r: Vec<f64>,
}

/// A process model chosen at run time (a built-in one, or a front end's own).
pub type DynProcess = Box<dyn Process + Send + Sync>;
/// A measurement model chosen at run time.
pub type DynObserve = Box<dyn Observe + Send + Sync>;

fn process(kind: ProcessKind) -> Result<(DynProcess, Option<AnyModel>)> {
    Ok(match kind {
        ProcessKind::Model {
            model,
            dt,
            substeps,
        } => (
            crate::with_model!(model.clone(), m => Box::new(ModelProcess::new(m, dt, substeps)?)),
            Some(model),
        ),
        ProcessKind::Parameters {
            model,
            names,
            bounds,
            dt,
            substeps,
        } => {
            let t = model.transmission("parameter estimation")?.clone();
            let params = TransmissionParam::parse_all(&names, t.n_links())?;
            (
                Box::new(ParamTransmission::new(t, params, bounds, dt, substeps)?),
                None,
            )
        }
        ProcessKind::InputStates {
            model,
            inputs,
            dt,
            substeps,
        } => (
            crate::with_model!(model, m => Box::new(InputStates::new(m, inputs, dt, substeps)?)),
            None,
        ),
        ProcessKind::Linear { f, b, n } => {
            if f.len() != n * n {
                return Err(CableError::Shape {
                    what: "F".into(),
                    expected: format!("({n}, {n})"),
                    got: format!("{} values", f.len()),
                });
            }
            let m = b.len().checked_div(n).unwrap_or(0);
            if b.len() != n * m {
                return Err(CableError::Shape {
                    what: "B".into(),
                    expected: format!("({n}, m)"),
                    got: format!("{} values", b.len()),
                });
            }
            (Box::new(LinearProcess::new(n, m, f, b)?), None)
        }
    })
}

/// A square-root UKF over `kind` measuring `measure`, at the moments `init`.
pub fn filter(
    kind: ProcessKind,
    measure: Measure,
    init: &Moments,
    scaling: SigmaScaling,
) -> Result<DynSrUkf> {
    let (process, model) = process(kind)?;
    let n = process.n_states();
    let observe: DynObserve = match (measure, model) {
        (Measure::States(idx), _) => Box::new(LinearObserve::select(n, &idx)?),
        (Measure::Matrix { rows, h }, _) => Box::new(LinearObserve::new(rows, n, h)?),
        (Measure::Outputs(idx), Some(model)) => {
            crate::with_model!(model, m => Box::new(ModelOutputs::new(m, idx)?))
        }
        (Measure::Outputs(_), None) => {
            return Err(CableError::InvalidOption {
                name: "outputs".into(),
                value: "given".into(),
                allowed: "a plain model filter (use states=[...] or H here)".into(),
            })
        }
    };
    SrUkf::new(
        process, observe, &init.x0, &init.p0, &init.q, &init.r, scaling,
    )
}

/// A square-root UKF over a front end's own process and measurement models (a user's
/// `fx`/`hx`): the same filter, recovery, masks, gating and health as the built-in models.
pub fn custom_filter(
    process: DynProcess,
    observe: DynObserve,
    init: &Moments,
    scaling: SigmaScaling,
) -> Result<DynSrUkf> {
    SrUkf::new(
        process, observe, &init.x0, &init.p0, &init.q, &init.r, scaling,
    )
}

/// Dual state–parameter estimation (seed 001 eqs 3.7–3.8) over a transmission: the state
/// filter at `init` measuring the states `measured`, the parameter filter over `names` with
/// covariance `p0_theta` and random-walk covariance `q_theta`.
#[allow(clippy::too_many_arguments)]
pub fn dual_filter(
    model: &AnyModel,
    names: &[String],
    bounds: Option<Vec<(f64, f64)>>,
    dt: f64,
    substeps: usize,
    measured: &[usize],
    init: &Moments,
    theta: (&[f64], &[f64]),
    scaling: SigmaScaling,
) -> Result<DualSrUkf> {
    let t = model.transmission("dual estimation")?.clone();
    let params = TransmissionParam::parse_all(names, t.n_links())?;
    let (p0_theta, q_theta) = theta;
    DualSrUkf::new(
        t, params, bounds, dt, substeps, measured, &init.x0, &init.p0, &init.q, p0_theta, q_theta,
        &init.r, scaling,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::{raven2, AntagonisticJoint};

    fn eye(n: usize, v: f64) -> Vec<f64> {
        let mut m = vec![0.0; n * n];
        for i in 0..n {
            m[i * n + i] = v;
        }
        m
    }

    fn moments(n: usize, p: usize) -> Moments {
        Moments {
            x0: vec![0.0; n],
            p0: eye(n, 1e-4),
            q: eye(n, 1e-8),
            r: eye(p, 1e-6),
        }
    }

    #[test]
    fn each_process_and_measure_builds_a_filter_of_the_right_size() {
        let model = AnyModel::from(raven2(1).unwrap());
        let s = SigmaScaling::default();
        let f = filter(
            ProcessKind::Model {
                model: model.clone(),
                dt: 1e-3,
                substeps: 1,
            },
            Measure::Outputs(vec![0, 1]),
            &moments(4, 2),
            s,
        )
        .unwrap();
        assert_eq!((f.n_states(), f.n_outputs()), (4, 2));
        let f = filter(
            ProcessKind::Parameters {
                model: model.clone(),
                names: vec!["cable_stiffness[0]".into()],
                bounds: None,
                dt: 1e-3,
                substeps: 1,
            },
            Measure::States(vec![0]),
            &moments(5, 1),
            s,
        )
        .unwrap();
        assert_eq!(f.n_states(), 5);
        let lin = ProcessKind::Linear {
            f: eye(2, 1.0),
            b: vec![],
            n: 2,
        };
        let m = Measure::Matrix {
            rows: 1,
            h: vec![1.0, 0.0],
        };
        assert_eq!(filter(lin, m, &moments(2, 1), s).unwrap().n_outputs(), 1);
    }

    fn refused(r: Result<DynSrUkf>) -> CableError {
        match r {
            Ok(_) => panic!("accepted"),
            Err(e) => e,
        }
    }

    #[test]
    fn wrong_combinations_are_named_errors() {
        let s = SigmaScaling::default();
        assert!(Measure::one_of(Some(vec![0]), Some(vec![0]), None).is_err());
        assert!(Measure::one_of(None, None, None).is_err());
        let joint = AnyModel::from(AntagonisticJoint::forceps_example());
        let kind = ProcessKind::Parameters {
            model: joint,
            names: vec!["x".into()],
            bounds: None,
            dt: 1e-3,
            substeps: 1,
        };
        let err = refused(filter(kind, Measure::States(vec![0]), &moments(5, 1), s));
        assert!(err.to_string().contains("CableTransmission"), "{err}");
        let lin = ProcessKind::Linear {
            f: eye(2, 1.0),
            b: vec![1.0; 3],
            n: 2,
        };
        let err = refused(filter(lin, Measure::States(vec![0]), &moments(2, 1), s));
        assert!(
            matches!(err, CableError::Shape { ref what, .. } if what == "B"),
            "{err}"
        );
        let lin = ProcessKind::Linear {
            f: eye(2, 1.0),
            b: vec![],
            n: 2,
        };
        let err = refused(filter(lin, Measure::Outputs(vec![0]), &moments(2, 1), s));
        assert!(err.to_string().contains("outputs"), "{err}");
    }
}
