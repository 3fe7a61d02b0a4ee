//! The network: dense layers between `mapminmax` maps, single-sample and batch evaluation.

use std::collections::BTreeMap;
use std::sync::{Mutex, TryLockError};

use rayon::prelude::*;

use super::{Activation, MapMinMax};
use crate::error::{check, CableError, Result, WeightsErrorKind};
use crate::lanes::{cpu_has_avx2, Lanes, LANES};

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
type Block = Lanes;

/// A layer as evaluated: outputs grouped in zero-padded blocks of four, each block's weights
/// stored input by input (`(blocks, n_in)` of `[f64; 4]`), so a block accumulates in
/// registers over the inputs with a fixed-length multiply-add across SIMD lanes, as two
/// partial sums `(b + w₀x₀ + w₂x₂ + …) + (w₁x₁ + w₃x₃ + …)`, and goes through the activation
/// while still in registers. The affine maps around the layer (input normalisation, the
/// activation's argument scaling, output de-normalisation) are folded into its weights, which
/// takes their latency off the real-time path.
#[derive(Debug, Clone, PartialEq)]
struct Dense {
    weight_b: Vec<Block>,
    bias: Vec<Block>,
    n_in: usize,
    blocks: usize,
    activation: Activation,
}

impl Dense {
    /// Fold inputs `aᵢ = gᵢ·uᵢ + dᵢ` and net inputs `z′ⱼ = sⱼ·zⱼ + tⱼ` into the layer:
    /// `z′ⱼ = Σᵢ (sⱼ Wⱼᵢ gᵢ) uᵢ + sⱼ (bⱼ + Σᵢ Wⱼᵢ dᵢ) + tⱼ`. Every product is one rounding
    /// of a stored value (no cancellation is introduced: `uᵢ` stays the centred input).
    fn new(layer: &Layer, g: &[f64], d: &[f64], s: &[f64], t: &[f64]) -> Self {
        let (n_in, n_out) = (layer.n_in, layer.n_out);
        let blocks = n_out.div_ceil(LANES);
        let mut weight_b = vec![[0.0; LANES]; n_in * blocks];
        let mut bias = vec![[0.0; LANES]; blocks];
        for j in 0..n_out {
            let row = &layer.weight[j * n_in..(j + 1) * n_in];
            let shift: f64 = row.iter().zip(d).map(|(w, d)| w * d).sum();
            bias[j / LANES][j % LANES] = s[j] * (layer.bias[j] + shift) + t[j];
            for (i, (w, gi)) in row.iter().zip(g).enumerate() {
                weight_b[(j / LANES) * n_in + i][j % LANES] = s[j] * w * gi;
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

    /// `x` holds the layer's `n_in` inputs; each output block `k` is handed to `emit(k, ·)`
    /// (padding lanes carry σ(0) and are never read as inputs).
    #[inline(always)]
    fn forward(&self, x: &[f64], mut emit: impl FnMut(usize, Block)) {
        let n_in = self.n_in;
        for k in 0..self.blocks {
            let ws = &self.weight_b[k * n_in..(k + 1) * n_in];
            // Two interleaved partial sums halve the add-latency chain of long rows.
            let (mut even, mut odd) = (self.bias[k], [0.0; LANES]);
            let mut pairs = ws.chunks_exact(2).zip(x.chunks_exact(2));
            for (w, xi) in &mut pairs {
                for l in 0..LANES {
                    even[l] += w[0][l] * xi[0];
                    odd[l] += w[1][l] * xi[1];
                }
            }
            if n_in % 2 == 1 {
                let (w, xi) = (ws[n_in - 1], x[n_in - 1]);
                for l in 0..LANES {
                    even[l] += w[l] * xi;
                }
            }
            for l in 0..LANES {
                even[l] += odd[l];
            }
            self.activation.apply_folded(&mut even);
            emit(k, even);
        }
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
    /// De-normalisation `y = a·h + c` when the last layer is not `purelin` (otherwise it is
    /// folded into that layer).
    out_affine: Option<(Vec<Block>, Vec<Block>)>,
    /// Scratch blocks a row needs.
    width: usize,
    /// The CPU has AVX2 (checked once, at construction).
    avx2: bool,
}

impl Net {
    /// Evaluate the `rows` rows of `xs` into the rows of `os`; `a`, `b` hold at least `width`
    /// blocks. On x86-64 CPUs with AVX2 the same code runs compiled for 256-bit lanes (one
    /// block per instruction); the operations and their order are identical, so are the
    /// results, bit for bit (no FMA contraction: Rust never fuses `a + w·x`).
    #[inline]
    fn eval_rows(&self, xs: &[f64], os: &mut [f64], rows: usize, a: &mut [Block], b: &mut [Block]) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when `is_x86_feature_detected!("avx2")` reported the
            // feature on this CPU (see `Net::new`), which is all `eval_rows_avx2` requires.
            #[allow(unsafe_code)]
            unsafe {
                return eval_rows_avx2(self, xs, os, rows, a, b);
            }
        }
        self.eval_rows_portable(xs, os, rows, a, b);
    }

    /// Rows are addressed by multiplication (`chunks_exact` would divide per call).
    #[inline(always)]
    fn eval_rows_portable(
        &self,
        xs: &[f64],
        os: &mut [f64],
        rows: usize,
        a: &mut [Block],
        b: &mut [Block],
    ) {
        let (n0, nl) = (self.input.len(), self.output.len());
        for r in 0..rows {
            self.eval(
                &xs[r * n0..(r + 1) * n0],
                &mut os[r * nl..(r + 1) * nl],
                a,
                b,
            );
        }
    }

    /// Evaluate one row.
    #[inline(always)]
    fn eval(&self, x: &[f64], out: &mut [f64], a: &mut [Block], b: &mut [Block]) {
        // The centred input; the gain and the −1 of `mapminmax` are in the first layer.
        for ((u, v), lo) in a.as_flattened_mut().iter_mut().zip(x).zip(&self.input.min) {
            *u = v - lo;
        }
        let (mut cur, mut nxt) = (a, b);
        let mut n_in = x.len();
        let (hidden, last) = self.dense.split_at(self.dense.len() - 1);
        for (layer, dense) in self.layers.iter().zip(hidden) {
            dense.forward(&cur.as_flattened()[..n_in], |k, v| nxt[k] = v);
            n_in = layer.n_out;
            std::mem::swap(&mut cur, &mut nxt);
        }
        // The last layer writes `out` directly: whole blocks as one store, the tail by lanes.
        let write = |out: &mut [f64], k: usize, v: Block| {
            let end = out.len().min((k + 1) * LANES);
            let lanes = &mut out[k * LANES..end];
            match <&mut Block>::try_from(&mut *lanes) {
                Ok(full) => *full = v,
                Err(_) => lanes.iter_mut().zip(v).for_each(|(o, v)| *o = v),
            }
        };
        let x_last = &cur.as_flattened()[..n_in];
        match &self.out_affine {
            None => last[0].forward(x_last, |k, v| write(out, k, v)),
            Some((h, c)) => last[0].forward(x_last, |k, v| {
                write(out, k, std::array::from_fn(|l| v[l] * h[k][l] + c[k][l]));
            }),
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn eval_rows_avx2(
    net: &Net,
    xs: &[f64],
    os: &mut [f64],
    rows: usize,
    a: &mut [Block],
    b: &mut [Block],
) {
    net.eval_rows_portable(xs, os, rows, a, b);
}

/// A multilayer perceptron with `mapminmax` normalisation, ready for real-time evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct Mlp {
    net: Net,
    info: MlpInfo,
    scratch: Scratch,
}

/// Work buffers of one single-sample evaluation ([`Mlp::forward_with`]): a caller that shares
/// one network between threads keeps one per thread.
#[derive(Debug, Clone, PartialEq)]
pub struct Scratch {
    a: Vec<Block>,
    b: Vec<Block>,
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
        range_bound(&layers, &output)?;
        let dense = fold_layers(&layers, &input, &output);
        for (l, d) in dense.iter().enumerate() {
            let flat = |v: &[Block]| v.iter().flatten().copied().collect::<Vec<f64>>();
            finite_values(&format!("layers.{l}.weight"), &flat(&d.weight_b))
                .and(finite_values(&format!("layers.{l}.bias"), &flat(&d.bias)))
                .map_err(|_| {
                    weights_err(
                        Value,
                        format!("layers.{l}.weight"),
                        "overflows once the input normalisation is folded in (weights or \
                         input range too extreme)"
                            .into(),
                    )
                })?;
        }
        let out_affine = (layers[layers.len() - 1].activation != Activation::Purelin).then(|| {
            let (h, c) = denormalisation(&output);
            (blocks_of(&h), blocks_of(&c))
        });
        Ok(Self {
            net: Net {
                dense,
                out_affine,
                layers,
                input,
                output,
                width,
                avx2: cpu_has_avx2(),
            },
            info,
            scratch: Scratch {
                a: vec![[0.0; LANES]; width],
                b: vec![[0.0; LANES]; width],
            },
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
    /// a wrong length or a non-finite input is an error and leaves `out` untouched; an input so
    /// far outside the training range that an output overflows is
    /// [`CableError::NonFiniteResult`] (`out` then holds the overflowed values).
    pub fn forward(&mut self, x: &[f64], out: &mut [f64]) -> Result<()> {
        let Self { net, scratch, .. } = self;
        forward_one(net, x, out, scratch)
    }

    /// [`Mlp::forward`] on a shared network with the caller's work buffers ([`Mlp::scratch`]).
    pub fn forward_with(&self, x: &[f64], out: &mut [f64], scratch: &mut Scratch) -> Result<()> {
        forward_one(&self.net, x, out, scratch)
    }

    /// [`Mlp::forward_with`] for threads sharing one set of work buffers: a thread that finds
    /// them in use takes fresh ones (one small allocation) instead of waiting, so a front end
    /// holding a global lock never deadlocks on them.
    pub fn forward_shared(
        &self,
        x: &[f64],
        out: &mut [f64],
        shared: &Mutex<Scratch>,
    ) -> Result<()> {
        match shared.try_lock() {
            Ok(mut s) => self.forward_with(x, out, &mut s),
            Err(TryLockError::Poisoned(p)) => self.forward_with(x, out, &mut p.into_inner()),
            Err(TryLockError::WouldBlock) => self.forward_with(x, out, &mut self.scratch()),
        }
    }

    /// Fresh work buffers for [`Mlp::forward_with`].
    pub fn scratch(&self) -> Scratch {
        self.scratch.clone()
    }

    /// [`Mlp::forward`] forced onto the portable (non-AVX2) path, to test that both agree.
    #[cfg(test)]
    pub(super) fn forward_portable(&mut self, x: &[f64], out: &mut [f64]) {
        self.net
            .eval_rows_portable(x, out, 1, &mut self.scratch.a, &mut self.scratch.b);
    }

    /// Rows of `x` `(N, n⁰)` row-major → rows of `out` `(N, nᴸ)`. Parallel (rayon) for
    /// `N ≥ PARALLEL_MIN_ROWS`. Checks shapes and finiteness first; on those errors `out` is
    /// untouched. An overflowed output is [`CableError::NonFiniteResult`] with its row.
    pub fn forward_batch(&self, x: &[f64], out: &mut [f64]) -> Result<()> {
        let (n0, nl) = (self.n_inputs(), self.n_outputs());
        let rows = x.len() / n0;
        if !x.len().is_multiple_of(n0) {
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
            self.net.eval_rows(xs, os, os.len() / nl, &mut a, &mut b);
        };
        if rows >= PARALLEL_MIN_ROWS {
            x.par_chunks(CHUNK_ROWS * n0)
                .zip(out.par_chunks_mut(CHUNK_ROWS * nl))
                .for_each(|(xs, os)| run(xs, os));
        } else {
            run(x, out);
        }
        check::result_finite("prediction", out, nl, OVERFLOW_HINT)
    }
}

/// One sample through `net` (see [`Mlp::forward`]).
fn forward_one(net: &Net, x: &[f64], out: &mut [f64], scratch: &mut Scratch) -> Result<()> {
    check::len("x", x, net.input.len())?;
    check::len("out", out, net.layers[net.layers.len() - 1].n_out)?;
    check::all_finite("x", x, 1)?;
    if scratch.a.len() != net.width || scratch.b.len() != net.width {
        return Err(CableError::Shape {
            what: "scratch".into(),
            expected: format!(
                "buffers of {} blocks (Mlp::scratch of this network)",
                net.width
            ),
            got: format!("{} and {}", scratch.a.len(), scratch.b.len()),
        });
    }
    net.eval_rows(x, out, 1, &mut scratch.a, &mut scratch.b);
    check::result_finite("prediction", out, 1, OVERFLOW_HINT)
}

/// What to do about a prediction that overflowed.
const OVERFLOW_HINT: &str = "an input is too far outside the network's training range";

/// Every input inside the training range must give finite outputs: with normalised inputs in
/// [−1, 1], each neuron's net input is bounded by `Σᵢ |Wⱼᵢ|·|aᵢ| + |bⱼ|`, `tansig` and
/// `logsig` outputs by 1, `purelin` outputs by their net input; the last bound, de-normalised,
/// must be finite. A file whose finite weights overflow on the data it was trained for is
/// refused at load, not discovered as NaN predictions.
fn range_bound(layers: &[Layer], output: &MapMinMax) -> Result<()> {
    let mut a = vec![1.0; layers[0].n_in];
    for (l, layer) in layers.iter().enumerate() {
        let z: Vec<f64> = (0..layer.n_out)
            .map(|j| {
                let row = &layer.weight[j * layer.n_in..(j + 1) * layer.n_in];
                row.iter().zip(&a).map(|(w, b)| w.abs() * b).sum::<f64>() + layer.bias[j].abs()
            })
            .collect();
        if let Some(j) = z.iter().position(|v| !v.is_finite()) {
            return Err(weights_err(
                WeightsErrorKind::Value,
                format!("layers.{l}.weight"),
                format!("neuron {j}'s net input overflows for inputs inside the training range"),
            ));
        }
        a = match layer.activation {
            Activation::Purelin => z,
            Activation::Tansig | Activation::Logsig => vec![1.0; layer.n_out],
        };
    }
    let bound: Vec<f64> = a
        .iter()
        .zip(output.gain())
        .zip(&output.min)
        .map(|((v, g), lo)| (v + 1.0) / g + lo.abs())
        .collect();
    finite_values("output.max", &bound).map_err(|_| {
        weights_err(
            WeightsErrorKind::Value,
            "output.max",
            "de-normalised outputs overflow for inputs inside the training range".into(),
        )
    })
}

/// The evaluated layers with the affine maps folded in (see [`Dense::new`]): the first layer
/// takes `x − x_min` and applies `mapminmax`'s gain and −1; each layer scales its net input
/// to the argument of `exp`; a `purelin` last layer also de-normalises its output,
/// `y = (a + 1)·h + y_min` with `h = 1/g`.
fn fold_layers(layers: &[Layer], input: &MapMinMax, output: &MapMinMax) -> Vec<Dense> {
    let last = layers.len() - 1;
    layers
        .iter()
        .enumerate()
        .map(|(l, layer)| {
            let (g, d) = if l == 0 {
                (input.gain().to_vec(), vec![-1.0; layer.n_in])
            } else {
                (vec![1.0; layer.n_in], vec![0.0; layer.n_in])
            };
            let (s, t) = if l == last && layer.activation == Activation::Purelin {
                denormalisation(output)
            } else {
                let f = layer.activation.fold_factor();
                (vec![f; layer.n_out], vec![0.0; layer.n_out])
            };
            Dense::new(layer, &g, &d, &s, &t)
        })
        .collect()
}

/// `mapminmax`'s reverse as `y = a·h + c`: `h = 1/g`, `c = h + y_min`.
fn denormalisation(output: &MapMinMax) -> (Vec<f64>, Vec<f64>) {
    let h: Vec<f64> = output.gain().iter().map(|g| 1.0 / g).collect();
    let c = h.iter().zip(&output.min).map(|(h, lo)| h + lo).collect();
    (h, c)
}

/// Values in zero-padded blocks of four.
fn blocks_of(v: &[f64]) -> Vec<Block> {
    v.chunks(LANES)
        .map(|c| std::array::from_fn(|l| c.get(l).copied().unwrap_or(0.0)))
        .collect()
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
