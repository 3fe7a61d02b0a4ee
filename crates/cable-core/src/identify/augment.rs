//! Candidates applied to the nominal model: the joint's located effects
//! ([`augment_joint`] → [`JointPlant`]), the transmission's ([`augment_transmission`]), and each
//! channel's sensor path ([`SensorChain`]).

use crate::dynamics::network::{Network, Presliding, TensionCreep};
use crate::dynamics::{AntagonisticJoint, CableTransmission};
use crate::error::Result;

use super::effects::Effect;
use super::plant::{
    exponential, BristleStribeck, CreepLaw, Hysteresis, JointPlant, JointPlay, PowerDrag,
};
use super::signal;
use super::site::{Candidate, Form, Site};

/// The operators of one channel's sensor path, applied in the order lag (one pole, two equal
/// poles or a resonance) → delay → sample-and-hold (instantaneous or averaged) → gain and bias.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SensorChain {
    /// Lag time constant (s); 0 = none.
    pub lag: f64,
    /// Two equal poles (critically damped) instead of one.
    pub second_order: bool,
    /// Damping ratio of a resonant second-order sensor (`lag` is then `1/ω_n`); 0 = none.
    pub zeta: f64,
    /// Transport delay (s).
    pub delay: f64,
    /// Sample-and-hold period (s); 0 = continuous.
    pub period: f64,
    /// Sample-and-hold phase (s).
    pub phase: f64,
    /// The converter reports the mean over its window (true) or the instantaneous value.
    pub averaging: bool,
    /// Gain error (–): the sensor reads `(1 + g)·y + b`.
    pub gain: f64,
    /// Bias (channel units).
    pub bias: f64,
}

impl SensorChain {
    /// Set the operator of candidate `c` from its parameters `p`; `j` is this channel's rank
    /// among the force channels when `c` sits at every force sensor (per-channel gain and bias,
    /// per-channel converter clocks).
    pub fn apply(&mut self, c: Candidate, p: &[f64], j: usize) {
        match c.effect {
            Effect::SensorLag => {
                self.lag = p[0].max(0.0);
                self.second_order = c.form == Form::SecondOrder;
                self.zeta = if c.form == Form::Resonant {
                    p[1].max(0.0)
                } else {
                    0.0
                };
            }
            Effect::TimeDelay => self.delay = p[0].max(0.0),
            Effect::SensorSampling => {
                // at every force sensor, each channel has its own period and phase
                let k = if matches!(c.site, Site::ForceSensors) {
                    2 * j
                } else {
                    0
                };
                self.period = p[k].max(0.0);
                self.phase = p[k + 1].max(0.0);
                self.averaging = c.form == Form::Averaging;
            }
            Effect::SensorGainBias => {
                let k = if matches!(c.site, Site::ForceSensors) {
                    2 * j
                } else {
                    0
                };
                self.gain = p[k];
                self.bias = p[k + 1];
            }
            _ => {}
        }
    }

    /// Run the path on `col` in place (`tmp` is scratch of the same length).
    pub fn run(&self, col: &mut Vec<f64>, tmp: &mut Vec<f64>, dt: f64) {
        if self.lag > 0.0 && self.zeta > 0.0 {
            signal::second_order_sensor(col, self.lag, self.zeta, dt, tmp);
            std::mem::swap(col, tmp);
        } else if self.lag > 0.0 {
            for _ in 0..if self.second_order { 2 } else { 1 } {
                signal::first_order_lag(col, self.lag, dt, tmp);
                std::mem::swap(col, tmp);
            }
        }
        if self.delay > 0.0 {
            signal::delay(col, self.delay, dt, tmp);
            std::mem::swap(col, tmp);
        }
        if self.period > 0.0 {
            if self.averaging {
                signal::sample_hold_mean(col, self.period, self.phase, dt, tmp);
            } else {
                signal::sample_hold(col, self.period, self.phase, dt, tmp);
            }
            std::mem::swap(col, tmp);
        }
        if self.gain != 0.0 || self.bias != 0.0 {
            signal::gain_bias(col, 1.0 + self.gain, self.bias, tmp);
            std::mem::swap(col, tmp);
        }
    }
}

