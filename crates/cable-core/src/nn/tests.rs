//! Invariants of the network and of its weight file: round trip, batch = single, and one typed
//! error per defect, naming the tensor.

#![allow(clippy::float_cmp)] // round trips and batch = single are exact by design

use std::collections::HashMap;

use safetensors::tensor::{Dtype, TensorView};

use super::*;
use crate::error::{CableError, WeightsErrorKind};

/// Deterministic values in (−1, 1) (64-bit LCG; no dependency).
fn lcg(seed: u64, n: usize) -> Vec<f64> {
    let mut s = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (0..n)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        })
        .collect()
}

fn net(sizes: &[usize], acts: &[Activation], seed: u64) -> Mlp {
    let layers = acts
        .iter()
        .enumerate()
        .map(|(l, &activation)| Layer {
            weight: lcg(seed + l as u64, sizes[l] * sizes[l + 1]),
            bias: lcg(seed + 100 + l as u64, sizes[l + 1]),
            n_in: sizes[l],
            n_out: sizes[l + 1],
            activation,
        })
        .collect();
    let n0 = sizes[0];
    let nl = sizes[sizes.len() - 1];
    let input = MapMinMax::new(vec![-2.0; n0], (0..n0).map(|i| 1.0 + i as f64).collect());
    let output = MapMinMax::new(vec![0.0; nl], vec![30.0; nl]);
    Mlp::new(layers, input, output, MlpInfo::default()).unwrap()
}

/// Straight from the equations in the module header, allocating freely.
fn naive(m: &Mlp, x: &[f64]) -> Vec<f64> {
    let (imap, omap) = (m.input_map(), m.output_map());
    let mut a: Vec<f64> = (0..x.len())
        .map(|i| 2.0 * (x[i] - imap.min[i]) / (imap.max[i] - imap.min[i]) - 1.0)
        .collect();
    for layer in m.layers() {
        a = (0..layer.n_out)
            .map(|j| {
                let z: f64 = layer.bias[j]
                    + (0..layer.n_in)
                        .map(|i| layer.weight[j * layer.n_in + i] * a[i])
                        .sum::<f64>();
                match layer.activation {
                    Activation::Logsig => 1.0 / (1.0 + (-z).exp()),
                    Activation::Tansig => 2.0 / (1.0 + (-2.0 * z).exp()) - 1.0,
                    Activation::Purelin => z,
                }
            })
            .collect();
    }
    (0..a.len())
        .map(|k| (a[k] + 1.0) * (omap.max[k] - omap.min[k]) / 2.0 + omap.min[k])
        .collect()
}

fn kind_and_item(e: CableError) -> (WeightsErrorKind, String) {
    match e {
        CableError::Weights { kind, item, .. } => (kind, item),
        other => panic!("expected a weights error, got {other:?}"),
    }
}

#[test]
fn forward_matches_the_equations_for_every_activation_and_shape() {
    use Activation::*;
    // Output tails of 1–3 lanes, odd input counts, two hidden layers, a sigmoid last layer
    // (de-normalised outside the folded weights).
    let cases: [(&[usize], &[Activation]); 6] = [
        (&[4, 10, 4], &[Tansig, Purelin]),
        (&[4, 10, 4], &[Logsig, Purelin]),
        (&[4, 10, 4], &[Tansig, Tansig]),
        (&[3, 7, 5, 2], &[Logsig, Tansig, Purelin]),
        (&[5, 9, 6], &[Tansig, Logsig]),
        (&[1, 1, 1], &[Tansig, Purelin]),
    ];
    for (sizes, acts) in cases {
        let mut m = net(sizes, acts, 3);
        let (n0, nl) = (sizes[0], sizes[sizes.len() - 1]);
        for (r, x) in lcg(9, 10 * n0).chunks(n0).enumerate() {
            let mut out = vec![0.0; nl];
            m.forward(x, &mut out).unwrap();
            let want = naive(&m, x);
            for k in 0..nl {
                assert!(
                    (out[k] - want[k]).abs() < 1e-12,
                    "{sizes:?} row {r} out {k}: {} vs {}",
                    out[k],
                    want[k]
                );
            }
            // The AVX2 build of the same code gives the same bits.
            let mut portable = vec![0.0; nl];
            m.forward_portable(x, &mut portable);
            assert_eq!(out, portable, "{sizes:?} row {r}");
        }
    }
}

