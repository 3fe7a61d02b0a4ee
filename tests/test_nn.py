"""Networks: Rust inference vs the NumPy reference vs torch, the weight file, the trainers.

Tolerances: forward passes agree to 1e-12 absolute (float64; the Rust core uses its own
rational exp, torch and NumPy use libm's), round trips to 1e-12, analytic vs autograd
Jacobian to 1e-12.
"""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
import safetensors.numpy
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

import cablekit
from cablekit.nn import MapMinMax, Mlp, PsoConfig, TrainConfig, export, export_onnx, flat, train_mlp
from cablekit.nn.datasets import forceps_free_motion, noisy_sine
from cablekit.nn.export import write_weights
from cablekit.nn.pso import pso
from tests.reference import mlp as ref

ATOL = 1e-12


@st.composite
def networks(draw):
    n_layers = draw(st.integers(1, 3))
    sizes = draw(st.lists(st.integers(1, 12), min_size=n_layers + 1, max_size=n_layers + 1))
    acts = draw(
        st.lists(st.sampled_from(["tansig", "logsig", "purelin"]), min_size=n_layers, max_size=n_layers)
    )
    seed = draw(st.integers(0, 2**31))
    scale = draw(st.sampled_from([0.1, 1.0, 5.0]))
    rng = np.random.default_rng(seed)
    weights = [rng.normal(0, scale, (sizes[i + 1], sizes[i])) for i in range(n_layers)]
    biases = [rng.normal(0, scale, sizes[i + 1]) for i in range(n_layers)]
    lo = rng.normal(0, 3, sizes[0])
    hi = lo + rng.uniform(0, 4, sizes[0]) * (rng.random(sizes[0]) > 0.1)  # some empty ranges
    olo = rng.normal(0, 10, sizes[-1])
    ohi = olo + rng.uniform(0.1, 20, sizes[-1])
    x = rng.normal(0, 3, (draw(st.integers(1, 40)), sizes[0]))
    return sizes, acts, weights, biases, (lo, hi, olo, ohi), x


def _write(tmp_path, net, name="net.safetensors"):
    _, acts, weights, biases, (lo, hi, olo, ohi), _ = net
    return write_weights(tmp_path / name, weights, biases, acts, MapMinMax(lo, hi), MapMinMax(olo, ohi))


@settings(max_examples=60)
@given(net=networks())
def test_rust_numpy_and_torch_forward_agree(tmp_path_factory, net):
    sizes, acts, weights, biases, (lo, hi, olo, ohi), x = net
    mlp = Mlp.load(_write(tmp_path_factory.mktemp("w"), net))
    want = ref.forward(x, weights, biases, acts, lo, hi, olo, ohi)
    got = mlp.predict(x)
    np.testing.assert_allclose(got, want, rtol=0, atol=ATOL * max(1.0, np.abs(want).max()))
    one = mlp.predict(np.ascontiguousarray(x[0]))
    assert one.shape == (sizes[-1],)
    np.testing.assert_array_equal(one, got[0])
    theta = torch.from_numpy(
        np.concatenate([np.concatenate([w.ravel(), b]) for w, b in zip(weights, biases, strict=True)])
    )
    a = torch.from_numpy(ref.mapminmax_apply(x, lo, hi))
    t_out = ref.mapminmax_reverse(flat.forward_one(theta, a, sizes, acts).numpy(), olo, ohi)
    np.testing.assert_allclose(got, t_out, rtol=0, atol=ATOL * max(1.0, np.abs(want).max()))
    assert mlp.sizes == sizes and mlp.activations == acts


@settings(max_examples=30, deadline=None)
@given(net=networks())
def test_onnx_export_runs_in_onnxruntime_like_the_rust_core(tmp_path_factory, net):
    import onnxruntime as ort

    sizes, acts, weights, biases, (lo, hi, olo, ohi), x = net
    d = tmp_path_factory.mktemp("onnx")
    mlp = Mlp.load(_write(d, net))
    want = ref.forward(x, weights, biases, acts, lo, hi, olo, ohi)
    scale = max(1.0, np.abs(want).max())
    for dtype, atol in (("float64", ATOL), ("float32", 1e-4)):
        path = export_onnx(mlp, d / f"net_{dtype}.onnx", dtype=dtype)
        sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
        (got,) = sess.run(None, {"x": x.astype(dtype)})
        assert got.dtype == np.dtype(dtype) and got.shape == want.shape
        np.testing.assert_allclose(got, want, rtol=0, atol=atol * scale)
        meta = sess.get_modelmeta().custom_metadata_map
        assert json.loads(meta["architecture"]) == {"sizes": sizes, "activations": acts}
        assert meta["onnx_dtype"] == dtype


