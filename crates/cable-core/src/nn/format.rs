//! The weight file: a safetensors file (no pickle) written by `cablekit.nn.export`.
//!
//! Tensors (all `F64`, little-endian):
//!
//! | name | shape |
//! |---|---|
//! | `layers.{l}.weight` | `(nˡ⁺¹, nˡ)`, torch's `Linear.weight` layout |
//! | `layers.{l}.bias` | `(nˡ⁺¹,)` |
//! | `input.min`, `input.max` | `(n⁰,)`: `mapminmax` training range of the inputs |
//! | `output.min`, `output.max` | `(nᴸ,)`: training range of the outputs |
//!
//! `__metadata__` (string → string, as safetensors requires):
//!
//! | key | value |
//! |---|---|
//! | `format` | `cablekit-mlp` (required) |
//! | `format_version` | `1` (required) |
//! | `architecture` | JSON `{"sizes": [4, 10, 4], "activations": ["tansig", "purelin"]}` (required) |
//! | `normalization` | `mapminmax` (the four range tensors are required) or `none` (required) |
//! | `input_names`, `input_units`, `output_names`, `output_units` | JSON lists of strings, one per feature |
//! | `training_data_sha256`, `cablekit_version`, `training` | provenance, kept verbatim |
//!
//! Any other tensor in the file is an error: a file that does not match its own architecture
//! is more likely a mix-up than something to ignore.

use std::collections::{BTreeMap, HashSet};

use safetensors::tensor::{Dtype, SafeTensors, TensorView};

use super::{Activation, Layer, MapMinMax, Mlp, MlpInfo};
use crate::error::{CableError, Result, WeightsErrorKind};

/// Value of the `format` metadata key.
pub const FORMAT: &str = "cablekit-mlp";
/// Value of the `format_version` metadata key this build reads and writes.
pub const FORMAT_VERSION: &str = "1";

fn err(kind: WeightsErrorKind, item: &str, reason: impl Into<String>) -> CableError {
    CableError::Weights {
        kind,
        item: item.to_owned(),
        reason: reason.into(),
    }
}

fn required<'a>(md: &'a std::collections::HashMap<String, String>, key: &str) -> Result<&'a str> {
    md.get(key).map(String::as_str).ok_or_else(|| {
        err(
            WeightsErrorKind::Metadata,
            key,
            "required metadata key is missing",
        )
    })
}

fn string_list(md: &std::collections::HashMap<String, String>, key: &str) -> Result<Vec<String>> {
    match md.get(key) {
        None => Ok(Vec::new()),
        Some(text) => serde_json::from_str::<Vec<String>>(text).map_err(|e| {
            err(
                WeightsErrorKind::Metadata,
                key,
                format!("must be a JSON list of strings: {e}"),
            )
        }),
    }
}

fn architecture(text: &str) -> Result<(Vec<usize>, Vec<Activation>)> {
    let bad = |why: String| err(WeightsErrorKind::Metadata, "architecture", why);
    let value: serde_json::Value =
        serde_json::from_str(text).map_err(|e| bad(format!("not valid JSON: {e}")))?;
    let sizes: Vec<usize> = value
        .get("sizes")
        .and_then(|v| serde_json::from_value(v.clone()).ok())
        .ok_or_else(|| bad("needs \"sizes\": a list of positive integers".into()))?;
    let names: Vec<String> = value
        .get("activations")
        .and_then(|v| serde_json::from_value(v.clone()).ok())
        .ok_or_else(|| bad("needs \"activations\": a list of names".into()))?;
    if sizes.len() < 2 || sizes.contains(&0) {
        return Err(bad(format!(
            "sizes {sizes:?} must list at least an input and an output size, all > 0"
        )));
    }
    if names.len() != sizes.len() - 1 {
        return Err(bad(format!(
            "{} activations for {} layers",
            names.len(),
            sizes.len() - 1
        )));
    }
    let acts = names
        .iter()
        .map(|n| Activation::parse(n, "architecture"))
        .collect::<Result<Vec<_>>>()?;
    Ok((sizes, acts))
}

/// Read a tensor as `f64` values of the given shape; missing, wrong dtype or wrong shape are
/// errors naming the tensor.
fn tensor(st: &SafeTensors<'_>, name: &str, shape: &[usize]) -> Result<Vec<f64>> {
    let view = st.tensor(name).map_err(|_| {
        err(
            WeightsErrorKind::Shape,
            name,
            format!("tensor is missing (expected shape {shape:?})"),
        )
    })?;
    if view.dtype() != Dtype::F64 {
        return Err(err(
            WeightsErrorKind::Corrupt,
            name,
            format!("dtype is {:?}, cablekit stores F64", view.dtype()),
        ));
    }
    if view.shape() != shape {
        return Err(err(
            WeightsErrorKind::Shape,
            name,
            format!(
                "shape {:?} disagrees with the architecture, which needs {shape:?}",
                view.shape()
            ),
        ));
    }
    Ok(view
        .data()
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().expect("chunks of 8 bytes")))
        .collect())
}

