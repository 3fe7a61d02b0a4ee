//! The network: dense layers between `mapminmax` maps, single-sample and batch evaluation.

use std::collections::BTreeMap;

use rayon::prelude::*;

use super::{Activation, MapMinMax};
use crate::error::{check, CableError, Result, WeightsErrorKind};

/// Batches with at least this many rows are split across rayon's threads.
pub const PARALLEL_MIN_ROWS: usize = 4096;
/// Rows per parallel work item (large enough to amortise the per-item scratch).
const CHUNK_ROWS: usize = 2048;

/// One dense layer `a_out = σ(W a_in + b)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Layer {
    /// Weights, row-major `(n_out, n_in)` (torch's `Linear.weight` layout).
    pub weight: Vec<f64>,
    /// Biases `(n_out,)`.
    pub bias: Vec<f64>,
    /// Inputs of the layer.
    pub n_in: usize,
    /// Outputs (neurons) of the layer.
    pub n_out: usize,
    /// Transfer function.
    pub activation: Activation,
}

/// SIMD block: outputs are processed four at a time.
const LANES: usize = 4;
type Block = [f64; LANES];

/// A layer as evaluated: outputs grouped in zero-padded blocks of four, each block's weights
/// stored input by input (`(blocks, n_in)` of `[f64; 4]`), so a block accumulates in
/// registers over the inputs with a fixed-length multiply-add across SIMD lanes, as two
/// partial sums `(b + w₀x₀ + w₂x₂ + …) + (w₁x₁ + w₃x₃ + …)`.
#[derive(Debug, Clone, PartialEq)]
struct Dense {
    weight_b: Vec<Block>,
    bias: Vec<Block>,
    n_in: usize,
    blocks: usize,
    activation: Activation,
}

impl Dense {
    fn new(layer: &Layer) -> Self {
        let (n_in, n_out) = (layer.n_in, layer.n_out);
        let blocks = n_out.div_ceil(LANES);
        let mut weight_b = vec![[0.0; LANES]; n_in * blocks];
        let mut bias = vec![[0.0; LANES]; blocks];
        for j in 0..n_out {
            bias[j / LANES][j % LANES] = layer.bias[j];
            for i in 0..n_in {
                weight_b[(j / LANES) * n_in + i][j % LANES] = layer.weight[j * n_in + i];
            }
        }
        Self {
            weight_b,
            bias,
            n_in,
            blocks,
            activation: layer.activation,
        }
    }

    /// `x` holds the layer's `n_in` inputs; `out` its `blocks` output blocks (padding lanes
    /// carry σ(0) and are never read as inputs).
    #[inline(always)]
    fn forward(&self, x: &[f64], out: &mut [Block]) {
        for ((o, b), ws) in out
            .iter_mut()
            .zip(&self.bias)
            .zip(self.weight_b.chunks_exact(self.n_in))
        {
            // Two interleaved partial sums halve the add-latency chain of long rows.
            let (mut even, mut odd) = (*b, [0.0; LANES]);
            let mut pairs = ws.chunks_exact(2).zip(x.chunks_exact(2));
            for (w, xi) in &mut pairs {
                for l in 0..LANES {
                    even[l] += w[0][l] * xi[0];
                    odd[l] += w[1][l] * xi[1];
                }
            }
            if ws.len() % 2 == 1 {
                let (w, xi) = (ws[ws.len() - 1], x[ws.len() - 1]);
                for l in 0..LANES {
                    even[l] += w[l] * xi;
                }
            }
            for l in 0..LANES {
                o[l] = even[l] + odd[l];
            }
        }
        self.activation.apply(out.as_flattened_mut());
    }
}

/// Names, units and free-form metadata carried with a network (all optional for evaluation).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MlpInfo {
    /// Input feature names, e.g. `["x_m_a", "v_m_a", …]`.
    pub input_names: Vec<String>,
    /// Input units, e.g. `["m", "m/s", …]`.
    pub input_units: Vec<String>,
    /// Output names.
    pub output_names: Vec<String>,
    /// Output units.
    pub output_units: Vec<String>,
    /// Every `__metadata__` entry of the file, verbatim (training method, data hash, version …).
    pub metadata: BTreeMap<String, String>,
}

/// The immutable part: layers and normalisation.
#[derive(Debug, Clone, PartialEq)]
struct Net {
    layers: Vec<Layer>,
    dense: Vec<Dense>,
    input: MapMinMax,
    output: MapMinMax,
    /// Scratch blocks a row needs.
    width: usize,
    /// The CPU has AVX2 (checked once, at construction).
    avx2: bool,
}

