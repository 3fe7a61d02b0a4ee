//! [`JointSpec`]: an antagonistic joint as named scalar parameters.

use std::collections::BTreeMap;

use crate::cable::{CableLaw, CableRun, Creep};
use crate::dynamics::{AntagonisticJoint, Contact};
use crate::error::{CableError, Result};
use crate::friction::{Dahl, StaticFriction};

/// What a parameter left out of a [`JointSpec`] means.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FieldDefault {
    /// It must be given.
    Required,
    /// This value.
    Value(f64),
    /// The value of another field (the return cable as the drive cable).
    Like(&'static str),
    /// The element it belongs to (contact, Dahl friction, creep) is absent.
    Absent,
}

/// The parameters of [`JointSpec::values`] with their defaults, SI units as in
/// [`AntagonisticJoint`]. Elements with several parameters (contact, Dahl, creep) are present
/// when their `Absent`-default parameters are all given, and absent when none is.
pub const JOINT_FIELDS: [(&str, FieldDefault); 27] = {
    use FieldDefault::{Absent, Like, Required, Value};
    [
        ("radius", Required),
        ("stiffness", Required),
        ("inertia", Required),
        ("damping", Value(0.0)),
        ("pretension", Value(0.0)),
        ("stiffness_return", Like("stiffness")),
        ("damping_return", Like("damping")),
        ("pretension_return", Like("pretension")),
        ("length_scale", Value(1.0)),
        ("viscous", Value(0.0)),
        ("coulomb", Value(0.0)),
        ("smoothing", Value(0.05)),
        ("static_friction", Like("coulomb")),
        ("stribeck_velocity", Value(1.0)),
        ("stribeck_exponent", Value(2.0)),
        ("capstan_mu", Value(0.0)),
        ("capstan_wrap", Value(0.0)),
        ("capstan_smoothing", Value(1e-3)),
        ("contact_angle", Absent),
        ("contact_stiffness", Absent),
        ("contact_damping", Value(0.0)),
        ("contact_lever_arm", Absent),
        ("dahl_coulomb", Absent),
        ("dahl_sigma0", Absent),
        ("dahl_exponent", Value(1.0)),
        ("creep_fraction", Absent),
        ("creep_time_constant", Absent),
    ]
};

/// An antagonistic joint as named parameters ([`JOINT_FIELDS`]) and a cable law.
#[derive(Debug, Clone, PartialEq)]
pub struct JointSpec {
    /// Parameters by name; one left out takes its default.
    pub values: BTreeMap<String, f64>,
    /// `"linear"` or `"exponential"`, both cables.
    pub cable_law: String,
}

impl Default for JointSpec {
    fn default() -> Self {
        Self {
            values: BTreeMap::new(),
            cable_law: "linear".into(),
        }
    }
}

impl JointSpec {
    /// The spec of named values as a front end gives them (unknown names are refused by
    /// [`build`](Self::build), values of the wrong kind here).
    pub fn from_named(named: impl IntoIterator<Item = (String, super::SpecValue)>) -> Result<Self> {
        let mut spec = Self::default();
        for (name, value) in named {
            if name == "cable_law" {
                spec.cable_law = value.text(&name)?;
            } else {
                let v = value.number(&name)?;
                spec.values.insert(name, v);
            }
        }
        Ok(spec)
    }

    /// Field `name` with its default applied; `None` for an absent element's parameter.
    fn get(&self, name: &str) -> Result<Option<f64>> {
        if let Some(v) = self.values.get(name) {
            return Ok(Some(*v));
        }
        let default = JOINT_FIELDS
            .iter()
            .find(|(f, _)| *f == name)
            .map(|(_, d)| *d)
            .unwrap_or(FieldDefault::Absent);
        match default {
            FieldDefault::Required => Err(CableError::InvalidOption {
                name: name.into(),
                value: "missing".into(),
                allowed: "a value (required)".into(),
            }),
            FieldDefault::Value(v) => Ok(Some(v)),
            FieldDefault::Like(other) => self.get(other),
            FieldDefault::Absent => Ok(None),
        }
    }

    fn value(&self, name: &str) -> Result<f64> {
        Ok(self.get(name)?.unwrap_or(0.0)) // only called for fields that have a default
    }

    /// The parameters of an element: all given, or none (the element is absent).
    fn element<const K: usize>(&self, what: &str, names: [&str; K]) -> Result<Option<[f64; K]>> {
        let got: Vec<Option<f64>> = names.iter().map(|n| self.get(n)).collect::<Result<_>>()?;
        match got.iter().filter(|v| v.is_some()).count() {
            0 => Ok(None),
            c if c == K => Ok(Some(std::array::from_fn(|i| got[i].unwrap_or(0.0)))),
            _ => Err(CableError::InvalidOption {
                name: what.into(),
                value: "partially specified".into(),
                allowed: format!("all of {} or none", names.join(", ")),
            }),
        }
    }

    /// Every value by name, the way [`from_named`](Self::from_named) takes them.
    pub fn named(&self) -> Vec<(String, super::SpecValue)> {
        let values = self
            .values
            .iter()
            .map(|(k, v)| (k.clone(), super::SpecValue::Number(*v)));
        values
            .chain([(
                "cable_law".into(),
                super::SpecValue::Text(self.cable_law.clone()),
            )])
            .collect()
    }

