//! Where a candidate effect acts, and in which form: a diagnosis candidate is the triple
//! `(effect, site, form)`, so the answer to "which effect" is "which effect, where, how".
//!
//! Sites of the antagonistic joint (the documented vocabulary of `diagnosis.json`):
//!
//! | site | what it is |
//! |---|---|
//! | `input` | the command path: the recorded motor displacement before it reaches the cables |
//! | `cable.drive`, `cable.return`, `cable.both` | the elastic cable runs |
//! | `contact.drive`, `contact.return`, `contact.both` | the cable–pulley contacts of the routing between the motor-side tension sensors and the joint (they act on the tension) |
//! | `motor` | the motor side of the cables: the actuator's drum or input spindle, its bearings and seals (seen only by a force measured at the motor) |
//! | `joint` | the joint: its bearing, its inertia |
//! | `sensor.<output>` | one measured channel's own path (e.g. `sensor.tension_motor_drive`, `sensor.theta`) |
//! | `sensors.force` | every force channel together (one amplifier, one bus) |
//!
//! Sites of the cable transmission: `input` (the recorded torques or references), `links`
//! (every link, one parameter each), `cables` (every cable pair, shared), and the sensor sites.
//!
//! Sites of a cable network ([`crate::dynamics::network`]) are derived from its structure, one
//! per element: `joint.<name>` (friction families, inertia), `cable.<name>` (stiffness forms,
//! damping, pretension), `routing.<name>` (the capstan losses of that cable's routing — its
//! contacts act through one lumped exponent, so contacts of one cable are one site), `motor.<name>`
//! (friction, rotor inertia), `input` and the sensor sites.
//!
//! Forms are the alternative physical laws of one effect at one site, e.g. a creep that relaxes
//! only the stretch-dependent tension (`elastic`) or the whole tension, pretension included
//! (`whole`).

use crate::error::{CableError, Result};

use super::effects::{bristle_floor, spec, Effect, ParamSpec, Scales, Stage};

/// One of the two cables of an antagonistic joint, or both.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Side {
    /// The drive cable (pulled by positive motor displacement).
    Drive,
    /// The return cable.
    Return,
    /// Both cables, with one shared parameter set.
    Both,
}

impl Side {
    /// `"drive"`, `"return"` or `"both"`.
    pub fn name(self) -> &'static str {
        match self {
            Side::Drive => "drive",
            Side::Return => "return",
            Side::Both => "both",
        }
    }

    /// Whether the side includes cable `k` (0 = drive, 1 = return).
    pub fn includes(self, k: usize) -> bool {
        matches!(
            (self, k),
            (Side::Both, _) | (Side::Drive, 0) | (Side::Return, 1)
        )
    }

    const ALL: [Side; 3] = [Side::Both, Side::Drive, Side::Return];
}

/// Where an effect acts (see the module table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Site {
    /// The command path (recorded input before the plant).
    Input,
    /// Cable runs.
    Cable(Side),
    /// Cable–pulley contacts between the motor-side sensors and the joint.
    Contact(Side),
    /// The motor side of the cables (drum or spindle bearings and seals), seen only by a force
    /// measured at the motor.
    Motor,
    /// The joint.
    Joint,
    /// Every link of a transmission (one parameter per link).
    Links,
    /// Every cable pair of a transmission (shared parameters).
    Cables,
    /// One measured channel's path (index into the problem's channels).
    Sensor(usize),
    /// Every force-sensor channel together.
    ForceSensors,
    /// One joint of a cable network (its index).
    NetJoint(u16),
    /// One cable of a cable network.
    NetCable(u16),
    /// The routing of one network cable (its contacts' capstan losses).
    NetRouting(u16),
    /// One motor of a cable network.
    NetMotor(u16),
}

/// Kinds of network elements a site can name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Element {
    /// A joint.
    Joint,
    /// A cable (also names a routing).
    Cable,
    /// A motor.
    Motor,
}

/// Names of a problem's channels and elements, for site identifiers. Any `Fn(usize) -> String`
/// naming channels is one (its elements then read `joint#0`, ...).
pub trait SiteNames {
    /// Name of channel `i`.
    fn channel(&self, i: usize) -> String;
    /// Name of element `i` of a kind.
    fn element(&self, kind: Element, i: usize) -> String {
        format!("{kind:?}#{i}").to_lowercase()
    }
}

impl<F: Fn(usize) -> String> SiteNames for F {
    fn channel(&self, i: usize) -> String {
        self(i)
    }
}

/// Look-up of channels and elements by name, for parsing site identifiers. Any
/// `Fn(&str) -> Option<usize>` finding channels is one (with no elements).
pub trait SiteIndex {
    /// Index of the channel called `name`.
    fn channel(&self, name: &str) -> Option<usize>;
    /// Index of the element of a kind called `name`.
    fn element(&self, _kind: Element, _name: &str) -> Option<usize> {
        None
    }
}

impl<F: Fn(&str) -> Option<usize>> SiteIndex for F {
    fn channel(&self, name: &str) -> Option<usize> {
        self(name)
    }
}

impl SiteNames for SiteContext {
    fn channel(&self, i: usize) -> String {
        self.channels
            .get(i)
            .cloned()
            .unwrap_or_else(|| format!("output{i}"))
    }
    fn element(&self, kind: Element, i: usize) -> String {
        self.network
            .as_ref()
            .and_then(|n| n.names(kind).get(i).cloned())
            .unwrap_or_else(|| format!("{kind:?}#{i}").to_lowercase())
    }
}

