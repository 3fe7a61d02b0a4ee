//! The candidate effects of the sim-to-real diagnosis: named, parametrised augmentations of a
//! nominal model. Each effect is zero (or identity) at its reference parameters, so the nominal
//! model is the augmented model at those values, and each acts where its physics acts:
//!
//! | effect | acts on | parameters (units) |
//! |---|---|---|
//! | `coulomb_friction` | joint | `F_c` (N·m) added Coulomb level, `ε` (rad/s) sign smoothing |
//! | `viscous_friction` | joint | `Δb` (N·m·s/rad) viscous error |
//! | `stribeck_friction` | joint | `F_c` (N·m), `F_s − F_c` (N·m), `v_s` (rad/s), shape `δ` (–) |
//! | `dahl_hysteresis` | joint | `F_d` (N·m), break-away angle `θ_d = F_d/σ₀` (rad) |
//! | `capstan_friction` | routing | `μφ` (–) capstan exponent at the motor-side sensors |
//! | `nonlinear_stiffness` | cables | `β` (1/m): `F(s) = k/β·(e^{βs} − 1)` (β < 0 softens) |
//! | `cable_damping` | cables | `Δc` (N·s/m) damping error |
//! | `creep` | cables | `κ` (–) relaxed fraction, `τ` (s) |
//! | `backlash` | input | `δ` (m) play half-width on the motor displacement |
//! | `slack` | cables | `ΔT₀` (N) pretension lost (cables slacken earlier) |
//! | `coupling` | input | `κ_c` (m per unit) of a coupled axis added to the drive |
//! | `sensor_lag` | force sensors | `τ_s` (s) first-order lag |
//! | `sensor_sampling` | force sensors | period (s), phase (s) of a sample-and-hold |
//! | `time_delay` | input | `d` (s) delay between the recorded input and the response |
//! | `sensor_gain_bias` | force sensors | per sensor channel: gain error (–), bias (N) |
//! | `inertia_error` | joint | `ε` (–): `J·(1 + ε)` |
//!
//! Forms with a stick phase: `coulomb_friction@joint/sticking` (`F_c`) and
//! `stribeck_friction@joint/lugre` (`F_c`, `F_s − F_c`, `v_s`; Gaussian shape) carry the friction
//! in a bristle state whose break-away displacement `θ_d` is [`bristle_floor`] (a fixed
//! parameter, lower = upper, so that every run replays the same law): the joint holds at rest
//! until the applied torque exceeds the (static) level, which a sign law smoothed in velocity
//! cannot do (it creeps at rest).

use crate::error::{CableError, Result};

/// A candidate effect (see the module table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Effect {
    /// Added Coulomb joint friction.
    CoulombFriction,
    /// Viscous joint friction error.
    ViscousFriction,
    /// Stribeck joint friction.
    StribeckFriction,
    /// Dahl (hysteretic, pre-sliding) joint friction.
    DahlHysteresis,
    /// Capstan losses between the cables and the motor-side tension sensors.
    CapstanFriction,
    /// Exponential (stiffening or softening) cable law instead of the linear one.
    NonlinearStiffness,
    /// Cable damping error.
    CableDamping,
    /// Cable creep / stress relaxation.
    Creep,
    /// Play in the motor-side drive.
    Backlash,
    /// Pretension loss.
    Slack,
    /// Kinematic coupling of another axis into the cable path.
    Coupling,
    /// First-order lag of the force sensors.
    SensorLag,
    /// Sample-and-hold of the force sensors.
    SensorSampling,
    /// Delay between recorded input and response.
    TimeDelay,
    /// Gain and bias errors of the force sensors.
    SensorGainBias,
    /// Joint inertia error.
    InertiaError,
}

/// Where an effect acts, which decides what must be recomputed when its parameters change.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Transforms the recorded inputs before the simulation.
    Input,
    /// Changes the simulated dynamics.
    Plant,
    /// Transforms simulated measurements (the plant is simulated once).
    Sensor,
}

