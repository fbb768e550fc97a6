"""ROS4HRI bodies -> Nao arm angles: the human model's joint states give the angles the skeleton path gives
for the same arm directions (known poses, random poses through both, the Nao chain reproducing the
directions), body selection, and the node fed synthesised REP-155 messages in a real process."""

import numpy as np
import pytest
import yaml

from gwr_predictor.data import hri_bodies
from gwr_predictor.data.angles import skeleton_to_angles
from gwr_predictor.data.errors import DataError
from gwr_predictor.data.hri_bodies import (
    HUMAN_ARM_JOINTS,
    arm_directions,
    body_arm_joints,
    body_to_nao,
    choose_body,
    ids_from_topics,
)
from gwr_predictor.nodes import messages
from gwr_predictor.nodes.messages import JointState
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS
from gwr_predictor.robot.nao import ARM_JOINTS, rot_x, rot_y, rot_z

PI2 = np.pi / 2
#: hri_fullbody's 20 joint names (jointstate.HUMAN_JOINT_NAMES), published as `<name>_<body id>`.
HRI_FULLBODY_JOINTS = ("waist", "r_head", "y_head", "p_head",
                       "l_y_shoulder", "l_p_shoulder", "l_r_shoulder", "l_elbow",
                       "r_y_shoulder", "r_p_shoulder", "r_r_shoulder", "r_elbow",
                       "l_y_hip", "l_p_hip", "l_r_hip", "l_knee", "r_y_hip", "r_p_hip", "r_r_hip", "r_knee")
ELBOW_STRAIGHT_L, ELBOW_STRAIGHT_R = -0.0349066, 0.0349066  # the Nao's straightest elbow roll


def both(chain):
    """The same human chain angles (y, p, r, elbow) on both arms."""
    return np.array(list(chain) * 2, dtype=float)


# --- known poses ---------------------------------------------------------------------------------


@pytest.mark.parametrize(("pose", "human", "nao"), [
    ("arms down", both([0, 0, 0, 0]), [PI2, 0, -PI2, ELBOW_STRAIGHT_L, PI2, 0, PI2, ELBOW_STRAIGHT_R]),
    ("arms forward", both([PI2, PI2, 0, 0]), [0, 0, -PI2, ELBOW_STRAIGHT_L, 0, 0, PI2, ELBOW_STRAIGHT_R]),
    ("arms sideways", both([0, PI2, 0, 0]), [0, 1.32645, -PI2, ELBOW_STRAIGHT_L, 0, -1.32645, PI2, ELBOW_STRAIGHT_R]),
    ("arms down, forearms forward", both([0, 0, 0, PI2]), [PI2, 0, -PI2, -1.54462, PI2, 0, PI2, 1.54462]),
    ("arms up", both([0, np.pi, 0, 0]), [-PI2, 0, -PI2, ELBOW_STRAIGHT_L, -PI2, 0, PI2, ELBOW_STRAIGHT_R]),
])
def test_known_poses_give_the_expected_nao_angles(pose, human, nao):
    clipped, _ = body_to_nao(human)
    np.testing.assert_allclose(clipped, nao, atol=1e-9, err_msg=pose)


def test_human_model_chain_conventions():
    u, f = arm_directions(np.zeros(4), "L")
    np.testing.assert_allclose([u, f], [[0, 0, -1], [0, 0, -1]], atol=1e-12)  # hanging
    u, _ = arm_directions([0, 0.5, 0, 0], "L")
    assert u[1] > 0.4  # p_shoulder raises the left arm to the left (+y)
    u, _ = arm_directions([0, 0.5, 0, 0], "R")
    assert u[1] < -0.4  # ... and the right arm to the right
    u, _ = arm_directions([0.5, PI2, 0, 0], "L")
    assert u[0] > 0.4  # y_shoulder swings a raised arm forward
    _, f = arm_directions([0, 0, 0, 0.5], "R")
    assert f[0] > 0.4  # elbow flexion brings a hanging forearm forward


# --- the same conventions as the skeleton path ---------------------------------------------------