/// Parse and validate a weight file held in memory.
pub fn read(bytes: &[u8]) -> Result<Mlp> {
    use WeightsErrorKind::{Corrupt, Metadata, Shape};
    let st = SafeTensors::deserialize(bytes).map_err(|e| {
        err(
            Corrupt,
            "file",
            format!("not a readable safetensors file: {e}"),
        )
    })?;
    let (_, header) = SafeTensors::read_metadata(bytes).map_err(|e| {
        err(
            Corrupt,
            "file",
            format!("not a readable safetensors file: {e}"),
        )
    })?;
    let md = header.metadata().as_ref().ok_or_else(|| {
        err(
            Metadata,
            "__metadata__",
            "missing: not a cablekit network file (export with cablekit.nn.export)",
        )
    })?;
    let format = required(md, "format")?;
    if format != FORMAT {
        return Err(err(
            Metadata,
            "format",
            format!("is {format:?}, expected {FORMAT:?}"),
        ));
    }
    let version = required(md, "format_version")?;
    if version != FORMAT_VERSION {
        return Err(err(
            Metadata,
            "format_version",
            format!(
                "version {version:?} is not supported by this build (reads {FORMAT_VERSION:?})"
            ),
        ));
    }
    let (sizes, acts) = architecture(required(md, "architecture")?)?;
    let mut expected: HashSet<String> = HashSet::new();
    let mut layers = Vec::with_capacity(acts.len());
    for (l, act) in acts.iter().enumerate() {
        let (n_in, n_out) = (sizes[l], sizes[l + 1]);
        let (wn, bn) = (format!("layers.{l}.weight"), format!("layers.{l}.bias"));
        layers.push(Layer {
            weight: tensor(&st, &wn, &[n_out, n_in])?,
            bias: tensor(&st, &bn, &[n_out])?,
            n_in,
            n_out,
            activation: *act,
        });
        expected.extend([wn, bn]);
    }
    let (n0, nl) = (sizes[0], sizes[sizes.len() - 1]);
    let (input, output) = match required(md, "normalization")? {
        "mapminmax" => {
            let names = ["input.min", "input.max", "output.min", "output.max"];
            expected.extend(names.iter().map(|s| s.to_string()));
            (
                MapMinMax::new(tensor(&st, names[0], &[n0])?, tensor(&st, names[1], &[n0])?),
                MapMinMax::new(tensor(&st, names[2], &[nl])?, tensor(&st, names[3], &[nl])?),
            )
        }
        "none" => (MapMinMax::identity(n0), MapMinMax::identity(nl)),
        other => {
            return Err(err(
                Metadata,
                "normalization",
                format!("is {other:?}, expected \"mapminmax\" or \"none\""),
            ))
        }
    };
    let mut extra: Vec<String> = st
        .names()
        .into_iter()
        .filter(|n| !expected.contains(*n))
        .map(str::to_owned)
        .collect();
    extra.sort();
    if let Some(first) = extra.first() {
        return Err(err(
            Shape,
            first,
            format!(
                "unexpected tensor (the architecture {sizes:?} does not use it; extra: {extra:?})"
            ),
        ));
    }
    let info = MlpInfo {
        input_names: string_list(md, "input_names")?,
        input_units: string_list(md, "input_units")?,
        output_names: string_list(md, "output_names")?,
        output_units: string_list(md, "output_units")?,
        metadata: md.iter().map(|(k, v)| (k.clone(), v.clone())).collect(),
    };
    Mlp::new(layers, input, output, info)
}

/// Serialise a network (with `mapminmax` normalisation) and its metadata. Keys this module
/// owns (`format`, `architecture`, names, …) are written from the network; other entries of
/// `info.metadata` are kept.
pub fn write(mlp: &Mlp) -> Result<Vec<u8>> {
    let mut md: BTreeMap<String, String> = mlp.info().metadata.clone();
    let acts: Vec<&str> = mlp.layers().iter().map(|l| l.activation.name()).collect();
    let json = |v: serde_json::Value| v.to_string();
    md.insert("format".into(), FORMAT.into());
    md.insert("format_version".into(), FORMAT_VERSION.into());
    md.insert(
        "architecture".into(),
        json(serde_json::json!({"sizes": mlp.sizes(), "activations": acts})),
    );
    md.insert("normalization".into(), "mapminmax".into());
    let info = mlp.info();
    for (key, list) in [
        ("input_names", &info.input_names),
        ("input_units", &info.input_units),
        ("output_names", &info.output_names),
        ("output_units", &info.output_units),
    ] {
        if !list.is_empty() {
            md.insert(key.into(), json(serde_json::json!(list)));
        }
    }
    let bytes = |v: &[f64]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let mut owned: Vec<(String, Vec<usize>, Vec<u8>)> = Vec::new();
    for (l, layer) in mlp.layers().iter().enumerate() {
        owned.push((
            format!("layers.{l}.weight"),
            vec![layer.n_out, layer.n_in],
            bytes(&layer.weight),
        ));
        owned.push((
            format!("layers.{l}.bias"),
            vec![layer.n_out],
            bytes(&layer.bias),
        ));
    }
    for (side, map) in [("input", mlp.input_map()), ("output", mlp.output_map())] {
        owned.push((format!("{side}.min"), vec![map.len()], bytes(&map.min)));
        owned.push((format!("{side}.max"), vec![map.len()], bytes(&map.max)));
    }
    let views = owned
        .iter()
        .map(|(name, shape, data)| {
            TensorView::new(Dtype::F64, shape.clone(), data)
                .map(|v| (name.clone(), v))
                .map_err(|e| err(WeightsErrorKind::Corrupt, name, e.to_string()))
        })
        .collect::<Result<Vec<_>>>()?;
    safetensors::tensor::serialize(views, Some(md.into_iter().collect()))
        .map_err(|e| err(WeightsErrorKind::Corrupt, "file", e.to_string()))
}

impl Mlp {
    /// Load from the bytes of a safetensors weight file (see [`format`](self)).
    pub fn from_safetensors(bytes: &[u8]) -> Result<Self> {
        read(bytes)
    }

    /// Serialise to safetensors bytes (see [`format`](self)).
    pub fn to_safetensors(&self) -> Result<Vec<u8>> {
        write(self)
    }
}