/// One parameter of an effect.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamSpec {
    /// Name, e.g. `"F_c"`.
    pub name: String,
    /// SI unit, e.g. `"N·m"`.
    pub unit: &'static str,
    /// Value at which the effect vanishes (the nominal model).
    pub reference: f64,
    /// Starting value of the fit.
    pub initial: f64,
    /// Lower bound.
    pub lower: f64,
    /// Upper bound.
    pub upper: f64,
    /// Typical magnitude (fit scaling, finite differences).
    pub scale: f64,
    /// Fitted by grid search, not by gradient steps (discrete-time effects).
    pub grid: bool,
    /// Further starting values tried before the local search (non-convex parameters such as
    /// time constants); the fit starts from the best combination. With [`SWEEP`] or more
    /// values, the parameter is swept alone first (a 1-D global search) and its best value
    /// enters the combinations.
    pub starts: Vec<f64>,
}

/// Number of starting values from which a parameter is swept on its own (see
/// [`ParamSpec::starts`]).
pub const SWEEP: usize = 4;

/// Builds a spec from `(name, unit, reference, initial, lower, upper, scale)`.
type SpecFn<'a> = dyn Fn(&str, &'static str, f64, f64, f64, f64, f64) -> ParamSpec + 'a;

impl ParamSpec {
    /// Starting values of a parameter given none: `initial + 3·scale`, `initial + 30·scale` and,
    /// when the range goes below, `initial − 3·scale`, each kept 5 % of the range inside the
    /// bounds (a start on a bound has no room for a forward difference): from a small effect to
    /// a large one, in the parameter's own scale.
    pub fn spread(&self) -> Vec<f64> {
        if self.grid || self.lower.partial_cmp(&self.upper) != Some(std::cmp::Ordering::Less) {
            return vec![];
        }
        let margin = if (self.upper - self.lower).is_finite() {
            0.05 * (self.upper - self.lower)
        } else {
            0.0
        };
        let (lo, hi) = (self.lower + margin, self.upper - margin);
        let mut v = vec![
            self.initial + 3.0 * self.scale,
            self.initial + 30.0 * self.scale,
        ];
        if self.lower < self.initial - self.scale {
            v.push(self.initial - 3.0 * self.scale);
        }
        v.into_iter()
            .map(|x| x.max(lo).min(hi))
            .filter(|x| x.is_finite() && (x - self.initial).abs() > 0.5 * self.scale)
            .collect()
    }

    /// The same spec with further starting values (kept inside the bounds).
    pub(crate) fn starts(mut self, v: &[f64]) -> Self {
        // max/min, not clamp: bounds from degenerate data scales must not panic
        self.starts = v
            .iter()
            .map(|x| x.max(self.lower).min(self.upper))
            .collect();
        self
    }
}

/// A spec from `(name, unit, reference, initial, lower, upper, scale)`, no grid, no further
/// starts.
pub(crate) fn spec(
    name: &str,
    unit: &'static str,
    reference: f64,
    initial: f64,
    lower: f64,
    upper: f64,
    scale: f64,
) -> ParamSpec {
    ParamSpec {
        name: name.into(),
        unit,
        reference,
        initial,
        lower,
        upper,
        scale: scale.abs().max(1e-300),
        grid: false,
        starts: vec![],
    }
}

