//! [`TransmissionSpec`]: a cable transmission as named per-link parameter lists (a scalar means
//! "the same on every link").

use std::collections::BTreeMap;

use crate::cable::{CableLaw, CableLoop, CableRun};
use crate::dynamics::{CableTransmission, Gravity, JointKind, TransmissionLink};
use crate::error::{CableError, Result};
use crate::friction::StaticFriction;

/// The numeric per-link fields of [`TransmissionSpec::values`], in order, with their defaults
/// (`None`: required). SI units as in [`TransmissionLink`].
pub const TRANSMISSION_FIELDS: [(&str, Option<f64>); 16] = [
    ("motor_inertia", None),
    ("gear_ratio", None),
    ("capstan_radius", None),
    ("joint_radius", None),
    ("link_inertia", None),
    ("cable_stiffness", None),
    ("cable_damping", Some(0.0)),
    ("pretension", Some(0.0)),
    ("motor_coulomb", Some(0.0)),
    ("motor_viscous", Some(0.0)),
    ("motor_smoothing", Some(0.1)),
    ("link_coulomb", Some(0.0)),
    ("link_viscous", Some(0.0)),
    ("link_smoothing", Some(1e-3)),
    ("gravity_amplitude", Some(0.0)),
    ("gravity_offset", Some(0.0)),
];

/// A transmission as named per-link parameter lists.
#[derive(Debug, Clone, PartialEq)]
pub struct TransmissionSpec {
    /// Per-link values by field name ([`TRANSMISSION_FIELDS`]); one value applies to every
    /// link; a field left out takes its default.
    pub values: BTreeMap<String, Vec<f64>>,
    /// Cable law of every link: `"linear"` or `"exponential"`.
    pub cable_law: String,
    /// Length scale of the exponential law (m).
    pub length_scale: f64,
    /// Joint kind per link (`"revolute"`, `"prismatic"`); empty: all revolute.
    pub joint_kind: Vec<String>,
    /// Coupling matrix `n × n` (rows); empty: none.
    pub coupling: Vec<Vec<f64>>,
}

impl Default for TransmissionSpec {
    fn default() -> Self {
        Self {
            values: BTreeMap::new(),
            cable_law: "linear".into(),
            length_scale: 1.0,
            joint_kind: Vec::new(),
            coupling: Vec::new(),
        }
    }
}

fn shape(what: &str, n: usize, got: usize) -> CableError {
    CableError::Shape {
        what: what.into(),
        expected: format!("1 or {n} values (one per link; the longest list given has {n})"),
        got: format!("{got}"),
    }
}

impl TransmissionSpec {
    /// The spec of named values as a front end gives them (unknown names are refused by
    /// [`build`](Self::build), values of the wrong kind here).
    pub fn from_named(named: impl IntoIterator<Item = (String, super::SpecValue)>) -> Result<Self> {
        let mut spec = Self::default();
        for (name, value) in named {
            match name.as_str() {
                "cable_law" => spec.cable_law = value.text(&name)?,
                "length_scale" => spec.length_scale = value.number(&name)?,
                "joint_kind" => spec.joint_kind = value.texts(&name)?,
                "coupling" => spec.coupling = value.rows(&name)?,
                _ => {
                    let v = value.numbers(&name)?;
                    spec.values.insert(name, v);
                }
            }
        }
        Ok(spec)
    }

    /// Links `n`: the longest list given (at least 1).
    pub fn links(&self) -> usize {
        self.values
            .values()
            .map(Vec::len)
            .chain([self.joint_kind.len(), self.coupling.len(), 1])
            .max()
            .unwrap_or(1)
    }

    /// Field `name` with `n` values (a single value broadcast, the default when left out).
    fn field(&self, name: &str, default: Option<f64>, n: usize) -> Result<Vec<f64>> {
        match (self.values.get(name), default) {
            (Some(v), _) if v.len() == n => Ok(v.clone()),
            (Some(v), _) if v.len() == 1 => Ok(vec![v[0]; n]),
            (Some(v), _) => Err(shape(name, n, v.len())),
            (None, Some(d)) => Ok(vec![d; n]),
            (None, None) => Err(CableError::InvalidOption {
                name: name.into(),
                value: "missing".into(),
                allowed: "a value per link (required)".into(),
            }),
        }
    }

    /// Every value by name, the way [`from_named`](Self::from_named) takes them.
    pub fn named(&self) -> Vec<(String, super::SpecValue)> {
        use super::SpecValue::{Number, Numbers, Rows, Text, Texts};
        let values = self
            .values
            .iter()
            .map(|(k, v)| (k.clone(), Numbers(v.clone())));
        values
            .chain([
                ("cable_law".into(), Text(self.cable_law.clone())),
                ("length_scale".into(), Number(self.length_scale)),
                ("joint_kind".into(), Texts(self.joint_kind.clone())),
                ("coupling".into(), Rows(self.coupling.clone())),
            ])
            .collect()
    }