def test_onnx_export_takes_a_path_keeps_names_and_rejects_bad_options(tmp_path):
    import onnx

    rng = np.random.default_rng(1)
    path = write_weights(
        tmp_path / "n.safetensors",
        [rng.normal(size=(5, 2)), rng.normal(size=(1, 5))],
        [rng.normal(size=5), rng.normal(size=1)],
        ["logsig", "purelin"],
        MapMinMax(np.array([0.0, -1.0]), np.array([2.0, 1.0])),
        MapMinMax(np.array([-3.0]), np.array([3.0])),
        input_names=["x_m", "v_m"],
        input_units=["m", "m/s"],
        output_names=["T"],
        output_units=["N"],
        metadata={"training_data_sha256": "abc"},
    )
    model = onnx.load(str(export_onnx(path, tmp_path / "n.onnx", opset=13)))
    props = {p.key: p.value for p in model.metadata_props}
    assert props["training_data_sha256"] == "abc" and json.loads(props["input_units"]) == ["m", "m/s"]
    assert "x_m [m]" in model.graph.doc_string and model.opset_import[0].version == 13
    for kwargs in ({"dtype": "float16"}, {"opset": 12}, {"opset": 17.0}):
        with pytest.raises(cablekit.errors.OnnxExportError):
            export_onnx(path, tmp_path / "bad.onnx", **kwargs)
    assert not (tmp_path / "bad.onnx").exists()
    with pytest.raises(cablekit.errors.WeightsCorruptError):
        export_onnx(tmp_path / "n.onnx", tmp_path / "bad.onnx")


def test_large_batches_run_in_parallel_and_equal_single_rows(tmp_path):
    rng = np.random.default_rng(1)
    w = [rng.normal(size=(10, 4)), rng.normal(size=(4, 10))]
    b = [rng.normal(size=10), rng.normal(size=4)]
    path = write_weights(
        tmp_path / "n.safetensors",
        w,
        b,
        ["tansig", "purelin"],
        MapMinMax(-np.ones(4), np.ones(4)),
        MapMinMax(np.zeros(4), 20 * np.ones(4)),
    )
    mlp = Mlp.load(path)
    x = rng.uniform(-1, 1, (20_000, 4))
    y = mlp.predict(x)
    for r in (0, 4095, 4096, 19_999):
        np.testing.assert_array_equal(y[r], mlp.predict(np.ascontiguousarray(x[r])))
    out = np.empty_like(y)
    mlp.predict_into(x, out)
    np.testing.assert_array_equal(out, y)


def test_predict_into_writes_in_place_and_leaves_out_untouched_on_error(tmp_path):
    rng = np.random.default_rng(2)
    mlp = Mlp.load(
        write_weights(
            tmp_path / "n.safetensors",
            [rng.normal(size=(3, 2))],
            [np.zeros(3)],
            ["tansig"],
            MapMinMax(np.zeros(2), np.ones(2)),
            MapMinMax(np.zeros(3), np.ones(3)),
        )
    )
    out = np.full(3, 7.0)
    x = np.array([0.2, 0.4])
    mlp.predict_into(x, out)
    np.testing.assert_array_equal(out, mlp.predict(x))
    out[:] = 7.0
    with pytest.raises(cablekit.NotFiniteError):
        mlp.predict_into(np.array([np.nan, 0.0]), out)
    with pytest.raises(cablekit.ShapeError):
        mlp.predict_into(np.zeros(3), out)
    with pytest.raises(cablekit.ShapeError):
        mlp.predict_into(np.zeros((4, 2)), out)
    with pytest.raises(cablekit.DTypeError):
        mlp.predict_into(np.zeros(2, dtype=np.float32), out)
    with pytest.raises(cablekit.LayoutError):
        mlp.predict_into(np.zeros(4)[::2], out)
    with pytest.raises(cablekit.ShapeError):
        mlp.predict(np.zeros((5, 3)))
    np.testing.assert_array_equal(out, 7.0)