/// Typical magnitudes of a data set, used to scale and bound effect parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scales {
    /// Sample interval (s).
    pub dt: f64,
    /// Shortest run duration (s).
    pub duration: f64,
    /// Typical joint torque (N·m), e.g. `r · max(T₀, rms tension)`.
    pub torque: f64,
    /// Typical joint speed (rad/s).
    pub speed: f64,
    /// Typical cable force (N).
    pub force: f64,
    /// Typical cable stretch (m).
    pub stretch: f64,
    /// Typical motor displacement excursion (m).
    pub travel: f64,
    /// Typical motor displacement speed (m/s).
    pub motor_speed: f64,
    /// Typical coupled-axis excursion (its units), 0 when the runs have none.
    pub coupled: f64,
    /// Nominal pretension (N).
    pub pretension: f64,
    /// Nominal viscous friction (N·m·s/rad).
    pub viscous: f64,
    /// Nominal smoothing velocity of the joint friction sign (rad/s).
    pub smoothing: f64,
    /// Nominal cable damping (N·s/m).
    pub damping: f64,
    /// Number of force-sensor channels.
    pub sensors: usize,
    /// Number of links (1 for the antagonistic joint).
    pub links: usize,
    /// Whether the plant is the cable transmission (per-link joint effects, no friction
    /// smoothing parameter, pretension loss as a fraction, coupling coefficients `C_ij`).
    pub transmission: bool,
    /// Smoothing of the sign of a cable's haul speed in its routing friction (m/s; a cable
    /// network's, else 1e-3).
    pub routing_smoothing: f64,
}

impl Effect {
    /// Every effect, in the canonical order of the issue.
    pub const ALL: [Effect; 16] = [
        Effect::CoulombFriction,
        Effect::ViscousFriction,
        Effect::StribeckFriction,
        Effect::DahlHysteresis,
        Effect::CapstanFriction,
        Effect::NonlinearStiffness,
        Effect::CableDamping,
        Effect::Creep,
        Effect::Backlash,
        Effect::Slack,
        Effect::Coupling,
        Effect::SensorLag,
        Effect::SensorSampling,
        Effect::TimeDelay,
        Effect::SensorGainBias,
        Effect::InertiaError,
    ];