def random_human(rng, n):
    return np.concatenate([np.stack([rng.uniform(-1.7, 1.1, n), rng.uniform(-0.4, 3.0, n),
                                     rng.uniform(-1.7, 1.5, n), rng.uniform(0.0, 2.5, n)], axis=-1)] * 2, axis=-1) \
        + rng.normal(0, 0.05, (n, 8))


def skeleton_from_human(human, camera):
    """A 15-joint skeleton whose arms have the human model's directions, seen by a camera of rotation `camera`."""
    n = human.shape[0]
    pos = np.zeros((n, len(SKELETON_JOINTS), 3))
    at = {name: i for i, name in enumerate(SKELETON_JOINTS)}
    fixed = {"head": (0, 0, 0.75), "neck": (0, 0, 0.55), "torso": (0, 0, 0.25), "left_hip": (0, 0.1, 0),
             "right_hip": (0, -0.1, 0), "left_knee": (0, 0.1, -0.45), "right_knee": (0, -0.1, -0.45),
             "left_foot": (0, 0.1, -0.9), "right_foot": (0, -0.1, -0.9), "left_shoulder": (0, 0.2, 0.5),
             "right_shoulder": (0, -0.2, 0.5)}
    for name, xyz in fixed.items():
        pos[:, at[name]] = xyz
    for k, (side, prefix) in enumerate((("L", "left"), ("R", "right"))):
        u, f = arm_directions(human[:, 4 * k:4 * k + 4], side)
        pos[:, at[f"{prefix}_elbow"]] = pos[:, at[f"{prefix}_shoulder"]] + 0.3 * u
        pos[:, at[f"{prefix}_hand"]] = pos[:, at[f"{prefix}_elbow"]] + 0.25 * f
    return pos @ camera.T + np.array([0.1, -0.2, 2.5])


def test_joint_states_and_a_skeleton_of_the_same_arms_give_the_same_angles():
    rng = np.random.default_rng(7)
    human = random_human(rng, 400)
    # OpenNI-like camera: the person faces it (x right, y up, z away from the sensor), slightly tilted
    camera = rot_x(0.2) @ np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])
    from_joints, raw = body_to_nao(human)
    from_skeleton = skeleton_to_angles(skeleton_from_human(human, camera))
    np.testing.assert_allclose(from_joints, from_skeleton, atol=1e-9)
    assert np.any(raw != from_joints)  # some poses needed the clip: it is the same clip


def test_the_nao_chain_reproduces_the_human_arm_directions():
    rng = np.random.default_rng(11)
    human = random_human(rng, 2000)
    _, raw = body_to_nao(human)
    x = np.array([1.0, 0.0, 0.0])
    for k, side in enumerate("LR"):
        u, f = arm_directions(human[:, 4 * k:4 * k + 4], side)
        pitch, roll, yaw, eroll = raw[:, 4 * k:4 * k + 4].T
        shoulder = rot_y(pitch) @ rot_z(roll)
        u_nao, f_nao = shoulder @ x, shoulder @ rot_x(yaw) @ rot_z(eroll) @ x
        # outside the two smoothed singular zones (angles.py) the inversion is exact
        regular = (np.hypot(u[:, 0], u[:, 2]) > 0.35) & (np.sin(np.abs(eroll)) > 0.7)
        assert regular.sum() > 300
        np.testing.assert_allclose(u_nao[regular], u[regular], atol=1e-9)
        np.testing.assert_allclose(f_nao[regular], f[regular], atol=1e-9)


def test_mirrored_arms_give_mirrored_nao_angles():
    rng = np.random.default_rng(5)
    chain = random_human(rng, 100)[:, :4]
    _, raw = body_to_nao(np.concatenate([chain, chain], axis=-1))
    np.testing.assert_allclose(raw[:, 4:], raw[:, :4] * [1, -1, -1, -1], atol=1e-9)


# --- reading joint states ---------------------------------------------------------------------------


