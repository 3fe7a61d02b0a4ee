//! The network model file (docs/models.md): its document, as JSON text (the Python loader reads
//! the TOML and hands the parsed document over), checked key by key. Every defect is a
//! [`CableError::Network`] naming the element and the key: an unknown key, a missing one, a
//! value of the wrong type.

use serde_json::{Map, Value};

use super::{
    invalid, BodySpec, CableSpec, ContactSpec, Drive, ExitWrap, JointSpec, MotorSpec, NetworkSpec,
    PathSpec, PulleySpec, SensorSpec, DEFAULT_CAPSTAN_SMOOTHING,
};
use crate::cable::{CableLaw, CableRun};
use crate::cdpr::PathLaw;
use crate::dynamics::Gravity;
use crate::error::Result;
use crate::friction::StaticFriction;

const TOP: &[&str] = &[
    "name",
    "description",
    "reference",
    "capstan_smoothing",
    "bodies",
    "joints",
    "pulleys",
    "cables",
    "motors",
    "sensors",
    "signals",
];
const BODY: &[&str] = &["name", "inertia"];
const JOINT: &[&str] = &[
    "name",
    "kind",
    "parent",
    "child",
    "coulomb",
    "viscous",
    "smoothing",
    "gravity_amplitude",
    "gravity_offset",
];
const PULLEY: &[&str] = &["name", "joint", "radius"];
const CABLE: &[&str] = &[
    "name",
    "routing",
    "motor",
    "motor_sense",
    "law",
    "stiffness",
    "length_scale",
    "damping",
    "pretension",
    "end_motor",
    "end_sense",
    "free_length",
    "path",
];
const PATH: &[&str] = &[
    "coefficient",
    "viscous",
    "guide_wrap",
    "exit_wrap",
    "law",
    "smoothing",
    "presliding",
    "exponent",
];
const CONTACT: &[&str] = &["pulley", "wrap", "sense", "mu"];
const MOTOR: &[&str] = &[
    "name",
    "drive",
    "inertia",
    "gear_ratio",
    "capstan_radius",
    "coulomb",
    "viscous",
    "smoothing",
];
const SENSOR: &[&str] = &["name", "kind", "target", "at"];

/// One table of the document with the element it describes, for error messages.
struct Table<'a> {
    map: &'a Map<String, Value>,
    element: String,
}

impl<'a> Table<'a> {
    fn new(value: &'a Value, element: String, allowed: &[&str]) -> Result<Self> {
        let map = value
            .as_object()
            .ok_or_else(|| invalid(element.clone(), "must be a table"))?;
        let unknown: Vec<&str> = map
            .keys()
            .map(String::as_str)
            .filter(|k| !allowed.contains(k))
            .collect();
        if !unknown.is_empty() {
            return Err(invalid(
                element,
                format!("has unknown key(s) {unknown:?}; known: {allowed:?}"),
            ));
        }
        Ok(Self { map, element })
    }

    fn num(&self, key: &str, default: Option<f64>) -> Result<f64> {
        match self.map.get(key) {
            None => default.ok_or_else(|| invalid(self.element.clone(), format!("needs {key}"))),
            Some(v) => v.as_f64().filter(|x| x.is_finite()).ok_or_else(|| {
                invalid(
                    self.element.clone(),
                    format!("{key} must be a finite number, got {v}"),
                )
            }),
        }
    }

    fn text(&self, key: &str, default: Option<&str>) -> Result<String> {
        match self.map.get(key) {
            None => default
                .map(str::to_owned)
                .ok_or_else(|| invalid(self.element.clone(), format!("needs {key}"))),
            Some(Value::String(s)) => Ok(s.clone()),
            Some(v) => Err(invalid(
                self.element.clone(),
                format!("{key} must be a string, got {v}"),
            )),
        }
    }

    /// `key`'s string, or `None` when the table leaves it out.
    fn optional_text(&self, key: &str) -> Result<Option<String>> {
        self.map.get(key).map(|_| self.text(key, None)).transpose()
    }

    /// `key`'s finite number, or `None` when the table leaves it out.
    fn optional_num(&self, key: &str) -> Result<Option<f64>> {
        self.map.get(key).map(|_| self.num(key, None)).transpose()
    }

    fn list(&self, key: &str) -> Result<&'a [Value]> {
        match self.map.get(key) {
            None => Ok(&[]),
            Some(Value::Array(a)) => Ok(a),
            Some(v) => Err(invalid(
                self.element.clone(),
                format!("{key} must be a list of tables, got {v}"),
            )),
        }
    }
}

fn each<'a, T>(
    items: &'a [Value],
    kind: &str,
    allowed: &[&str],
    mut build: impl FnMut(&Table<'a>, String) -> Result<T>,
) -> Result<Vec<T>> {
    items
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let name = v
                .get("name")
                .and_then(Value::as_str)
                .map_or_else(|| format!("{kind}[{i}]"), |n| format!("{kind} {n:?}"));
            let t = Table::new(v, name.clone(), allowed)?;
            build(&t, t.text("name", None)?)
        })
        .collect()
}

fn friction(t: &Table<'_>, smoothing: f64) -> Result<StaticFriction> {
    StaticFriction::coulomb_viscous(
        &t.element,
        t.num("coulomb", Some(0.0))?,
        t.num("viscous", Some(0.0))?,
        t.num("smoothing", Some(smoothing))?,
    )
}