    /// Canonical name (used in the JSON output).
    pub fn name(self) -> &'static str {
        match self {
            Effect::CoulombFriction => "coulomb_friction",
            Effect::ViscousFriction => "viscous_friction",
            Effect::StribeckFriction => "stribeck_friction",
            Effect::DahlHysteresis => "dahl_hysteresis",
            Effect::CapstanFriction => "capstan_friction",
            Effect::NonlinearStiffness => "nonlinear_stiffness",
            Effect::CableDamping => "cable_damping",
            Effect::Creep => "creep",
            Effect::Backlash => "backlash",
            Effect::Slack => "slack",
            Effect::Coupling => "coupling",
            Effect::SensorLag => "sensor_lag",
            Effect::SensorSampling => "sensor_sampling",
            Effect::TimeDelay => "time_delay",
            Effect::SensorGainBias => "sensor_gain_bias",
            Effect::InertiaError => "inertia_error",
        }
    }

    /// Parse a canonical name.
    pub fn from_name(name: &str) -> Result<Self> {
        Effect::ALL
            .iter()
            .copied()
            .find(|e| e.name() == name)
            .ok_or_else(|| CableError::InvalidOption {
                name: "effect".into(),
                value: name.into(),
                allowed: Effect::ALL
                    .iter()
                    .map(|e| format!("{:?}", e.name()))
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }

    /// Where the effect acts.
    pub fn stage(self) -> Stage {
        match self {
            Effect::Backlash | Effect::Coupling | Effect::TimeDelay => Stage::Input,
            Effect::SensorLag | Effect::SensorSampling | Effect::SensorGainBias => Stage::Sensor,
            _ => Stage::Plant,
        }
    }

    /// Whether the effect has internal state (memory beyond the nominal states).
    pub fn has_state(self) -> bool {
        matches!(
            self,
            Effect::DahlHysteresis
                | Effect::Creep
                | Effect::Backlash
                | Effect::SensorLag
                | Effect::SensorSampling
        )
    }

    /// One-line physical description.
    pub fn description(self) -> &'static str {
        match self {
            Effect::CoulombFriction => "velocity-independent joint friction (Coulomb)",
            Effect::ViscousFriction => "joint friction proportional to speed differs from nominal",
            Effect::StribeckFriction => "joint friction peaking at low speed (Stribeck)",
            Effect::DahlHysteresis => "pre-sliding hysteresis of joint friction (Dahl)",
            Effect::CapstanFriction => "cable friction over routing pulleys (capstan, exp(μφ))",
            Effect::NonlinearStiffness => "cable tension not linear in stretch",
            Effect::CableDamping => "cable damping differs from nominal",
            Effect::Creep => "cable tension relaxes under sustained stretch (creep)",
            Effect::Backlash => "play between the motor and the cables",
            Effect::Slack => "pretension lower than nominal: cables slacken earlier",
            Effect::Coupling => "another axis moves this joint's cables",
            Effect::SensorLag => "force sensors low-pass the tension (first-order lag)",
            Effect::SensorSampling => "force sensors sample and hold at a low rate",
            Effect::TimeDelay => "delay between the recorded input and the response",
            Effect::SensorGainBias => "force sensor calibration: gain and offset errors",
            Effect::InertiaError => "joint inertia differs from nominal",
        }
    }

    /// Transmission-specific parameter layouts (per link or per coupling coefficient); `None`
    /// where the joint's layout applies unchanged.
    fn transmission_params(self, s: &Scales, p: &SpecFn<'_>) -> Option<Vec<ParamSpec>> {
        let tq = s.torque;
        let w = s.speed.max(1e-9);
        let per_link = |name: &str, unit: &'static str, init: f64, lo: f64, hi: f64, sc: f64| {
            (0..s.links)
                .map(|i| p(&format!("{name}[{i}]"), unit, 0.0, init, lo, hi, sc))
                .collect::<Vec<_>>()
        };
        Some(match self {
            Effect::CoulombFriction => per_link("F_c", "N·m", 0.02 * tq, 0.0, 10.0 * tq, 0.1 * tq),
            Effect::ViscousFriction => {
                let sc = 0.1 * tq / w;
                per_link("delta_b", "N·m·s/rad", 0.0, -s.viscous, 100.0 * sc, sc)
            }
            Effect::InertiaError => per_link("epsilon", "1", 0.0, -0.95, 1e3, 0.5),
            // with a linear cable law the pretension matters only once a cable slackens: the
            // cost is flat near zero loss, so the fit also starts from large losses
            Effect::Slack => {
                vec![p("delta_T0_frac", "1", 0.0, 0.05, 0.0, 0.95, 0.1).starts(&[0.3, 0.6, 0.85])]
            }
            Effect::NonlinearStiffness => {
                // the transmission's exponential law needs a positive length scale: stiffening only
                let st = s.stretch.max(1e-12);
                vec![p("beta", "1/m", 0.0, 0.0, 0.0, 30.0 / st, 0.3 / st)]
            }
            Effect::Coupling => {
                let mut v = Vec::new();
                for i in 1..s.links {
                    for j in 0..i {
                        v.push(p(&format!("C[{i}][{j}]"), "1", 0.0, 0.0, -2.0, 2.0, 0.1));
                    }
                }
                v
            }
            _ => return None,
        })
    }

    /// Parameters with bounds and scales for data of typical magnitudes `s`.
    pub fn params(self, s: &Scales) -> Vec<ParamSpec> {
        let p = spec;
        let tq = s.torque;
        let w = s.speed.max(1e-9);
        // a dense sweep of whole-sample values for the non-convex time parameters (delays, lag
        // constants): the fit starts from the best of them (a 1-D global search)
        let samples = |n: &[f64]| -> Vec<f64> { n.iter().map(|k| k * s.dt).collect() };
        if s.transmission {
            if let Some(v) = self.transmission_params(s, &p) {
                return v;
            }
        }
        match self {
            Effect::CoulombFriction => {
                // the sign's smoothing velocity is fitted too: real dry friction is sharper than
                // any regularised model, and a fixed smoothing would hand the low-speed part of
                // the gap to Stribeck or Dahl candidates
                let eps_lo = (2e-3 * w).max(1e-6);
                let eps0 = s.smoothing.min(10.0 * w).max(eps_lo); // never a panicking clamp
                vec![
                    p("F_c", "N·m", 0.0, 0.02 * tq, 0.0, 10.0 * tq, 0.1 * tq),
                    p(
                        "eps",
                        "rad/s",
                        eps0,
                        eps0,
                        eps_lo,
                        10.0 * w.max(s.smoothing),
                        eps0,
                    )
                    .starts(&[0.2 * eps0]),
                ]
            }
            Effect::ViscousFriction => {
                let sc = 0.1 * tq / w;
                vec![p(
                    "delta_b",
                    "N·m·s/rad",
                    0.0,
                    0.0,
                    -s.viscous,
                    100.0 * sc,
                    sc,
                )]
            }
            Effect::StribeckFriction => vec![
                p("F_c", "N·m", 0.0, 0.02 * tq, 0.0, 10.0 * tq, 0.1 * tq),
                p(
                    "F_s_minus_F_c",
                    "N·m",
                    0.0,
                    0.02 * tq,
                    0.0,
                    10.0 * tq,
                    0.1 * tq,
                )
                .starts(&[0.2 * tq]),
                p(
                    "v_s",
                    "rad/s",
                    0.1 * w,
                    0.1 * w,
                    1e-2 * w,
                    10.0 * w,
                    0.1 * w,
                )
                .starts(&[0.03 * w, 0.3 * w]),
                p("delta", "1", 2.0, 2.0, 0.5, 3.0, 0.5).starts(&[1.0]),
            ],
            Effect::DahlHysteresis => {
                // break-away displacement θ_d = F_d/σ₀ rather than σ₀: the pre-sliding rate
                // |θ̇|/θ_d then does not grow without bound as F_d → 0, and its lower bound keeps
                // the state resolvable at the sample rate
                let th_lo = bristle_floor(s);
                let th0 = (0.02 * s.speed).max(20.0 * th_lo);
                vec![
                    p("F_d", "N·m", 0.0, 0.02 * tq, 0.0, 10.0 * tq, 0.1 * tq),
                    p("theta_d", "rad", th0, th0, th_lo, 1.0, th0).starts(&[0.25 * th0, 4.0 * th0]),
                ]
            }
            Effect::CapstanFriction => vec![p("mu_phi", "1", 0.0, 0.02, 0.0, 3.0, 0.1)],
            Effect::NonlinearStiffness => {
                let st = s.stretch.max(1e-12);
                vec![p("beta", "1/m", 0.0, 0.0, -0.3 / st, 30.0 / st, 0.3 / st)]
            }
            Effect::CableDamping => {
                let sc = 0.1 * s.force / s.motor_speed.max(1e-12);
                vec![p("delta_c", "N·s/m", 0.0, 0.0, -s.damping, 1e3 * sc, sc)]
            }
            Effect::Creep => vec![
                p("kappa", "1", 0.0, 0.05, 0.0, 0.9, 0.1),
                p("tau", "s", 0.5, 0.5, 5.0 * s.dt, 10.0 * s.duration, 0.5).starts(&[0.1, 2.0]),
            ],
            Effect::Backlash => {
                let st = s.stretch.max(1e-9);
                vec![p(
                    "delta",
                    "m",
                    0.0,
                    0.1 * st,
                    0.0,
                    0.2 * s.travel.max(st),
                    st,
                )]
            }
            Effect::Slack => vec![p(
                "delta_T0",
                "N",
                0.0,
                0.05 * s.pretension,
                0.0,
                s.pretension,
                0.1 * s.pretension.max(1e-9),
            )],
            Effect::Coupling => {
                let sc = if s.coupled > 0.0 {
                    s.travel / s.coupled
                } else {
                    1.0
                };
                vec![p(
                    "kappa_c",
                    "m/unit",
                    0.0,
                    0.0,
                    -10.0 * sc,
                    10.0 * sc,
                    0.1 * sc,
                )]
            }
            Effect::SensorLag => vec![p(
                "tau_s",
                "s",
                0.0,
                2.0 * s.dt,
                0.0,
                0.2 * s.duration,
                10.0 * s.dt,
            )
            .starts(&samples(&[
                1.0, 3.0, 5.0, 7.0, 10.0, 15.0, 20.0, 30.0, 50.0, 80.0,
            ]))],
            Effect::SensorSampling => {
                let mut v = vec![
                    // period 0 = a continuous sensor (the nominal)
                    p("period", "s", 0.0, 0.1, 0.0, 0.25 * s.duration, 0.1),
                    p("phase", "s", 0.0, 0.0, 0.0, 0.25 * s.duration, 0.1),
                ];
                v.iter_mut().for_each(|q| q.grid = true);
                v
            }
            Effect::TimeDelay => vec![p(
                "d",
                "s",
                0.0,
                2.0 * s.dt,
                0.0,
                0.1 * s.duration,
                10.0 * s.dt,
            )
            .starts(&samples(&[
                1.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 15.0, 20.0, 25.0, 30.0, 40.0, 60.0,
            ]))],
            Effect::SensorGainBias => (0..s.sensors)
                .flat_map(|i| {
                    [
                        p(&format!("gain_error[{i}]"), "1", 0.0, 0.0, -0.9, 10.0, 0.1),
                        p(
                            &format!("bias[{i}]"),
                            "N",
                            0.0,
                            0.0,
                            -100.0 * s.force,
                            100.0 * s.force,
                            0.1 * s.force,
                        ),
                    ]
                })
                .collect(),
            // a position-driven joint's resonance moves with its inertia: the cost is not
            // convex in ε (a 4.5× inertia made no progress from ε = 0), so sweep it
            Effect::InertiaError => vec![p("epsilon", "1", 0.0, 0.0, -0.95, 1e3, 0.5)
                .starts(&[-0.6, -0.3, 0.3, 1.0, 2.0, 4.0, 8.0])],
        }
    }
}

