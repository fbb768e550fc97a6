"""Stamped standard twins of the labelled arrays, with real node processes: `skeleton_poses` (PoseArray) beside
`skeleton` and `predicted_trajectory` (JointTrajectory) beside `predictions` carry the same stamp in
header.stamp and the same values, so packages that read headers (message_filters, `ros2 topic delay`) can
use them; the recorder records the skeleton twin by default."""

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from gwr_predictor.nodes import messages, standard_messages
from gwr_predictor.nodes.bag_recorder import PARAMS as RECORDER_PARAMS
from gwr_predictor.nodes.messages import Float64MultiArray, JointState
from gwr_predictor.nodes.skeleton_source import PARAMS as SOURCE_PARAMS
from gwr_predictor.nodes.standard_messages import JointTrajectory, PoseArray
from gwr_predictor.pipeline import bag_reader, conventions
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.markers import SKELETON_FRAME
from gwr_predictor.robot.nao import ARM_JOINTS

ROOT = Path(__file__).resolve().parents[1]
FAST = {"diagnostics_period_s": 0.3}
POSE = np.array([1.2, 0.2, -1.0, -0.5, 1.2, -0.2, 1.0, 0.5])  # inside every joint limit


def by_stamp(msgs: list, read) -> dict[tuple[int, int], object]:
    """{(sec, nanosec): the read message}: twins pair by their exact stamp."""
    return {key: value for key, value in (read(m) for m in msgs)}


def skeleton_entry(msg: Float64MultiArray) -> tuple[tuple[int, int], tuple]:
    stamp, names, positions = messages.read_skeleton(msg)
    return conventions.split_stamp(stamp), (names, positions)


def poses_entry(msg: PoseArray) -> tuple[tuple[int, int], tuple]:
    stamp, frame_id, positions = standard_messages.read_pose_array(msg)
    return (msg.header.stamp.sec, msg.header.stamp.nanosec), (frame_id, positions, stamp)


