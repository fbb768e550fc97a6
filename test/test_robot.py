"""Delay line, motor model and the delayed robot (kinematic and PyBullet backends)."""

import numpy as np
import pytest

from gwr_predictor.robot import nao
from gwr_predictor.robot.delayed_arm import DelayLine, MotorModel, MotorParams, RobotError, RobotParams, SimulatedRobot

REST = np.array([1.4, 0.2, -1.2, -0.5, 1.4, -0.2, 1.2, 0.5])
MOVED = REST + np.array([-0.6, 0.3, 0.5, -0.4, -0.6, -0.3, -0.5, 0.4])


def onset(times: np.ndarray, positions: np.ndarray, start: np.ndarray, tol: float = 1e-6) -> float:
    """First time the positions leave `start`."""
    moved = np.any(np.abs(positions - start) > tol, axis=1)
    return float(times[np.argmax(moved)]) if moved.any() else np.inf


def test_delay_line_releases_values_after_the_delay():
    line = DelayLine(0.3, initial="none yet")
    line.push(0.0, "a")
    line.push(0.1, "b")
    assert line.get(0.29) == "none yet"
    assert line.get(0.30) == "a"
    assert line.get(0.39) == "a"
    assert line.get(0.40) == "b"
    assert len(line) == 0


def test_delay_line_keeps_order_and_drops_overtaken_values_when_the_delay_shrinks():
    line = DelayLine(0.5)
    line.push(0.0, "slow")  # due at 0.5
    line.delay_s = 0.1
    line.push(0.2, "fast")  # due at 0.3, overtakes "slow"
    assert line.get(0.31) == "fast"
    assert line.get(0.6) == "fast"  # the older value never comes back
    assert line.dropped == 1


def test_delay_line_with_growing_delay_holds_the_last_value():
    line = DelayLine(0.1)
    line.push(0.0, 1)
    line.delay_s = 0.4
    line.push(0.1, 2)  # due at 0.5
    assert line.get(0.2) == 1
    assert line.get(0.49) == 1
    assert line.get(0.5) == 2


def test_delay_line_per_value_delay_overrides_the_line_delay():
    line = DelayLine(1.0)
    line.push(0.0, "x", delay_s=0.05)
    assert line.get(0.05) == "x"


def test_motor_latency_is_visible_in_a_step_response():
    motor = MotorModel(MotorParams(latency_s=0.035), initial=REST)
    motor.command(MOVED)
    dt = 0.001
    times, positions = [], []
    for _ in range(200):
        positions.append(motor.step(dt).copy())
        times.append(motor.t)
    assert onset(np.array(times), np.array(positions), REST) == pytest.approx(0.035 + dt, abs=1.5 * dt)


def test_motor_moves_at_its_velocity_limits_then_stops_on_target():
    motor = MotorModel(MotorParams(latency_s=0.0), initial=REST)
    motor.command(MOVED)
    first = motor.step(0.01).copy()
    limits = np.array([nao.VELOCITY_LIMITS[n] for n in nao.ARM_JOINTS])
    np.testing.assert_allclose(np.abs(first - REST), np.minimum(np.abs(MOVED - REST), limits * 0.01))
    for _ in range(50):
        motor.step(0.01)
    np.testing.assert_allclose(motor.position, MOVED)


def test_first_order_motor_slows_down_near_the_target():
    motor = MotorModel(MotorParams(latency_s=0.0, time_constant_s=0.05), initial=REST)
    motor.command(REST + 0.05)
    gaps = [np.abs(motor.step(0.01) - (REST + 0.05)).max() for _ in range(20)]
    ratios = np.array(gaps[1:6]) / np.array(gaps[:5])
    np.testing.assert_allclose(ratios, 0.8, atol=1e-9)  # error shrinks by 1 - dt/tau per step


@pytest.mark.parametrize("backend", ["kinematic", "pybullet"])
def test_the_robot_input_clips_commands_to_joint_limits_and_says_so(backend):
    wild = np.full(8, 3.0)  # beyond the upper limit of every joint
    with SimulatedRobot(delay_s=0.0, latency_s=0.0, dt=0.01, backend=backend, initial=REST) as robot:
        assert robot.command(wild) is True
        robot.advance(1.0)
        np.testing.assert_allclose(robot.joint_positions(), nao.clip_to_limits(wild), atol=2e-3)
        assert robot.command(REST) is False  # within the limits: sent as it is
        robot.advance(1.0)
        np.testing.assert_allclose(robot.joint_positions(), REST, atol=2e-3)


def step_response(robot: SimulatedRobot, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    robot.command(MOVED)
    times, positions = [], []
    while robot.t < seconds - 1e-9:
        positions.append(robot.step())
        times.append(robot.t)
    return np.array(times), np.array(positions)


def test_simulated_robot_starts_moving_after_delay_plus_latency():
    with SimulatedRobot(delay_s=0.3, latency_s=0.04, dt=0.01, initial=REST) as robot:
        times, positions = step_response(robot, 0.6)
    assert onset(times, positions, REST) == pytest.approx(0.35, abs=0.011)
    np.testing.assert_allclose(positions[-1], MOVED)


def test_pybullet_backend_follows_the_same_delay():
    with SimulatedRobot(delay_s=0.2, latency_s=0.03, dt=0.01, backend="pybullet", initial=REST) as robot:
        times, positions = step_response(robot, 0.8)
    assert onset(times, positions, REST, tol=1e-3) == pytest.approx(0.24, abs=0.021)
    np.testing.assert_allclose(positions[-1], MOVED, atol=0.02)


def test_state_reports_are_delayed_by_state_delay():
    with SimulatedRobot(delay_s=0.0, latency_s=0.0, dt=0.01, state_delay_s=0.1, initial=REST) as robot:
        robot.command(MOVED)
        robot.advance(0.3)
        np.testing.assert_allclose(robot.joint_positions(), MOVED)
        robot.command(REST)
        robot.advance(0.05)
        assert np.allclose(robot.state(), MOVED)  # the report is 0.1 s old
        assert not np.allclose(robot.joint_positions(), MOVED)


def test_changing_the_delay_applies_to_commands_sent_afterwards():
    with SimulatedRobot(delay_s=0.5, latency_s=0.0, dt=0.01, initial=REST) as robot:
        robot.delay_s = 0.1
        times, positions = step_response(robot, 0.3)
    assert onset(times, positions, REST) == pytest.approx(0.11, abs=0.011)


@pytest.mark.parametrize(("field", "value"), [("delay_s", -0.1), ("latency_s", 11.0), ("dt", 0.0),
                                              ("backend", "gazebo"), ("state_delay_s", float("nan"))])
def test_robot_params_reject_bad_values_naming_the_field(field, value):
    with pytest.raises(RobotError, match=field):
        RobotParams(**{field: value})


def test_motor_params_need_one_velocity_limit_per_joint():
    with pytest.raises(RobotError, match="velocity_limits"):
        MotorParams(velocity_limits=(1.0, 2.0))


def test_commands_of_the_wrong_size_are_rejected():
    with SimulatedRobot() as robot, pytest.raises(RobotError, match="8 joint angles"):
        robot.command(np.zeros(10))
