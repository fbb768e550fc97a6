"""Bad input never crashes a running node: it is rejected (or repaired) by the stated rule, counted per
reason on /diagnostics, and the node keeps working on the good input that follows."""

import numpy as np
import pytest

from gwr_predictor.data.demonstrator import default_subjects, demonstrate_one
from gwr_predictor.nodes import messages
from gwr_predictor.nodes.messages import Float64MultiArray, JointState
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS
from gwr_predictor.robot.nao import ARM_JOINTS

FAST = {"diagnostics_period_s": 0.2, "warn_throttle_s": 1.0}
POSE = np.array([1.2, 0.2, -1.0, -0.5, 1.2, -0.2, 1.0, 0.5])  # inside every joint limit


class Stamps:
    """Increasing stamps (s) on demand; `back`/`same` give the bad ones."""

    def __init__(self, start: float, period: float) -> None:
        self.t, self.period = start, period

    def next(self, gap: float = 0.0) -> float:
        self.t += self.period + gap
        return self.t


def skeleton(stamp, positions, names=SKELETON_JOINTS):
    return messages.skeleton_msg(stamp, positions, names)


def joint_state(stamp, values=POSE, names=ARM_JOINTS):
    msg = JointState()
    msg.header.stamp = messages.to_time(stamp)
    msg.name = list(names)
    msg.position = [float(v) for v in values]
    return msg


def wait_counters(session, diagnostics, node, expected, procs, timeout=20.0):
    """Spin until the node's /diagnostics show at least the expected counts, then compare exactly."""
    def seen():
        values = diagnostics.get(node, {})
        return all(int(values.get(k, "0")) >= v for k, v in expected.items())

    session.probe.spin_until(seen, timeout, lambda: f"counters {expected} of {node}; have {diagnostics.get(node)}",
                             procs)
    session.probe.spin_for(0.5)  # nothing more should arrive
    values = diagnostics[node]
    assert {k: int(values.get(k, "0")) for k in expected} == expected