impl SiteIndex for SiteContext {
    fn channel(&self, name: &str) -> Option<usize> {
        self.channels.iter().position(|c| c == name)
    }
    fn element(&self, kind: Element, name: &str) -> Option<usize> {
        self.network
            .as_ref()
            .and_then(|n| n.names(kind).iter().position(|c| c == name))
    }
}

impl Site {
    /// Whether effects here act on the plant's outputs after it (a measured channel's path):
    /// the plant's replay does not depend on their parameters.
    pub fn after_plant(self) -> bool {
        matches!(self, Site::Sensor(_) | Site::ForceSensors)
    }

    /// The site's name in the documented vocabulary; `names` names channels and elements.
    pub fn name(self, names: &dyn SiteNames) -> String {
        let el = |k, i: u16| names.element(k, usize::from(i));
        match self {
            Site::NetJoint(i) => format!("joint.{}", el(Element::Joint, i)),
            Site::NetCable(i) => format!("cable.{}", el(Element::Cable, i)),
            Site::NetRouting(i) => format!("routing.{}", el(Element::Cable, i)),
            Site::NetMotor(i) => format!("motor.{}", el(Element::Motor, i)),
            Site::Input => "input".into(),
            Site::Cable(s) => format!("cable.{}", s.name()),
            Site::Contact(s) => format!("contact.{}", s.name()),
            Site::Motor => "motor".into(),
            Site::Joint => "joint".into(),
            Site::Links => "links".into(),
            Site::Cables => "cables".into(),
            Site::Sensor(i) => format!("sensor.{}", names.channel(i)),
            Site::ForceSensors => "sensors.force".into(),
        }
    }

    /// Parse a site name; `index` finds channels and network elements by name (a network's
    /// element is looked up before the antagonistic joint's sides).
    pub fn parse(name: &str, index: &dyn SiteIndex) -> Result<Self> {
        let bad = || CableError::InvalidOption {
            name: "site".into(),
            value: name.into(),
            allowed:
                "input, cable.{drive,return,both}, contact.{drive,return,both}, motor, joint, \
                      links, cables, sensor.<output>, sensors.force; on a cable network \
                      joint.<joint>, cable.<cable>, routing.<cable>, motor.<motor>"
                    .into(),
        };
        let element = |kind, tail: &str| {
            index
                .element(kind, tail)
                .and_then(|i| u16::try_from(i).ok())
        };
        let side = |s: &str| Side::ALL.into_iter().find(|x| x.name() == s);
        Ok(match name {
            "input" => Site::Input,
            "joint" => Site::Joint,
            "motor" => Site::Motor,
            "links" => Site::Links,
            "cables" => Site::Cables,
            "sensors.force" => Site::ForceSensors,
            _ => {
                let (head, tail) = name.split_once('.').ok_or_else(bad)?;
                match head {
                    "joint" => Site::NetJoint(element(Element::Joint, tail).ok_or_else(bad)?),
                    "routing" => Site::NetRouting(element(Element::Cable, tail).ok_or_else(bad)?),
                    "motor" => Site::NetMotor(element(Element::Motor, tail).ok_or_else(bad)?),
                    "cable" => match element(Element::Cable, tail) {
                        Some(i) => Site::NetCable(i),
                        None => Site::Cable(side(tail).ok_or_else(bad)?),
                    },
                    "contact" => Site::Contact(side(tail).ok_or_else(bad)?),
                    "sensor" => Site::Sensor(index.channel(tail).ok_or_else(bad)?),
                    _ => return Err(bad()),
                }
            }
        })
    }

    /// Human phrase for the site, e.g. "in the cable–pulley contact of the drive cable".
    pub fn phrase(self, names: &dyn SiteNames) -> String {
        let el = |k, i: u16| names.element(k, usize::from(i));
        let cable = |s: Side| match s {
            Side::Drive => "the drive cable".to_owned(),
            Side::Return => "the return cable".to_owned(),
            Side::Both => "both cables".to_owned(),
        };
        match self {
            Site::Input => "in the command path (before the cables)".into(),
            Site::Cable(s) => format!("in {}", cable(s)),
            Site::Contact(Side::Both) => "in the cable–pulley contacts of both cables".into(),
            Site::Contact(s) => format!("in the cable–pulley contact of {}", cable(s)),
            Site::Motor => {
                "on the motor side (the drum or input spindle and its bearings, before the cables)"
                    .into()
            }
            Site::Joint => "at the joint".into(),
            Site::Links => "at every link".into(),
            Site::Cables => "in every cable pair".into(),
            Site::Sensor(i) => format!("in the {} channel's own path", names.channel(i)),
            Site::ForceSensors => "in every force sensor's path".into(),
            Site::NetJoint(i) => format!("at joint {}", el(Element::Joint, i)),
            Site::NetCable(i) => format!("in cable {}", el(Element::Cable, i)),
            Site::NetRouting(i) => format!(
                "in the cable–pulley contacts along cable {}'s routing",
                el(Element::Cable, i)
            ),
            Site::NetMotor(i) => format!(
                "at motor {} (its bearings, gearhead and rotor)",
                el(Element::Motor, i)
            ),
        }
    }
}