def test_hri_fullbody_joint_names_with_the_body_suffix_are_read_in_order():
    values = np.arange(20) * 0.01
    names = [f"{n}_b7x" for n in HRI_FULLBODY_JOINTS]
    got = body_arm_joints(names, values, "b7x")
    np.testing.assert_array_equal(got, [values[HRI_FULLBODY_JOINTS.index(j)] for j in HUMAN_ARM_JOINTS])
    np.testing.assert_array_equal(body_arm_joints(list(HRI_FULLBODY_JOINTS), values, "b7x"), got)  # bare names


@pytest.mark.parametrize(("names", "values", "reason"), [
    (list(HRI_FULLBODY_JOINTS), np.zeros(19), "layout"),
    (list(HRI_FULLBODY_JOINTS[:7]), np.zeros(7), "missing_joints"),
    (list(HRI_FULLBODY_JOINTS), np.r_[np.zeros(5), np.nan, np.zeros(14)], "non_finite"),
    (["l_elbow", "l_elbow_b1"], np.zeros(2), "layout"),
])
def test_unusable_joint_states_raise_with_a_reason(names, values, reason):
    with pytest.raises(DataError) as err:
        body_arm_joints(names, values, "b1")
    assert err.value.reason == reason


# --- choosing the body ---------------------------------------------------------------------------


def test_first_keeps_the_followed_body_while_it_is_tracked():
    assert choose_body([], None) is None
    assert choose_body(["b2", "b1"], None) == "b2"
    assert choose_body(["b2", "b1"], "b1") == "b1"
    assert choose_body(["b3"], "b1") == "b3"
    assert choose_body(["bad/id", "ok"], None) == "ok"


def test_nearest_uses_positions_with_a_margin_against_flicker():
    d = {"a": 2.0, "b": 1.9, "c": 1.0}
    assert choose_body(["a", "b"], None, "nearest", d) == "b"
    assert choose_body(["a", "b"], "a", "nearest", d, switch_margin_m=0.2) == "a"  # only 0.1 m nearer
    assert choose_body(["a", "b", "c"], "a", "nearest", d, switch_margin_m=0.2) == "c"
    assert choose_body(["x", "a"], None, "nearest", d) == "a"  # a known distance beats none
    assert choose_body(["x", "y"], None, "nearest", d) == "x"  # no distances: as 'first'
    with pytest.raises(DataError, match="selection"):
        choose_body(["a"], None, "tallest")


def test_ids_from_graph_topics():
    topics = ["/humans/bodies/b1/joint_states", "/humans/bodies/b2/roi", "/humans/bodies/tracked",
              "/other/bodies/b3/joint_states", "/humans/bodies/b0/joint_states"]
    assert ids_from_topics(topics) == ["b0", "b1"]
    assert ids_from_topics(topics, "/other/bodies/") == ["b3"]


def test_config_yaml_names_only_declared_parameters():
    from ros_harness import ROOT

    from gwr_predictor.nodes.hri_bodies import PARAMS
    from gwr_predictor.nodes.pipeline_node import COMMON_PARAMS

    specs = {s.name: s for s in (*COMMON_PARAMS, *PARAMS)}
    values = yaml.safe_load((ROOT / "config" / "hri_bodies.yaml").read_text())["/**/hri_bodies"]["ros__parameters"]
    assert set(values) <= set(specs)
    for name, value in values.items():
        specs[name].check(value)


# --- the node, in a real process -------------------------------------------------------------------


def hri_joint_state(stamp, body, human, drop=()):
    values = dict.fromkeys(HRI_FULLBODY_JOINTS, 0.0)
    values.update(zip(HUMAN_ARM_JOINTS, human, strict=True))
    names = [n for n in HRI_FULLBODY_JOINTS if n not in drop]
    return messages.joint_state(stamp, [f"{n}_{body}" for n in names], [values[n] for n in names])