/// A cable's `path` table (seed 002's pulley friction between its last contact and its end).
fn path(v: &Value, cable: &str) -> Result<PathSpec> {
    let t = Table::new(v, format!("{cable}.path"), PATH)?;
    let exit_wrap = match t.map.get("exit_wrap") {
        None => ExitWrap::Fixed(0.0),
        Some(Value::String(s)) => ExitWrap::Signal(s.clone()),
        Some(_) => ExitWrap::Fixed(t.num("exit_wrap", None)?),
    };
    let law = PathLaw::named(
        Some(&t.text("law", Some("dahl"))?),
        t.optional_num("smoothing")?,
        t.optional_num("presliding")?,
        t.optional_num("exponent")?,
    )
    .map_err(|e| invalid(format!("{}.law", t.element), e.to_string()))?;
    Ok(PathSpec {
        coefficient: t.num("coefficient", None)?,
        viscous: t.num("viscous", Some(0.0))?,
        guide_wrap: t.num("guide_wrap", Some(0.0))?,
        exit_wrap,
        law,
    })
}

impl NetworkSpec {
    /// The network a model file's document (JSON text of the parsed TOML) describes.
    pub fn from_json(text: &str) -> Result<Self> {
        let doc: Value = serde_json::from_str(text)
            .map_err(|e| invalid("network file".into(), format!("is not a document: {e}")))?;
        let top = Table::new(&doc, "network file".into(), TOP)?;
        let bodies = each(top.list("bodies")?, "body", BODY, |t, name| {
            Ok(BodySpec {
                name,
                inertia: t.num("inertia", None)?,
            })
        })?;
        let joints = each(top.list("joints")?, "joint", JOINT, |t, name| {
            let f = friction(t, 1e-3)?;
            Ok(JointSpec {
                name,
                kind: t.text("kind", Some("revolute"))?,
                parent: t.text("parent", Some("base"))?,
                child: t.text("child", None)?,
                coulomb: f.coulomb,
                viscous: f.viscous,
                smoothing: f.smoothing,
                gravity: Gravity {
                    amplitude: t.num("gravity_amplitude", Some(0.0))?,
                    offset: t.num("gravity_offset", Some(0.0))?,
                },
            })
        })?;
        let pulleys = each(top.list("pulleys")?, "pulley", PULLEY, |t, name| {
            Ok(PulleySpec {
                name,
                joint: t.optional_text("joint")?,
                radius: t.num("radius", None)?,
            })
        })?;
        let motors = each(top.list("motors")?, "motor", MOTOR, |t, name| {
            let drive = Drive::from_name(&t.text("drive", None)?, &format!("{}.drive", t.element))?;
            Ok(MotorSpec {
                name,
                drive,
                inertia: t.num("inertia", Some(0.0))?,
                gear_ratio: t.num("gear_ratio", Some(1.0))?,
                capstan_radius: t.num("capstan_radius", None)?,
                friction: friction(t, 0.1)?,
            })
        })?;
        let cables = each(top.list("cables")?, "cable", CABLE, |t, name| {
            let routing = t
                .list("routing")?
                .iter()
                .enumerate()
                .map(|(k, v)| {
                    let c = Table::new(v, format!("{}.routing[{k}]", t.element), CONTACT)?;
                    Ok(ContactSpec {
                        pulley: c.text("pulley", None)?,
                        wrap: c.num("wrap", None)?,
                        sense: c.num("sense", Some(1.0))?,
                        mu: c.num("mu", Some(0.0))?,
                    })
                })
                .collect::<Result<Vec<_>>>()?;
            let law = CableLaw::from_name(
                &t.text("law", Some("linear"))?,
                t.num("stiffness", None)?,
                t.num("length_scale", Some(1.0))?,
                &t.element,
            )?;
            Ok(CableSpec {
                name,
                routing,
                run: CableRun::new(
                    law,
                    t.num("damping", Some(0.0))?,
                    t.num("pretension", Some(0.0))?,
                    &t.element,
                )?,
                motor: t.optional_text("motor")?,
                motor_sense: t.num("motor_sense", Some(1.0))?,
                end_motor: t.optional_text("end_motor")?,
                end_sense: t.num("end_sense", Some(1.0))?,
                free_length: t.optional_num("free_length")?,
                path: t.map.get("path").map(|v| path(v, &t.element)).transpose()?,
            })
        })?;
        let sensors = each(top.list("sensors")?, "sensor", SENSOR, |t, name| {
            Ok(SensorSpec {
                name,
                kind: t.text("kind", None)?,
                target: t.text("target", None)?,
                at: t.text("at", Some("motor"))?,
            })
        })?;
        Ok(Self {
            bodies,
            joints,
            pulleys,
            cables,
            motors,
            sensors,
            capstan_smoothing: top.num("capstan_smoothing", Some(DEFAULT_CAPSTAN_SMOOTHING))?,
            signals: match top.map.get("signals") {
                None => Vec::new(),
                Some(v) => v
                    .as_array()
                    .and_then(|a| a.iter().map(|s| s.as_str().map(str::to_owned)).collect())
                    .ok_or_else(|| {
                        invalid(
                            "network file.signals".into(),
                            "must be a list of signal names (strings)",
                        )
                    })?,
            },
        })
    }
}
