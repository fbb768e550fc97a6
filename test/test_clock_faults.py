"""Clock faults: a node clock that jumps (either way), use_sim_time changed live, a process stopped and resumed.

- the robot's time base follows a jump by restarting there, never by simulating the gap: nao_sim keeps
  publishing and stops on SIGINT after a /clock jump of +1e6 s;
- the compensator's command stamps follow a clock that jumps back (a looping replay), so the robot keeps
  accepting them on every loop;
- use_sim_time cannot be switched while a node runs (refused with a reason; it is read at start);
- after SIGSTOP/SIGCONT the compensator commands only the newest of the observations queued meanwhile.
"""

import signal
import time

import numpy as np
import pytest
from rclpy.qos import QoSProfile, ReliabilityPolicy
from test_live_parameters import POSE, set_param

from gwr_predictor.nodes import messages
from gwr_predictor.nodes.delay_compensator import take_queued
from gwr_predictor.pipeline.clock_jumps import ClockJumpWatch, CommandStamps, RobotTimeBase
from gwr_predictor.pipeline.conventions import TOPIC_ANGLES, TOPIC_COMMAND, TOPIC_ROBOT_STATE
from gwr_predictor.robot.delayed_arm import SimulatedRobot
from gwr_predictor.robot.nao import ARM_JOINTS

FAST = {"diagnostics_period_s": 0.3}
SIM = {**FAST, "use_sim_time": True}
CLOCK_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
T0 = 1000.0


# --- library level --------------------------------------------------------------------------------


def test_robot_time_base_restarts_at_a_forward_jump_instead_of_simulating_the_gap():
    base = RobotTimeBase(max_jump_s=1.0)
    robot = SimulatedRobot(backend="kinematic")
    for now in (T0, T0 + 0.02, T0 + 0.5):
        target, jump = base.target(now, robot.t)
        robot.advance(target - robot.t)
        assert jump == 0.0
    assert robot.t == pytest.approx(0.5, abs=0.011)
    target, jump = base.target(T0 + 1e6, robot.t)
    assert jump == pytest.approx(1e6 - 0.5, abs=0.02) and target == robot.t  # nothing to simulate
    target, jump = base.target(T0 + 1e6 + 0.3, robot.t)
    assert jump == 0.0 and target - robot.t == pytest.approx(0.3, abs=0.011)  # and on from there


def test_robot_time_base_restarts_at_a_backward_jump_and_stands_through_small_ones():
    base = RobotTimeBase(max_jump_s=1.0)
    assert base.target(T0 + 20.0, 5.0) == (5.0, 0.0)
    assert base.target(T0 + 19.5, 5.0) == (5.0, 0.0)  # back 0.5 s, within the bound: the robot waits
    target, jump = base.target(T0, 5.0)  # a looping replay starts over
    assert jump == pytest.approx(-20.0) and target == 5.0
    assert base.target(T0 + 0.1, 5.0) == pytest.approx((5.1, 0.0))


def test_clock_jump_watch_reports_jumps_beyond_the_bound_either_way():
    watch = ClockJumpWatch(max_jump_s=1.0)
    assert [watch.check(t) for t in (0.0, T0, T0 + 0.5, T0 + 0.4, T0 + 30.0, T0, 0.0, T0 + 0.2)] == pytest.approx(
        [0.0, 0.0, 0.0, 0.0, 29.6, -30.0, 0.0, 0.0])  # 0: sim time without /clock, not a reading


def test_command_stamps_increase_on_one_tick_and_follow_a_clock_that_jumps_back():
    stamps = CommandStamps(max_jump_s=1.0)
    first, second = stamps.next(T0 + 20.0), stamps.next(T0 + 20.0)  # two commands on one /clock tick
    assert second > first == T0 + 20.0
    assert stamps.next(T0 + 19.5) > second  # a small step back: still increasing
    assert stamps.next(T0) == T0 and stamps.restarts == 1  # the loop starts over: so do the stamps
    assert stamps.next(T0 + 0.1) == T0 + 0.1


