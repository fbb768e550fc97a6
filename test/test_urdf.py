"""The generated Nao URDF: shipped copy, joints and limits, and agreement with nao.forward_kinematics."""

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from gwr_predictor.robot import nao
from gwr_predictor.robot.pybullet_nao import NaoSimulator
from gwr_predictor.robot.urdf import HAND_LINKS, build_nao_urdf, default_urdf_path, write_urdf

AXES = {"ShoulderPitch": "0 1 0", "ShoulderRoll": "0 0 1", "ElbowYaw": "1 0 0", "ElbowRoll": "0 0 1",
        "WristYaw": "1 0 0"}


@pytest.fixture(scope="module")
def robot() -> ET.Element:
    return ET.fromstring(build_nao_urdf())


def test_shipped_urdf_equals_a_fresh_build():
    assert default_urdf_path().read_text(encoding="utf-8") == build_nao_urdf()


def test_write_urdf_writes_the_build_to_a_chosen_path(tmp_path):
    path = write_urdf(tmp_path / "sub" / "nao.urdf")
    assert path.read_text(encoding="utf-8") == build_nao_urdf()


def test_revolute_joints_are_exactly_the_robot_arm_joints(robot):
    revolute = [j.get("name") for j in robot.findall("joint") if j.get("type") == "revolute"]
    assert sorted(revolute) == sorted(nao.ROBOT_ARM_JOINTS)


def test_arm_joints_carry_nao_axes_limits_and_velocities(robot):
    for joint in robot.findall("joint"):
        name = joint.get("name")
        if joint.get("type") != "revolute":
            continue
        assert joint.find("axis").get("xyz") == AXES[name[1:]], name
        limit = joint.find("limit")
        lo, hi = nao.JOINT_LIMITS[name]
        assert float(limit.get("lower")) == pytest.approx(lo, abs=1e-12)
        assert float(limit.get("upper")) == pytest.approx(hi, abs=1e-12)
        assert float(limit.get("velocity")) == pytest.approx(nao.VELOCITY_LIMITS[name])
        assert float(limit.get("effort")) > 0


def test_hand_frames_are_fixed_links_at_the_hand_offset(robot):
    for side, link in HAND_LINKS.items():
        joint = next(j for j in robot.findall("joint") if j.find("child").get("link") == link)
        assert joint.get("type") == "fixed"
        offset = np.array([float(v) for v in joint.find("origin").get("xyz").split()])
        np.testing.assert_allclose(offset, nao.side_offsets(side)[3], atol=1e-12)


def test_every_link_has_positive_mass_and_inertia(robot):
    for link in robot.findall("link"):
        inertial = link.find("inertial")
        assert float(inertial.find("mass").get("value")) > 0, link.get("name")
        moments = [float(inertial.find("inertia").get(k)) for k in ("ixx", "iyy", "izz")]
        assert min(moments) > 0, link.get("name")
        a, b, c = sorted(moments)
        assert a + b >= c * (1 - 1e-9), f"{link.get('name')}: moments violate the triangle inequality"


def test_pybullet_link_frames_match_forward_kinematics():
    rng = np.random.default_rng(7)
    lo, hi = nao.limits_array()
    with NaoSimulator() as sim:
        for _ in range(25):
            angles = rng.uniform(lo, hi)
            sim.reset(angles)
            expected = nao.forward_kinematics(angles)
            got = sim.arm_points()
            for side in nao.SIDES:
                for point in ("shoulder", "elbow", "wrist", "hand"):
                    np.testing.assert_allclose(getattr(got[side], point), getattr(expected[side], point),
                                               atol=1e-6, err_msg=f"{side} {point} at {angles}")


def test_wrist_yaw_turns_the_hand_like_forward_kinematics():
    angles = np.array([0.3, 0.4, -0.7, -1.0, 0.2, -0.5, 0.9, 1.1])
    with NaoSimulator() as sim:
        sim.reset({**dict(zip(nao.ARM_JOINTS, angles, strict=True)), "LWristYaw": 1.2, "RWristYaw": -0.6})
        got = sim.arm_points()
    for side, yaw in (("L", 1.2), ("R", -0.6)):
        sel = angles[:4] if side == "L" else angles[4:]
        np.testing.assert_allclose(got[side].hand, nao.arm_forward_kinematics(side, sel, yaw).hand, atol=1e-6)