/// Alternative laws of one effect at one site.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Form {
    /// The effect's standard law (the only form of most effects).
    Standard,
    /// Friction that grows with the transmitted load (arXiv 2410.08650's M3: `F_c + μ_L·|τ|`).
    LoadDependent,
    /// Dahl hysteresis with a fitted shape exponent `n` (standard: `n = 1`).
    Generalised,
    /// Creep of the whole tension, pretension included (standard: the stretch-dependent part).
    Whole,
    /// Polynomial hardening `k·s + k₃·s³` (standard: exponential law).
    Cubic,
    /// Second-order (critically damped) sensor dynamics (standard: first order).
    SecondOrder,
    /// The cable law's stiffness off by a factor `1 + ε_k` (standard: exponential hardening).
    Scale,
    /// A second-order sensor with its own natural frequency and damping ratio (a load cell's
    /// mechanical resonance): it may ring (standard: one pole).
    Resonant,
    /// An integrating converter (HX711, sigma-delta): each report is the mean over its
    /// conversion window (standard: the instantaneous value is held).
    Averaging,
    /// Dry friction carried by a bristle state stiff enough that its pre-sliding displacement
    /// is one sample's travel (Coulomb's level): the joint sticks at rest until the applied
    /// torque exceeds the level (standard: a sign law smoothed in velocity, which creeps).
    Sticking,
    /// Stribeck friction carried by a LuGre bristle state (Canudas de Wit et al. 1995, without
    /// the bristle damping): the joint sticks at rest below the static level `F_s`, breaks away
    /// and slides at the Stribeck curve's level (standard: a smoothed velocity law, which creeps).
    Lugre,
    /// Viscous drag as a power of speed, `b·|θ̇|ⁿ·sgn(θ̇)` (standard: linear in speed).
    PowerLaw,
    /// Creep of a wound cable's stretch: a Kelvin–Voigt element in series with the elastic one,
    /// its crept length kept while a winch changes the free length (standard: creep of the
    /// tension, the crept strain carried with the cable). The two agree on a cable of fixed
    /// length; only a cable a motor winds has this form.
    Stretch,
}

impl Form {
    /// `"standard"`, `"load_dependent"`, `"generalised"`, `"whole"`, `"cubic"`, `"second_order"`,
    /// `"scale"`, `"resonant"`, `"averaging"`, `"sticking"`, `"lugre"`, `"power_law"`,
    /// `"stretch"`.
    pub fn name(self) -> &'static str {
        match self {
            Form::Standard => "standard",
            Form::LoadDependent => "load_dependent",
            Form::Generalised => "generalised",
            Form::Whole => "whole",
            Form::Cubic => "cubic",
            Form::SecondOrder => "second_order",
            Form::Scale => "scale",
            Form::Resonant => "resonant",
            Form::Averaging => "averaging",
            Form::Sticking => "sticking",
            Form::Lugre => "lugre",
            Form::PowerLaw => "power_law",
            Form::Stretch => "stretch",
        }
    }

    /// Parse a form name.
    pub fn parse(name: &str) -> Result<Self> {
        [
            Form::Standard,
            Form::LoadDependent,
            Form::Generalised,
            Form::Whole,
            Form::Cubic,
            Form::SecondOrder,
            Form::Scale,
            Form::Resonant,
            Form::Averaging,
            Form::Sticking,
            Form::Lugre,
            Form::PowerLaw,
            Form::Stretch,
        ]
        .into_iter()
        .find(|f| f.name() == name)
        .ok_or_else(|| CableError::InvalidOption {
            name: "form".into(),
            value: name.into(),
            allowed: "standard, load_dependent, generalised, whole, cubic, second_order, scale, \
                      resonant, averaging, sticking, lugre, power_law, stretch"
                .into(),
        })
    }
}

/// A diagnosis candidate: an effect at a site in a form.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Candidate {
    /// The physical effect (one of the 16 canonical names).
    pub effect: Effect,
    /// Where it acts.
    pub site: Site,
    /// Which law.
    pub form: Form,
}

/// What a plant offers to candidates: its kind and its measured channels.
#[derive(Debug, Clone, PartialEq)]
pub struct SiteContext {
    /// The cable transmission (true) or the antagonistic joint (false).
    pub transmission: bool,
    /// Number of links (joint: 1).
    pub links: usize,
    /// Channel names (the plant's output names), in channel order.
    pub channels: Vec<String>,
    /// Whether each channel is a force sensor (lag, sampling, gain apply).
    pub force: Vec<bool>,
    /// Whether a coupled-axis signal is recorded.
    pub coupled: bool,
    /// The elements of a cable network (`None` for the built-in plants).
    pub network: Option<NetworkSites>,
}

/// The elements of a cable network that sites are derived from.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct NetworkSites {
    /// Joint names.
    pub joints: Vec<String>,
    /// Cable names.
    pub cables: Vec<String>,
    /// Motor names.
    pub motors: Vec<String>,
    /// Per motor: torque-driven (its friction and inertia are in the dynamics).
    pub torque_driven: Vec<bool>,
    /// Per cable: the motor that hauls it.
    pub cable_motor: Vec<Option<usize>>,
    /// Per cable: whether friction on its routing acts in the dynamics (it has a driver with
    /// inertia: a torque-driven motor or a driven stage).
    pub routing_in_dynamics: Vec<bool>,
    /// Per cable: whether its motor winds it (its free length changes with the motor's angle).
    pub wound: Vec<bool>,
}

impl NetworkSites {
    /// The names of one kind of element.
    pub fn names(&self, kind: Element) -> &[String] {
        match kind {
            Element::Joint => &self.joints,
            Element::Cable => &self.cables,
            Element::Motor => &self.motors,
        }
    }
}

