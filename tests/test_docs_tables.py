"""Tables in the docs that a command prints are checked against that command (issue #38: a
documented peak error of 0.108° had drifted from the 0.319° the example printed)."""

from __future__ import annotations

import re

from tests.examples import ROOT, run_example


def _rows(text: str, head: str) -> dict[tuple[str, str], list[float]]:
    """The numeric rows of the markdown table whose header starts with ``head``."""
    start = text.index(head)
    block = text[start:].split("\n\n", 1)[0].splitlines()[2:]
    out = {}
    for line in block:
        cells = [c.strip() for c in line.strip("|").split("|")]
        out[(cells[0], cells[1])] = [float(re.sub(r"[^0-9.eE+-]", "", c)) for c in cells[2:-1]]
    return out


def test_the_joint_state_table_in_the_docs_is_what_the_example_prints(tmp_path):
    done = run_example("joint_states.py", tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    head = "| exp. | joint | UKF MAE | kinematics MAE | UKF peak | kinematics peak | unit |"
    printed = _rows((tmp_path / "table.md").read_text(), head)
    documented = _rows((ROOT / "docs" / "estimation.md").read_text(), head)
    assert printed.keys() == documented.keys()
    for key, values in printed.items():
        for got, doc in zip(values, documented[key], strict=True):
            # the docs print 4 decimals; a few percent leaves room for another CPU's rounding
            assert abs(got - doc) <= 0.03 * abs(doc) + 2e-4, (key, got, doc)