    /// The validated joint.
    pub fn build(&self) -> Result<AntagonisticJoint> {
        super::known_names(
            "joint parameter",
            self.values.keys(),
            &JOINT_FIELDS.map(|f| f.0),
        )?;
        let v = |name: &str| self.value(name);
        let run = |side: &str, suffix: &str| -> Result<CableRun> {
            let law = CableLaw::from_name(
                &self.cable_law,
                v(&format!("stiffness{suffix}"))?,
                v("length_scale")?,
                side,
            )?;
            CableRun::new(
                law,
                v(&format!("damping{suffix}"))?,
                v(&format!("pretension{suffix}"))?,
                side,
            )
        };
        let contact = self
            .element(
                "contact",
                ["contact_angle", "contact_stiffness", "contact_lever_arm"],
            )?
            .map(|[a, k, l]| Contact::new(a, k, v("contact_damping")?, l))
            .transpose()?;
        let friction = StaticFriction::stribeck(
            "friction",
            v("coulomb")?,
            v("static_friction")?,
            v("stribeck_velocity")?,
            v("stribeck_exponent")?,
            v("viscous")?,
            v("smoothing")?,
        )?;
        let dahl = self
            .element("dahl", ["dahl_coulomb", "dahl_sigma0"])?
            .map(|[c, s]| Dahl::new(s, c, v("dahl_exponent")?))
            .transpose()?;
        let creep = self
            .element("creep", ["creep_fraction", "creep_time_constant"])?
            .map(|[k, t]| Creep::new(k, t))
            .transpose()?;
        AntagonisticJoint::new(
            v("radius")?,
            run("drive", "")?,
            run("return", "_return")?,
            v("inertia")?,
            friction,
            v("capstan_mu")?,
            v("capstan_wrap")?,
            v("capstan_smoothing")?,
            contact,
        )?
        .with_dahl(dahl)?
        .with_creep(creep)
    }

    /// The spec a joint was built from (every parameter; an absent element's left out).
    pub fn of(j: &AntagonisticJoint) -> Self {
        let mut values: Vec<(&str, f64)> = vec![
            ("radius", j.radius),
            ("stiffness", j.drive.law.stiffness()),
            ("damping", j.drive.damping),
            ("pretension", j.drive.pretension),
            ("stiffness_return", j.ret.law.stiffness()),
            ("damping_return", j.ret.damping),
            ("pretension_return", j.ret.pretension),
            (
                "length_scale",
                match j.drive.law {
                    CableLaw::Exponential { length_scale, .. } => length_scale,
                    CableLaw::Linear { .. } => 1.0,
                },
            ),
            ("inertia", j.inertia),
            ("viscous", j.friction.viscous),
            ("coulomb", j.friction.coulomb),
            ("smoothing", j.friction.smoothing),
            ("static_friction", j.friction.static_level),
            ("stribeck_velocity", j.friction.stribeck_velocity),
            ("stribeck_exponent", j.friction.stribeck_exponent),
            ("capstan_mu", j.capstan_mu),
            ("capstan_wrap", j.capstan_wrap),
            ("capstan_smoothing", j.capstan_smoothing),
        ];
        if let Some(c) = j.contact {
            values.extend([
                ("contact_angle", c.angle),
                ("contact_stiffness", c.stiffness),
                ("contact_damping", c.damping),
                ("contact_lever_arm", c.lever_arm),
            ]);
        }
        if let Some(d) = j.dahl {
            values.extend([
                ("dahl_coulomb", d.coulomb),
                ("dahl_sigma0", d.sigma0),
                ("dahl_exponent", d.exponent),
            ]);
        }
        if let Some(c) = j.creep {
            values.extend([
                ("creep_fraction", c.fraction),
                ("creep_time_constant", c.time_constant),
            ]);
        }
        Self {
            values: values.into_iter().map(|(k, v)| (k.to_owned(), v)).collect(),
            cable_law: j.drive.law.name().to_owned(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_joint_rebuilt_from_its_spec_is_the_same_joint() {
        let j = AntagonisticJoint::forceps_example();
        let spec = JointSpec::of(&j);
        assert_eq!(spec.build().unwrap(), j);
        let mut with = spec.clone();
        for (k, v) in [
            ("dahl_coulomb", 0.01),
            ("dahl_sigma0", 50.0),
            ("creep_fraction", 0.2),
            ("creep_time_constant", 1.0),
        ] {
            with.values.insert(k.into(), v);
        }
        let j2 = with.build().unwrap();
        assert_eq!(JointSpec::of(&j2).build().unwrap(), j2);
    }

    #[test]
    fn defaults_follow_their_field_and_partial_elements_are_refused() {
        let mut spec = JointSpec::default();
        for (k, v) in [("radius", 3e-3), ("stiffness", 1e4), ("inertia", 1e-5)] {
            spec.values.insert(k.into(), v);
        }
        spec.values.insert("pretension".into(), 7.0);
        let j = spec.build().unwrap();
        assert_eq!((j.ret.pretension, j.ret.law.stiffness()), (7.0, 1e4));
        let mut bad = spec.clone();
        bad.values.insert("dahl_sigma0".into(), 10.0);
        assert!(
            matches!(bad.build(), Err(CableError::InvalidOption { ref name, .. }) if name == "dahl")
        );
        let mut bad = spec.clone();
        bad.values.remove("radius");
        assert!(
            matches!(bad.build(), Err(CableError::InvalidOption { ref name, .. }) if name == "radius")
        );
        let mut bad = spec;
        bad.values.insert("radious".into(), 1.0);
        assert!(bad.build().is_err());
    }
}
