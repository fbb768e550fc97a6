"""Standard views and interfaces with real node processes over DDS: robot_description + every movable
joint, /diagnostics from a namespace, K4ABT body-tracking input, skeleton / predicted-arm markers,
predictions as JointTrajectory and the compensator's joint_trajectory_controller output."""

import time
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from k4abt_bodies import body, markers

from gwr_predictor.data import k4abt
from gwr_predictor.data.angles import skeleton_to_angles
from gwr_predictor.nodes import messages, standard_messages
from gwr_predictor.nodes.messages import DiagnosticArray, Float64MultiArray, JointState
from gwr_predictor.nodes.qos import status_qos
from gwr_predictor.nodes.standard_messages import JointTrajectory, Marker, MarkerArray, String
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS
from gwr_predictor.robot.nao import ARM_JOINTS, clip_to_limits

FAST = {"diagnostics_period_s": 0.3}
POSE = np.array([1.2, 0.2, -1.0, -0.5, 1.2, -0.2, 1.0, 0.5])  # inside every joint limit


def statuses(arrays: list, name: str) -> list:
    return [s for a in arrays for s in a.status if s.name == name]


@pytest.mark.ros
def test_nao_sim_in_a_namespace_latches_its_urdf_reports_every_movable_joint_and_diagnoses_on_root(ros):
    probe = ros.probe
    diagnostics = probe.subscribe("/diagnostics", DiagnosticArray, status_qos())  # only the absolute topic
    states = probe.subscribe("/robot1/joint_states", JointState)
    sim = ros.start("nao_sim", params={**FAST, "backend": "kinematic", "state_rate_hz": 20.0}, namespace="/robot1")
    probe.spin_until(lambda: statuses(diagnostics, "/robot1/nao_sim"), 60, "/robot1/nao_sim on /diagnostics", [sim])
    status = statuses(diagnostics, "/robot1/nao_sim")[-1]
    assert status.hardware_id.startswith("simulated Nao (kinematic) on ")

    # a viewer that joins late still gets the URDF (transient-local, as robot_state_publisher)
    probe.spin_for(0.5)
    description = probe.subscribe("/robot1/robot_description", String, standard_messages.latched_qos())
    probe.spin_until(lambda: description, 20, "the latched robot_description", [sim])
    root = ET.fromstring(description[0].data)
    movable = {j.get("name") for j in root.findall("joint") if j.get("type") not in ("fixed", None)}
    assert len(movable) == 10

    probe.spin_until(lambda: len(states) >= 5, 20, "joint_states", [sim])
    _, names, positions = messages.read_joint_state(states[-1])
    assert set(names) == movable and len(names) == 10
    assert np.isfinite(positions).all()
    wrists = messages.select_joints(names, positions, ("LWristYaw", "RWristYaw"))
    np.testing.assert_array_equal(wrists, [0.0, 0.0])  # nothing commands the wrists


def driver_message(bodies: dict, stamp: float) -> MarkerArray:
    """What the Azure Kinect driver publishes for one capture, with a DELETEALL in front as some do."""
    ids, xyz = markers(bodies)
    msg = standard_messages.body_markers(stamp, "depth_camera_link", ids, xyz)
    msg.markers.insert(0, Marker(action=Marker.DELETEALL))
    return msg


@pytest.mark.ros
def test_angle_extractor_follows_the_nearest_k4abt_body_and_draws_its_skeleton(ros):
    probe = ros.probe
    diagnostics = probe.subscribe_diagnostics()
    angles = probe.subscribe("/arm_angles", JointState)
    skeleton_markers = probe.subscribe("/skeleton_markers", MarkerArray)
    extractor = ros.start("angle_extractor", params={**FAST, "input": "k4abt_markers"})
    ros.wait_for_node(diagnostics, "/angle_extractor", timeout=60)
    pub = probe.publisher("/body_tracking_data", MarkerArray)
    probe.wait_for_subscribers(pub)
    near, far = body(distance=1.9, left_arm="forward"), body(distance=3.4, left_arm="sideways", lateral=0.5)
    rng = np.random.default_rng(0)
    frames, sent = 9, []
    for i in range(frames):  # 30 fps captures, a few millimetres of tracker noise
        noisy = {j: p + rng.normal(0.0, 0.003, 3) for j, p in near.items()}
        sent.append(k4abt.nearest_body(*markers({8: noisy})).positions)
        pub.publish(driver_message({3: far, 8: noisy}, 50.0 + i / 30.0))
        probe.spin_for(0.02)
    probe.spin_until(lambda: len(angles) >= 3 and len(skeleton_markers) >= frames, 20, "3 angle frames",
                     [extractor])
    stamp, names, values = messages.read_joint_state(angles[0])
    assert names == ARM_JOINTS and abs(stamp - (50.0 + 1 / 30.0)) < 1e-6  # the middle of the first 3
    median = np.median(np.stack(sent[:3]), axis=0)  # the paper's median of 3, of the near body only
    np.testing.assert_allclose(values, clip_to_limits(skeleton_to_angles(median, SKELETON_JOINTS)), atol=1e-9)
    assert abs(values[0]) < 0.1 and abs(values[4] - np.pi / 2) < 0.2  # left arm ahead, right arm down
    counts = diagnostics["/angle_extractor"]
    probe.spin_until(lambda: diagnostics["/angle_extractor"].get("body_tracking.nearest_of_several") == str(frames),
                     10, "the body counter", [extractor])
    assert int(counts.get("skeleton.accepted", "0")) <= frames

    first = skeleton_markers[0]
    joints, bones = first.markers
    assert joints.type == Marker.SPHERE_LIST and bones.type == Marker.LINE_LIST
    assert joints.header.frame_id == "skeleton_camera" and messages.from_time(joints.header.stamp) == 50.0
    assert len(joints.points) == 11  # 15 joints, legs not tracked
    assert len(bones.points) == 2 * 11  # the 15 bones minus the 4 that touch a knee or a foot
    head = near[k4abt.K4ABT_JOINTS.index("HEAD")]
    assert any(abs(p.y + head[1]) < 0.02 and abs(p.z - head[2]) < 0.02 for p in joints.points)  # y up now