class FakeHandle:
    """What `take_queued` uses of an rclpy subscription handle: a context manager with take_message."""

    def __init__(self, queued: list[object]) -> None:
        self.queued = list(queued)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def take_message(self, msg_type, raw):
        return (self.queued.pop(0), {}) if self.queued else None


class FakeSubscription:
    def __init__(self, queued: list[object]) -> None:
        self.handle, self.msg_type, self.raw = FakeHandle(queued), object, False


def test_take_queued_returns_every_waiting_message_oldest_first_and_empties_the_queue():
    sub = FakeSubscription(["b", "c", "d"])
    assert take_queued(sub) == ["b", "c", "d"]
    assert take_queued(sub) == []


# --- real processes -------------------------------------------------------------------------------


def publish_clock(pub, seconds: float) -> None:
    pub.publish(messages.clock_msg(round(seconds * 1e9)))


def state_stamps(box: list) -> list[float]:
    return [messages.read_joint_state(m)[0] for m in box]


@pytest.mark.ros
def test_nao_sim_follows_clock_jumps_either_way_and_stays_responsive_to_sigint(ros):
    probe = ros.probe
    diagnostics = ros.diagnostics
    states = probe.subscribe(TOPIC_ROBOT_STATE, messages.JointState)
    clock = probe.publisher("/clock", messages.Clock, CLOCK_QOS)
    sim = ros.start_ready("nao_sim", params={**SIM, "backend": "kinematic"})

    def run_clock(start: float, seconds: float) -> None:
        t = start
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            publish_clock(clock, t)
            probe.spin_for(0.01)
            t += 0.01

    run_clock(T0, 1.0)
    probe.spin_until(lambda: any(s >= T0 for s in state_stamps(states)), 20, "joint_states on the first clock", [sim])
    def states_near(t: float) -> bool:
        return any(t <= s <= t + 5.0 for s in state_stamps(states))

    for target in (T0 + 1e6, T0 + 10.0):  # forward far beyond any catch-up, then back (a replay loop)
        run_clock(target, 1.5)
        probe.spin_until(lambda t=target: states_near(t), 5, f"joint_states at the clock {target}", [sim])
    probe.spin_until(lambda: diagnostics["/nao_sim"].get("clock_jumps.back") == "1", 5, "the back jump counted", [sim])
    assert diagnostics["/nao_sim"].get("clock_jumps.forward") == "1", diagnostics["/nao_sim"]
    assert "node clock jumped forward by 99999" in sim.output()
    started = time.monotonic()
    code, killed = sim.stop(signal.SIGINT, timeout=5.0)
    assert code == 0 and not killed and time.monotonic() - started < 5.0, sim.output()[-2000:]


@pytest.mark.ros
def test_use_sim_time_changed_live_is_refused_and_the_robot_keeps_publishing(ros):
    probe = ros.probe
    states = probe.subscribe(TOPIC_ROBOT_STATE, messages.JointState)
    sim = ros.start_ready("nao_sim", params={**FAST, "backend": "kinematic"})
    result = set_param(probe, "/nao_sim", "use_sim_time", True, [sim])
    assert not result.successful and "use_sim_time" in result.reason and "restart" in result.reason, result
    assert set_param(probe, "/nao_sim", "use_sim_time", False, [sim]).successful  # no change: fine
    before = len(states)
    probe.spin_until(lambda: len(states) >= before + 10, 5, "joint_states after the refused change", [sim])
    assert "refused a live change of 'use_sim_time'" in sim.output()