impl SiteContext {
    fn force_channels(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.force.len()).filter(|&i| self.force[i])
    }

    /// Whether a force is measured at the motor itself (a motor torque): motor-side friction
    /// shows there and nowhere else.
    fn motor_force_measured(&self) -> bool {
        self.channels.iter().any(|c| c == "net_motor_force")
    }

    /// Whether a motor-side tension is measured (contact effects show there).
    fn motor_side_measured(&self) -> bool {
        self.channels
            .iter()
            .any(|c| c.starts_with("tension_motor") || c == "net_motor_force")
    }
}

impl Candidate {
    /// A candidate in the standard form.
    pub fn new(effect: Effect, site: Site) -> Self {
        Self {
            effect,
            site,
            form: Form::Standard,
        }
    }

    /// The same candidate in another form.
    pub fn with_form(mut self, form: Form) -> Self {
        self.form = form;
        self
    }

    /// The candidate an effect name alone means (diagnosis v1): its classic site and form.
    pub fn default_for(effect: Effect, transmission: bool) -> Self {
        use Effect::*;
        let site = match effect {
            Backlash | Coupling | TimeDelay => Site::Input,
            SensorLag | SensorSampling | SensorGainBias => Site::ForceSensors,
            CapstanFriction => Site::Contact(Side::Both),
            NonlinearStiffness | CableDamping | Creep | Slack if transmission => Site::Cables,
            NonlinearStiffness | CableDamping | Creep | Slack => Site::Cable(Side::Both),
            _ if transmission => Site::Links,
            _ => Site::Joint,
        };
        Self::new(effect, site)
    }

    /// Every candidate that can physically act on a plant with this context, in a stable order
    /// (effects in canonical order, then sites, then forms).
    pub fn library(ctx: &SiteContext) -> Vec<Candidate> {
        let mut v = Vec::new();
        for e in Effect::ALL {
            for c in Self::of_effect(e, ctx) {
                v.push(c);
            }
        }
        v
    }

    /// The candidates of one effect on a plant with this context.
    pub fn of_effect(effect: Effect, ctx: &SiteContext) -> Vec<Candidate> {
        use Effect::*;
        let c = |site| Candidate::new(effect, site);
        let sides = |f: fn(Side) -> Site| Side::ALL.map(|s| Candidate::new(effect, f(s))).to_vec();
        // sensor sites: every force channel alone, and all force channels together when there
        // are several
        let force: Vec<usize> = ctx.force_channels().collect();
        let mut sensor_sites: Vec<Site> = force.iter().map(|&i| Site::Sensor(i)).collect();
        if force.len() > 1 {
            sensor_sites.push(Site::ForceSensors);
        }
        let sensors = |forms: &[Form]| -> Vec<Candidate> {
            sensor_sites
                .iter()
                .flat_map(|&s| forms.iter().map(move |&f| c(s).with_form(f)))
                .collect()
        };
        // the measurement path, alike on the joint and a network: a delay of the input, of every
        // force channel or of one encoder (its own bus or clock), the force sensors' lag forms,
        // converters and calibration
        let measurement = || -> Vec<Candidate> {
            match effect {
                TimeDelay => {
                    let mut v = vec![c(Site::Input)];
                    v.extend(sensors(&[Form::Standard]));
                    v.extend(
                        (0..ctx.channels.len())
                            .filter(|&i| !ctx.force[i])
                            .map(|i| c(Site::Sensor(i))),
                    );
                    v
                }
                SensorLag => sensors(&[Form::Standard, Form::SecondOrder, Form::Resonant]),
                SensorSampling => sensors(&[Form::Standard, Form::Averaging]),
                SensorGainBias => sensors(&[Form::Standard]),
                _ => vec![],
            }
        };
        if let Some(net) = &ctx.network {
            // a network's play sits between a motor and its capstan (a plant element)
            return match effect.stage() {
                Stage::Plant => Self::of_network_effect(effect, ctx, net),
                _ if effect == Backlash => Self::of_network_effect(effect, ctx, net),
                _ => measurement(),
            };
        }
        if ctx.transmission {
            return match effect {
                CoulombFriction | ViscousFriction | InertiaError => vec![c(Site::Links)],
                NonlinearStiffness | CableDamping | Slack => vec![c(Site::Cables)],
                Coupling if ctx.links >= 2 => vec![c(Site::Input)],
                TimeDelay => {
                    let mut v = vec![c(Site::Input)];
                    v.extend(sensors(&[Form::Standard]));
                    v
                }
                SensorLag => sensors(&[Form::Standard, Form::SecondOrder, Form::Resonant]),
                SensorSampling => sensors(&[Form::Standard, Form::Averaging]),
                SensorGainBias => sensors(&[Form::Standard]),
                _ => vec![],
            };
        }
        let motor = |mut v: Vec<Candidate>| {
            if ctx.motor_force_measured() {
                v.push(c(Site::Motor));
            }
            v
        };
        match effect {
            CoulombFriction => motor(vec![
                c(Site::Joint),
                c(Site::Joint).with_form(Form::LoadDependent),
                c(Site::Joint).with_form(Form::Sticking),
            ]),
            ViscousFriction => motor(vec![
                c(Site::Joint),
                c(Site::Joint).with_form(Form::PowerLaw),
            ]),
            StribeckFriction => vec![c(Site::Joint), c(Site::Joint).with_form(Form::Lugre)],
            InertiaError => vec![c(Site::Joint)],
            DahlHysteresis => {
                let mut v = vec![c(Site::Joint), c(Site::Joint).with_form(Form::Generalised)];
                if ctx.motor_side_measured() {
                    v.extend(sides(Site::Contact));
                }
                motor(v)
            }
            CapstanFriction if ctx.motor_side_measured() => sides(Site::Contact),
            NonlinearStiffness => {
                let mut v = sides(Site::Cable);
                v.push(c(Site::Cable(Side::Both)).with_form(Form::Cubic));
                // the nominal stiffness itself is wrong (a calibration from one load level, an
                // unmodelled compliant stage in series with the cables)
                v.push(c(Site::Cable(Side::Both)).with_form(Form::Scale));
                v
            }
            CableDamping | Slack => sides(Site::Cable),
            Creep => {
                let mut v = sides(Site::Cable);
                v.extend(
                    sides(Site::Cable)
                        .into_iter()
                        .map(|x| x.with_form(Form::Whole)),
                );
                v
            }
            // in the input path (a coupling, a drum with loose turns) or between the joint
            // pulley and the link (a hub's clearance)
            Backlash => vec![c(Site::Input), c(Site::Joint)],
            Coupling if ctx.coupled => vec![c(Site::Input)],
            _ => measurement(),
        }
    }