#[test]
fn batch_equals_single_in_serial_and_parallel_regimes() {
    let mut m = net(
        &[3, 7, 5, 2],
        &[Activation::Logsig, Activation::Tansig, Activation::Purelin],
        5,
    );
    for rows in [1, 17, PARALLEL_MIN_ROWS + 2049] {
        let x = lcg(rows as u64, rows * 3);
        let mut out = vec![0.0; rows * 2];
        m.forward_batch(&x, &mut out).unwrap();
        for r in (0..rows).step_by(97) {
            let mut one = [0.0; 2];
            m.forward(&x[r * 3..r * 3 + 3], &mut one).unwrap();
            assert_eq!(&out[r * 2..r * 2 + 2], &one, "rows {rows}, row {r}");
        }
    }
}

#[test]
fn bad_inputs_are_typed_errors_and_leave_out_untouched() {
    let mut m = net(&[4, 10, 4], &[Activation::Tansig, Activation::Purelin], 1);
    let mut out = [7.0; 4];
    assert!(matches!(
        m.forward(&[0.0; 3], &mut out),
        Err(CableError::Shape { .. })
    ));
    assert!(matches!(
        m.forward(&[0.0, f64::NAN, 0.0, 0.0], &mut out),
        Err(CableError::NotFinite { index: 1, .. })
    ));
    assert_eq!(out, [7.0; 4]);
    let mut big = vec![7.0; 8];
    let x = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, f64::INFINITY, 0.0];
    match m.forward_batch(&x, &mut big) {
        Err(CableError::NotFinite {
            index, location, ..
        }) => {
            assert_eq!(index, 6);
            assert!(location.contains("row 1, column 2"));
        }
        other => panic!("{other:?}"),
    }
    assert!(big.iter().all(|v| *v == 7.0));
    assert!(matches!(
        m.forward_batch(&x[..7], &mut big),
        Err(CableError::Shape { .. })
    ));
}

#[test]
fn weight_file_round_trips_exactly() {
    let mut m = net(&[4, 10, 4], &[Activation::Tansig, Activation::Purelin], 11);
    let bytes = m.to_safetensors().unwrap();
    let mut back = Mlp::from_safetensors(&bytes).unwrap();
    assert_eq!(back.sizes(), vec![4, 10, 4]);
    assert_eq!(back.layers(), m.layers());
    let x = [0.3, -0.2, 1.5, 0.0];
    let (mut a, mut b) = ([0.0; 4], [0.0; 4]);
    m.forward(&x, &mut a).unwrap();
    back.forward(&x, &mut b).unwrap();
    assert_eq!(a, b);
    assert_eq!(back.info().metadata["format"], format::FORMAT);
}

/// A tensor's dtype, shape and little-endian bytes.
type RawTensor = (Dtype, Vec<usize>, Vec<u8>);

