"""Parameters as `ros2 param` sees them, through a plain rclpy client of the nodes' parameter services:
ranges in the descriptors, live changes (checked like at start, then in force), read-only ones refused."""

import time

import numpy as np
import pytest
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, SetParameters

from gwr_predictor.nodes import messages
from gwr_predictor.nodes.messages import Float64MultiArray, JointState
from gwr_predictor.robot.nao import ARM_JOINTS

FAST = {"diagnostics_period_s": 0.3}
POSE = np.array([1.2, 0.2, -1.0, -0.5, 1.2, -0.2, 1.0, 0.5])


def call(probe, node: str, service: str, srv_type, request, procs):
    client = probe.node.create_client(srv_type, f"{node}/{service}")
    probe.spin_until(client.service_is_ready, 20, f"the {service} service of {node}", procs)
    future = client.call_async(request)
    probe.spin_until(future.done, 20, f"{service} of {node}", procs)
    return future.result()


def describe(probe, node: str, names: list[str], procs) -> dict:
    reply = call(probe, node, "describe_parameters", DescribeParameters, DescribeParameters.Request(names=names),
                 procs)
    return {d.name: d for d in reply.descriptors}


def set_param(probe, node: str, name: str, value, procs):
    if isinstance(value, bool):
        v = ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=value)
    elif isinstance(value, float):
        v = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
    elif isinstance(value, int):
        v = ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=value)
    else:
        v = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value)
    reply = call(probe, node, "set_parameters", SetParameters,
                 SetParameters.Request(parameters=[Parameter(name=name, value=v)]), procs)
    return reply.results[0]


@pytest.mark.ros
def test_compensator_mode_and_delay_change_live_with_the_start_checks(ros):
    probe = ros.probe
    diagnostics = probe.subscribe_diagnostics()
    commands = probe.subscribe("/joint_commands", JointState)
    comp = ros.start("delay_compensator", params={**FAST, "mode": "none", "stale_after_s": 5.0})
    procs = [comp]
    ros.wait_for_node(diagnostics, "/delay_compensator", timeout=60)

    d = describe(probe, "/delay_compensator", ["delay_s", "frame_period_s", "mode"], procs)
    fp = d["delay_s"].floating_point_range[0]
    assert (fp.from_value, fp.to_value) == (0.0, 60.0) and not d["delay_s"].read_only
    assert "changed while the node runs" in d["delay_s"].additional_constraints
    assert d["frame_period_s"].read_only
    assert "read-only: read once at start" in d["frame_period_s"].additional_constraints
    assert d["frame_period_s"].floating_point_range[0].from_value == 0.001
    assert not d["mode"].read_only and "'variable'" in d["mode"].additional_constraints

    # refused: out of range, not a choice, read-only -- and nothing changes
    bad = set_param(probe, "/delay_compensator", "delay_s", 99.0, procs)  # refused by the descriptor's range
    assert not bad.successful and "delay_s" in bad.reason and "60.0" in bad.reason
    bad = set_param(probe, "/delay_compensator", "delay_s", 99, procs)  # an integer: the spec's own check
    assert not bad.successful and "outside the allowed range [0.0, 60.0]" in bad.reason
    bad = set_param(probe, "/delay_compensator", "mode", "sideways", procs)
    assert not bad.successful and "'sideways' is not allowed" in bad.reason
    bad = set_param(probe, "/delay_compensator", "frame_period_s", 0.2, procs)
    assert not bad.successful and "read-only" in bad.reason

    angles = probe.publisher("/arm_angles", JointState)
    preds = probe.publisher("/predictions", Float64MultiArray)
    probe.wait_for_subscribers(angles)
    probe.wait_for_subscribers(preds)
    table = POSE + 0.02 * np.arange(1, 7)[:, None]  # P(t+k) = POSE + 0.02 k: the step shows in the command

    def command_for_a_new_frame() -> np.ndarray:
        stamp = time.time()
        before = len(commands)
        angles.publish(messages.joint_state(stamp, ARM_JOINTS, POSE))
        preds.publish(messages.predictions_msg(stamp, table))
        probe.spin_until(lambda: len(commands) > before, 10, "a command", procs)
        probe.spin_for(0.3)
        return messages.read_joint_state(commands[-1])[2]

    np.testing.assert_allclose(command_for_a_new_frame(), POSE)  # mode none: the observation itself
    for name, value in (("mode", "fixed"), ("delay_s", 0.3)):
        ok = set_param(probe, "/delay_compensator", name, value, procs)
        assert ok.successful, ok.reason
    np.testing.assert_allclose(command_for_a_new_frame(), table[2])  # 0.3 s ahead = P(t+3)
    assert set_param(probe, "/delay_compensator", "delay_s", 0.5, procs).successful
    np.testing.assert_allclose(command_for_a_new_frame(), table[4])
    probe.spin_until(lambda: diagnostics["/delay_compensator"].get("delay_s") == "0.5", 5, "the new delay", procs)
    assert diagnostics["/delay_compensator"]["mode"] == "fixed"
    assert diagnostics["/delay_compensator"]["parameters.changed"] == "3"