def test_pose_array_round_trip_keeps_nan_for_untracked_joints_and_refuses_oversized_arrays():
    positions = np.arange(45, dtype=float).reshape(15, 3) / 10.0
    positions[SKELETON_JOINTS.index("left_foot")] = np.nan
    msg = standard_messages.pose_array(12.25, "kinect", positions)
    assert msg.header.frame_id == "kinect" and len(msg.poses) == 15
    assert all(p.orientation.w == 1.0 and p.orientation.x == p.orientation.y == p.orientation.z == 0.0
               for p in msg.poses)
    stamp, frame_id, back = standard_messages.read_pose_array(msg)
    assert stamp == 12.25 and frame_id == "kinect"
    np.testing.assert_array_equal(back, positions)  # NaN where NaN (assert_array_equal treats NaN as equal)
    msg.poses = msg.poses * (conventions.MAX_JOINTS // 15 + 1)
    with pytest.raises(PipelineError) as too_large:
        standard_messages.read_pose_array(msg)
    assert too_large.value.reason == "too_large"


def test_configs_record_and_declare_the_skeleton_twin():
    recorder = yaml.safe_load((ROOT / "config" / "bag_recorder.yaml").read_text())["/**/bag_recorder"]
    assert conventions.TOPIC_SKELETON_POSES in recorder["ros__parameters"]["topics"]
    default_topics = next(s.default for s in RECORDER_PARAMS if s.name == "topics")
    assert conventions.TOPIC_SKELETON_POSES in default_topics
    assert conventions.TOPIC_TYPES[conventions.TOPIC_SKELETON_POSES] == "geometry_msgs/msg/PoseArray"
    source = yaml.safe_load((ROOT / "config" / "skeleton_source.yaml").read_text())["/**/skeleton_source"]
    specs = {s.name: s.default for s in SOURCE_PARAMS}
    assert source["ros__parameters"]["standard_outputs"] is True is specs["standard_outputs"]
    assert source["ros__parameters"]["frame_id"] == specs["frame_id"] == SKELETON_FRAME


@pytest.mark.ros
def test_skeleton_source_publishes_a_stamped_pose_array_twin_of_every_skeleton_and_the_recorder_keeps_it(
        ros, tmp_path):
    probe = ros.probe
    diagnostics = ros.diagnostics
    skeletons = probe.subscribe("/skeleton", Float64MultiArray)
    poses = probe.subscribe("/skeleton_poses", PoseArray)
    recorder = ros.start("bag_recorder", params={**FAST, "path": str(tmp_path / "bag"),
                                                 "topics": ["skeleton", "skeleton_poses"]})
    ros.wait_for_node(diagnostics, "/bag_recorder", timeout=60)
    source = ros.start("skeleton_source", params={**FAST, "patterns": ["wave_both"], "loop": True,
                                                  "joint_dropout_rate": 0.1, "wait_for_subscribers": 2})
    off = ros.start("skeleton_source", params={**FAST, "source": "none", "standard_outputs": False},
                    namespace="/off")
    probe.wait_for_graph({"/skeleton_poses": ("skeleton_source", ["bag_recorder", "probe"])}, settle_s=0.0)
    n = 40
    probe.spin_until(lambda: len(skeletons) >= n and len(poses) >= n, 30, f"{n} skeletons and their poses",
                     [source, recorder])
    ros.wait_for_node(diagnostics, "/off/skeleton_source", timeout=60)
    source.stop()
    probe.spin_for(0.3)

    skel, twins = by_stamp(skeletons, skeleton_entry), by_stamp(poses, poses_entry)
    first = min(twins)  # the probe's two subscriptions may match a frame apart
    assert len(twins) == len(poses) and set(twins) == {k for k in skel if k >= first}  # a twin per frame
    untracked = 0
    for key, (frame_id, twin_positions, stamp) in twins.items():
        names, positions = skel[key]
        assert names == SKELETON_JOINTS and frame_id == SKELETON_FRAME
        assert stamp == pytest.approx(key[0] + key[1] * 1e-9, abs=1e-12)
        np.testing.assert_array_equal(twin_positions, positions)  # SKELETON_JOINTS order, NaN where untracked
        untracked += int(np.isnan(positions).any(axis=1).sum())
    assert untracked > 0  # the dropouts reached both

    # standard_outputs: false: no twin publisher at all
    assert probe.node.count_publishers("/off/skeleton") == 1
    assert probe.node.count_publishers("/off/skeleton_poses") == 0
    assert off.running()

    code, killed = recorder.stop()
    assert code == 0 and not killed, recorder.output()
    recorded: dict[str, list] = {}
    for m in bag_reader.read_bag(tmp_path / "bag"):
        recorded.setdefault(m.topic, []).append(m.msg)
    assert len(recorded.get("/skeleton_poses", [])) > 0
    bag_skel = {conventions.split_stamp(float(m.data[0])) for m in recorded["/skeleton"]}
    bag_poses = {(m.header.stamp.sec, m.header.stamp.nanosec) for m in recorded["/skeleton_poses"]}
    assert bag_poses == {k for k in bag_skel if k >= min(bag_poses)}
    assert all(m.header.frame_id == SKELETON_FRAME and len(m.poses) == 15 for m in recorded["/skeleton_poses"])


@pytest.mark.ros
def test_predicted_trajectory_is_on_by_default_and_carries_every_prediction_at_its_stamp(ros):
    probe = ros.probe
    diagnostics = ros.diagnostics
    preds = probe.subscribe("/predictions", Float64MultiArray)
    trajectories = probe.subscribe("/predicted_trajectory", JointTrajectory)
    horizon, period = 4, 0.05
    learner = ros.start("arm_predictor", params={**FAST, "checkpoint_interval_s": 0.0, "horizon": horizon,
                                                 "frame_period_s": period})
    ros.wait_for_node(diagnostics, "/arm_predictor", timeout=60)
    pub = probe.publisher("/arm_angles", JointState)
    probe.wait_for_subscribers(pub)
    n = 24
    for i in range(n):
        t = 100.0 + period * i + 1e-4 * math.sqrt(i)  # stamps no float rounds to a whole nanosecond
        pub.publish(messages.joint_state(t, ARM_JOINTS, POSE + 0.15 * np.sin(0.3 * i + np.arange(8))))
        probe.spin_for(0.01)
    probe.spin_until(lambda: len(preds) >= n - 2 * horizon - 2 and len(trajectories) == len(preds), 30,
                     "a trajectory per prediction", [learner])
    for p_msg, t_msg in zip(preds, trajectories, strict=True):
        stamp, names, p = messages.read_predictions(p_msg)
        assert (t_msg.header.stamp.sec, t_msg.header.stamp.nanosec) == conventions.split_stamp(stamp)
        _, t_names, traj = standard_messages.read_joint_trajectory(t_msg)
        assert t_names == names == ARM_JOINTS and p.shape == (horizon, 8)
        np.testing.assert_allclose(traj.times_from_start, period * np.arange(1, horizon + 1), atol=1e-9)
        np.testing.assert_array_equal(traj.positions, p)


@pytest.mark.ros
def test_an_empty_frame_for_the_poses_stops_the_source_naming_the_parameter(ros):
    code, output = ros.run("skeleton_source", params={"frame_id": ""})
    assert code == 2 and "parameter 'frame_id' is empty" in output