/// The smallest break-away displacement of a joint bristle (Dahl, sticking, LuGre) state (rad):
/// one sample's travel at the typical joint speed, below which pre-sliding is not observable.
pub fn bristle_floor(s: &Scales) -> f64 {
    (s.speed * s.dt).max(1e-7)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scales() -> Scales {
        Scales {
            dt: 1e-3,
            duration: 20.0,
            torque: 0.025,
            speed: 2.0,
            force: 10.0,
            stretch: 3e-4,
            travel: 2e-3,
            motor_speed: 5e-3,
            coupled: 0.5,
            pretension: 10.0,
            viscous: 1e-4,
            smoothing: 0.05,
            damping: 20.0,
            sensors: 2,
            links: 1,
            transmission: false,
            routing_smoothing: 1e-3,
        }
    }

    #[test]
    fn names_round_trip_and_are_unique() {
        for e in Effect::ALL {
            assert_eq!(Effect::from_name(e.name()).unwrap(), e);
        }
        let mut names: Vec<_> = Effect::ALL.iter().map(|e| e.name()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), 16);
        assert!(matches!(
            Effect::from_name("friction"),
            Err(CableError::InvalidOption { .. })
        ));
    }

    #[test]
    fn specs_are_consistent() {
        for e in Effect::ALL {
            for q in e.params(&scales()) {
                assert!(
                    q.lower <= q.reference && q.reference <= q.upper,
                    "{e:?} {q:?}"
                );
                assert!(q.lower <= q.initial && q.initial <= q.upper, "{e:?} {q:?}");
                assert!(q.scale > 0.0 && q.scale.is_finite(), "{e:?} {q:?}");
            }
        }
        assert_eq!(Effect::SensorGainBias.params(&scales()).len(), 4);
    }
}