    /// The plant candidates of one effect on a cable network: every element where its physics
    /// acts and shows in the measured channels.
    fn of_network_effect(effect: Effect, ctx: &SiteContext, net: &NetworkSites) -> Vec<Candidate> {
        use Effect::*;
        let c = |site| Candidate::new(effect, site);
        let idx = |i: usize| u16::try_from(i).unwrap_or(u16::MAX);
        let joints = || (0..net.joints.len()).map(|j| c(Site::NetJoint(idx(j))));
        let cables = || (0..net.cables.len()).map(|k| c(Site::NetCable(idx(k))));
        // a motor's friction shows in the dynamics of a torque-driven motor, and in the current
        // of a position-driven one when it is measured
        let measured = |name: String| ctx.channels.contains(&name);
        let motors = || {
            (0..net.motors.len())
                .filter(|&i| net.torque_driven[i] || measured(format!("load_m:{}", net.motors[i])))
                .map(|i| c(Site::NetMotor(idx(i))))
        };
        // the routing's friction acts on its driver's dynamics, and changes the motor-side
        // tension and the motor's load
        let routings = || {
            (0..net.cables.len())
                .filter(|&k| {
                    net.routing_in_dynamics[k]
                        || measured(format!("T_motor:{}", net.cables[k]))
                        || net.cable_motor[k]
                            .is_some_and(|i| measured(format!("load_m:{}", net.motors[i])))
                })
                .map(|k| c(Site::NetRouting(idx(k))))
        };
        match effect {
            // dry friction as a smoothed sign law, or held in a stiff bristle (pre-sliding)
            // state that sticks at rest: the joint's sticking and LuGre forms
            CoulombFriction => joints()
                .chain(joints().map(|x| x.with_form(Form::Sticking)))
                .chain(motors())
                .collect(),
            ViscousFriction => joints().chain(motors()).collect(),
            StribeckFriction => joints()
                .chain(joints().map(|x| x.with_form(Form::Lugre)))
                .collect(),
            InertiaError => joints()
                .chain(motors().filter(
                    |m| matches!(m.site, Site::NetMotor(i) if net.torque_driven[usize::from(i)]),
                ))
                .collect(),
            CapstanFriction => routings().collect(),
            NonlinearStiffness => cables()
                .chain(cables().map(|x| x.with_form(Form::Scale)))
                .collect(),
            CableDamping | Slack => cables().collect(),
            // pre-sliding of a joint's dry friction, or of a routing's (a pulley's bristles)
            DahlHysteresis => joints().chain(routings()).collect(),
            // a wound cable's creep also in its stretch (the forms differ where the free length
            // changes)
            Creep => cables()
                .chain(cables().map(|x| x.with_form(Form::Whole)))
                .chain(
                    (0..net.cables.len())
                        .filter(|&k| net.wound[k])
                        .map(|k| c(Site::NetCable(idx(k))).with_form(Form::Stretch)),
                )
                .collect(),
            // play between a position-driven motor and its capstan (a torque-driven motor's
            // play and a joint hub's clearance are not modelled on networks); not at a motor
            // that only moves cables' far ends (a parallel robot's measured platform)
            Backlash => (0..net.motors.len())
                .filter(|&i| !net.torque_driven[i] && net.cable_motor.contains(&Some(i)))
                .map(|i| c(Site::NetMotor(idx(i))))
                .collect(),
            // the coupling its routing already describes
            _ => vec![],
        }
    }

    /// Whether the candidate lives in the joint's bristle state (Dahl hysteresis, the sticking
    /// Coulomb and the LuGre Stribeck forms); a fit holds at most one of them.
    pub fn uses_joint_bristle(&self) -> bool {
        self.effect == Effect::DahlHysteresis
            || matches!(
                (self.effect, self.form),
                (Effect::CoulombFriction, Form::Sticking) | (Effect::StribeckFriction, Form::Lugre)
            )
    }

    /// Whether the candidate can act on a plant with this context.
    pub fn applies(&self, ctx: &SiteContext) -> bool {
        Self::of_effect(self.effect, ctx).contains(self)
    }

    /// Identifier `effect@site` (with `/form` when not standard), e.g.
    /// `creep@cable.both/whole`.
    pub fn id(&self, names: &dyn SiteNames) -> String {
        let mut s = format!("{}@{}", self.effect.name(), self.site.name(names));
        if self.form != Form::Standard {
            s.push('/');
            s.push_str(self.form.name());
        }
        s
    }

