"""msg <-> conventions conversions: layouts survive a CDR round trip, bad layouts are refused."""

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message

from gwr_predictor.nodes import messages
from gwr_predictor.nodes.messages import DiagnosticArray, Float64MultiArray, JointState
from gwr_predictor.pipeline import conventions
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.robot.nao import ARM_JOINTS


def cdr_round_trip(msg, msg_type):
    return deserialize_message(serialize_message(msg), msg_type)


def test_time_round_trip_keeps_nanoseconds():
    for seconds in (0.0, 1.5, 1795368253.066564812, 12.999999999):
        t = messages.to_time(seconds)
        assert 0 <= t.nanosec < 1_000_000_000
        assert abs(messages.from_time(t) - seconds) < 1e-6


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf")])
def test_time_refuses_negative_and_non_finite(bad):
    with pytest.raises(ValueError, match="stamp"):
        messages.to_time(bad)


def test_skeleton_round_trip_through_cdr():
    rng = np.random.default_rng(1)
    positions = rng.normal(size=(len(conventions.SKELETON_JOINTS), 3))
    msg = cdr_round_trip(messages.skeleton_msg(12.25, positions), Float64MultiArray)
    assert [d.label for d in msg.layout.dim] == [conventions.joint_label(conventions.SKELETON_JOINTS), "xyz"]
    assert msg.layout.data_offset == 1
    stamp, names, back = messages.read_skeleton(msg)
    assert stamp == 12.25
    assert names == conventions.SKELETON_JOINTS
    np.testing.assert_array_equal(back, positions)


def test_predictions_round_trip_through_cdr():
    preds = np.arange(6 * 8, dtype=float).reshape(6, 8) / 10
    msg = cdr_round_trip(messages.predictions_msg(3.0, preds), Float64MultiArray)
    stamp, names, back = messages.read_predictions(msg)
    assert (stamp, names) == (3.0, ARM_JOINTS)
    np.testing.assert_array_equal(back, preds)


def test_predictions_with_a_truncated_payload_are_refused():
    msg = messages.predictions_msg(3.0, np.zeros((6, 8)))
    msg.data = msg.data[:-1]
    with pytest.raises(PipelineError, match="expected data_offset 1 and 49 values"):
        messages.read_predictions(msg)


def test_skeleton_with_a_prediction_layout_is_refused():
    with pytest.raises(PipelineError, match="skeleton layout"):
        messages.read_skeleton(messages.predictions_msg(3.0, np.zeros((6, 8))))


def test_joint_state_round_trip_and_selection_in_any_order():
    positions = np.linspace(-1, 1, 8)
    msg = cdr_round_trip(messages.joint_state(5.5, ARM_JOINTS, positions), JointState)
    stamp, names, back = messages.read_joint_state(msg)
    assert stamp == 5.5 and names == ARM_JOINTS
    np.testing.assert_array_equal(back, positions)
    shuffled = list(reversed(names)) + ["HeadYaw"]
    values = np.concatenate([back[::-1], [0.3]])
    np.testing.assert_array_equal(messages.select_joints(shuffled, values, ARM_JOINTS), positions)


def test_joint_selection_names_missing_and_duplicated_joints():
    with pytest.raises(PipelineError, match="missing joints \\['RElbowRoll'\\]") as missing:
        messages.select_joints(ARM_JOINTS[:-1], np.zeros(7), ARM_JOINTS)
    assert missing.value.reason == "missing_joints"  # what the rejection counters read, not the message
    with pytest.raises(PipelineError, match="appears twice") as twice:
        messages.select_joints(ARM_JOINTS + ARM_JOINTS[:1], np.zeros(9), ARM_JOINTS)
    assert twice.value.reason == ""


def test_joint_state_with_fewer_positions_than_names_is_refused():
    msg = messages.joint_state(1.0, ARM_JOINTS, np.zeros(8))
    msg.position = [0.0] * 7
    with pytest.raises(PipelineError, match="8 joint names but 7 positions"):
        messages.read_joint_state(msg)


def test_diagnostics_round_trip():
    status = messages.diagnostic_status("/angle_extractor", {"received": 3, "rate": 0.1234567}, "ok")
    msg = cdr_round_trip(messages.diagnostic_array(2.0, [status]), DiagnosticArray)
    assert messages.read_diagnostics(msg) == {"/angle_extractor": {"received": "3", "rate": "0.123457"}}
    assert msg.status[0].level == messages.OK