def test_every_corrupt_file_raises_its_own_error_naming_the_item(tmp_path):
    rng = np.random.default_rng(3)
    good = write_weights(
        tmp_path / "good.safetensors",
        [rng.normal(size=(10, 4)), rng.normal(size=(4, 10))],
        [np.zeros(10), np.zeros(4)],
        ["tansig", "purelin"],
        MapMinMax(-np.ones(4), np.ones(4)),
        MapMinMax(np.zeros(4), np.ones(4)),
    )
    tensors = safetensors.numpy.load_file(good)
    with open(good, "rb") as fh:
        n = int.from_bytes(fh.read(8), "little")
        meta = json.loads(fh.read(n))["__metadata__"]

    def variant(name, tensors_=None, meta_=None, raw=None):
        p = tmp_path / f"{name}.safetensors"
        if raw is not None:
            p.write_bytes(raw)
        else:
            safetensors.numpy.save_file(tensors_ if tensors_ is not None else tensors, p, metadata=meta_)
        return p

    bad_shape = dict(tensors, **{"layers.0.weight": np.zeros((10, 3))})
    nan_w = dict(tensors, **{"layers.1.weight": np.where(np.eye(4, 10) > 0, np.nan, 1.0)})
    no_arch = {k: v for k, v in meta.items() if k != "architecture"}
    relu = dict(meta, architecture=json.dumps({"sizes": [4, 10, 4], "activations": ["relu", "purelin"]}))
    cases = [
        (variant("trunc", raw=good.read_bytes()[:-17]), cablekit.errors.WeightsCorruptError, "file"),
        (variant("nometa"), cablekit.errors.WeightsMetadataError, "__metadata__"),
        (variant("noarch", meta_=no_arch), cablekit.errors.WeightsMetadataError, "architecture"),
        (variant("relu", meta_=relu), cablekit.errors.WeightsMetadataError, "architecture"),
        (variant("shape", bad_shape, meta), cablekit.errors.WeightsShapeError, "layers.0.weight"),
        (variant("nan", nan_w, meta), cablekit.errors.WeightsValueError, "layers.1.weight"),
        (
            variant("f32", dict(tensors, **{"layers.0.bias": np.zeros(10, np.float32)}), meta),
            cablekit.errors.WeightsCorruptError,
            "layers.0.bias",
        ),
    ]
    for path, exc, item in cases:
        with pytest.raises(exc) as info:
            Mlp.load(path)
        assert info.value.item == item, (path.name, str(info.value))
        assert isinstance(info.value, cablekit.errors.WeightsFormatError)
    with pytest.raises(FileNotFoundError):
        Mlp.load(tmp_path / "missing.safetensors")


def test_train_export_load_round_trip_matches_torch_and_numpy(tmp_path):
    data = forceps_free_motion(n_samples=1500, seed=4)
    res = train_mlp(data.x, data.y, method="pso-lm", epochs=15, seed=4, progress=False)
    path = export(
        res,
        tmp_path / "forceps.safetensors",
        input_names=data.input_names,
        input_units=data.input_units,
        output_names=data.output_names,
        output_units=data.output_units,
    )
    mlp = Mlp.load(path)
    assert mlp.sizes == [4, 10, 4] and mlp.input_names == list(data.input_names)
    assert mlp.output_units == ["N"] * 4
    md = mlp.metadata
    assert md["training_data_sha256"] == res.data_sha256 and md["cablekit_version"] == cablekit.__version__
    assert json.loads(md["training"])["method"] == "pso-lm"
    rust = mlp.predict(data.x)
    np.testing.assert_allclose(rust, res.predict(data.x), rtol=0, atol=ATOL * 100)
    theta = torch.from_numpy(
        np.concatenate([np.concatenate([w.ravel(), b]) for w, b in zip(res.weights, res.biases, strict=True)])
    )
    t_out = res.output_map.reverse(
        flat.forward_one(
            theta, torch.from_numpy(res.input_map.apply(data.x)), mlp.sizes, res.activations
        ).numpy()
    )
    np.testing.assert_allclose(rust, t_out, rtol=0, atol=ATOL * 100)
    # the official safetensors reader sees the same tensors
    loaded = safetensors.numpy.load_file(path)
    np.testing.assert_array_equal(loaded["layers.0.weight"], res.weights[0])
    # and the Rust writer round-trips the file
    again = Mlp.from_bytes(mlp.to_bytes())
    np.testing.assert_array_equal(again.predict(data.x), rust)
    # the fit is real: far better than predicting the mean
    test = res.split["test"]
    assert res.test_mse < 0.2 * np.mean((data.y[test] - data.y.mean(0)) ** 2)


def test_training_is_deterministic_for_a_seed():
    data = forceps_free_motion(n_samples=800, seed=1)
    a = train_mlp(data.x, data.y, method="pso-lm", epochs=5, seed=7, progress=False)
    b = train_mlp(data.x, data.y, method="pso-lm", epochs=5, seed=7, progress=False)
    c = train_mlp(data.x, data.y, method="pso-lm", epochs=5, seed=8, progress=False)
    for wa, wb in zip(a.weights, b.weights, strict=True):
        np.testing.assert_array_equal(wa, wb)
    assert a.pso_history == b.pso_history and a.pso_history != c.pso_history


