"""The ROS-free halves of the standard views and interfaces: K4ABT body tracking -> skeleton, marker
geometry, trajectories, the 10-joint robot state (no DDS here; test_standard_interfaces.py runs nodes)."""

import xml.etree.ElementTree as ET

import numpy as np
import pytest
from k4abt_bodies import body, markers

from gwr_predictor.data import k4abt
from gwr_predictor.data.angles import skeleton_to_angles
from gwr_predictor.data.demonstrator import default_subjects, demonstrate_one
from gwr_predictor.data.errors import DataError
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS
from gwr_predictor.pipeline.markers import SKELETON_BONES, arm_figure, skeleton_figure
from gwr_predictor.pipeline.trajectory import command_trajectory, prediction_trajectory
from gwr_predictor.robot import nao
from gwr_predictor.robot.urdf import default_urdf_path

A = {name: i for i, name in enumerate(nao.ARM_JOINTS)}


def angles_of(bodies: dict) -> tuple[k4abt.TrackedBody, np.ndarray]:
    tracked = k4abt.nearest_body(*markers(bodies))
    return tracked, skeleton_to_angles(tracked.positions, SKELETON_JOINTS, clip=False)


def test_k4abt_index_table_is_the_sdk_order():
    assert k4abt.N_JOINTS == 32
    for index, name in ((0, "PELVIS"), (3, "NECK"), (5, "SHOULDER_LEFT"), (7, "WRIST_LEFT"), (12, "SHOULDER_RIGHT"),
                        (14, "WRIST_RIGHT"), (18, "HIP_LEFT"), (22, "HIP_RIGHT"), (26, "HEAD"), (31, "EAR_RIGHT")):
        assert k4abt.K4ABT_JOINTS[index] == name


def test_arm_pointing_at_the_sensor_is_pitch_zero_and_hanging_arm_pitch_half_pi():
    """Geometry written from the sensor's frame only: sides and handedness of the mapping are right."""
    _, a = angles_of({1: body(left_arm="forward")})
    assert abs(a[A["LShoulderPitch"]]) < 0.05 and abs(a[A["LShoulderRoll"]]) < 0.05
    assert abs(a[A["RShoulderPitch"]] - np.pi / 2) < 0.15 and abs(a[A["RShoulderRoll"]]) < 0.1


def test_left_arm_raised_to_the_persons_left_is_a_positive_left_shoulder_roll():
    _, a = angles_of({1: body(left_arm="sideways")})
    assert a[A["LShoulderRoll"]] > 1.3  # ~pi/2 unclipped (the Nao stops at 1.33): away from the body
    _, down = angles_of({1: body(left_arm="down")})
    assert abs(down[A["LShoulderRoll"]]) < 0.1 and abs(down[A["LShoulderPitch"]] - np.pi / 2) < 0.15


def test_the_nearest_of_several_bodies_is_chosen_whatever_the_ids():
    near, far = body(distance=1.8, left_arm="forward"), body(distance=3.2, left_arm="sideways", lateral=0.4)
    tracked, a = angles_of({2: far, 7: near})
    assert tracked.body_id == 7 and tracked.n_bodies == 2
    assert abs(a[A["LShoulderPitch"]]) < 0.05  # the near person's pose, not the far one's raised arm
    far_only = body(distance=3.2, left_arm="sideways")
    del far_only[0]  # no pelvis: its distance comes from the mean of its joints
    assert k4abt.nearest_body(*markers({3: far_only, 9: near})).body_id == 9


def test_untracked_joints_are_nan_and_unknown_joint_indices_are_counted():
    ids, xyz = markers({4: body()})
    ids = np.append(ids, [4 * 100 + 40, 4 * 100 + 99])
    xyz = np.vstack([xyz, np.zeros((2, 3))])
    tracked = k4abt.nearest_body(ids, xyz)
    assert tracked.unknown_markers == 2
    names = dict(zip(SKELETON_JOINTS, tracked.positions, strict=True))
    assert all(np.isnan(names[n]).all() for n in ("left_knee", "left_foot", "right_knee", "right_foot"))
    assert np.isfinite(names["left_hand"]).all()
    # the skeleton convention: the person's right at +x (the sensor's left), y up, depth unchanged
    assert names["right_shoulder"][0] > names["left_shoulder"][0]
    assert names["head"][1] > names["torso"][1]
    assert names["torso"][2] == pytest.approx(2.0)


