"""The README's main job: `cablekit simulate --example …` writes a CSV, JSON summary and PNG."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

import cablekit as ck
from cablekit.cli import main
from cablekit.examples import run_example


@pytest.mark.parametrize("example", ["raven-link", "forceps"])
def test_simulate_example_writes_csv_json_png(tmp_path, example, capsys):
    assert main(["simulate", "--example", example, "--out", str(tmp_path), "--duration", "1.0"]) == 0
    stem = example.replace("-", "_")
    with (tmp_path / f"{stem}.csv").open() as fh:
        rows = list(csv.reader(fh))
    header, data = rows[0], np.array(rows[1:], dtype=float)
    assert header[0] == "t" and data.shape == (1000, len(header))
    np.testing.assert_allclose(np.diff(data[:, 0]), 1e-3, rtol=1e-9)
    # the CSV holds exactly what the Python API returns for the same run
    direct = run_example(example, duration=1.0)
    for name in direct.output_names:
        np.testing.assert_array_equal(data[:, header.index(name)], direct[name])
    summary = json.loads((tmp_path / f"{stem}.json").read_text())
    assert summary["samples"] == 1000 and summary["substeps"] >= 1
    png = (tmp_path / f"{stem}.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    assert "wrote" in capsys.readouterr().out


def test_raven_example_tracks_and_shows_cable_stretch():
    res = run_example("raven-link", duration=2.0)
    ref = res.meta["reference_joint"]
    # the servo tracks after the start-up transient (within 1.5° / 3 mm)...
    err = np.abs(np.column_stack([res[f"q_l{i}"] for i in (1, 2, 3)]) - ref)[500:]
    assert np.max(err[:, :2]) < np.radians(1.5) and np.max(err[:, 2]) < 3e-3
    # ...and the joint differs from the motor-encoder kinematics by the cable stretch
    model = ck.CableTransmission.raven2(3)
    q_kin = np.array([model.motor_to_joint(np.ascontiguousarray(row)) for row in res.states[:, 0::4]])
    stretch_err = np.abs(q_kin - res.states[:, 2::4])
    assert 0 < np.max(stretch_err[:, 0]) < np.radians(1.0)


def test_unknown_example_is_a_clean_error(capsys):
    with pytest.raises(SystemExit):
        main(["simulate", "--example", "nope"])
    with pytest.raises(ck.ParameterError, match="unknown example"):
        run_example("nope")
    with pytest.raises(ck.ParameterError, match="duration"):
        run_example("forceps", duration=-1.0)


def test_version_and_exit_codes_tell_usage_from_bad_input_from_a_failed_run(capsys, tmp_path):
    import cablekit
    from cablekit.cli import EXIT_FAILED, EXIT_INPUT, EXIT_INTERNAL, EXIT_USAGE, exit_code

    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0 and cablekit.__version__ in capsys.readouterr().out
    with pytest.raises(SystemExit) as done:
        main(["simulate", "--no-such-option"])
    assert done.value.code == EXIT_USAGE
    # bad input: a model file that does not exist
    code = main(
        ["diagnose", str(tmp_path / "fit.csv"), "--holdout", str(tmp_path / "h.csv"), "--model", "nope.toml"]
    )
    assert code == EXIT_INPUT
    assert exit_code(cablekit.ParameterError("x")) == EXIT_INPUT
    assert exit_code(cablekit.ConvergenceError("x")) == EXIT_FAILED
    assert exit_code(cablekit.SimulationDivergedError("x")) == EXIT_FAILED
    assert exit_code(cablekit.InternalError("x")) == EXIT_INTERNAL


def test_the_package_carries_its_licence():
    from importlib.metadata import metadata
    from pathlib import Path

    meta = metadata("cablekit")
    assert meta["License"] == "Apache-2.0"
    assert "License :: OSI Approved :: Apache Software License" in meta.get_all("Classifier")
    text = (Path(__file__).resolve().parents[1] / "LICENSE").read_text()
    assert "Apache License" in text and "Version 2.0, January 2004" in text


def _parsers(parser, path=()):
    """Every (sub-)command's parser with its command path."""
    import argparse

    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, (*path, name))


def test_help_shows_every_default_and_every_option_is_explained():
    import argparse

    from cablekit.cli import build_parser

    seen = 0
    for path, parser in _parsers(build_parser()):
        text = " ".join(parser.format_help().split())
        for action in parser._actions:
            if not action.option_strings or isinstance(
                action, argparse._HelpAction | argparse._VersionAction
            ):
                continue
            flag = action.option_strings[-1]
            # every option says what it does (a choice list alone counts: it names the values)
            assert action.help or action.choices, f"cablekit {' '.join(path)} {flag}: no help text"
            if action.default not in (None, False, argparse.SUPPRESS, []):
                seen += 1
                shown = f"(default: {action.default})" in text or f"default: {action.default}" in text
                assert shown, f"cablekit {' '.join(path)} {flag}: default {action.default!r} not in --help"
    assert seen > 20  # the check looked at the options that have defaults


def test_help_texts_name_the_physics_not_only_the_paper(capsys):
    from cablekit.cli import build_parser

    for path, parser in _parsers(build_parser()):
        for action in parser._actions:
            words = action.help or ""
            if "seed 00" in words:
                # a reference to a seed paper is fine beside a description, not instead of one
                before = words.split("seed 00")[0]
                assert len(before.split()) >= 4, f"cablekit {' '.join(path)}: {words!r}"


def test_python_dash_m_runs_the_command(tmp_path):
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-m", "cablekit.cli", "--version"], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.startswith("cablekit ")