/// Rebuild a file with one tensor replaced (or dropped, with `None`) and metadata edited.
fn tamper(
    bytes: &[u8],
    tensor: Option<(&str, Option<RawTensor>)>,
    meta: impl FnOnce(&mut HashMap<String, String>),
) -> Vec<u8> {
    let st = safetensors::SafeTensors::deserialize(bytes).unwrap();
    let (_, header) = safetensors::SafeTensors::read_metadata(bytes).unwrap();
    let mut md = header.metadata().clone().unwrap();
    meta(&mut md);
    let mut owned: Vec<(String, Dtype, Vec<usize>, Vec<u8>)> = st
        .tensors()
        .into_iter()
        .map(|(n, v)| (n, v.dtype(), v.shape().to_vec(), v.data().to_vec()))
        .collect();
    if let Some((name, replacement)) = tensor {
        owned.retain(|t| t.0 != name);
        if let Some((d, s, data)) = replacement {
            owned.push((name.to_owned(), d, s, data));
        }
    }
    let views: Vec<(String, TensorView<'_>)> = owned
        .iter()
        .map(|(n, d, s, data)| (n.clone(), TensorView::new(*d, s.clone(), data).unwrap()))
        .collect();
    safetensors::tensor::serialize(views, Some(md)).unwrap()
}

#[test]
fn every_defect_has_its_own_kind_and_names_the_item() {
    use WeightsErrorKind::*;
    let good = net(&[4, 10, 4], &[Activation::Tansig, Activation::Purelin], 2)
        .to_safetensors()
        .unwrap();
    let f64s = |v: &[f64]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let mut nan_w = lcg(1, 40);
    nan_w[13] = f64::NAN;
    let cases: Vec<(&str, Vec<u8>, WeightsErrorKind, &str)> = vec![
        (
            "truncated",
            good[..good.len() - 9].to_vec(),
            Corrupt,
            "file",
        ),
        ("empty", Vec::new(), Corrupt, "file"),
        (
            "garbage",
            b"\x10\0\0\0\0\0\0\0not json at all!".to_vec(),
            Corrupt,
            "file",
        ),
        (
            "no metadata",
            {
                let st = safetensors::SafeTensors::deserialize(&good).unwrap();
                safetensors::tensor::serialize(st.tensors(), None).unwrap()
            },
            Metadata,
            "__metadata__",
        ),
        (
            "no architecture",
            tamper(&good, None, |m| {
                m.remove("architecture");
            }),
            Metadata,
            "architecture",
        ),
        (
            "unknown activation",
            tamper(&good, None, |m| {
                m.insert(
                    "architecture".into(),
                    r#"{"sizes":[4,10,4],"activations":["relu","purelin"]}"#.into(),
                );
            }),
            Metadata,
            "architecture",
        ),
        (
            "future version",
            tamper(&good, None, |m| {
                m.insert("format_version".into(), "2".into());
            }),
            Metadata,
            "format_version",
        ),
        (
            "names of the wrong length",
            tamper(&good, None, |m| {
                m.insert("input_names".into(), r#"["a","b"]"#.into());
            }),
            Metadata,
            "input_names",
        ),
        (
            "wrong shape",
            tamper(
                &good,
                Some((
                    "layers.0.weight",
                    Some((Dtype::F64, vec![4, 10], f64s(&lcg(1, 40)))),
                )),
                |_| {},
            ),
            Shape,
            "layers.0.weight",
        ),
        (
            "missing tensor",
            tamper(&good, Some(("layers.1.bias", None)), |_| {}),
            Shape,
            "layers.1.bias",
        ),
        (
            "extra tensor",
            tamper(
                &good,
                Some(("layers.2.weight", Some((Dtype::F64, vec![1], f64s(&[1.0]))))),
                |_| {},
            ),
            Shape,
            "layers.2.weight",
        ),
        (
            "f32 weights",
            tamper(
                &good,
                Some(("layers.0.bias", Some((Dtype::F32, vec![10], vec![0u8; 40])))),
                |_| {},
            ),
            Corrupt,
            "layers.0.bias",
        ),
        (
            "nan weight",
            tamper(
                &good,
                Some((
                    "layers.0.weight",
                    Some((Dtype::F64, vec![10, 4], f64s(&nan_w))),
                )),
                |_| {},
            ),
            Value,
            "layers.0.weight",
        ),
        (
            "reversed range",
            tamper(
                &good,
                Some(("output.max", Some((Dtype::F64, vec![4], f64s(&[-1.0; 4]))))),
                |_| {},
            ),
            Value,
            "output.max",
        ),
    ];
    for (what, bytes, kind, item) in cases {
        let (k, i) = kind_and_item(Mlp::from_safetensors(&bytes).unwrap_err());
        assert_eq!((k, i.as_str()), (kind, item), "{what}");
    }
}

/// A stable-toolchain stand-in for a coverage-guided fuzzer on the Rust weight parser (the
/// atheris target in `fuzz/` cannot see inside the compiled core): 20 000 files made from a
/// valid one by random byte flips, insertions, deletions and truncations must each load or give
/// a typed error — never a panic — and a file that loads must predict finite numbers inside its
/// training range.
#[test]
fn mutated_weight_files_load_or_fail_typed_never_panic() {
    let good = net(&[3, 5, 2], &[Activation::Logsig, Activation::Purelin], 5)
        .to_safetensors()
        .unwrap();
    let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        s
    };
    let (mut loaded, mut refused) = (0, 0);
    for _ in 0..20_000 {
        let mut b = good.clone();
        for _ in 0..1 + next() % 4 {
            let at = (next() as usize) % b.len().max(1);
            match next() % 4 {
                0 => b[at] ^= 1 << (next() % 8),
                1 => b[at] = next() as u8,
                2 => b.insert(at, next() as u8),
                _ => b.truncate(at),
            }
            if b.is_empty() {
                break;
            }
        }
        match std::panic::catch_unwind(|| Mlp::from_safetensors(&b)) {
            Err(_) => panic!("the parser panicked on a mutated file"),
            Ok(Err(CableError::Weights { .. })) => refused += 1,
            Ok(Err(e)) => panic!("not a weights error: {e}"),
            Ok(Ok(mut m)) => {
                loaded += 1;
                let x = vec![0.0; m.n_inputs()];
                let mut y = vec![0.0; m.n_outputs()];
                if m.input_map().min.iter().all(|v| *v <= 0.0)
                    && m.input_map().max.iter().all(|v| *v >= 0.0)
                {
                    m.forward(&x, &mut y).unwrap();
                    assert!(y.iter().all(|v| v.is_finite()));
                }
            }
        }
    }
    assert!(
        loaded > 0 && refused > 0,
        "{loaded} loaded, {refused} refused"
    );
}