    /// Parse `effect`, `effect@site` or `effect@site/form`; an effect alone means its classic
    /// site ([`Candidate::default_for`]).
    pub fn parse(id: &str, transmission: bool, index: &dyn SiteIndex) -> Result<Self> {
        let (effect, rest) = match id.split_once('@') {
            Some((e, r)) => (e, Some(r)),
            None => (id, None),
        };
        let effect = Effect::from_name(effect)?;
        let Some(rest) = rest else {
            return Ok(Self::default_for(effect, transmission));
        };
        let (site, form) = match rest.split_once('/') {
            Some((s, f)) => (s, Form::parse(f)?),
            None => (rest, Form::Standard),
        };
        Ok(Self {
            effect,
            site: Site::parse(site, index)?,
            form,
        })
    }

    /// One sentence a user reads, e.g. "hysteresis (Dahl) in the cable–pulley contact of the
    /// drive cable".
    pub fn sentence(&self, names: &dyn SiteNames) -> String {
        let what = match (self.effect, self.form) {
            (Effect::CoulombFriction, Form::LoadDependent) => {
                "dry friction growing with the transmitted load"
            }
            (Effect::ViscousFriction, Form::PowerLaw) => {
                "joint drag growing as a power of speed (not linearly)"
            }
            (Effect::CoulombFriction, Form::Sticking) => {
                "dry friction that holds the joint at rest (a stiff bristle state)"
            }
            (Effect::StribeckFriction, Form::Lugre) => {
                "joint friction that sticks at rest and drops once sliding (Stribeck, LuGre state)"
            }
            (Effect::DahlHysteresis, Form::Generalised) => {
                "hysteresis (Dahl, fitted shape exponent)"
            }
            (Effect::DahlHysteresis, _) => "hysteresis (Dahl)",
            (Effect::Creep, Form::Whole) => "creep relaxing the whole tension, pretension included",
            (Effect::Creep, Form::Stretch) => {
                "creep of the cable's stretch (a Kelvin–Voigt element in series, its crept length \
                 kept as the winch changes the free length)"
            }
            (Effect::NonlinearStiffness, Form::Cubic) => "cubic hardening of the cable law",
            (Effect::NonlinearStiffness, Form::Scale) => {
                "a stiffness other than the nominal (a compliant stage in series)"
            }
            (Effect::SensorLag, Form::SecondOrder) => "second-order (critically damped) lag",
            (Effect::Backlash, _) if self.site == Site::Joint => {
                "play between the joint pulley and the link (the link's share of the inertia \
                 beyond a clearance)"
            }
            (Effect::SensorLag, Form::Resonant) => {
                "a second-order sensor with its own resonance (natural frequency and damping)"
            }
            (Effect::SensorSampling, Form::Averaging) => {
                "an integrating converter that reports the mean over each conversion window and holds it"
            }
            (e, _) => e.description(),
        };
        format!("{what} {}", self.site.phrase(names))
    }
}