impl Net {
    /// Evaluate the rows of `xs` into the rows of `os`; `a`, `b` hold at least `width`
    /// blocks. On x86-64 CPUs with AVX2 the same code runs compiled for 256-bit lanes (one
    /// block per instruction); the operations and their order are identical, so are the
    /// results, bit for bit (no FMA contraction: Rust never fuses `a + w·x`).
    #[inline]
    fn eval_rows(&self, xs: &[f64], os: &mut [f64], a: &mut [Block], b: &mut [Block]) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when `is_x86_feature_detected!("avx2")` reported the
            // feature on this CPU (see `Net::new`), which is all `eval_rows_avx2` requires.
            #[allow(unsafe_code)]
            unsafe {
                return eval_rows_avx2(self, xs, os, a, b);
            }
        }
        self.eval_rows_portable(xs, os, a, b);
    }

    #[inline(always)]
    fn eval_rows_portable(&self, xs: &[f64], os: &mut [f64], a: &mut [Block], b: &mut [Block]) {
        let (n0, nl) = (self.input.len(), self.output.len());
        for (x, out) in xs.chunks_exact(n0).zip(os.chunks_exact_mut(nl)) {
            self.eval(x, out, a, b);
        }
    }

    /// Evaluate one row.
    #[inline(always)]
    fn eval(&self, x: &[f64], out: &mut [f64], a: &mut [Block], b: &mut [Block]) {
        let n0 = self.input.len();
        self.input.apply(x, &mut a.as_flattened_mut()[..n0]);
        let (mut cur, mut nxt) = (a, b);
        let mut n_in = n0;
        for (layer, dense) in self.layers.iter().zip(&self.dense) {
            dense.forward(&cur.as_flattened()[..n_in], &mut nxt[..dense.blocks]);
            n_in = layer.n_out;
            std::mem::swap(&mut cur, &mut nxt);
        }
        self.output
            .reverse(&cur.as_flattened()[..self.output.len()], out);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn eval_rows_avx2(net: &Net, xs: &[f64], os: &mut [f64], a: &mut [Block], b: &mut [Block]) {
    net.eval_rows_portable(xs, os, a, b);
}

/// A multilayer perceptron with `mapminmax` normalisation, ready for real-time evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct Mlp {
    net: Net,
    info: MlpInfo,
    scratch_a: Vec<Block>,
    scratch_b: Vec<Block>,
}

fn weights_err(kind: WeightsErrorKind, item: impl Into<String>, reason: String) -> CableError {
    CableError::Weights {
        kind,
        item: item.into(),
        reason,
    }
}

impl Mlp {
    /// Assemble and validate a network. Layer sizes must chain (`layers[l].n_in ==
    /// layers[l-1].n_out`), the normalisations must match the first input and last output
    /// sizes, every value must be finite and every range ordered (`min ≤ max`); name and unit
    /// lists, when given, must have one entry per feature.
    pub fn new(
        layers: Vec<Layer>,
        input: MapMinMax,
        output: MapMinMax,
        info: MlpInfo,
    ) -> Result<Self> {
        use WeightsErrorKind::{Metadata, Shape, Value};
        if layers.is_empty() {
            return Err(weights_err(
                Shape,
                "layers",
                "a network needs at least one layer".into(),
            ));
        }
        for (l, layer) in layers.iter().enumerate() {
            let expect_in = if l == 0 {
                input.len()
            } else {
                layers[l - 1].n_out
            };
            let name = format!("layers.{l}.weight");
            if layer.n_in != expect_in || layer.n_in == 0 || layer.n_out == 0 {
                return Err(weights_err(
                    Shape,
                    name,
                    format!(
                        "has {} inputs, the previous stage gives {expect_in}",
                        layer.n_in
                    ),
                ));
            }
            if layer.weight.len() != layer.n_in * layer.n_out {
                return Err(weights_err(
                    Shape,
                    name,
                    format!(
                        "holds {} values, ({}, {}) needs {}",
                        layer.weight.len(),
                        layer.n_out,
                        layer.n_in,
                        layer.n_in * layer.n_out
                    ),
                ));
            }
            if layer.bias.len() != layer.n_out {
                return Err(weights_err(
                    Shape,
                    format!("layers.{l}.bias"),
                    format!("has {} values, expected {}", layer.bias.len(), layer.n_out),
                ));
            }
            for (what, data) in [
                (name, &layer.weight),
                (format!("layers.{l}.bias"), &layer.bias),
            ] {
                finite_values(&what, data)?;
            }
        }
        let last = layers[layers.len() - 1].n_out;
        if output.len() != last {
            return Err(weights_err(
                Shape,
                "output.min",
                format!("has {} features, the last layer gives {last}", output.len()),
            ));
        }
        for (side, map) in [("input", &input), ("output", &output)] {
            finite_values(&format!("{side}.min"), &map.min)?;
            finite_values(&format!("{side}.max"), &map.max)?;
            if let Some(i) = map.min.iter().zip(&map.max).position(|(lo, hi)| hi < lo) {
                return Err(weights_err(
                    Value,
                    format!("{side}.max"),
                    format!(
                        "range of feature {i} is reversed (max {} < min {})",
                        map.max[i], map.min[i]
                    ),
                ));
            }
        }
        for (key, names, n) in [
            ("input_names", &info.input_names, input.len()),
            ("input_units", &info.input_units, input.len()),
            ("output_names", &info.output_names, last),
            ("output_units", &info.output_units, last),
        ] {
            if !names.is_empty() && names.len() != n {
                return Err(weights_err(
                    Metadata,
                    key,
                    format!("lists {} entries for {n} features", names.len()),
                ));
            }
        }
        let width = layers
            .iter()
            .map(|l| l.n_out)
            .chain([input.len()])
            .max()
            .unwrap_or(0)
            .div_ceil(LANES);
        Ok(Self {
            net: Net {
                dense: layers.iter().map(Dense::new).collect(),
                layers,
                input,
                output,
                width,
                avx2: cpu_has_avx2(),
            },
            info,
            scratch_a: vec![[0.0; LANES]; width],
            scratch_b: vec![[0.0; LANES]; width],
        })
    }

