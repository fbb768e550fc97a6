"""The bad-input cases test_node_bad_input.py does not cover, so that every node x every kind of bad
input of docs/reliability.md is exercised once: robot commands and robot states with wrong layouts,
limits and stamps; predictions repeated, going back or empty; the learner's long gaps, stamps going
back, duplicate names and a burst; skeleton arrays whose sizes lie; malformed files given to nodes.
Each is rejected or repaired by its rule, counted on /diagnostics, and the node keeps working."""

from pathlib import Path

import numpy as np
import pytest
from test_node_bad_input import FAST, POSE, Stamps, joint_state, ros_now, skeleton, wait_counters

from gwr_predictor.data.angles import skeleton_to_angles
from gwr_predictor.data.demonstrator import default_subjects, demonstrate_one
from gwr_predictor.nodes import messages
from gwr_predictor.nodes.messages import Float64MultiArray, JointState
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS
from gwr_predictor.robot.nao import ARM_JOINTS, clip_to_limits

OVER_LIMIT = POSE + np.where(np.arange(8) == 0, 3.0, 0.0)  # far beyond LShoulderPitch's limit
NEAR_LIMIT = POSE + np.where(np.arange(8) == 0, 0.9, 0.0)  # 1.2 + 0.9 = 2.1 rad: within 0.2 rad of it
DUPLICATE = [*ARM_JOINTS[:7], ARM_JOINTS[0]]


@pytest.mark.ros
def test_robot_commands_states_and_predictions_every_kind(ros):
    probe = ros.probe
    diagnostics = probe.subscribe_diagnostics()
    procs = [ros.start("nao_sim", params={**FAST, "backend": "kinematic"}, remaps={"joint_states": "/sim_states"}),
             ros.start("delay_compensator", params=FAST, remaps={"joint_commands": "/compensator_commands"})]
    for name in ("/nao_sim", "/delay_compensator"):
        ros.wait_for_node(diagnostics, name, timeout=60)
    states_out = probe.subscribe("/sim_states", JointState)
    commands = probe.subscribe("/compensator_commands", JointState)
    cmd_pub = probe.publisher("/joint_commands", JointState)
    state_pub = probe.publisher("/joint_states", JointState)
    preds_pub = probe.publisher("/predictions", Float64MultiArray)
    angles_pub = probe.publisher("/arm_angles", JointState)
    for pub in (cmd_pub, state_pub, preds_pub, angles_pub):
        probe.wait_for_subscribers(pub)

    # --- nao_sim commands: the kinds test_node_bad_input.py does not send
    c = Stamps(300.0, 0.1)
    t0 = c.next()
    cmd_pub.publish(joint_state(t0))  # accepted
    short = joint_state(c.next())
    short.position = short.position[:3]
    cmd_pub.publish(short)  # layout: 8 names, 3 positions
    cmd_pub.publish(joint_state(c.next(), POSE, DUPLICATE))  # layout: a name twice
    cmd_pub.publish(JointState())  # missing_joints: empty
    # commands beyond a limit, near or far (a predictor's pose may overshoot by any amount): the
    # robot's input clips them, as the offline robot does; no out_of_limits rule for commands
    cmd_pub.publish(joint_state(c.next(), OVER_LIMIT))  # accepted, clipped
    cmd_pub.publish(joint_state(t0))  # stamp: repeated
    cmd_pub.publish(joint_state(t0 - 5.0))  # stamp: back
    cmd_pub.publish(joint_state(c.next(), NEAR_LIMIT))  # accepted, clipped
    cmd_pub.publish(joint_state(c.next(gap=30.0)))  # a long gap is fine for commands: accepted
    wait_counters(ros, diagnostics, "/nao_sim", {
        "rejected.joint_commands.layout": 2, "rejected.joint_commands.missing_joints": 1,
        "rejected.joint_commands.out_of_limits": 0, "rejected.joint_commands.stamp": 2,
        "joint_commands.clipped": 2, "commands.accepted": 4}, procs)
    before = len(states_out)
    probe.spin_until(lambda: len(states_out) > before + 5, 10, "nao_sim still reporting states", procs)

    # --- delay_compensator: robot states (no stamp rule: the robot's clock is its own)
    state_pub.publish(joint_state(10.0, np.full(8, np.inf)))  # non_finite
    state_pub.publish(joint_state(10.0, POSE[:6], ARM_JOINTS[:6]))  # missing_joints
    state_pub.publish(joint_state(10.0, POSE, DUPLICATE))  # layout
    state_pub.publish(joint_state(10.0, OVER_LIMIT))  # out_of_limits
    state_pub.publish(joint_state(5.0))  # an older stamp is accepted for robot states
    # --- predictions: stamps repeated and going back, empty, joints in another order (repaired)
    now = ros_now(probe)
    angles_pub.publish(joint_state(now))
    preds = np.tile(POSE, (6, 1))
    order = list(reversed(range(8)))
    preds_pub.publish(messages.predictions_msg(now, preds[:, order], tuple(ARM_JOINTS[i] for i in order)))
    preds_pub.publish(messages.predictions_msg(now, preds))  # stamp: repeated
    preds_pub.publish(messages.predictions_msg(now - 1.0, preds))  # stamp: back
    preds_pub.publish(Float64MultiArray())  # layout: empty
    preds_pub.publish(messages.predictions_msg(now, np.zeros((6, 8)), ("x",) * 8))  # layout: unknown joints
    wait_counters(ros, diagnostics, "/delay_compensator", {
        "rejected.joint_states.non_finite": 1, "rejected.joint_states.missing_joints": 1,
        "rejected.joint_states.layout": 1, "rejected.joint_states.out_of_limits": 1, "rejected.joint_states.stamp": 0,
        "rejected.predictions.stamp": 2, "rejected.predictions.layout": 2, "predictions.received": 1}, procs)
    # the reordered predictions were put back in ARM_JOINTS order before use
    probe.spin_until(lambda: any(np.allclose(messages.read_joint_state(m)[2], POSE) for m in commands), 10,
                     "a command from the reordered predictions", procs)
    assert all(p.running() for p in procs)