@pytest.mark.ros
def test_learner_publishes_its_predictions_as_a_joint_trajectory_and_the_predicted_arm(ros):
    probe = ros.probe
    diagnostics = probe.subscribe_diagnostics()
    preds = probe.subscribe("/predictions", Float64MultiArray)
    trajectories = probe.subscribe("/predicted_trajectory", JointTrajectory)
    arm = probe.subscribe("/predicted_arm_markers", MarkerArray)
    intervals = probe.subscribe("/prediction_interval", Float64MultiArray)
    bounds = [probe.subscribe(f"/predicted_trajectory_{b}", JointTrajectory) for b in ("lower", "upper")]
    learner = ros.start("arm_predictor", params={**FAST, "checkpoint_interval_s": 0.0})
    ros.wait_for_node(diagnostics, "/arm_predictor", timeout=60)
    pub = probe.publisher("/arm_angles", JointState)
    probe.wait_for_subscribers(pub)
    n = 30
    for i in range(n):
        pub.publish(messages.joint_state(100.0 + 0.1 * i, ARM_JOINTS, POSE + 0.15 * np.sin(0.3 * i + np.arange(8))))
        probe.spin_for(0.01)
    probe.spin_until(lambda: len(preds) >= n - 10 and len(trajectories) == len(preds) and len(arm) == len(preds)
                     and len(intervals) == len(preds) and all(len(b) == len(preds) for b in bounds),
                     30, "predictions and their interval on every output", [learner])
    for p_msg, i_msg, *bound_msgs in zip(preds, intervals, *bounds, strict=True):  # the default's interval
        stamp, _, p = messages.read_predictions(p_msg)
        i_stamp, names, share, lower, upper = messages.read_interval(i_msg)
        assert i_stamp == stamp and names == ARM_JOINTS and share == 0.8
        assert np.all(lower <= p) and np.all(p <= upper)
        for msg, bound in zip(bound_msgs, (lower, upper), strict=True):
            t_stamp, _, traj = standard_messages.read_joint_trajectory(msg)
            assert t_stamp == pytest.approx(stamp, abs=1e-9)
            np.testing.assert_allclose(traj.positions, bound)
    for p_msg, t_msg in zip(preds, trajectories, strict=True):
        stamp, names, p = messages.read_predictions(p_msg)
        t_stamp, t_names, traj = standard_messages.read_joint_trajectory(t_msg)
        assert t_stamp == pytest.approx(stamp, abs=1e-9) and t_names == names == ARM_JOINTS
        np.testing.assert_allclose(traj.times_from_start, 0.1 * np.arange(1, 7), atol=1e-9)
        np.testing.assert_allclose(traj.positions, p)
    joints, segments = arm[-1].markers
    assert joints.header.frame_id == "torso" and len(joints.points) == 6 and len(segments.points) == 8
    # stamped when drawn (the node clock), not at t+h: a viewer transforms it with the TF of now, not of the future
    assert abs(messages.from_time(joints.header.stamp) - time.time()) < 10.0


@pytest.mark.ros
def test_compensator_commands_a_joint_trajectory_controller(ros):
    probe = ros.probe
    diagnostics = probe.subscribe_diagnostics()
    trajectories = probe.subscribe("/arm/joint_trajectory_controller/joint_trajectory", JointTrajectory)
    commands = probe.subscribe("/arm/joint_commands", JointState)
    both = ros.start("delay_compensator", params={**FAST, "mode": "none", "output": "both", "trajectory_time_s": 0.2},
                     namespace="/arm")
    only = ros.start("delay_compensator", params={**FAST, "mode": "none", "output": "joint_trajectory"},
                     namespace="/real")
    for name in ("/arm/delay_compensator", "/real/delay_compensator"):
        ros.wait_for_node(diagnostics, name, timeout=60)
    pub = probe.publisher("/arm/arm_angles", JointState)
    probe.wait_for_subscribers(pub)
    sent = [POSE + 0.05 * k for k in range(5)]
    for k, pose in enumerate(sent):
        pub.publish(messages.joint_state(10.0 + 0.1 * k, ARM_JOINTS, pose))
        probe.spin_for(0.02)
    def newest_commanded() -> bool:
        return bool(commands) and len(trajectories) == len(commands) and np.allclose(
            messages.read_joint_state(commands[-1])[2], sent[-1])

    # a command per observation, but only the newest of what queued behind a busy callback
    probe.spin_until(newest_commanded, 20, "a trajectory and a JointState per handled observation", [both])
    order = [int(np.argmin([np.abs(messages.read_joint_state(c)[2] - p).max() for p in sent])) for c in commands]
    assert order == sorted(set(order))  # in order, none twice
    for msg, command, k in zip(trajectories, commands, order, strict=True):
        stamp, names, traj = standard_messages.read_joint_trajectory(msg)
        assert stamp == 0.0 and names == ARM_JOINTS  # 0: the controller starts it on arrival
        assert traj.times_from_start.tolist() == [pytest.approx(0.2)]
        np.testing.assert_allclose(traj.positions[0], sent[k])
        np.testing.assert_allclose(messages.read_joint_state(command)[2], sent[k])
    # output joint_trajectory alone: no JointState command publisher at all
    assert probe.node.count_publishers("/real/joint_trajectory_controller/joint_trajectory") == 1
    assert probe.node.count_publishers("/real/joint_commands") == 0
    assert only.running()