@pytest.mark.ros
def test_bad_input_is_rejected_counted_and_the_nodes_keep_working(ros):
    probe = ros.probe
    diagnostics = probe.subscribe_diagnostics()
    procs = [
        ros.start("angle_extractor", params=FAST, remaps={"arm_angles": "/extracted_angles"}),
        ros.start("arm_predictor", params=FAST, remaps={"predictions": "/learner_predictions"}),
        ros.start("delay_compensator", params=FAST, remaps={"joint_commands": "/compensator_commands"}),
        ros.start("nao_sim", params={**FAST, "backend": "kinematic"}),
    ]
    for name in ("/angle_extractor", "/arm_predictor", "/delay_compensator", "/nao_sim"):
        ros.wait_for_node(diagnostics, name, timeout=60)
    extracted = probe.subscribe("/extracted_angles", JointState)
    learner_predictions = probe.subscribe("/learner_predictions", Float64MultiArray)
    commands = probe.subscribe("/compensator_commands", JointState)
    skel_pub = probe.publisher("/skeleton", Float64MultiArray)
    angles_pub = probe.publisher("/arm_angles", JointState)
    preds_pub = probe.publisher("/predictions", Float64MultiArray)
    cmd_pub = probe.publisher("/joint_commands", JointState)
    for pub, n in ((skel_pub, 1), (angles_pub, 2), (preds_pub, 1), (cmd_pub, 1)):
        probe.wait_for_subscribers(pub, n)
    frame = demonstrate_one("wave_both", default_subjects(1)[0], 1).positions[10]

    # --- skeletons: 6 rejected, unknown joints ignored, untracked hand -> the smoothed frame dropped
    s = Stamps(100.0, 1 / 30)
    first = s.next()
    skel_pub.publish(skeleton(first, frame))
    skel_pub.publish(messages.predictions_msg(s.next(), np.zeros((6, 8))))  # layout
    skel_pub.publish(Float64MultiArray())  # layout (empty)
    skel_pub.publish(skeleton(s.next(), np.where(np.arange(45).reshape(15, 3) == 4, np.inf, frame)))  # non_finite
    skel_pub.publish(skeleton(s.next(), frame * 1000.0))  # out_of_range (millimetres)
    skel_pub.publish(skeleton(first, frame))  # stamp repeated
    skel_pub.publish(skeleton(first - 1.0, frame))  # stamp back
    extra = (*SKELETON_JOINTS, "tail")
    skel_pub.publish(skeleton(s.next(gap=2.0), np.vstack([frame, [[0.0, 0.0, 2.0]]]), extra))  # new sequence
    skel_pub.publish(skeleton(s.next(), frame))
    skel_pub.publish(skeleton(s.next(), frame))  # -> angles 1
    no_hand = frame.copy()
    no_hand[SKELETON_JOINTS.index("left_hand")] = np.nan
    for gap in (2.0, 0.0, 0.0):  # new sequence, 3 frames without the left hand -> dropped
        skel_pub.publish(skeleton(s.next(gap=gap), no_hand))
    for _ in range(3):
        skel_pub.publish(skeleton(s.next(), frame))  # -> angles 2
    wait_counters(ros, diagnostics, "/angle_extractor", {
        "rejected.skeleton.layout": 2, "rejected.skeleton.non_finite": 1, "rejected.skeleton.out_of_range": 1,
        "rejected.skeleton.stamp": 2, "rejected.frame.missing_joints": 1, "skeleton.unknown_joints_ignored": 1,
        "sequence_gaps": 2, "angles.published": 2}, procs)
    assert len(extracted) == 2
    assert all(messages.read_joint_state(m)[1] == ARM_JOINTS for m in extracted)

    # --- arm angles: read by both arm_predictor and delay_compensator
    a = Stamps(200.0, 0.1)
    t0 = a.next()
    angles_pub.publish(joint_state(t0))
    angles_pub.publish(joint_state(a.next(), np.where(np.arange(8) == 2, np.nan, POSE)))  # non_finite
    angles_pub.publish(joint_state(a.next(), POSE[:7], ARM_JOINTS[:7]))  # missing_joints
    angles_pub.publish(JointState())  # missing_joints (empty)
    bad = joint_state(a.next())
    bad.position = bad.position[:5]
    angles_pub.publish(bad)  # layout: 8 names, 5 positions
    angles_pub.publish(joint_state(a.next(), POSE + np.where(np.arange(8) == 0, 3.0, 0.0)))  # out_of_limits
    angles_pub.publish(joint_state(t0))  # stamp repeated
    angles_pub.publish(joint_state(a.next(), POSE + np.where(np.arange(8) == 0, 0.9, 0.0)))  # clipped (1.2+0.9)
    order = list(reversed(range(8)))
    for _ in range(6):  # shuffled names plus an extra joint: accepted
        angles_pub.publish(joint_state(a.next(), [*POSE[order], 0.0], [*(ARM_JOINTS[i] for i in order), "HeadYaw"]))
    expected_angles = {"rejected.arm_angles.non_finite": 1, "rejected.arm_angles.missing_joints": 2,
                       "rejected.arm_angles.layout": 1, "rejected.arm_angles.out_of_limits": 1,
                       "rejected.arm_angles.stamp": 1, "arm_angles.clipped": 1}
    wait_counters(ros, diagnostics, "/arm_predictor", {**expected_angles, "frames.learned": 8,
                                                       "frames.missing": 4}, procs)
    # the rejected messages left a 0.5 s stamp gap: 4 missing frames (windows cleared); the default
    # predictor predicts on every accepted frame (hold-last until its window refills): t0 + 7 good ones
    probe.spin_until(lambda: len(learner_predictions) >= 8, 10, "predictions after the bad angles", procs)
    assert len(learner_predictions) == 8

    # --- predictions and commands
    preds_pub.publish(messages.predictions_msg(a.next(), np.zeros((6, 7)), ARM_JOINTS[:7]))  # layout (7 joints)
    nan_preds = np.tile(POSE, (6, 1))
    nan_preds[3, 3] = np.nan
    preds_pub.publish(messages.predictions_msg(a.next(), nan_preds))  # non_finite
    wait_counters(ros, diagnostics, "/delay_compensator",
                  {**expected_angles, "rejected.predictions.layout": 1, "rejected.predictions.non_finite": 1},
                  procs)
    before = len(commands)
    preds_pub.publish(messages.predictions_msg(ros_now(probe), np.tile(POSE, (6, 1))))
    probe.spin_until(lambda: len(commands) > before, 10, "a command from good predictions", procs)
    np.testing.assert_allclose(messages.read_joint_state(commands[-1])[2], POSE)

    c = Stamps(300.0, 0.1)
    cmd_pub.publish(joint_state(c.next(), np.full(8, np.nan)))  # non_finite
    cmd_pub.publish(joint_state(c.next(), POSE, [f"Joint{i}" for i in range(8)]))  # missing_joints (unknown names)
    cmd_pub.publish(joint_state(c.next()))
    wait_counters(ros, diagnostics, "/nao_sim", {"rejected.joint_commands.non_finite": 1,
                                                 "rejected.joint_commands.missing_joints": 1,
                                                 "commands.accepted": 1}, procs)
    assert all(p.running() for p in procs), [p.output()[-500:] for p in procs if not p.running()]
    warnings = procs[0].output()
    assert "rejected input [skeleton.layout]" in warnings