@pytest.mark.ros
def test_compensator_stamps_follow_a_looping_clock_and_the_robot_accepts_every_loop(ros):
    probe = ros.probe
    diagnostics = ros.diagnostics
    commands = probe.subscribe(TOPIC_COMMAND, messages.JointState)
    clock = probe.publisher("/clock", messages.Clock, CLOCK_QOS)
    angles = probe.publisher(TOPIC_ANGLES, messages.JointState)
    comp = ros.start("delay_compensator", params={**SIM, "mode": "fixed"})
    # a tight stamp rule at the robot: commands stamped a loop ahead of its clock would all be refused
    sim = ros.start("nao_sim", params={**SIM, "backend": "kinematic", "max_stamp_ahead_s": 0.5})
    for name in ("/delay_compensator", "/nao_sim"):
        ros.wait_for_node(diagnostics, name, timeout=60)
    probe.wait_for_graph({TOPIC_ANGLES: ("probe", ["delay_compensator"]),
                          TOPIC_COMMAND: ("delay_compensator", ["nao_sim", "probe"])})

    def one_loop(frames: int = 40, period: float = 0.05) -> None:
        for k in range(frames):  # the replayed clock, then the frame stamped with it
            stamp = T0 + k * period
            publish_clock(clock, stamp)
            probe.spin_for(0.005)
            angles.publish(messages.joint_state(stamp, ARM_JOINTS, 0.2 * np.sin(stamp + np.arange(8))))
            probe.spin_for(period)

    loop_stamps = []
    for _ in range(3):
        start = len(commands)
        one_loop()
        probe.spin_for(0.3)
        loop_stamps.append(state_stamps(commands[start:]))
    probe.spin_for(0.5)
    robot, comp_diag = diagnostics["/nao_sim"], diagnostics["/delay_compensator"]
    for stamps in loop_stamps:  # every loop's commands are stamped on that loop's time line
        assert len(stamps) >= 30 and T0 <= min(stamps) <= T0 + 0.5 and max(stamps) <= T0 + 2.0 + 0.1, stamps
    assert "rejected.joint_commands.stamp_ahead" not in robot, robot
    accepted = int(robot.get("commands.accepted", "0"))
    assert accepted >= sum(len(s) for s in loop_stamps) - 8, (robot, comp_diag)  # a few at each loop's start
    assert comp_diag.get("clock_jumps.back") == "2", comp_diag
    assert "node clock jumped back" in comp.output() and "node clock jumped back" in sim.output()


@pytest.mark.ros
def test_after_sigstop_the_compensator_commands_only_the_newest_queued_observation(ros):
    probe = ros.probe
    diagnostics = ros.diagnostics
    commands = probe.subscribe(TOPIC_COMMAND, messages.JointState)
    angles = probe.publisher(TOPIC_ANGLES, messages.JointState)
    comp = ros.start("delay_compensator", params={**FAST, "mode": "fixed"})  # no predictions: observations commanded
    ros.wait_for_node(diagnostics, "/delay_compensator", timeout=60)
    probe.wait_for_graph({TOPIC_ANGLES: ("probe", ["delay_compensator"]),
                          TOPIC_COMMAND: ("delay_compensator", ["probe"])})

    def pose(k: int) -> np.ndarray:
        return POSE + 0.01 * k  # within the joint limits: commanded unclipped

    def send(k: int) -> None:
        angles.publish(messages.joint_state(time.time(), ARM_JOINTS, pose(k)))
        probe.spin_for(0.02)

    for k in range(5):
        send(k)
    probe.spin_until(lambda: len(commands) >= 5, 10, "the commands before the stop", [comp])
    probe.spin_for(0.3)
    before = len(commands)
    comp.send_signal(signal.SIGSTOP)
    try:
        for k in range(5, 25):  # 20 observations queue up while it stands
            send(k)
        probe.spin_for(0.3)
    finally:
        comp.send_signal(signal.SIGCONT)

    def commanded() -> list[np.ndarray]:
        return [messages.read_joint_state(m)[2] for m in commands[before:]]

    # A long stop can leave all but the first queued sample to DDS's reliable repair, which comes a
    # heartbeat later (measured 1.0-1.2 s after a 3 s stop): so wait for the newest, not a fixed time.
    probe.spin_until(lambda: any(np.allclose(a, pose(24)) for a in commanded()), 15, "pose 24 commanded", [comp])
    probe.spin_for(0.5)
    after = commanded()
    assert np.allclose(after[-1], pose(24))
    assert len(after) <= 5, [round((a[0] - POSE[0]) * 100) for a in after]  # not one per queued observation
    probe.spin_until(lambda: diagnostics["/delay_compensator"].get("arm_angles.received") == "25", 5,
                     "every observation read", [comp])
    status = diagnostics["/delay_compensator"]
    assert int(status["arm_angles.superseded"]) == 20 - len(after), status  # each one not commanded is counted