    /// The validated model.
    pub fn build(&self) -> Result<CableTransmission> {
        super::known_names(
            "transmission parameter",
            self.values.keys(),
            &TRANSMISSION_FIELDS.map(|f| f.0),
        )?;
        let n = self.links();
        let mut v = BTreeMap::new();
        for (name, default) in TRANSMISSION_FIELDS {
            v.insert(name, self.field(name, default, n)?);
        }
        let kinds = match self.joint_kind.len() {
            0 => vec!["revolute".to_owned(); n],
            k if k == n => self.joint_kind.clone(),
            k => return Err(shape("joint_kind", n, k)),
        };
        if !self.coupling.is_empty()
            && (self.coupling.len() != n || self.coupling.iter().any(|r| r.len() != n))
        {
            return Err(CableError::Shape {
                what: "coupling".into(),
                expected: format!("{n} x {n}"),
                got: format!("{} rows", self.coupling.len()),
            });
        }
        let mut links = Vec::with_capacity(n);
        for i in 0..n {
            let p = format!("links[{i}]");
            let law = CableLaw::from_name(
                &self.cable_law,
                v["cable_stiffness"][i],
                self.length_scale,
                &p,
            )?;
            let friction = |side: &str| {
                StaticFriction::coulomb_viscous(
                    &format!("{p}.{side}"),
                    v[format!("{side}_coulomb").as_str()][i],
                    v[format!("{side}_viscous").as_str()][i],
                    v[format!("{side}_smoothing").as_str()][i],
                )
            };
            links.push(TransmissionLink {
                motor_inertia: v["motor_inertia"][i],
                gear_ratio: v["gear_ratio"][i],
                capstan_radius: v["capstan_radius"][i],
                motor_friction: friction("motor")?,
                cable: CableLoop {
                    run: CableRun::new(law, v["cable_damping"][i], v["pretension"][i], &p)?,
                },
                kind: JointKind::from_name(&kinds[i], &format!("{p}.joint_kind"))?,
                joint_radius: v["joint_radius"][i],
                link_inertia: v["link_inertia"][i],
                link_friction: friction("link")?,
                gravity: Gravity {
                    amplitude: v["gravity_amplitude"][i],
                    offset: v["gravity_offset"][i],
                },
            });
        }
        CableTransmission::new(links, &self.coupling.concat())
    }

    /// The spec a model was built from (every field per link).
    pub fn of(t: &CableTransmission) -> Self {
        let links = t.links();
        let col = |f: &dyn Fn(&TransmissionLink) -> f64| links.iter().map(f).collect::<Vec<f64>>();
        let values: [(&str, Vec<f64>); 16] = [
            ("motor_inertia", col(&|l| l.motor_inertia)),
            ("gear_ratio", col(&|l| l.gear_ratio)),
            ("capstan_radius", col(&|l| l.capstan_radius)),
            ("joint_radius", col(&|l| l.joint_radius)),
            ("link_inertia", col(&|l| l.link_inertia)),
            ("cable_stiffness", col(&|l| l.cable.run.law.stiffness())),
            ("cable_damping", col(&|l| l.cable.run.damping)),
            ("pretension", col(&|l| l.cable.run.pretension)),
            ("motor_coulomb", col(&|l| l.motor_friction.coulomb)),
            ("motor_viscous", col(&|l| l.motor_friction.viscous)),
            ("motor_smoothing", col(&|l| l.motor_friction.smoothing)),
            ("link_coulomb", col(&|l| l.link_friction.coulomb)),
            ("link_viscous", col(&|l| l.link_friction.viscous)),
            ("link_smoothing", col(&|l| l.link_friction.smoothing)),
            ("gravity_amplitude", col(&|l| l.gravity.amplitude)),
            ("gravity_offset", col(&|l| l.gravity.offset)),
        ];
        let first = links[0].cable.run.law;
        let n = t.n_links();
        let c = t.coupling();
        Self {
            values: values.into_iter().map(|(k, v)| (k.to_owned(), v)).collect(),
            cable_law: first.name().to_owned(),
            length_scale: match first {
                CableLaw::Exponential { length_scale, .. } => length_scale,
                CableLaw::Linear { .. } => 1.0,
            },
            joint_kind: links.iter().map(|l| l.kind.name().to_owned()).collect(),
            coupling: (0..n).map(|i| c[i * n..(i + 1) * n].to_vec()).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_model_rebuilt_from_its_spec_is_the_same_model() {
        for links in 1..=3 {
            let t = crate::dynamics::raven2(links).unwrap();
            let spec = TransmissionSpec::of(&t);
            assert_eq!(TransmissionSpec::of(&spec.build().unwrap()), spec);
        }
    }

    #[test]
    fn scalars_broadcast_defaults_apply_and_mistakes_are_named() {
        let mut spec = TransmissionSpec::default();
        for (k, v) in [
            ("motor_inertia", vec![1e-5]),
            ("gear_ratio", vec![10.0, 12.0]),
            ("capstan_radius", vec![0.01]),
            ("joint_radius", vec![0.02]),
            ("link_inertia", vec![1e-3]),
            ("cable_stiffness", vec![1e4]),
        ] {
            spec.values.insert(k.into(), v);
        }
        let t = spec.build().unwrap();
        assert_eq!(t.n_links(), 2);
        let back = TransmissionSpec::of(&t);
        assert_eq!(back.values["motor_inertia"], vec![1e-5, 1e-5]);
        assert_eq!(back.values["motor_smoothing"], vec![0.1, 0.1]);
        let mut bad = spec.clone();
        bad.values.insert("pretension".into(), vec![1.0, 2.0, 3.0]);
        // three pretensions make three links: the two gear ratios disagree
        assert!(
            matches!(bad.build(), Err(CableError::Shape { ref what, .. }) if what == "gear_ratio")
        );
        let mut bad = spec.clone();
        bad.values.remove("gear_ratio");
        assert!(
            matches!(bad.build(), Err(CableError::InvalidOption { ref name, .. }) if name == "gear_ratio")
        );
        let mut bad = spec.clone();
        bad.values.insert("gear_raito".into(), vec![1.0]);
        assert!(bad.build().is_err());
        let mut bad = spec;
        bad.values.insert("cable_stiffness".into(), vec![-1.0]);
        assert!(matches!(
            bad.build(),
            Err(CableError::InvalidParameter { .. })
        ));
    }
}