def ros_now(probe) -> float:
    return probe.node.get_clock().now().nanoseconds * 1e-9


@pytest.mark.ros
def test_a_burst_of_skeletons_is_processed_in_order(ros):
    """200 frames published back to back (a tracker catching up): every third one gives an angle frame."""
    probe = ros.probe
    proc = ros.start_ready("angle_extractor", params=FAST)
    out = probe.subscribe("/arm_angles", JointState)
    pub = probe.publisher("/skeleton", Float64MultiArray)
    probe.wait_for_subscribers(pub)
    seq = demonstrate_one("rotate_cw_both", default_subjects(1)[0], 1)
    stamps = 500.0 + np.arange(30) / 30.0
    for stamp, frame in zip(stamps, seq.positions[:30], strict=True):
        pub.publish(skeleton(stamp, frame))  # 30 frames without spinning in between
    probe.spin_until(lambda: len(out) >= 10, 15, "10 angle frames from the burst", [proc])
    probe.spin_for(0.3)
    got = [messages.read_joint_state(m)[0] for m in out]
    np.testing.assert_allclose(got, stamps[1::3])  # in order, stamped with each group's middle frame
    assert proc.running()


class FakeLogger:
    def __init__(self):
        self.lines = []

    def warning(self, text):
        self.lines.append(("warning", text))

    def info(self, text):
        self.lines.append(("info", text))


def test_rejections_are_counted_per_reason_and_warned_at_most_once_per_period(monkeypatch):
    from gwr_predictor.pipeline import input_rules

    clock = [100.0]
    monkeypatch.setattr(input_rules.time, "monotonic", lambda: clock[0])
    log = FakeLogger()
    counter = input_rules.RejectionCounter(log, throttle_s=5.0)
    for _ in range(4):
        counter.reject("skeleton.layout", "bad dims")
    counter.reject("skeleton.stamp", "went back")
    clock[0] += 6.0
    counter.reject("skeleton.layout", "bad dims")
    assert counter.snapshot() == {"rejected.skeleton.layout": 5, "rejected.skeleton.stamp": 1}
    assert counter.rejected == 6
    assert [text for _, text in log.lines] == [
        "rejected input [skeleton.layout]: bad dims; 1 so far",
        "rejected input [skeleton.stamp]: went back; 1 so far",
        "rejected input [skeleton.layout]: bad dims (3 more since the last warning); 5 so far",
    ]