@pytest.mark.ros
def test_learner_gaps_stamps_duplicates_and_a_burst(ros):
    probe = ros.probe
    diagnostics = ros.diagnostics
    learner = ros.start_ready("arm_predictor", params=FAST)
    predictions = probe.subscribe("/predictions", Float64MultiArray)
    pub = probe.publisher("/arm_angles", JointState)
    probe.wait_for_subscribers(pub)
    seq = demonstrate_one("wave_both", default_subjects(1)[0], 1)
    angles = clip_to_limits(skeleton_to_angles(seq.positions, SKELETON_JOINTS))  # a real movement, slowed down
    assert len(angles) >= 42 and np.all(np.isfinite(angles))
    a = Stamps(400.0, 0.1)
    stamps = [a.next() for _ in range(40)]
    for stamp, row in zip(stamps, angles[:40], strict=True):
        pub.publish(joint_state(stamp, row))  # a burst of 40 frames (< the queue depth of 50), no spinning
    pub.publish(joint_state(stamps[10], angles[0]))  # stamp: back
    pub.publish(joint_state(a.next(), angles[0], DUPLICATE))  # layout: a name twice
    stamps.append(a.next(gap=5.0))
    pub.publish(joint_state(stamps[-1], angles[40]))  # long gap: the sequence ends, learning goes on
    stamps.append(a.next(gap=0.2))
    pub.publish(joint_state(stamps[-1], angles[41]))  # short gap: 2 missing frames bridged
    wait_counters(ros, diagnostics, "/arm_predictor", {
        "frames.learned": 42, "rejected.arm_angles.stamp": 1, "rejected.arm_angles.layout": 1,
        "sequences.reset_on_gap": 1, "frames.missing": 2}, [learner])
    got = [round(messages.read_predictions(m)[0], 6) for m in predictions]
    # the burst came out in order, one prediction per frame once the windows are full
    assert got == sorted(got) and set(got) <= {round(t, 6) for t in stamps} and len(got) >= 30
    assert learner.running()


@pytest.mark.ros
def test_skeletons_whose_sizes_lie_and_bad_stamps(ros):
    probe = ros.probe
    diagnostics = ros.diagnostics
    proc = ros.start_ready("angle_extractor", params=FAST)
    out = probe.subscribe("/arm_angles", JointState)
    pub = probe.publisher("/skeleton", Float64MultiArray)
    probe.wait_for_subscribers(pub)
    frame = demonstrate_one("wave_both", default_subjects(1)[0], 1).positions[10]
    short = skeleton(10.0, frame)
    short.data = short.data[:30]  # dims say 15 x 3, the data holds fewer
    pub.publish(short)  # layout
    lying = skeleton(10.0, frame)
    lying.layout.dim[0].size = 14  # dim size disagrees with the 15 names of its label
    pub.publish(lying)  # layout
    offset = skeleton(10.0, frame)
    offset.layout.data_offset = 0  # no stamp slot
    pub.publish(offset)  # layout
    pub.publish(skeleton(0.0, frame))  # stamp: zero
    nan_stamp = skeleton(10.0, frame)
    nan_stamp.data[0] = np.nan
    pub.publish(nan_stamp)  # stamp: NaN
    fewer = tuple(n for n in SKELETON_JOINTS if n != "head")
    s = Stamps(20.0, 1 / 30)
    for _ in range(3):  # a tracker without the head: filled with NaN, the arms do not need it
        pub.publish(skeleton(s.next(), frame[1:], fewer))
    wait_counters(ros, diagnostics, "/angle_extractor", {
        "rejected.skeleton.layout": 3, "rejected.skeleton.stamp": 2, "skeleton.missing_joints_filled_nan": 3,
        "angles.published": 1}, [proc])
    assert len(out) == 1 and proc.running()


@pytest.mark.ros
def test_malformed_files_given_to_nodes_stop_them_naming_the_file(ros, tmp_path):
    skeleton_file = tmp_path / "person.npz"
    skeleton_file.write_bytes(b"PK\x03\x04 truncated")
    code, out = ros.run("skeleton_source", params={"source": "file", "file": str(skeleton_file)}, timeout=60)
    assert code == 1 and f"{skeleton_file}: not a readable NPZ archive" in out
    half_bag = tmp_path / "crashed_bag"
    half_bag.mkdir()
    (half_bag / "crashed_bag.mcap").write_bytes(b"\x89MCAP0\r\n")
    code, out = ros.run("bag_player", params={"bag": str(half_bag)}, timeout=60)
    assert code == 1 and f"{half_bag}: no metadata.yaml" in out and "recover_bag" in out


def test_the_rules_table_names_every_counter_the_tests_check():
    """docs/reliability.md lists each rule by its counter: keep the document and the code in step."""
    doc = Path(__file__).resolve().parents[1] / "docs" / "reliability.md"
    text = doc.read_text()
    for reason in ("layout", "missing_joints", "non_finite", "out_of_limits", "stamp", "out_of_range",
                   "clipped", "reset_on_gap", "frames.missing", "missing_joints_filled_nan", "unknown_joints_ignored",
                   "messages.on_disk", "corrupt_moved_aside"):
        assert reason in text, reason