@pytest.mark.ros
def test_learning_switches_off_live_and_the_checkpoint_interval_restarts_the_saves(ros, tmp_path):
    probe = ros.probe
    diagnostics = probe.subscribe_diagnostics()
    checkpoint = tmp_path / "model.npz"
    learner = ros.start("arm_predictor", params={**FAST, "checkpoint": str(checkpoint), "checkpoint_interval_s": 0.0})
    procs = [learner]
    ros.wait_for_node(diagnostics, "/arm_predictor", timeout=60)
    d = describe(probe, "/arm_predictor", ["seed", "learn", "checkpoint_interval_s", "horizon"], procs)
    assert d["seed"].read_only and d["seed"].integer_range[0].to_value == 2**31 - 1
    assert not d["learn"].read_only and not d["checkpoint_interval_s"].read_only
    assert d["horizon"].read_only and d["horizon"].integer_range
    assert not set_param(probe, "/arm_predictor", "seed", 5, procs).successful

    pub = probe.publisher("/arm_angles", JointState)
    probe.wait_for_subscribers(pub)

    def feed(first: int, n: int) -> None:
        for i in range(first, first + n):
            pub.publish(messages.joint_state(100.0 + 0.1 * i, ARM_JOINTS, POSE + 0.1 * np.sin(0.3 * i + np.arange(8))))
            probe.spin_for(0.01)

    feed(0, 10)
    probe.spin_until(lambda: diagnostics["/arm_predictor"].get("frames.learned") == "10", 20, "10 learned", procs)
    assert set_param(probe, "/arm_predictor", "learn", False, procs).successful
    feed(10, 5)
    probe.spin_until(lambda: diagnostics["/arm_predictor"].get("frames.seen") == "5", 20, "5 seen", procs)
    assert diagnostics["/arm_predictor"]["frames.learned"] == "10"

    assert not checkpoint.exists()  # interval 0: only at shutdown
    assert not set_param(probe, "/arm_predictor", "checkpoint_interval_s", -1.0, procs).successful
    assert set_param(probe, "/arm_predictor", "checkpoint_interval_s", 0.3, procs).successful
    probe.spin_until(checkpoint.exists, 10, "a periodic checkpoint", procs)


@pytest.mark.ros
def test_simulator_delay_changes_live(ros):
    probe = ros.probe
    diagnostics = probe.subscribe_diagnostics()
    sim = ros.start("nao_sim", params={**FAST, "backend": "kinematic"})
    procs = [sim]
    ros.wait_for_node(diagnostics, "/nao_sim", timeout=60)
    d = describe(probe, "/nao_sim", ["delay_s", "render_width", "backend"], procs)
    assert not d["delay_s"].read_only
    r = d["render_width"].integer_range[0]
    assert (r.from_value, r.to_value, r.step) == (16, 4096, 1) and d["render_width"].read_only
    assert d["backend"].read_only and not d["backend"].integer_range and not d["backend"].floating_point_range
    assert set_param(probe, "/nao_sim", "delay_s", 0.25, procs).successful
    probe.spin_until(lambda: diagnostics["/nao_sim"].get("delay_s") == "0.25", 10, "the robot's new delay", procs)
    bad = set_param(probe, "/nao_sim", "delay_s", 61.0, procs)
    assert not bad.successful and "delay_s" in bad.reason
    assert not set_param(probe, "/nao_sim", "latency_s", 0.1, procs).successful