impl Candidate {
    /// Parameters of the candidate for data of typical magnitudes `s`: the effect's own
    /// parameters, laid out for its site and form.
    pub fn params(&self, s: &Scales) -> Vec<ParamSpec> {
        let base = self.effect.params(s);
        let side = |v: Vec<ParamSpec>| -> Vec<ParamSpec> {
            // a one-cable site names its parameters after the cable
            match self.site {
                Site::Cable(x) | Site::Contact(x) if x != Side::Both => v
                    .into_iter()
                    .map(|mut q| {
                        q.name = format!("{}[{}]", q.name, x.name());
                        q
                    })
                    .collect(),
                _ => v,
            }
        };
        let p = spec;
        // a friction level at the motor side (N at the motor)
        let motor_level = || {
            p(
                "F_m",
                "N",
                0.0,
                0.1 * s.force,
                0.0,
                100.0 * s.force,
                s.force,
            )
        };
        match (self.effect, self.site, self.form) {
            // on a network joint the sticking forms are the sign law sharpened to a ten-thousandth
            // of the typical speed, which the replay's implicit friction holds at rest (fixed)
            (Effect::CoulombFriction, Site::NetJoint(_), Form::Sticking)
            | (Effect::StribeckFriction, Site::NetJoint(_), Form::Lugre) => {
                let e = 1e-4 * s.speed.max(1e-12);
                let mut v: Vec<ParamSpec> = if self.effect == Effect::CoulombFriction {
                    base.into_iter().take(1).collect()
                } else {
                    base
                };
                v.push(p("eps_s", "rad/s", e, e, e, e, e));
                v
            }
            // the bristle forms carry the level(s) only: their break-away displacement is the
            // resolution floor (one sample's travel), below which no pre-sliding is observable
            // (fixed: lower = upper, carried with the parameters so that every run replays the
            // same law)
            (Effect::CoulombFriction, _, Form::Sticking)
            | (Effect::StribeckFriction, _, Form::Lugre) => {
                let th = bristle_floor(s);
                let n = if self.effect == Effect::CoulombFriction {
                    1
                } else {
                    3
                };
                let mut v: Vec<ParamSpec> = base.into_iter().take(n).collect();
                v.push(p("theta_d", "rad", th, th, th, th, th));
                v
            }
            (Effect::ViscousFriction, _, Form::PowerLaw) => {
                // the drag at the typical speed w (so that n moves the shape, not the level), n
                // from shear thinning (0.2) to thickening (3), and w itself as a fixed parameter
                let w = s.speed.max(1e-9);
                let sc = 0.1 * s.torque;
                vec![
                    p("b_w", "N·m", 0.0, 0.0, 0.0, 100.0 * sc, sc),
                    p("n", "1", 1.0, 1.0, 0.2, 3.0, 0.3).starts(&[0.5, 2.0]),
                    p("v_r", "rad/s", w, w, w, w, w),
                ]
            }
            (Effect::CoulombFriction, _, Form::LoadDependent) => {
                let mut v = base;
                // μ_L: dry friction per N·m of transmitted torque (arXiv 2410.08650, M3)
                v.insert(1, p("mu_L", "1", 0.0, 0.02, 0.0, 2.0, 0.05));
                v
            }
            (Effect::DahlHysteresis, Site::Joint, Form::Generalised) => {
                let mut v = base;
                v.push(p("n", "1", 1.0, 1.0, 0.3, 4.0, 0.5).starts(&[2.0]));
                v
            }
            (Effect::DahlHysteresis, Site::NetRouting(_), _) => {
                // level: the routing's capstan exponent μφ (added to the nominal's); break-away:
                // hauled cable (m)
                let st = s.stretch.max(1e-9);
                let lo = (s.motor_speed * s.dt * 0.1).max(1e-9);
                vec![
                    p("mu_phi", "1", 0.0, 0.02, 0.0, 3.0, 0.1),
                    p("x_d", "m", st, st, lo, 0.5 * s.travel.max(10.0 * st), st)
                        .starts(&[0.1 * st, 10.0 * st]),
                ]
            }
            (Effect::DahlHysteresis, Site::Contact(_), _) => {
                // level: the contact's capstan exponent μφ; break-away: cable sliding (m)
                let st = s.stretch.max(1e-9);
                let lo = (s.motor_speed * s.dt * 0.1).max(1e-9);
                side(vec![
                    p("mu_phi", "1", 0.0, 0.02, 0.0, 3.0, 0.1),
                    p("x_d", "m", st, st, lo, 0.5 * s.travel.max(10.0 * st), st)
                        .starts(&[0.1 * st, 10.0 * st]),
                ])
            }
            (Effect::NonlinearStiffness, _, Form::Cubic) => {
                let st = s.stretch.max(1e-12);
                vec![p(
                    "gamma",
                    "1/m²",
                    0.0,
                    0.0,
                    -0.3 / (st * st),
                    30.0 / (st * st),
                    0.3 / (st * st),
                )]
            }
            // motor side: forces in N at the motor, driven by the motor displacement
            // a network's dry friction keeps its element's sign smoothing: the network has no
            // per-interval friction substeps, so a fitted sharpening could outrun RK4's
            // stability at the advised substeps
            (Effect::CoulombFriction, Site::NetJoint(_), _) => base.into_iter().take(1).collect(),
            (Effect::CoulombFriction, Site::NetMotor(_), _) => vec![motor_level()],
            // a routing's friction: its level, and the sharpness of its sign (a capstan's dry
            // friction is sharper than any regularised law; its smoothing vanishes at the
            // nominal's)
            (Effect::CapstanFriction, Site::NetRouting(_), _) => {
                let e = s.routing_smoothing;
                vec![
                    p("mu_phi", "1", 0.0, 0.02, 0.0, 3.0, 0.1),
                    p("eps_h", "m/s", e, e, 1e-3 * e, 10.0 * e, e).starts(&[0.1 * e, 0.01 * e]),
                ]
            }
            (Effect::CoulombFriction, Site::Motor, _) => {
                let v = s.motor_speed.max(1e-9);
                vec![
                    motor_level(),
                    p("eps_m", "m/s", 0.0, 0.01 * v, 1e-4 * v, v, 0.01 * v),
                ]
            }
            (Effect::ViscousFriction, Site::Motor | Site::NetMotor(_), _) => {
                let b = s.force / s.motor_speed.max(1e-9);
                vec![p("b_m", "N·s/m", 0.0, 0.0, 0.0, 100.0 * b, b)]
            }
            (Effect::DahlHysteresis, Site::Motor, _) => {
                let st = s.stretch.max(1e-9);
                let lo = (s.motor_speed * s.dt * 0.1).max(1e-9);
                vec![
                    motor_level(),
                    p("x_d", "m", st, st, lo, 0.5 * s.travel.max(10.0 * st), st)
                        .starts(&[0.1 * st, 10.0 * st]),
                ]
            }
            (Effect::NonlinearStiffness, _, Form::Scale) => {
                vec![p("eps_k", "1", 0.0, 0.0, -0.95, 20.0, 0.2).starts(&[-0.6, -0.3, 0.5, 2.0])]
            }
            (Effect::SensorLag, _, Form::Resonant) => {
                // τ = 1/ω_n (swept like the lag constant) and the damping ratio ζ: from a ringing
                // cell (0.05) to an overdamped amplifier (3); ζ = 1 is the two-pole lag
                let mut v = base;
                v.push(p("zeta", "1", 1.0, 0.5, 0.05, 3.0, 0.3).starts(&[0.15, 0.3, 1.0]));
                v
            }
            (Effect::Backlash, Site::Joint, _) => {
                // the clearance (rad of joint angle), the link's share of the inertia, and the
                // contact's stiffness as a multiple of the cables' torsional stiffness
                // a cable stretch in joint angle (the radius is motor speed over joint speed)
                let radius = s.motor_speed / s.speed.max(1e-12);
                let th = (s.stretch / radius.max(1e-9)).clamp(1e-6, 0.02);
                // a clearance of 0 is the nominal rigid hub (the reference), but a vanishing one
                // still leaves the two-mass contact: the fit stays above it, so no finite
                // difference straddles the switch
                vec![
                    p("delta_j", "rad", 0.0, th, 1e-3 * th, 0.2, th).starts(&[
                        0.1 * th,
                        0.3 * th,
                        3.0 * th,
                        10.0 * th,
                    ]),
                    p("link_share", "1", 0.7, 0.7, 0.05, 0.95, 0.2).starts(&[0.3]),
                    p("k_ratio", "1", 10.0, 10.0, 0.5, 1e3, 10.0).starts(&[2.0, 100.0]),
                ]
            }
            (Effect::SensorGainBias, Site::Sensor(_), _) => base.into_iter().take(2).collect(),
            // every force channel with its own converter: each its own clock (period and
            // phase), as one HX711 per load cell has
            (Effect::SensorSampling, Site::ForceSensors, _) => (0..s.sensors.max(1))
                .flat_map(|i| {
                    base.iter().map(move |q| {
                        let mut q = q.clone();
                        q.name = format!("{}[{i}]", q.name);
                        q
                    })
                })
                .collect(),
            (
                Effect::SensorGainBias
                | Effect::SensorLag
                | Effect::SensorSampling
                | Effect::TimeDelay,
                _,
                _,
            ) => base,
            _ => side(base),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ctx() -> SiteContext {
        SiteContext {
            transmission: false,
            links: 1,
            channels: vec![
                "tension_motor_drive".into(),
                "tension_motor_return".into(),
                "theta".into(),
            ],
            force: vec![true, true, false],
            coupled: true,
            network: None,
        }
    }

    fn name_of(i: usize) -> String {
        ctx().channels[i].clone()
    }

    fn index_of(s: &str) -> Option<usize> {
        ctx().channels.iter().position(|c| c == s)
    }

    #[test]
    fn ids_round_trip_and_are_unique() {
        let lib = Candidate::library(&ctx());
        assert!(lib.len() > 40, "{}", lib.len());
        let mut ids: Vec<String> = lib.iter().map(|c| c.id(&name_of)).collect();
        for (c, id) in lib.iter().zip(&ids) {
            assert_eq!(Candidate::parse(id, false, &index_of).unwrap(), *c, "{id}");
            assert!(c.applies(&ctx()));
        }
        ids.sort();
        ids.dedup();
        assert_eq!(ids.len(), lib.len());
        // every canonical effect has at least one site on a fully measured joint
        for e in Effect::ALL {
            assert!(lib.iter().any(|c| c.effect == e), "{e:?}");
        }
    }

    #[test]
    fn names_and_sentences_read_as_documented() {
        let c = Candidate::new(Effect::DahlHysteresis, Site::Contact(Side::Drive));
        assert_eq!(c.id(&name_of), "dahl_hysteresis@contact.drive");
        assert_eq!(
            c.sentence(&name_of),
            "hysteresis (Dahl) in the cable–pulley contact of the drive cable"
        );
        let d = Candidate::new(Effect::TimeDelay, Site::Sensor(1));
        assert_eq!(d.id(&name_of), "time_delay@sensor.tension_motor_return");
        let w = Candidate::new(Effect::Creep, Site::Cable(Side::Both)).with_form(Form::Whole);
        assert_eq!(w.id(&name_of), "creep@cable.both/whole");
        // an effect alone is its classic site
        assert_eq!(
            Candidate::parse("sensor_lag", false, &index_of).unwrap(),
            Candidate::new(Effect::SensorLag, Site::ForceSensors)
        );
    }

    #[test]
    fn bad_ids_are_typed_errors_and_sites_must_apply() {
        for bad in [
            "creep@cable.left",
            "creep@nowhere",
            "sensor_lag@sensor.T9",
            "friction@joint",
            "creep@cable.both/sideways",
        ] {
            assert!(
                matches!(
                    Candidate::parse(bad, false, &index_of),
                    Err(CableError::InvalidOption { .. })
                ),
                "{bad}"
            );
        }
        // a lag on the encoder, capstan without a motor-side sensor
        assert!(!Candidate::new(Effect::SensorLag, Site::Sensor(2)).applies(&ctx()));
        let mut no_motor = ctx();
        no_motor.channels = vec!["theta".into()];
        no_motor.force = vec![false];
        assert!(Candidate::of_effect(Effect::CapstanFriction, &no_motor).is_empty());
    }

    #[test]
    fn motor_side_friction_needs_a_force_measured_at_the_motor() {
        let motor = |e| Candidate::new(e, Site::Motor);
        // cable tension sensors do not see a drum's bearing friction
        for e in [
            Effect::CoulombFriction,
            Effect::ViscousFriction,
            Effect::DahlHysteresis,
        ] {
            assert!(!motor(e).applies(&ctx()), "{e:?}");
        }
        let mut spindle = ctx();
        spindle.channels = vec!["net_motor_force".into(), "theta".into()];
        spindle.force = vec![true, false];
        for e in [
            Effect::CoulombFriction,
            Effect::ViscousFriction,
            Effect::DahlHysteresis,
        ] {
            assert!(motor(e).applies(&spindle), "{e:?}");
        }
        assert!(!motor(Effect::StribeckFriction).applies(&spindle));
        let c = motor(Effect::DahlHysteresis);
        let name = |i: usize| spindle.channels[i].clone();
        assert_eq!(c.id(&name), "dahl_hysteresis@motor");
        let index = |s: &str| spindle.channels.iter().position(|c| c == s);
        assert_eq!(
            Candidate::parse("dahl_hysteresis@motor", false, &index).unwrap(),
            c
        );
        let k = Candidate::new(Effect::NonlinearStiffness, Site::Cable(Side::Both))
            .with_form(Form::Scale);
        assert_eq!(k.id(&name), "nonlinear_stiffness@cable.both/scale");
        assert!(k.applies(&spindle));
    }
}