def test_pso_converges_on_a_convex_function_and_is_reproducible():
    def sphere(x):
        return ((x - 0.5) ** 2).sum(dim=1)

    cfg = PsoConfig(swarm=20, iterations=300, w=0.729, c1=1.49445, c2=1.49445, x_max=5.0, v_max=1.0)
    best, hist = pso(sphere, 8, cfg, torch.Generator().manual_seed(0))
    assert hist[-1] < 1e-8 and hist[0] > 1.0
    np.testing.assert_allclose(best.numpy(), 0.5, atol=1e-4)
    assert all(b <= a for a, b in itertools.pairwise(hist))
    best2, hist2 = pso(sphere, 8, cfg, torch.Generator().manual_seed(0))
    assert hist2 == hist and torch.equal(best, best2)
    # Table 1 settings (w = 1) with clamping stay bounded and still improve
    _, h = pso(sphere, 8, PsoConfig(), torch.Generator().manual_seed(0))
    assert np.isfinite(h[-1]) and h[-1] < h[0]


def test_bayesian_regularisation_generalises_better_than_plain_lm_on_the_noisy_sine():
    lm_mse, br_mse = [], []
    for seed in range(5):
        p, t, pt, tt = noisy_sine(seed)
        common = dict(
            hidden=(20,), epochs=300, test_fraction=0.0, val_fraction=0.0, seed=seed, progress=False
        )
        lm = train_mlp(p, t, method="lm", **common)
        br = train_mlp(p, t, method="br", **common)
        lm_mse.append(np.mean((lm.predict(pt) - tt) ** 2))
        br_mse.append(np.mean((br.predict(pt) - tt) ** 2))
        g = [h["gamma"] for h in br.history]
        assert all(0 < v < 61 for v in g), "effective parameters within (0, P)"
        assert g[-1] < 30, "regularisation switches off at least half of the 61 parameters"
        assert all(h["alpha"] > 0 and h["beta"] > 0 for h in br.history)
    assert np.median(br_mse) < 0.5 * np.median(lm_mse), (br_mse, lm_mse)
    assert sum(b < a for a, b in zip(lm_mse, br_mse, strict=True)) >= 4, (br_mse, lm_mse)


def test_analytic_jacobian_equals_autograd():
    torch.set_default_dtype(torch.float64)
    sizes, acts = [3, 5, 4, 2], ["tansig", "logsig", "purelin"]
    g = torch.Generator().manual_seed(0)
    th = torch.randn(flat.n_params(sizes), generator=g)
    x = torch.randn(7, 3, generator=g)

    def one(t, xi):
        return flat.forward_one(t, xi.unsqueeze(0), sizes, acts)[0]

    want = torch.func.vmap(torch.func.jacrev(one), in_dims=(None, 0))(th, x).reshape(-1, th.numel())
    torch.testing.assert_close(flat.jacobian(th, x, sizes, acts), want, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "exc"),
    [
        ({"method": "sgd"}, cablekit.ParameterError),
        ({"activation": "relu"}, cablekit.ParameterError),
        ({"hidden": (0,)}, cablekit.ParameterError),
        ({"pso": PsoConfig(v_max=-1.0)}, cablekit.ParameterError),
        ({"test_fraction": 0.95}, cablekit.ParameterError),
    ],
)
def test_bad_training_configuration_is_a_typed_error(kwargs, exc):
    x = np.random.default_rng(0).normal(size=(50, 2))
    with pytest.raises(exc):
        train_mlp(x, x, progress=False, **kwargs)


def test_bad_training_data_is_a_typed_error():
    x = np.random.default_rng(0).normal(size=(50, 2))
    y = x.copy()
    y[3, 1] = np.nan
    with pytest.raises(cablekit.NotFiniteError):
        train_mlp(x, y, progress=False)
    with pytest.raises(cablekit.ShapeError):
        train_mlp(x, x[:40], progress=False)
    with pytest.raises(cablekit.ShapeError):
        train_mlp(x[:5], x[:5], progress=False)


def test_config_defaults_are_table_1():
    c = TrainConfig()
    assert (c.hidden, c.epochs, c.test_fraction, c.lr) == ((10,), 100, 0.10, 0.005)
    assert (c.pso.swarm, c.pso.iterations, c.pso.c1, c.pso.c2, c.pso.w) == (10, 30, 1.49445, 1.49445, 1.0)
