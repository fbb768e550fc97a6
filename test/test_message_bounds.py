"""Every message field that sizes an allocation is bounded where the message is unpacked, and the
compensator's guard costs memory bounded by the steps it can command, whatever horizon a message claims."""

import tracemalloc

import numpy as np
import pytest

from gwr_predictor.learning.params import MAX_HORIZON, HierarchyParams
from gwr_predictor.pipeline import conventions
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.input_rules import ArmAnglesCheck, RejectionCounter
from gwr_predictor.registry import make_predictor
from gwr_predictor.robot.compensator import DelayCompensator
from gwr_predictor.robot.nao import ARM_JOINTS

POSE = np.array([1.2, 0.2, -1.0, -0.5, 1.2, -0.2, 1.0, 0.5])


class _Quiet:
    def warning(self, text):
        pass

    info = warning


def test_a_prediction_longer_than_the_horizon_limit_is_refused_on_unpacking():
    packed = conventions.pack_predictions(1.0, np.zeros((MAX_HORIZON + 1, 8)))
    with pytest.raises(PipelineError, match="horizon") as too_large_horizon:
        conventions.unpack_predictions(packed)
    assert too_large_horizon.value.reason == "too_large"
    _, names, preds = conventions.unpack_predictions(conventions.pack_predictions(1.0, np.zeros((MAX_HORIZON, 8))))
    assert preds.shape == (MAX_HORIZON, 8) and names == ARM_JOINTS


def _peak_bytes(run) -> int:
    tracemalloc.start()
    try:
        run()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("horizon", [2000, 250])
def test_the_guard_memory_does_not_grow_with_the_horizon_of_its_predictions(horizon):
    """Horizon 2000 asked 477 GiB of the guard (cubic); 30 sets of horizon 250 took about 1 GB."""
    comp = DelayCompensator("guarded", delay_s=0.6)

    def run():
        for k in range(30):
            t = 0.1 * k
            comp.command(t, POSE, np.tile(POSE, (horizon, 1)), t, obs_stamp=t)

    # the predictions themselves are horizon x 8 floats (128 KB at 2000); the guard keeps 12 x 13 x 8
    assert _peak_bytes(run) < 2_000_000
    model, hold = comp.guard_mse
    assert model.shape == hold.shape == (12,)  # steps up to delay + staleness allowance + 1
    assert np.all(model[:5] == 0.0) and np.all(hold[:5] == 0.0)  # a still person, exact predictions


def test_joint_names_are_bounded_and_unique_in_every_layout():
    many = tuple(f"j{i}" for i in range(conventions.MAX_JOINTS + 1))
    with pytest.raises(PipelineError, match="joint names") as too_large_joint:
        conventions.unpack_skeleton(conventions.pack_skeleton(0.5, np.zeros((len(many), 3)), many))
    with pytest.raises(PipelineError, match="characters") as too_large_characters:
        conventions.parse_joint_label(conventions.joint_label(("x" * (conventions.MAX_NAME_CHARS + 1),)))
    assert too_large_joint.value.reason == too_large_characters.value.reason == "too_large"
    twice = (*conventions.SKELETON_JOINTS[:-1], "head")
    with pytest.raises(PipelineError, match="'head' appears twice") as layout:
        conventions.unpack_skeleton(conventions.pack_skeleton(0.5, np.zeros((15, 3)), twice))
    assert layout.value.reason == ""
    _, names, pos = conventions.unpack_skeleton(conventions.pack_skeleton(0.5, np.ones((15, 3))))
    assert names == conventions.SKELETON_JOINTS and pos.shape == (15, 3)


def test_a_joint_state_with_too_many_names_is_counted_as_too_large():
    counters = RejectionCounter(_Quiet())
    check = ArmAnglesCheck(counters, "arm_angles", check_stamps=False)
    names = [*ARM_JOINTS, *(f"extra{i}" for i in range(conventions.MAX_JOINTS))]
    assert check.accept(1.0, names, np.concatenate([POSE, np.zeros(conventions.MAX_JOINTS)])) is None
    assert counters.snapshot() == {"rejected.arm_angles.too_large": 1}
    assert check.accept(1.1, list(ARM_JOINTS), POSE) is not None


