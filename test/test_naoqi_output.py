"""The naoqi output: commands for a real Nao are clipped into the joint limits and rate-limited before they
leave, in naoqi_bridge_msgs/JointAnglesWithSpeed on `joint_angles`; the message package is imported only
when that output is chosen. naoqi_bridge_msgs has no wheel here, so the message is a stand-in class of
the same fields (injected as `naoqi_bridge_msgs.msg`), and a real process can only show the missing-package
stop."""

import sys
import types

import numpy as np
import pytest
import rclpy

from gwr_predictor.nodes import messages
from gwr_predictor.parameters.spec import ParameterError
from gwr_predictor.robot import naoqi_output
from gwr_predictor.robot.errors import RobotError
from gwr_predictor.robot.nao import ARM_JOINTS, limits_array
from gwr_predictor.robot.naoqi_output import SafeArmCommands

LO, HI = limits_array()
DOWN = np.array([1.5, 0.1, -1.2, -0.4, 1.5, -0.1, 1.2, 0.4])  # inside every limit


class _Header:
    def __init__(self):
        self.stamp = None
        self.frame_id = ""


class JointAnglesWithSpeed:
    """Stand-in of naoqi_bridge_msgs/msg/JointAnglesWithSpeed: the same fields, nothing else."""

    __slots__ = ("header", "joint_angles", "joint_names", "relative", "speed")

    def __init__(self):
        self.header, self.joint_names, self.joint_angles, self.speed, self.relative = _Header(), [], [], 0.0, 0


@pytest.fixture
def fake_naoqi_msgs(monkeypatch):
    package, module = types.ModuleType("naoqi_bridge_msgs"), types.ModuleType("naoqi_bridge_msgs.msg")
    module.JointAnglesWithSpeed = JointAnglesWithSpeed
    package.msg = module
    monkeypatch.setitem(sys.modules, "naoqi_bridge_msgs", package)
    monkeypatch.setitem(sys.modules, "naoqi_bridge_msgs.msg", module)
    return JointAnglesWithSpeed


# --- the library: clip, rate limit, message fields -------------------------------------------------


def test_commands_are_clipped_into_the_joint_limits():
    safe = SafeArmCommands(max_joint_speed=2.0)
    out, limited = safe.command(0.0, DOWN + np.array([3.0, 3.0, 3.0, 3.0, -3.0, -3.0, -3.0, -3.0]))
    assert not limited  # nothing to limit against: no earlier command, no robot pose
    np.testing.assert_array_equal(out, np.clip(DOWN + [3, 3, 3, 3, -3, -3, -3, -3], LO, HI))
    assert np.all((out >= LO) & (out <= HI))


def test_each_command_moves_at_most_max_joint_speed_times_the_time_since_the_last():
    safe = SafeArmCommands(max_joint_speed=2.0, max_step_s=0.2)
    safe.command(10.0, DOWN)
    jump = DOWN.copy()
    jump[0] = -1.5  # shoulder pitch 3 rad away
    out, limited = safe.command(10.1, jump)
    assert limited
    assert out[0] == pytest.approx(DOWN[0] - 2.0 * 0.1)
    np.testing.assert_array_equal(out[1:], DOWN[1:])
    # a pause does not release a jump: the elapsed time counts at most max_step_s
    out, _ = safe.command(20.0, jump)
    assert out[0] == pytest.approx(DOWN[0] - 0.2 - 2.0 * 0.2)
    # a command that is close enough passes unchanged
    near = out + 0.01
    again, limited = safe.command(20.1, near)
    assert not limited and np.allclose(again, near)


def test_the_first_command_is_limited_from_the_robots_reported_pose():
    safe = SafeArmCommands(max_joint_speed=1.0, max_step_s=0.1)
    robot = DOWN.copy()
    target = DOWN + 1.0 * np.sign(HI - DOWN)  # 1 rad towards the upper limits (inside them)
    out, limited = safe.command(0.0, target, robot_pose=robot)
    assert limited
    np.testing.assert_allclose(np.abs(out - robot), 0.1)


def test_a_random_command_stream_never_leaves_the_limits_nor_exceeds_the_speed():
    rng = np.random.default_rng(3)
    safe = SafeArmCommands(max_joint_speed=1.5, max_step_s=0.2)
    t, previous = 0.0, None
    for _ in range(300):
        dt = rng.uniform(0.0, 0.3)
        t += dt
        out, _ = safe.command(t, rng.uniform(-4.0, 4.0, 8))
        assert np.all((out >= LO) & (out <= HI))
        if previous is not None:
            assert np.max(np.abs(out - previous)) <= 1.5 * min(dt, 0.2) + 1e-12
        previous = out


def test_bad_commands_and_settings_raise_the_packages_error():
    with pytest.raises(RobotError, match="8 finite angles"):
        SafeArmCommands(2.0).command(0.0, [np.nan] * 8)
    with pytest.raises(RobotError, match="8 finite angles"):
        SafeArmCommands(2.0).command(0.0, [0.0] * 7)
    with pytest.raises(ParameterError, match="max_joint_speed"):
        SafeArmCommands(0.0)


