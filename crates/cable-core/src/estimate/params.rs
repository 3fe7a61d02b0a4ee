//! Parameters of a cable transmission as filter states (joint state–parameter estimation, seed
//! 001 §3.3 and ch. 4): the augmented state `[x; θ]` with `θ` a random walk, the model rebuilt
//! from `θ` for every sigma point, and bounds enforced by projecting the sigma points and the
//! mean (`k_e > 0`, `b_e ≥ 0`, a pulley radius within its tolerance).

use crate::cable::CableLaw;
use crate::dynamics::{CableTransmission, Model};
use crate::error::{CableError, Result};
use crate::integrate::{InputHold, Rk4, SimOptions};

use super::models::Process;

/// One estimable parameter of a [`CableTransmission`] (0-based link indices).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TransmissionParam {
    /// Cable stiffness `k_e` (N/m) of link `i`.
    CableStiffness(usize),
    /// Cable damping `b_e` (N·s/m) of link `i`.
    CableDamping(usize),
    /// Cable coupling coefficient `C_ij` (`i > j`).
    Coupling(usize, usize),
    /// Joint pulley radius `r_l` (m) of link `i`.
    JointRadius(usize),
    /// Link inertia (kg·m² or kg) of link `i`.
    LinkInertia(usize),
    /// Link Coulomb friction (N·m or N) of link `i`.
    LinkCoulomb(usize),
    /// Link viscous friction of link `i`.
    LinkViscous(usize),
}

fn index(text: &str) -> Option<Vec<usize>> {
    // "name[1]" or "name[2][0]"
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(open) = rest.find('[') {
        let close = rest[open..].find(']')? + open;
        out.push(rest[open + 1..close].trim().parse().ok()?);
        rest = &rest[close + 1..];
    }
    if rest.is_empty() {
        Some(out)
    } else {
        None
    }
}

impl TransmissionParam {
    /// Parse `"cable_stiffness[1]"`, `"coupling[2][0]"`, … (the keyword names of
    /// `cablekit.CableTransmission`), checking the indices against `links`.
    pub fn parse(name: &str, links: usize) -> Result<Self> {
        let bad = || CableError::InvalidOption {
            name: "parameter".into(),
            value: name.into(),
            allowed:
                "cable_stiffness[i], cable_damping[i], coupling[i][j] (i > j), joint_radius[i], \
                      link_inertia[i], link_coulomb[i], link_viscous[i] with 0 <= i < links"
                    .into(),
        };
        let open = name.find('[').ok_or_else(bad)?;
        let idx = index(&name[open..]).ok_or_else(bad)?;
        let one = |f: fn(usize) -> Self| match idx.as_slice() {
            [i] if *i < links => Ok(f(*i)),
            _ => Err(bad()),
        };
        match &name[..open] {
            "cable_stiffness" => one(Self::CableStiffness),
            "cable_damping" => one(Self::CableDamping),
            "joint_radius" => one(Self::JointRadius),
            "link_inertia" => one(Self::LinkInertia),
            "link_coulomb" => one(Self::LinkCoulomb),
            "link_viscous" => one(Self::LinkViscous),
            "coupling" => match idx.as_slice() {
                [i, j] if *i < links && *j < *i => Ok(Self::Coupling(*i, *j)),
                _ => Err(bad()),
            },
            _ => Err(bad()),
        }
    }

    /// Parse every name of `names` for a model of `links` links.
    pub fn parse_all(names: &[String], links: usize) -> Result<Vec<Self>> {
        names.iter().map(|n| Self::parse(n, links)).collect()
    }

    /// Current value in `m`.
    pub fn get(&self, m: &CableTransmission) -> f64 {
        let l = m.links();
        match *self {
            Self::CableStiffness(i) => l[i].cable.run.law.stiffness(),
            Self::CableDamping(i) => l[i].cable.run.damping,
            Self::Coupling(i, j) => m.coupling()[i * m.n_links() + j],
            Self::JointRadius(i) => l[i].joint_radius,
            Self::LinkInertia(i) => l[i].link_inertia,
            Self::LinkCoulomb(i) => l[i].link_friction.coulomb,
            Self::LinkViscous(i) => l[i].link_friction.viscous,
        }
    }

    /// Physical bounds that always apply (positive stiffness, radius and inertia; non-negative
    /// damping and friction; coupling free).
    pub fn natural_bounds(&self) -> (f64, f64) {
        match self {
            Self::CableStiffness(_) | Self::JointRadius(_) | Self::LinkInertia(_) => {
                (f64::MIN_POSITIVE, f64::INFINITY)
            }
            Self::CableDamping(_) | Self::LinkCoulomb(_) | Self::LinkViscous(_) => {
                (0.0, f64::INFINITY)
            }
            Self::Coupling(..) => (f64::NEG_INFINITY, f64::INFINITY),
        }
    }
}