def test_the_input_check_counts_too_large_layout_and_missing_joints_apart():
    counters = RejectionCounter(_Quiet())
    check = ArmAnglesCheck(counters, "arm_angles", check_stamps=False)
    assert check.accept(1.0, [*ARM_JOINTS, *(f"x{i}" for i in range(conventions.MAX_JOINTS))],
                       np.zeros(8 + conventions.MAX_JOINTS)) is None
    assert check.accept(1.1, [*ARM_JOINTS, "LShoulderPitch"], np.zeros(9)) is None  # a name twice
    assert check.accept(1.2, list(ARM_JOINTS), np.zeros(7)) is None  # 8 names, 7 positions
    assert check.accept(1.3, list(ARM_JOINTS[:7]), np.zeros(7)) is None
    assert counters.snapshot() == {"rejected.arm_angles.too_large": 1, "rejected.arm_angles.layout": 2,
                                   "rejected.arm_angles.missing_joints": 1}


def test_the_default_predictor_takes_every_horizon_the_learner_declares():
    """The learner's parameter range is [1, MAX_HORIZON]; the default refused more than 64 with a traceback."""
    model = make_predictor("gated_llm_gwr", HierarchyParams.from_flat({"horizon": 80}), seed=0)
    out = None
    for t in range(20):
        out = model.step(0.3 * np.sin(0.2 * t + np.arange(8)))
    assert out is not None and out.shape == (80, 8)


@pytest.mark.ros
def test_one_huge_prediction_does_not_stop_the_compensator(ros):
    from test_node_bad_input import FAST, joint_state, ros_now, wait_counters

    from gwr_predictor.nodes import messages
    from gwr_predictor.nodes.messages import Float64MultiArray, JointState

    probe, diagnostics = ros.probe, ros.diagnostics
    proc = ros.start_ready("delay_compensator", params=FAST)
    commands = probe.subscribe("/joint_commands", JointState)
    angles_pub = probe.publisher("/arm_angles", JointState)
    preds_pub = probe.publisher("/predictions", Float64MultiArray)
    probe.wait_for_subscribers(preds_pub)
    probe.wait_for_subscribers(angles_pub)
    angles_pub.publish(joint_state(ros_now(probe)))
    huge = messages.predictions_msg(ros_now(probe), np.tile(POSE, (2000, 1)))
    for _ in range(3):
        preds_pub.publish(huge)
    wait_counters(ros, diagnostics, "/delay_compensator", {"rejected.predictions.too_large": 3}, [proc])
    before = len(commands)
    preds_pub.publish(messages.predictions_msg(ros_now(probe), np.tile(POSE, (6, 1))))
    probe.spin_until(lambda: len(commands) > before, 10, "a command after the huge predictions", [proc])
    assert proc.running()


def test_a_body_tracking_message_with_too_many_markers_is_refused_before_it_is_read():
    from gwr_predictor.nodes import standard_messages

    n = conventions.MAX_MARKERS + 1
    msg = standard_messages.body_markers(1.0, "depth_camera_link", range(n), np.zeros((n, 3)))
    with pytest.raises(PipelineError, match="markers") as too_large_markers:
        standard_messages.read_body_markers(msg)
    assert too_large_markers.value.reason == "too_large"
    msg.markers = msg.markers[:32]
    assert standard_messages.read_body_markers(msg)[2].shape == (32,)


@pytest.mark.ros
def test_a_skeleton_with_too_many_joints_is_counted_and_the_extractor_keeps_working(ros):
    from test_node_bad_input import FAST, skeleton, wait_counters

    from gwr_predictor.data.demonstrator import default_subjects, demonstrate_one
    from gwr_predictor.nodes.messages import Float64MultiArray, JointState

    probe, diagnostics = ros.probe, ros.diagnostics
    proc = ros.start_ready("angle_extractor", params=FAST)
    out = probe.subscribe("/arm_angles", JointState)
    pub = probe.publisher("/skeleton", Float64MultiArray)
    probe.wait_for_subscribers(pub)
    frames = demonstrate_one("wave_both", default_subjects(1)[0], 1).positions[:6]
    many = (*conventions.SKELETON_JOINTS, *(f"extra{i}" for i in range(conventions.MAX_JOINTS)))
    pub.publish(skeleton(10.0, np.zeros((len(many), 3)), many))
    for k, frame in enumerate(frames):
        pub.publish(skeleton(10.1 + k / 30, frame))
    wait_counters(ros, diagnostics, "/angle_extractor", {"rejected.skeleton.too_large": 1}, [proc])
    probe.spin_until(lambda: len(out) >= 2, 10, "angles after the oversized skeleton", [proc])
    assert proc.running()