/// The diagnosis joint of nominal `nom` with the plant candidates applied.
pub fn augment_joint(nom: &AntagonisticJoint, effects: &[(Candidate, &[f64])]) -> JointPlant {
    let mut m = JointPlant::from(nom);
    let nominal_capstan = m.capstan;
    let sides = |s: Site| -> Vec<usize> {
        match s {
            Site::Cable(x) | Site::Contact(x) => (0..2).filter(|&k| x.includes(k)).collect(),
            _ => vec![],
        }
    };
    for &(c, p) in effects {
        if c.site == Site::Motor {
            match c.effect {
                Effect::CoulombFriction => {
                    m.motor.coulomb = p[0].max(0.0);
                    m.motor.smoothing = p[1];
                }
                Effect::ViscousFriction => m.motor.viscous = p[0].max(0.0),
                Effect::DahlHysteresis if p[0] > 0.0 => {
                    m.motor.dahl = Some(Hysteresis {
                        level: p[0],
                        breakaway: p[1],
                        exponent: 1.0,
                    })
                }
                _ => {}
            }
            continue;
        }
        match c.effect {
            // dry friction in a stiff bristle state: it sticks at rest (the level, or the
            // Stribeck curve's static level, holds the joint) and slides at the level
            Effect::CoulombFriction | Effect::StribeckFriction
                if matches!(c.form, Form::Sticking | Form::Lugre) =>
            {
                let (stribeck, breakaway) = if c.form == Form::Lugre {
                    (BristleStribeck::new(p[1], p[2]), p[3])
                } else {
                    (None, p[1])
                };
                let level = p[0].max(0.0);
                if level + stribeck.map_or(0.0, |b| b.excess) > 0.0 && breakaway > 0.0 {
                    m.dahl = Some(Hysteresis {
                        level,
                        breakaway,
                        exponent: 1.0,
                    });
                    m.dahl_stribeck = stribeck;
                }
            }
            Effect::CoulombFriction => {
                m.friction.coulomb += p[0];
                m.friction.static_level += p[0];
                if c.form == Form::LoadDependent {
                    m.load_friction = p[1].max(0.0);
                    m.friction.smoothing = p[2];
                } else {
                    m.friction.smoothing = p[1];
                }
            }
            Effect::ViscousFriction
                if c.form == Form::PowerLaw && p[..3].iter().all(|&v| v > 0.0) =>
            {
                m.power_drag = Some(PowerDrag {
                    coefficient: p[0],
                    exponent: p[1],
                    reference: p[2],
                });
            }
            Effect::ViscousFriction if c.form == Form::PowerLaw => {} // no drag at b = 0
            Effect::ViscousFriction => m.friction.viscous = (m.friction.viscous + p[0]).max(0.0),
            Effect::StribeckFriction => {
                m.friction.coulomb += p[0];
                m.friction.static_level += p[0] + p[1];
                m.friction.stribeck_velocity = p[2];
                m.friction.stribeck_exponent = p[3];
            }
            Effect::DahlHysteresis if p[0] > 0.0 => {
                if let Site::Contact(_) = c.site {
                    for k in sides(c.site) {
                        m.contact_hysteresis[k] = Some(Hysteresis {
                            level: p[0],
                            breakaway: p[1],
                            exponent: 1.0,
                        });
                    }
                } else {
                    m.dahl = Some(Hysteresis {
                        level: p[0],
                        breakaway: p[1],
                        exponent: if c.form == Form::Generalised {
                            p[2]
                        } else {
                            1.0
                        },
                    });
                }
            }
            Effect::CapstanFriction => {
                for k in sides(c.site) {
                    m.capstan[k] = nominal_capstan[k] + p[0];
                }
            }
            Effect::NonlinearStiffness => {
                for k in sides(c.site) {
                    if c.form == Form::Cubic {
                        m.cables[k].cubic = p[0];
                    } else if c.form == Form::Scale {
                        m.cables[k].run.law = m.cables[k].run.law.scaled(1.0 + p[0]);
                    } else {
                        m.cables[k].run.law = exponential(&m.cables[k].run, p[0]);
                    }
                }
            }
            Effect::CableDamping => {
                for k in sides(c.site) {
                    let d = &mut m.cables[k].run.damping;
                    *d = (*d + p[0]).max(0.0);
                }
            }
            Effect::Creep if p[0] > 0.0 => {
                for k in sides(c.site) {
                    m.cables[k].creep = Some(CreepLaw {
                        fraction: p[0],
                        time_constant: p[1],
                        whole: c.form == Form::Whole,
                    });
                }
            }
            Effect::Slack => {
                for k in sides(c.site) {
                    let t = &mut m.cables[k].run.pretension;
                    *t = (*t - p[0]).max(0.0);
                }
            }
            Effect::InertiaError => m.inertia *= 1.0 + p[0],
            Effect::Backlash if c.site == Site::Joint && p[0] > 0.0 => {
                m.play = Some(JointPlay {
                    half_gap: p[0],
                    link_share: p[1].clamp(0.01, 0.99),
                    stiffness_ratio: p[2].max(1e-3),
                })
            }
            // operators, handled by the caller
            _ => {}
        }
    }
    m.layout();
    m
}

