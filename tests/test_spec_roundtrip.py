"""A model file written by ``write_model_toml`` reads back into the same spec: every table
(servo gains, column units, calibration conditions included), whatever the values."""

from __future__ import annotations

import tomllib

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cablekit.diagnose.selftest import make_case
from cablekit.diagnose.selftest_transmission import make_transmission_case
from cablekit.diagnose.spec import load_model_spec, model_spec_from_dict, write_model_toml

_JOINT = make_case((), 1, 2.0).spec
_SERVO = make_transmission_case((), 1, 2.0).spec
finite = st.floats(-1e300, 1e300, allow_nan=False, allow_infinity=False)


@settings(max_examples=40, deadline=None)
@given(
    servo=st.booleans(),
    conditions=st.dictionaries(
        st.sampled_from(["pitch_deg", "roll_deg", "yaw_index"]), st.lists(finite, min_size=1, max_size=3)
    ),
    scale=st.floats(1e-6, 1e6),
    offset=finite,
    comment=st.text(max_size=40),
)
def test_a_written_model_file_reads_back_into_the_same_spec(
    tmp_path_factory, servo, conditions, scale, offset, comment
):
    spec = _SERVO if servo else _JOINT
    doc = spec.to_dict()
    column = next(iter(doc["outputs"].values()))
    doc["units"] = {column: {"scale": scale, "offset": offset}}
    doc["conditions"] = conditions
    spec = model_spec_from_dict(doc, "<generated>")
    path = write_model_toml(spec, tmp_path_factory.mktemp("m") / "model.toml", comment)
    with path.open("rb") as fh:
        assert tomllib.load(fh) == spec.to_dict()  # valid TOML whatever the comment holds
    back = load_model_spec(path)
    assert back.to_dict() == spec.to_dict()
    assert back.column_units == spec.column_units and back.conditions == spec.conditions
    if servo:
        assert back.servo() == spec.servo()


def test_the_servo_gains_are_written():
    doc = _SERVO.to_dict()
    assert set(doc["servo"]) == {"kp", "kd", "torque_limit"}
    with pytest.raises(Exception, match="servo"):
        model_spec_from_dict({k: v for k, v in doc.items() if k != "servo"}, "<no servo>")
