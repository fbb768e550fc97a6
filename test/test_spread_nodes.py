"""The interval on the wire, in-process (real rclpy nodes, their callbacks called directly): the learner
publishes the default's interval before its predictions, stamped alike; the compensator with `spread_shrink`
pulls a command by the interval of the same frame, and commands as it is when that interval is missing.
(The DDS path of the same topics: test_standard_interfaces.)"""

from __future__ import annotations

import time

import numpy as np
import pytest
from ros_harness import in_process

from gwr_predictor.nodes import messages, standard_messages
from gwr_predictor.robot.nao import ARM_JOINTS

pytestmark = pytest.mark.ros
POSE = np.array([1.2, 0.2, -1.0, -0.5, 1.2, -0.2, 1.0, 0.5])


@pytest.fixture(scope="module")
def nodes():
    from gwr_predictor.nodes.arm_predictor import ArmPredictorNode
    from gwr_predictor.nodes.delay_compensator import DelayCompensatorNode

    with in_process(["-p", "delay_compensator:spread_shrink:=1.0", "-p", "delay_compensator:mode:=fixed",
                     "-p", "delay_compensator:delay_s:=0.3", "-p", "stop_if_duplicate:=false"],
                    learner=ArmPredictorNode, compensator=DelayCompensatorNode) as built:
        yield built


def test_the_learner_publishes_the_interval_of_each_prediction_first(nodes, monkeypatch):
    node = nodes["learner"]
    sent: list = []
    for topic, pub in zip(("interval", "lower", "upper"), node.interval_pubs, strict=True):
        monkeypatch.setattr(pub, "publish", lambda msg, topic=topic: sent.append((topic, msg)))
    monkeypatch.setattr(node.pred_pub, "publish", lambda msg: sent.append(("predictions", msg)))
    now = time.time()
    for k in range(20):
        node.on_angles(messages.joint_state(now + 0.1 * k, ARM_JOINTS, POSE + 0.1 * np.sin(0.4 * k + np.arange(8))))
        if sent:
            assert [t for t, _ in sent[-4:]] == ["interval", "lower", "upper", "predictions"]
            stamp, names, share, lower, upper = messages.read_interval(sent[-4][1])
            p_stamp, _, preds = messages.read_predictions(sent[-1][1])
            assert stamp == p_stamp == pytest.approx(now + 0.1 * k) and names == ARM_JOINTS and share == 0.8
            stated = node.model.interval()
            np.testing.assert_array_equal(lower, stated[0])
            np.testing.assert_array_equal(upper, stated[1])
            assert np.all(lower <= preds) and np.all(preds <= upper)
            for (_, msg), bound in zip(sent[-3:-1], stated, strict=True):
                t_stamp, t_names, trajectory = standard_messages.read_joint_trajectory(msg)
                assert t_stamp == pytest.approx(stamp) and t_names == ARM_JOINTS
                np.testing.assert_allclose(trajectory.positions, bound)
                np.testing.assert_allclose(trajectory.times_from_start, 0.1 * np.arange(1, 7), atol=1e-9)
    assert len(sent) >= 4 * 10


def test_the_compensator_pulls_a_command_by_the_interval_of_its_frame(nodes, monkeypatch):
    node = nodes["compensator"]
    sent: list = []
    monkeypatch.setattr(node.command_pub, "publish", sent.append)
    now = time.time()
    preds = POSE + 0.1 * np.arange(1, 7)[:, None]  # every joint moves 0.1 rad per frame
    half = np.full((6, 8), 0.3)
    node.on_observation(messages.joint_state(now, ARM_JOINTS, POSE))
    node.on_interval(messages.interval_msg(now, preds - half, preds + half, 0.8))
    node.on_predictions(messages.predictions_msg(now, preds))
    move = preds[2] - POSE  # 300 ms: step 3
    np.testing.assert_allclose(sent[-1].position, POSE + move**2 / (move**2 + half[2] ** 2) * move)
    missing = node.counters.get("interval.missing")
    node.on_observation(messages.joint_state(now + 0.1, ARM_JOINTS, POSE))
    node.on_predictions(messages.predictions_msg(now + 0.1, preds))  # its interval never came
    np.testing.assert_allclose(sent[-1].position, preds[2])
    assert node.counters.get("interval.missing") == missing + 1
    rejected = node.counters.get("rejected.prediction_interval.non_finite")
    node.on_interval(messages.interval_msg(now + 0.2, preds - np.nan, preds + half, 0.8))
    assert node.counters.get("rejected.prediction_interval.non_finite") == rejected + 1