/// The cable transmission with its plant candidates applied (per-link joint effects, shared
/// cable effects, coupling coefficients added to the nominal `C_ij`). Errors when a trial value
/// makes the transmission invalid (the fit rejects that step).
pub fn augment_transmission(
    nom: &CableTransmission,
    effects: &[(Candidate, &[f64])],
) -> Result<CableTransmission> {
    let n = nom.n_links();
    let mut links = nom.links().to_vec();
    let mut coupling = nom.coupling();
    for &(c, p) in effects {
        match c.effect {
            Effect::CoulombFriction => {
                for (l, f) in links.iter_mut().zip(p) {
                    l.link_friction.coulomb += f;
                    l.link_friction.static_level += f;
                }
            }
            Effect::ViscousFriction => {
                for (l, b) in links.iter_mut().zip(p) {
                    l.link_friction.viscous = (l.link_friction.viscous + b).max(0.0);
                }
            }
            Effect::InertiaError => {
                for (l, eps) in links.iter_mut().zip(p) {
                    l.link_inertia *= 1.0 + eps;
                }
            }
            Effect::NonlinearStiffness if p[0] > 0.0 => {
                for l in &mut links {
                    l.cable.run.law = exponential(&l.cable.run, p[0]);
                }
            }
            Effect::CableDamping => {
                for l in &mut links {
                    l.cable.run.damping = (l.cable.run.damping + p[0]).max(0.0);
                }
            }
            Effect::Slack => {
                for l in &mut links {
                    l.cable.run.pretension *= 1.0 - p[0];
                }
            }
            Effect::Coupling => {
                let mut k = 0;
                for i in 1..n {
                    for j in 0..i {
                        coupling[i * n + j] += p[k];
                        k += 1;
                    }
                }
            }
            _ => {}
        }
    }
    CableTransmission::new(links, &coupling)
}