def test_message_fields_are_those_of_joint_angles_with_speed(fake_naoqi_msgs):
    msg = naoqi_output.fill_message(naoqi_output.message_type()(), DOWN + 1e-9, 0.3)
    assert isinstance(msg, JointAnglesWithSpeed)
    assert msg.joint_names == list(ARM_JOINTS)
    assert msg.joint_angles == [float(v) for v in (DOWN + 1e-9).astype(np.float32)]  # float32[] on the wire
    assert msg.speed == 0.3 and msg.relative == 0  # absolute angles (relative=1 would be changeAngles)


def test_without_naoqi_bridge_msgs_the_error_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "naoqi_bridge_msgs", None)  # import fails as if not installed
    monkeypatch.setitem(sys.modules, "naoqi_bridge_msgs.msg", None)
    with pytest.raises(RobotError, match=r"needs the naoqi_bridge_msgs/msg/JointAnglesWithSpeed message.*"
                                               r"ros-jazzy-naoqi-bridge-msgs"):
        naoqi_output.message_type()


def test_speed_warning_when_naoqi_moves_slower_than_the_rate_limit_allows():
    assert naoqi_output.speed_warning(0.3, 2.0) is None  # 0.3 x 7.19 = 2.16 rad/s
    assert "lag" in naoqi_output.speed_warning(0.1, 2.0)


# --- the delay_compensator's naoqi branch, in process ------------------------------------------------


@pytest.fixture
def naoqi_compensator(fake_naoqi_msgs, monkeypatch):
    from ros_harness import allocate_domain_id, release_domain_id

    from gwr_predictor.nodes.delay_compensator import DelayCompensatorNode

    created = {}
    original = DelayCompensatorNode.create_publisher

    def create_publisher(self, msg_type, topic, qos, **kwargs):
        if msg_type is fake_naoqi_msgs:  # no type support for a stand-in: record instead of publishing
            created["topic"], created["sent"] = topic, []
            return types.SimpleNamespace(publish=created["sent"].append)
        return original(self, msg_type, topic, qos, **kwargs)

    monkeypatch.setattr(DelayCompensatorNode, "create_publisher", create_publisher)
    domain = allocate_domain_id()
    rclpy.init(args=["--ros-args", "-p", "output:=naoqi", "-p", "mode:=none", "-p", "naoqi_speed:=0.4",
                     "-p", "max_joint_speed:=1.0", "-p", "stop_if_duplicate:=false"], domain_id=domain)
    node = DelayCompensatorNode()
    try:
        yield node, created
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        release_domain_id(domain)


def observation(stamp, angles):
    return messages.joint_state(stamp, ARM_JOINTS, angles)


def test_output_naoqi_publishes_rate_limited_joint_angles_with_speed_on_joint_angles(naoqi_compensator):
    node, created = naoqi_compensator
    assert created["topic"] == "joint_angles"  # relative: a namespaced pipeline drives its own robot
    assert node.command_pub is None and node.trajectory_pub is None
    now = node.now_s()
    node.on_observation(observation(now - 0.2, DOWN))
    raised = DOWN.copy()
    raised[4] = -1.0  # right shoulder pitch 2.5 rad away, at once
    node.on_observation(observation(now - 0.1, raised))
    first, second = created["sent"]
    assert isinstance(second, JointAnglesWithSpeed)
    assert second.joint_names == list(ARM_JOINTS) and second.speed == pytest.approx(0.4) and second.relative == 0
    np.testing.assert_allclose(first.joint_angles, DOWN, atol=1e-6)
    step = second.joint_angles[4] - first.joint_angles[4]
    assert -0.2 - 1e-6 <= step < 0.0  # at most 1 rad/s x (time between the two, capped at max_step_s)
    assert messages.from_time(second.header.stamp) > messages.from_time(first.header.stamp)
    assert node.counters.get("naoqi.rate_limited") == 1 and node.counters.get("naoqi.published") == 2


@pytest.mark.ros
def test_output_naoqi_without_the_message_package_stops_with_one_clear_line(ros):
    code, out = ros.run("delay_compensator", params={"output": "naoqi"}, timeout=30)
    assert code == 1, out
    lines = [line for line in out.splitlines() if "naoqi_bridge_msgs" in line]
    assert len(lines) == 1 and "stopping: output 'naoqi' needs" in lines[0], out
    assert "Traceback" not in out


def test_absurd_but_finite_predictions_are_rejected_with_a_warning_not_clipped(naoqi_compensator):
    node, created = naoqi_compensator
    now = node.now_s()
    predictions = np.tile(DOWN, (6, 1))
    predictions[3, 1] = 1e300  # finite, and no angle of a shoulder
    node.on_predictions(messages.predictions_msg(now - 0.1, predictions))
    assert node.counters.get("predictions.received") == 0
    assert node.diagnostic_values()["rejected.predictions.out_of_range"] == 1
    overshoot = np.tile(DOWN, (6, 1))
    overshoot[5, 0] += 1.0  # past a limit by 1 rad: an extrapolation the robot's input clips
    node.on_predictions(messages.predictions_msg(now - 0.05, overshoot))
    assert node.counters.get("predictions.received") == 1 and not created["sent"]  # mode none commands no prediction
