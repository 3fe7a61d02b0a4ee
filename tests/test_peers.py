"""The agreement checks of ``benches/peers.py`` (issue #40 §4), without the timing: every peer
gives the same answer as cablekit on the bench's inputs (``--quick`` sizes), and a deliberately
wrong answer voids its row — no times, no ratio — so the check can fail. Every peer is in the
``test`` extra (qpsolvers, highspy and pyswarms are skipped only where that extra is not
installed); a missing peer of the ``test`` extra is a failure (its row would read "not
installed")."""

from __future__ import annotations

import importlib.util
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from tests.examples import ROOT


def _load() -> Any:
    spec = importlib.util.spec_from_file_location("peers", ROOT / "benches" / "peers.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


peers = _load()
CFG = peers.Config.make(quick=True)
KERNELS = {k.name: k for k in peers.KERNELS}
#: peers' modules the test extra does not install
OPTIONAL = {"qpsolvers", "highspy", "pyswarms"}


def _peer(kernel: str, name: str) -> tuple[Any, Any]:
    k = KERNELS[kernel]
    p = k.peer(name)
    for module in p.needs:
        # (found, not imported: pyswarms writes report.log into the working directory on import)
        if module in OPTIONAL and importlib.util.find_spec(module) is None:
            pytest.skip(f"{module} is not installed (the test extra has it)")
    return k, p


@pytest.mark.parametrize(
    ("kernel", "name"), [(k.name, p.name) for k in peers.KERNELS for p in k.peers], ids=lambda s: s
)
def test_every_peer_agrees_with_cablekit(kernel, name):
    k, p = _peer(kernel, name)
    row = peers.measure(k, p, CFG, timing=False)
    assert row.status == "ok", row.status
    assert row.agreement and row.ours_s is None and row.ratio is None


def _shifted(answer: Any) -> Any:
    return [a + 0.01 for a in answer]  # 10 mN on every tension


def _nudged(answer: np.ndarray) -> np.ndarray:
    out = np.array(answer, dtype=np.float64)
    out[0, 0] += 1e-6 * np.abs(out).max()
    return out


def _filter(answer: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    xs, ps = answer
    return xs + 1e-6 * (np.abs(xs) + 1e-3), ps


def _ode(answer: Any) -> Any:
    answer.y = answer.y * (1.0 + 1e-3)
    return answer


WRONG = [
    ("tension", "NumPy closed form", _shifted),
    ("nn", "onnxruntime, batch", _nudged),
    ("srukf", "filterpy, Raven-II model in Rust", _filter),
    ("simulate", "solve_ivp LSODA, NumPy model", _ode),
    ("workspace", "scipy HiGHS LP per pose", np.logical_not),
    ("diagnose", "scipy least_squares, one candidate", lambda p: {k: 1.05 * v for k, v in p.items()}),
]


@pytest.mark.parametrize(("kernel", "name", "wrong"), WRONG, ids=[f"{k}:{n}" for k, n, _ in WRONG])
def test_a_wrong_answer_voids_the_row_and_nothing_is_timed(kernel, name, wrong):
    k, p = _peer(kernel, name)

    def build(cfg: Any) -> Any:
        pair = p.build(cfg)
        right = pair.theirs.answer or pair.theirs.run
        return replace(pair, theirs=replace(pair.theirs, answer=lambda: wrong(right())))

    row = peers.measure(k, replace(p, build=build), CFG, timing=True)
    assert row.status.startswith("void: "), row.status
    assert row.ours_s is None and row.peer_s is None and row.ratio is None


def test_a_peer_that_raises_is_void_and_a_missing_one_is_not_installed():
    k, p = _peer("tension", "NumPy closed form")

    def boom() -> None:
        raise ValueError("no answer")

    raising = replace(p, build=lambda cfg: replace(p.build(cfg), theirs=peers.Side("boom", boom)))
    row = peers.measure(k, raising, CFG)
    assert row.status == "void: peer raised ValueError: no answer" and row.ratio is None

    def never(cfg: Any) -> Any:
        raise AssertionError("built without its module")

    missing = peers.Peer("absent", ("no_such_module_for_peers",), never)
    assert peers.measure(k, missing, CFG).status == "not installed: no_such_module_for_peers"


def test_the_docs_section_is_replaced_between_its_markers_and_the_rest_kept(tmp_path):
    from benches.peerbench import report

    row = peers.Row("tension", "quadprog", "ok", "ours", "theirs", "pose", "same", "", 1e-6, 2e-6, 3)
    void = peers.Row("tension", "qpsolvers", "void: tensions differ", agreement="tensions differ")
    doc = report.document([row, void], CFG, 1.0)
    md, js = tmp_path / "b.md", tmp_path / "b.json"
    old = report.START + "\nOLD SECTION\n" + report.END
    md.write_text("# Benchmarks\n\nbefore\n\n" + old + "\n\nafter\n")
    report.write(md, js, doc, [row, void], peers.KERNELS)
    text = md.read_text()
    assert text.startswith("# Benchmarks\n\nbefore\n\n") and text.endswith("\n\nafter\n")
    assert "OLD SECTION" not in text and text.count(report.START) == 1 and "| 2× |" in text
    assert "| **void** | tensions differ |" in text
    report.write(md, js, doc, [row, void], peers.KERNELS)
    assert md.read_text() == text
    assert '"ratio": 2.0' in js.read_text() and '"ratio": null' in js.read_text()