/// The cable network with its plant candidates applied at their elements: a joint's friction
/// (Coulomb, viscous, Stribeck, the dry laws also sharpened to stick; its dry friction as a
/// pre-sliding Dahl state) and inertia, a cable's creep (a state), a position-driven motor's play, a cable's law (exponential hardening or a stiffness
/// scale), damping and pretension, a routing's friction (its capstan exponent and the sharpness
/// of its sign), a motor's friction (given, as at
/// the joint's motor site, in N of cable at its capstan) and rotor inertia. Dry friction keeps
/// the element's sign smoothing.
pub fn augment_network(nom: &Network, effects: &[(Candidate, &[f64])]) -> Network {
    let mut m = nom.clone();
    for &(c, p) in effects {
        match (c.site, c.effect) {
            (Site::NetJoint(j), e) => {
                let j = usize::from(j);
                let f = m.joint_friction_mut(j);
                match e {
                    // the sticking forms: the sign law sharpened to the stick's resolution (the
                    // replay integrates the friction implicitly, so it holds the joint at rest
                    // below the level instead of creeping; last parameter, fixed)
                    Effect::CoulombFriction => {
                        f.coulomb += p[0];
                        f.static_level += p[0];
                        if c.form == Form::Sticking {
                            f.smoothing = f.smoothing.min(p[1]);
                        }
                    }
                    Effect::ViscousFriction => f.viscous = (f.viscous + p[0]).max(0.0),
                    Effect::StribeckFriction => {
                        f.coulomb += p[0];
                        f.static_level += p[0] + p[1];
                        f.stribeck_velocity = p[2];
                        f.stribeck_exponent = p[3];
                        if c.form == Form::Lugre {
                            f.smoothing = f.smoothing.min(p[4]);
                        }
                    }
                    Effect::InertiaError => m.scale_joint_inertia(j, 1.0 + p[0]),
                    // the joint's dry friction becomes a pre-sliding (Dahl) element of level
                    // F_c + ΔF (additive where the nominal has none)
                    Effect::DahlHysteresis => {
                        let level = (f.coulomb + p[0]).max(0.0);
                        f.coulomb = 0.0;
                        f.static_level = 0.0;
                        m.set_presliding(j, Presliding::dahl(level, p[1].max(f64::MIN_POSITIVE)));
                    }
                    _ => {}
                }
            }
            (Site::NetCable(k), Effect::Creep) => m.set_creep(
                usize::from(k),
                TensionCreep {
                    fraction: p[0].clamp(0.0, 0.99),
                    time_constant: p[1].max(f64::MIN_POSITIVE),
                    whole: c.form == Form::Whole,
                    stretch: c.form == Form::Stretch,
                },
            ),
            // about the cable's reference stretch (its tension where it was held stays)
            (Site::NetCable(k), Effect::NonlinearStiffness) if c.form == Form::Scale => {
                m.set_stiffness_scale(usize::from(k), 1.0 + p[0]);
            }
            (Site::NetCable(k), e) => {
                let run = m.cable_run_mut(usize::from(k));
                match (e, c.form) {
                    (Effect::NonlinearStiffness, _) => run.law = exponential(run, p[0]),
                    (Effect::CableDamping, _) => run.damping = (run.damping + p[0]).max(0.0),
                    (Effect::Slack, _) => run.pretension = (run.pretension - p[0]).max(0.0),
                    _ => {}
                }
            }
            (Site::NetRouting(k), Effect::CapstanFriction) => {
                m.set_routing_friction(usize::from(k), p[0], p[1]);
            }
            // the routing's friction ramps over a break-away sliding after each reversal
            (Site::NetRouting(k), Effect::DahlHysteresis) => {
                m.set_routing_dahl(usize::from(k), p[0], p[1]);
            }
            (Site::NetMotor(i), e) => {
                let i = usize::from(i);
                let rho = m.motor_rho(i);
                match e {
                    // a position-driven motor's friction is a term of its load, integrated
                    // nowhere: a friction the nominal lacks is resolved as sharply as its
                    // cables' capstan friction (same motion, same dry contact; the file's motor
                    // smoothing regularises a torque-driven motor's dynamics). A nominal's own
                    // dry friction keeps its law, so that the reference is the nominal.
                    Effect::CoulombFriction => {
                        let dry = *m.motor_friction_mut(i);
                        #[allow(clippy::float_cmp)] // none at all in the nominal
                        let sharp = (!m.motor_is_torque_driven(i)
                            && dry.coulomb == 0.0
                            && dry.static_level == 0.0)
                            .then(|| m.capstan_smoothing() / rho);
                        let f = m.motor_friction_mut(i);
                        f.coulomb += p[0].max(0.0) * rho;
                        f.static_level += p[0].max(0.0) * rho;
                        if let Some(eps) = sharp {
                            f.smoothing = f.smoothing.min(eps);
                        }
                    }
                    Effect::ViscousFriction => {
                        let f = m.motor_friction_mut(i);
                        f.viscous += p[0].max(0.0) * rho * rho;
                    }
                    Effect::InertiaError => m.scale_motor_inertia(i, 1.0 + p[0]),
                    // the play's half-width in m of cable at the capstan
                    Effect::Backlash => m.set_play(i, p[0].max(0.0) / rho),
                    _ => {}
                }
            }
            _ => {}
        }
    }
    m
}