def test_bad_marker_ids_are_named():
    assert k4abt.nearest_body(np.zeros(0), np.zeros((0, 3))) is None
    with pytest.raises(DataError, match="negative marker ids"):
        k4abt.nearest_body(np.array([-5]), np.zeros((1, 3)))
    with pytest.raises(DataError, match="2 marker ids"):
        k4abt.group_bodies(np.array([1, 2]), np.zeros((3, 3)))


def test_demonstrator_skeleton_survives_the_round_trip_through_k4abt_markers():
    """A whole demonstrator sequence as driver messages: the arm angles are those of the original."""
    seq = demonstrate_one("wave_both", default_subjects(1)[0], repetition=1, seed=0)
    frames = seq.positions[::10]
    for frame in frames:
        joints = k4abt.from_skeleton(frame)
        present = np.flatnonzero(np.all(np.isfinite(joints), axis=1))
        tracked = k4abt.nearest_body(100 + present, joints[present])
        np.testing.assert_allclose(tracked.positions, frame, atol=1e-12)
    expected = skeleton_to_angles(frames, SKELETON_JOINTS)
    got = skeleton_to_angles(np.stack([k4abt.to_skeleton(k4abt.from_skeleton(f)) for f in frames]), SKELETON_JOINTS)
    np.testing.assert_allclose(got, expected, atol=1e-9)


def test_skeleton_figure_leaves_out_untracked_joints_and_their_bones():
    frame = np.arange(45, dtype=float).reshape(15, 3)
    full = skeleton_figure(frame)
    assert full.points.shape == (15, 3) and full.segments.shape == (2 * len(SKELETON_BONES), 3)
    frame[SKELETON_JOINTS.index("left_hand")] = np.nan
    part = skeleton_figure(frame)
    assert part.points.shape == (14, 3) and part.segments.shape == (2 * (len(SKELETON_BONES) - 1), 3)
    assert np.isfinite(part.segments).all()
    # consecutive rows are the two ends of a bone
    ends = {tuple(part.segments[i]) for i in range(0, len(part.segments), 2)}
    assert tuple(frame[SKELETON_JOINTS.index("head")]) in ends


def test_arm_figure_is_the_forward_kinematics():
    pose = np.array([0.0, 0.0, 0.0, -0.04, np.pi / 2, 0.0, 0.0, 0.04])  # left arm ahead, right arm down
    fig = arm_figure(pose)
    assert fig.points.shape == (6, 3) and fig.segments.shape == (8, 3)
    left_hand, right_hand = fig.points[2], fig.points[5]
    assert left_hand[0] > 0.2 and right_hand[2] < -0.1  # ahead of the torso / below the shoulder


def test_prediction_trajectory_points_are_at_t_plus_k_periods():
    preds = np.arange(48, dtype=float).reshape(6, 8)
    traj = prediction_trajectory(preds, 0.1)
    np.testing.assert_allclose(traj.times_from_start, [0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    np.testing.assert_array_equal(traj.positions, preds)
    one = command_trajectory(preds[0], 0.25)
    assert one.times_from_start.tolist() == [0.25] and one.positions.shape == (1, 8)
    # a real robot's input: the pose is clipped into the joint limits there, once
    np.testing.assert_array_equal(one.positions[0], nao.clip_to_limits(preds[0]))
    inside = np.mean(nao.limits_array(), axis=0)
    np.testing.assert_array_equal(command_trajectory(inside, 0.1).positions[0], inside)
    with pytest.raises(ValueError, match="frame period"):
        prediction_trajectory(preds, 0.0)


def test_robot_state_covers_every_movable_urdf_joint():
    root = ET.parse(default_urdf_path()).getroot()
    movable = [j.get("name") for j in root.findall("joint") if j.get("type") != "fixed"]
    assert sorted(movable) == sorted(nao.ROBOT_ARM_JOINTS) and len(movable) == 10
    full = nao.robot_arm_positions(np.arange(8.0), (0.5, -0.5))
    by_name = dict(zip(nao.ROBOT_ARM_JOINTS, full, strict=True))
    assert [by_name[n] for n in nao.ARM_JOINTS] == list(range(8))
    assert by_name["LWristYaw"] == 0.5 and by_name["RWristYaw"] == -0.5