    /// Number of inputs.
    pub fn n_inputs(&self) -> usize {
        self.net.input.len()
    }

    /// Number of outputs.
    pub fn n_outputs(&self) -> usize {
        self.net.output.len()
    }

    /// Layer sizes `[n⁰, n¹, …, nᴸ]`.
    pub fn sizes(&self) -> Vec<usize> {
        std::iter::once(self.n_inputs())
            .chain(self.net.layers.iter().map(|l| l.n_out))
            .collect()
    }

    /// The layers, input first.
    pub fn layers(&self) -> &[Layer] {
        &self.net.layers
    }

    /// Input normalisation.
    pub fn input_map(&self) -> &MapMinMax {
        &self.net.input
    }

    /// Output normalisation.
    pub fn output_map(&self) -> &MapMinMax {
        &self.net.output
    }

    /// Names, units and metadata.
    pub fn info(&self) -> &MlpInfo {
        &self.info
    }

    /// One sample: `x` `(n⁰,)` physical inputs → `out` `(nᴸ,)` physical outputs. No allocation;
    /// a wrong length or a non-finite input is an error and leaves `out` untouched.
    pub fn forward(&mut self, x: &[f64], out: &mut [f64]) -> Result<()> {
        check::len("x", x, self.n_inputs())?;
        check::len("out", out, self.n_outputs())?;
        check::all_finite("x", x, 1)?;
        self.net
            .eval_rows(x, out, &mut self.scratch_a, &mut self.scratch_b);
        Ok(())
    }

    /// Rows of `x` `(N, n⁰)` row-major → rows of `out` `(N, nᴸ)`. Parallel (rayon) for
    /// `N ≥ PARALLEL_MIN_ROWS`. Checks shapes and finiteness first; on error `out` is untouched.
    pub fn forward_batch(&self, x: &[f64], out: &mut [f64]) -> Result<()> {
        let (n0, nl) = (self.n_inputs(), self.n_outputs());
        let rows = x.len() / n0;
        if x.len() % n0 != 0 {
            return Err(CableError::Shape {
                what: "x".into(),
                expected: format!("(N, {n0})"),
                got: format!("{} values", x.len()),
            });
        }
        if out.len() != rows * nl {
            return Err(CableError::Shape {
                what: "out".into(),
                expected: format!("({rows}, {nl})"),
                got: format!("{} values", out.len()),
            });
        }
        let bad = if rows >= PARALLEL_MIN_ROWS {
            const SPAN: usize = 1 << 16;
            x.par_chunks(SPAN).enumerate().find_map_first(|(c, xs)| {
                xs.iter().position(|v| !v.is_finite()).map(|i| c * SPAN + i)
            })
        } else {
            x.iter().position(|v| !v.is_finite())
        };
        if let Some(index) = bad {
            return Err(CableError::NotFinite {
                what: "x".into(),
                index,
                value: x[index],
                location: format!(" (row {}, column {})", index / n0, index % n0),
            });
        }
        let run = |xs: &[f64], os: &mut [f64]| {
            let mut a = vec![[0.0; LANES]; self.net.width];
            let mut b = vec![[0.0; LANES]; self.net.width];
            self.net.eval_rows(xs, os, &mut a, &mut b);
        };
        if rows >= PARALLEL_MIN_ROWS {
            x.par_chunks(CHUNK_ROWS * n0)
                .zip(out.par_chunks_mut(CHUNK_ROWS * nl))
                .for_each(|(xs, os)| run(xs, os));
        } else {
            run(x, out);
        }
        Ok(())
    }
}

fn cpu_has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

fn finite_values(what: &str, data: &[f64]) -> Result<()> {
    match data.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(weights_err(
            WeightsErrorKind::Value,
            what,
            format!("value {} at flat index {i} is not finite", data[i]),
        )),
    }
}