/// `base` with the parameters named `names` (see [`TransmissionParam::parse`]) set to
/// `values` (finite, one per name); the result validated like any transmission.
pub fn with_named_params(
    base: &CableTransmission,
    names: &[String],
    values: &[f64],
) -> Result<CableTransmission> {
    let params = TransmissionParam::parse_all(names, base.n_links())?;
    crate::error::check::len("values", values, params.len())?;
    crate::error::check::all_finite("values", values, 1)?;
    with_params(base, &params, values)
}

/// `base` with `params` set to `values`.
pub fn with_params(
    base: &CableTransmission,
    params: &[TransmissionParam],
    values: &[f64],
) -> Result<CableTransmission> {
    let mut links = base.links().to_vec();
    let n = links.len();
    let mut coupling = base.coupling();
    for (p, &v) in params.iter().zip(values) {
        match *p {
            TransmissionParam::CableStiffness(i) => {
                let law = &mut links[i].cable.run.law;
                *law = match *law {
                    CableLaw::Linear { .. } => CableLaw::Linear { stiffness: v },
                    CableLaw::Exponential { length_scale, .. } => CableLaw::Exponential {
                        stiffness: v,
                        length_scale,
                    },
                };
            }
            TransmissionParam::CableDamping(i) => links[i].cable.run.damping = v,
            TransmissionParam::Coupling(i, j) => coupling[i * n + j] = v,
            TransmissionParam::JointRadius(i) => links[i].joint_radius = v,
            TransmissionParam::LinkInertia(i) => links[i].link_inertia = v,
            TransmissionParam::LinkCoulomb(i) => {
                let f = &mut links[i].link_friction;
                let extra = f.static_level - f.coulomb;
                f.coulomb = v;
                f.static_level = v + extra.max(0.0);
            }
            TransmissionParam::LinkViscous(i) => links[i].link_friction.viscous = v,
        }
    }
    CableTransmission::new(links, &coupling)
}

/// The process `[x; θ]`: `x` integrated by RK4 through the transmission whose `params` are
/// `θ`, `θ` held (its random walk is the filter's process noise). Every sigma point's `θ` is
/// first projected into `bounds`; [`Process::project`] does the same for the mean.
#[derive(Debug, Clone)]
pub struct ParamTransmission {
    base: CableTransmission,
    params: Vec<TransmissionParam>,
    bounds: Vec<(f64, f64)>,
    dt: f64,
    substeps: usize,
    rk4: Rk4,
    theta: Vec<f64>,
    cache: Option<(Vec<f64>, CableTransmission)>,
}

impl ParamTransmission {
    /// `bounds[k]` intersected with the parameter's natural bounds; `dt`, `substeps` as for
    /// [`ModelProcess`](super::ModelProcess).
    pub fn new(
        base: CableTransmission,
        params: Vec<TransmissionParam>,
        bounds: Option<Vec<(f64, f64)>>,
        dt: f64,
        substeps: usize,
    ) -> Result<Self> {
        SimOptions::new(dt, substeps, InputHold::Zoh)?;
        let p = params.len();
        let user = bounds.unwrap_or_else(|| vec![(f64::NEG_INFINITY, f64::INFINITY); p]);
        if user.len() != p {
            return Err(CableError::Shape {
                what: "bounds".into(),
                expected: format!("{p} (lower, upper) pairs"),
                got: format!("{}", user.len()),
            });
        }
        let mut bounds = Vec::with_capacity(p);
        for (k, (param, (lo, hi))) in params.iter().zip(user).enumerate() {
            // NaN first: max/min below would silently replace it by the natural bound
            for (end, v) in [("lower", lo), ("upper", hi)] {
                if v.is_nan() {
                    return Err(CableError::InvalidParameter {
                        name: format!("bounds[{k}].{end}"),
                        value: v,
                        requirement: "a number (-inf or inf for no bound)",
                    });
                }
            }
            let (nlo, nhi) = param.natural_bounds();
            let b = (lo.max(nlo), hi.min(nhi));
            if b.0.is_nan() || b.1.is_nan() || b.0 > b.1 {
                return Err(CableError::InvalidParameter {
                    name: format!("bounds[{k}]"),
                    value: lo,
                    requirement: "lower <= upper, inside the parameter's physical range",
                });
            }
            bounds.push(b);
        }
        let rk4 = Rk4::for_model(&base);
        Ok(Self {
            base,
            params,
            bounds,
            dt,
            substeps,
            rk4,
            theta: vec![0.0; p],
            cache: None,
        })
    }