@pytest.mark.ros
def test_node_follows_a_discovered_body_and_publishes_its_nao_angles(ros):
    probe = ros.probe
    diagnostics = ros.diagnostics
    proc = ros.start_ready("hri_bodies", params={"discovery_period_s": 0.2, "diagnostics_period_s": 0.2})
    angles = probe.subscribe("/arm_angles", JointState)
    tracker = probe.publisher(f"{hri_bodies.BODIES_NAMESPACE}/k3p/joint_states", JointState)
    probe.spin_until(lambda: diagnostics["/hri_bodies"].get("body") == "k3p", 20, "body k3p followed", [proc])
    probe.wait_for_subscribers(tracker, 1)
    forward = both([PI2, PI2, 0, 0])
    down = both([0, 0, 0, 0])
    t0 = 1000.0
    frames = [forward, forward, down, down, down, down]  # median of 3: forward, then down
    for i, human in enumerate(frames):
        tracker.publish(hri_joint_state(t0 + i / 30, "k3p", human))
    tracker.publish(hri_joint_state(t0 + 7 / 30, "k3p", down, drop=("r_elbow",)))
    probe.spin_until(lambda: len(angles) >= 2 and "rejected.joint_states.missing_joints"
                     in diagnostics["/hri_bodies"], 20, "two angle frames and the rejection", [proc])
    first, second = (messages.read_joint_state(m) for m in angles[:2])
    assert first[1] == ARM_JOINTS
    assert first[0] == pytest.approx(t0 + 1 / 30) and second[0] == pytest.approx(t0 + 4 / 30)  # middle frames
    np.testing.assert_allclose(first[2], body_to_nao(forward)[0], atol=1e-9)
    np.testing.assert_allclose(second[2], body_to_nao(down)[0], atol=1e-9)
    assert diagnostics["/hri_bodies"]["angles.clipped_to_limits"] == "2"  # straight elbows clip
    assert proc.running


# --- input rules, on the node in process -------------------------------------------------------------


@pytest.fixture
def hri_node():
    import rclpy
    from ros_harness import allocate_domain_id, release_domain_id

    from gwr_predictor.nodes.hri_bodies import HriBodiesNode

    domain = allocate_domain_id()
    rclpy.init(args=["--ros-args", "-p", "body_id:=b1", "-p", "selection:=nearest", "-p", "median_of_3:=false",
                     "-p", "stop_if_duplicate:=false"], domain_id=domain)
    node = HriBodiesNode()
    try:
        yield node
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        release_domain_id(domain)


def test_oversized_joint_states_and_another_bodys_frame_are_rejected_and_counted(hri_node):
    node, down = hri_node, both([0, 0, 0, 0])
    huge = messages.JointState()
    huge.name = [f"j{i}_b1" for i in range(200_008)]  # about 4 MB on the wire
    huge.position = np.zeros(200_008)
    huge.header.stamp = messages.to_time(1000.0)
    node.on_joint_states("b1", huge)
    crossed = hri_joint_state(1000.1, "b1", down)
    crossed.header.frame_id = "body_b2"  # the other body's joint states on this body's topic
    node.on_joint_states("b1", crossed)
    values = node.diagnostic_values()
    assert values["rejected.joint_states.too_large"] == 1 and values["rejected.joint_states.frame_id"] == 1
    assert node.counters.get("joint_states.accepted") == 0
    for i, frame in enumerate(("", "body_b1", "torso_b1")):  # no frame, or one of the body's own
        own = hri_joint_state(1000.2 + i / 30, "b1", down)
        own.header.frame_id = frame
        node.on_joint_states("b1", own)
    assert node.counters.get("joint_states.accepted") == 3 and node.counters.get("angles.published") == 3


def test_positions_in_another_frame_are_rejected_and_counted(hri_node):
    from geometry_msgs.msg import PointStamped

    def position(frame, x):
        msg = PointStamped()
        msg.header.frame_id = frame
        msg.point.x = x
        return msg

    node = hri_node
    node.on_position("b1", position("camera_color_optical_frame", 2.0))
    node.on_position("b2", position("map", 1.0))  # nearer, but measured from elsewhere
    node.on_position("b3", position("", 0.5))
    assert node.distances == {"b1": 2.0}
    assert node.diagnostic_values()["rejected.position.frame_id"] == 2