    /// The parameters' current values in the base model (the natural start of `θ`).
    pub fn initial(&self) -> Vec<f64> {
        self.params.iter().map(|p| p.get(&self.base)).collect()
    }

    /// The estimated parameters.
    pub fn params(&self) -> &[TransmissionParam] {
        &self.params
    }

    /// Effective bounds.
    pub fn bounds(&self) -> &[(f64, f64)] {
        &self.bounds
    }
}

impl Process for ParamTransmission {
    fn n_states(&self) -> usize {
        self.base.n_states() + self.params.len()
    }
    fn n_inputs(&self) -> usize {
        self.base.n_inputs()
    }
    fn propagate(&mut self, x: &mut [f64], u: &[f64]) {
        let n = self.base.n_states();
        for (k, (lo, hi)) in self.bounds.iter().enumerate() {
            self.theta[k] = x[n + k].clamp(*lo, *hi);
            x[n + k] = self.theta[k];
        }
        let hit = matches!(&self.cache, Some((t, _)) if *t == self.theta);
        if !hit {
            match with_params(&self.base, &self.params, &self.theta) {
                Ok(m) => self.cache = Some((self.theta.clone(), m)),
                Err(_) => {
                    // an invalid model (outside every sensible range): poison this point, the
                    // filter reports the divergence
                    x[..n].fill(f64::NAN);
                    return;
                }
            }
        }
        let model = &self.cache.as_ref().expect("set above").1;
        let h = self.dt / self.substeps as f64;
        for _ in 0..self.substeps {
            self.rk4.step(model, &mut x[..n], u, h);
        }
    }
    fn project(&self, x: &mut [f64]) {
        let n = self.base.n_states();
        for (k, (lo, hi)) in self.bounds.iter().enumerate() {
            x[n + k] = x[n + k].clamp(*lo, *hi);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::raven2;

    #[test]
    fn names_parse_and_values_round_trip() {
        let m = raven2(3).unwrap();
        let names = [
            "cable_stiffness[1]",
            "cable_damping[2]",
            "coupling[2][0]",
            "joint_radius[0]",
            "link_coulomb[1]",
        ];
        let params: Vec<_> = names
            .iter()
            .map(|s| TransmissionParam::parse(s, 3).unwrap())
            .collect();
        let v: Vec<f64> = params.iter().map(|p| p.get(&m) * 1.1).collect();
        let m2 = with_params(&m, &params, &v).unwrap();
        for (p, want) in params.iter().zip(&v) {
            assert!((p.get(&m2) - want).abs() <= 1e-12 * want.abs());
        }
        for bad in [
            "cable_stiffness[3]",
            "coupling[0][1]",
            "mass[0]",
            "cable_stiffness",
            "coupling[1]",
        ] {
            assert!(matches!(
                TransmissionParam::parse(bad, 3),
                Err(CableError::InvalidOption { .. })
            ));
        }
    }

    #[test]
    fn sigma_points_are_projected_into_the_bounds() {
        let m = raven2(2).unwrap();
        let p = vec![TransmissionParam::CableStiffness(1)];
        let mut proc =
            ParamTransmission::new(m.clone(), p, Some(vec![(5e4, 2e5)]), 1e-3, 4).unwrap();
        let mut x = vec![0.0; 9];
        x[8] = -1.0; // a negative stiffness drawn by a sigma point
        proc.propagate(&mut x, &[0.0; 4]);
        assert!((x[8] - 5e4).abs() < 1e-9);
        assert!(x[..8].iter().all(|v| v.is_finite()));
    }
}

/// Dual estimation (seed 001 eqs 3.7–3.8, Wan & van der Merwe): a state filter over the
/// transmission with the current parameter estimate and a parameter filter over `θ` alone (a
/// random walk, eq 3.7) whose measurement is `d_k = H·F(x̂_{k−1}, u; θ)` (eq 3.8): the state
/// filter's last estimate propagated with each parameter sigma point. Each step updates the
/// parameters first, then the state with the new parameters.
#[derive(Debug, Clone)]
pub struct DualSrUkf {
    /// The state filter.
    pub state: super::SrUkf<super::ModelProcess<CableTransmission>, super::LinearObserve>,
    /// The parameter filter.
    pub params: super::SrUkf<RandomWalk, ParamObserve>,
    base: CableTransmission,
    names: Vec<TransmissionParam>,
}

/// `θ_k = θ_{k−1}` (the filter adds the random walk), projected into bounds.
#[derive(Debug, Clone)]
pub struct RandomWalk {
    bounds: Vec<(f64, f64)>,
}

impl RandomWalk {
    /// A random walk of `p` parameters kept within `bounds` (`lower ≤ upper`, either may be
    /// infinite).
    pub fn new(bounds: Vec<(f64, f64)>, p: usize) -> Result<Self> {
        if bounds.len() != p {
            return Err(CableError::Shape {
                what: "bounds".into(),
                expected: format!("{p} (lower, upper) pairs"),
                got: format!("{}", bounds.len()),
            });
        }
        for (i, &(lo, hi)) in bounds.iter().enumerate() {
            if lo.is_nan() || hi.is_nan() || lo > hi {
                return Err(CableError::InvalidParameter {
                    name: format!("bounds[{i}]"),
                    value: lo,
                    requirement: "lower <= upper, not NaN",
                });
            }
        }
        Ok(Self { bounds })
    }
}

impl Process for RandomWalk {
    fn n_states(&self) -> usize {
        self.bounds.len()
    }
    fn n_inputs(&self) -> usize {
        0
    }
    fn propagate(&mut self, x: &mut [f64], _u: &[f64]) {
        self.project(x);
    }
    fn project(&self, x: &mut [f64]) {
        for (v, (lo, hi)) in x.iter_mut().zip(&self.bounds) {
            *v = v.clamp(*lo, *hi);
        }
    }
}

/// The parameter filter's measurement: the state filter's previous estimate propagated one
/// period with the parameters `θ`, then measured.
#[derive(Debug, Clone)]
pub struct ParamObserve {
    proc: ParamTransmission,
    idx: Vec<usize>,
    x_prev: Vec<f64>,
    u: Vec<f64>,
    buf: Vec<f64>,
}

impl super::Observe for ParamObserve {
    fn n_outputs(&self) -> usize {
        self.idx.len()
    }
    fn observe(&mut self, theta: &[f64], _u: &[f64], y: &mut [f64]) {
        let n = self.x_prev.len();
        self.buf[..n].copy_from_slice(&self.x_prev);
        self.buf[n..].copy_from_slice(theta);
        self.proc.propagate(&mut self.buf, &self.u);
        for (yi, &k) in y.iter_mut().zip(&self.idx) {
            *yi = self.buf[k];
        }
    }
}

impl DualSrUkf {
    /// State filter at `(x0, p0)` with process noise `q`, parameter filter at the model's
    /// parameter values with covariance `p0_theta` and random-walk covariance `q_theta`; both
    /// measure the states `measured` with noise covariance `r`. Bounds as for
    /// [`ParamTransmission`].
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        base: CableTransmission,
        params: Vec<TransmissionParam>,
        bounds: Option<Vec<(f64, f64)>>,
        dt: f64,
        substeps: usize,
        measured: &[usize],
        x0: &[f64],
        p0: &[f64],
        q: &[f64],
        p0_theta: &[f64],
        q_theta: &[f64],
        r: &[f64],
        scaling: super::SigmaScaling,
    ) -> Result<Self> {
        let proc = ParamTransmission::new(base.clone(), params.clone(), bounds, dt, substeps)?;
        let theta0 = proc.initial();
        let n = base.n_states();
        let state = super::SrUkf::new(
            super::ModelProcess::new(base.clone(), dt, substeps)?,
            super::LinearObserve::select(n, measured)?,
            x0,
            p0,
            q,
            r,
            scaling,
        )?;
        let walk = RandomWalk {
            bounds: proc.bounds().to_vec(),
        };
        let obs = ParamObserve {
            idx: measured.to_vec(),
            x_prev: x0.to_vec(),
            u: vec![0.0; base.n_inputs()],
            buf: vec![0.0; n + params.len()],
            proc,
        };
        let params_filter = super::SrUkf::new(walk, obs, &theta0, p0_theta, q_theta, r, scaling)?;
        Ok(Self {
            state,
            params: params_filter,
            base,
            names: params,
        })
    }

    /// Inputs `m` of the transmission.
    pub(crate) fn base_inputs(&self) -> usize {
        self.base.n_inputs()
    }

    /// One step: parameters updated from `y` through the state filter's last estimate, the
    /// state filter's model rebuilt with them, then the state predicted and updated.
    pub fn step(&mut self, u: &[f64], y: &[f64], mask: Option<&[bool]>) -> Result<()> {
        crate::error::check::len("u", u, self.base.n_inputs())?;
        self.params.observe.x_prev.copy_from_slice(self.state.x());
        self.params.observe.u.copy_from_slice(u);
        self.params.step(&[], y, mask)?;
        let stepped = with_params(&self.base, &self.names, self.params.x()).and_then(|model| {
            self.state.process.model = model;
            self.state.step(u, y, mask)
        });
        if stepped.is_err() {
            // leave both filters as they were before this step
            self.params.undo_last_step();
            self.state.process.model = with_params(&self.base, &self.names, self.params.x())?;
        }
        stepped
    }
}
