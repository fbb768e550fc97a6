"""delay_compensator: predictions -> the robot command that cancels the robot's delay.

Subscribes to the observed angles, the predictions and the robot's reported joint states; on every
prediction (and on an observation when no usable prediction exists) asks
`gwr_predictor.robot.compensator.DelayCompensator` which pose to execute and publishes it as a
JointState on `joint_commands`. Mode "none" forwards each observation (the uncompensated baseline).

`output` chooses where commands go: `joint_state` (the simulator's `joint_commands`),
`joint_trajectory` (a one-point `trajectory_msgs/JointTrajectory` on
`joint_trajectory_controller/joint_trajectory`, what ros2_control's joint_trajectory_controller
executes on a real robot: reach the pose `trajectory_time_s` after arrival), `both`, or `naoqi`: a
`naoqi_bridge_msgs/JointAnglesWithSpeed` on `joint_angles` for a real Nao through naoqi_driver2, clipped
into the joint limits and rate-limited to `max_joint_speed` first (`gwr_predictor.robot.naoqi_output`,
docs/real_robot.md); that message package is imported only when this output is chosen.

Messages that queued while the node stood (a stall, SIGSTOP/SIGCONT) are read together: only the newest
observation and the newest prediction make a command (the others count as `<input>.superseded`), so
the robot is not sent through every stale pose. A node clock that jumps back beyond `max_clock_jump_s`
(a looping replay) restarts the time line: command stamps follow the clock again, predictions, robot
states and stamp rules of the old line are dropped (`clock_jumps.back`, with a warning).

With `spread_shrink` > 0 it also reads `prediction_interval`, the interval the learner states with its
predictions (published just before them, same stamp), and pulls each command towards the observation where
that interval is wide (`compensator.py`); a prediction whose interval has not arrived is commanded as it is
(`interval.missing`).

`mode` and `delay_s` can change while it runs (`ros2 param set /delay_compensator delay_s 0.4`):
the new compensator starts from the next command (the variable mode's history starts over).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from gwr_predictor.parameters.spec import ParameterError, ParamSpec
from gwr_predictor.pipeline import conventions
from gwr_predictor.pipeline.clock_jumps import CLOCK_JUMP_SPEC, ClockJumpWatch, CommandStamps
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.input_rules import absurd_predictions
from gwr_predictor.pipeline.trajectory import command_trajectory
from gwr_predictor.robot import compensator, naoqi_output
from gwr_predictor.robot.errors import RobotError
from gwr_predictor.robot.nao import ARM_JOINTS

from . import messages, standard_messages
from .exits import NodeFatalError
from .pipeline_node import PipelineNode
from .qos import stream_qos
from .runner import run_node

PARAMS = (
    replace(compensator.PARAM_SPECS["mode"], live=True),
    replace(compensator.PARAM_SPECS["delay_s"], live=True),
    ParamSpec("frame_period_s", 0.1, "spacing of the predicted frames (s)", 0.001, 10.0),
    compensator.PARAM_SPECS["stale_after_s"],
    compensator.PARAM_SPECS["guard_decay"],
    compensator.PARAM_SPECS["guard_margin"],
    compensator.PARAM_SPECS["guard_min_frames"],
    compensator.PARAM_SPECS["spread_shrink"],
    ParamSpec("robot_state_timeout_s", 0.5, "a robot state older than this is ignored (variable mode)", 0.0, 3600.0),
    CLOCK_JUMP_SPEC,
    ParamSpec("output", "joint_state", "joint_state: JointState on joint_commands (nao_sim); joint_trajectory: "
              "JointTrajectory on joint_trajectory_controller/joint_trajectory (ros2_control); both; naoqi: "
              "naoqi_bridge_msgs/JointAnglesWithSpeed on joint_angles (a real Nao through naoqi_driver2)",
              choices=("joint_state", "joint_trajectory", "both", "naoqi")),
    ParamSpec("trajectory_time_s", 0.1, "joint_trajectory output: time_from_start of the commanded pose (s); "
              "about one command period, so the controller moves smoothly from command to command", 0.001, 10.0),
    naoqi_output.PARAM_SPECS["naoqi_speed"],
    naoqi_output.PARAM_SPECS["max_joint_speed"],
    naoqi_output.PARAM_SPECS["max_step_s"],
)


class DelayCompensatorNode(PipelineNode):
    NODE_NAME = "delay_compensator"

    def __init__(self) -> None:
        super().__init__(self.NODE_NAME, PARAMS)
        p = self.params
        self.compensator = self.make_compensator(p["mode"], p["delay_s"])
        self.observations = self.arm_check("arm_angles")
        self.robot_states = self.arm_check("joint_states", check_stamps=False)
        self.observation: np.ndarray | None = None
        self.predictions: np.ndarray | None = None
        self.pred_stamp: float | None = None
        self.pred_stamps = self.stamp_check()
        self.robot_state: np.ndarray | None = None
        self.robot_state_time = -np.inf
        self.interval: tuple[float, tuple[np.ndarray, np.ndarray]] | None = None  # (stamp, (lower, upper))
        self.obs_stamp: float | None = None
        self.fallback_sent_for: float | None = None  # the observation last commanded as a fallback
        self.command_stamps = CommandStamps(p["max_clock_jump_s"])
        self.clock_jumps = ClockJumpWatch(p["max_clock_jump_s"])
        output = p["output"]
        self.command_pub = (self.create_publisher(messages.JointState, conventions.TOPIC_COMMAND, stream_qos())
                            if output in ("joint_state", "both") else None)
        self.trajectory_pub = (self.create_publisher(standard_messages.JointTrajectory,
                                                     conventions.TOPIC_TRAJECTORY_COMMAND, stream_qos())
                               if output in ("joint_trajectory", "both") else None)
        self.naoqi_pub, self.naoqi_type, self.naoqi_safety = (self.make_naoqi_output() if output == "naoqi"
                                                              else (None, None, None))
        self.observation_sub = self.create_subscription(messages.JointState, conventions.TOPIC_ANGLES,
                                                        self.on_observation, stream_qos())
        if p["spread_shrink"] > 0:  # subscribed before the predictions: a wait set ready for both serves it first
            self.create_subscription(messages.Float64MultiArray, conventions.TOPIC_PREDICTION_INTERVAL,
                                     self.on_interval, stream_qos())
        self.prediction_sub = self.create_subscription(messages.Float64MultiArray, conventions.TOPIC_PREDICTIONS,
                                                       self.on_predictions, stream_qos())
        self.create_subscription(messages.JointState, conventions.TOPIC_ROBOT_STATE, self.on_robot_state,
                                 stream_qos())
        self.create_timer(p["frame_period_s"], self.fallback_if_stale)  # idle in mode none
        self.get_logger().info(f"mode {p['mode']}, compensating {p['delay_s']} s")

    def make_naoqi_output(self) -> tuple[Any, type, naoqi_output.SafeArmCommands]:
        """The JointAnglesWithSpeed publisher, its type (the message package is imported only now) and the
        safety layer every naoqi command passes."""
        p = self.params
        try:
            msg_type = naoqi_output.message_type()
        except RobotError as exc:
            raise NodeFatalError(str(exc)) from None
        warning = naoqi_output.speed_warning(p["naoqi_speed"], p["max_joint_speed"])
        if warning is not None:
            self.get_logger().warning(warning)
        return (self.create_publisher(msg_type, naoqi_output.TOPIC_JOINT_ANGLES, stream_qos()), msg_type,
                naoqi_output.SafeArmCommands(p["max_joint_speed"], p["max_step_s"]))

    def make_compensator(self, mode: str, delay_s: float) -> compensator.DelayCompensator:
        """The library compensator for `mode` and `delay_s` (RobotError if they do not fit)."""
        p = self.params
        return compensator.DelayCompensator(params=compensator.CompensatorParams(
            mode, delay_s, p["frame_period_s"], p["stale_after_s"], guard_decay=p["guard_decay"],
            guard_margin=p["guard_margin"], guard_min_frames=p["guard_min_frames"], spread_shrink=p["spread_shrink"]))

    def check_live(self, name: str, value: Any) -> None:
        if name in ("mode", "delay_s"):
            mode, delay = (value, self.params["delay_s"]) if name == "mode" else (self.params["mode"], value)
            try:
                self.make_compensator(mode, delay)
            except RobotError as exc:
                raise ParameterError(f"parameter '{name}': {exc}") from None

    def on_live_parameter(self, name: str, value: Any) -> None:
        if name in ("mode", "delay_s"):
            self.compensator = self.make_compensator(self.params["mode"], self.params["delay_s"])
            self.fallback_sent_for = None

    def follow_clock(self) -> float:
        """The node clock now; a jump back beyond `max_clock_jump_s` first restarts the time line."""
        now = self.now_s()
        jump = self.clock_jumps.check(now)
        if jump < 0.0:
            self.restart_time_line(now, jump)
        return now

    def restart_time_line(self, now: float, jump: float) -> None:
        """Forget what is stamped on the old time line (predictions, robot state, stamp rules, the variable
        mode's history); the newest observation stays the pose to fall back on."""
        self.counters.count("clock_jumps.back")
        self.counters.warn_throttled(
            "clock_jumps.back", f"node clock jumped back by {-jump:.3f} s to {now:.3f} s (a looping replay?): "
            "command stamps, predictions and stamp rules start over on the new time line")
        self.compensator = self.make_compensator(self.params["mode"], self.params["delay_s"])
        self.observations = self.arm_check("arm_angles")
        self.predictions, self.pred_stamp, self.interval = None, None, None
        self.pred_stamps.reset()
        self.robot_state, self.robot_state_time = None, -np.inf

    def on_observation(self, msg: messages.JointState) -> None:
        """Store the newest pose (of this one and any queued behind it); command it directly in mode none or
        when no usable prediction exists."""
        self.follow_clock()
        newest = self.newest(msg, self.observation_sub, "arm_angles",
                             lambda m: self.observations.accept(*messages.joint_state_fields(m)))
        if newest is None:
            return
        self.obs_stamp, self.observation = newest
        if self.params["mode"] == "none":
            self.publish_command()
        else:
            self.fallback_if_stale()

    def on_predictions(self, msg: messages.Float64MultiArray) -> None:
        """A new P(t+1..t+h) (the newest of this one and any queued behind it): command the pose it gives for
        now (fixed or Eq. 11)."""
        self.follow_clock()
        newest = self.newest(msg, self.prediction_sub, "predictions", self.read_prediction)
        if newest is None:
            return
        self.pred_stamp, self.predictions = newest
        if self.params["mode"] != "none":
            self.fallback_sent_for = None
            self.publish_command()

    def newest(self, msg: Any, subscription: Any, input_name: str,
               read: Callable[[Any], tuple[float, np.ndarray] | None]) -> tuple[float, np.ndarray] | None:
        """The newest valid (stamp, angles) of `msg` and whatever queued behind it on `subscription`: every
        message is read (and counted as `<input>.received` or rejected), the older valid ones count as
        `<input>.superseded` and command nothing."""
        newest = None
        for taken in (msg, *take_queued(subscription)):
            accepted = read(taken)
            if accepted is not None:
                self.counters.count(f"{input_name}.received")
                if newest is not None:
                    self.counters.count(f"{input_name}.superseded")
                newest = accepted
        return newest

    def read_prediction(self, msg: messages.Float64MultiArray) -> tuple[float, np.ndarray] | None:
        """(stamp, predictions in ARM_JOINTS order) of a valid message, else None (the rejection counted)."""
        try:
            stamp, names, preds = messages.read_predictions(msg)
            if names != ARM_JOINTS:
                preds = preds[:, [names.index(n) for n in ARM_JOINTS]]
        except ValueError as exc:  # a PipelineError (too large ones counted apart) or an arm joint missing
            too_large = isinstance(exc, PipelineError) and exc.reason == "too_large"
            self.counters.reject("predictions.too_large" if too_large else "predictions.layout", str(exc))
            return None
        if not np.all(np.isfinite(preds)):
            self.counters.reject("predictions.non_finite", "NaN or inf in the predictions")
            return None
        absurd = absurd_predictions(preds)
        if absurd is not None:
            self.counters.reject("predictions.out_of_range", absurd)
            return None
        if not self.check_stamp(self.pred_stamps, "predictions", stamp):
            return None
        return stamp, preds

    def on_interval(self, msg: messages.Float64MultiArray) -> None:
        """The interval stated with the predictions of one frame: kept for the command those predictions make."""
        try:
            stamp, names, _, lower, upper = messages.read_interval(msg)
            order = [names.index(n) for n in ARM_JOINTS]
        except ValueError as exc:  # a PipelineError or an arm joint missing
            self.counters.reject("prediction_interval.layout", str(exc))
            return
        if not (np.isfinite(lower).all() and np.isfinite(upper).all()):
            self.counters.reject("prediction_interval.non_finite", "NaN or inf in the interval")
            return
        self.counters.count("prediction_interval.received")
        self.interval = stamp, (lower[:, order], upper[:, order])

    def stated_interval(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The interval stated with the current predictions (same stamp), if it arrived."""
        if self.params["spread_shrink"] <= 0 or self.pred_stamp is None or self.params["mode"] == "none":
            return None
        if self.interval is None or abs(self.interval[0] - self.pred_stamp) > 1e-6:
            self.counters.count("interval.missing")
            return None
        return self.interval[1]

    def fallback_if_stale(self) -> None:
        """Without a usable prediction (none yet, or the sequence ended), command the newest observation,
        once per observation, so that the robot does not hold a pose that was only predicted."""
        now = self.follow_clock()
        if self.params["mode"] == "none" or self.observation is None or self.fallback_sent_for == self.obs_stamp:
            return
        if not self.compensator.stale(now, self.pred_stamp):
            return
        self.fallback_sent_for = self.obs_stamp
        self.publish_command()

    def on_robot_state(self, msg: messages.JointState) -> None:
        now = self.follow_clock()
        accepted = self.robot_states.accept(*messages.joint_state_fields(msg))
        if accepted is not None:
            self.robot_state, self.robot_state_time = accepted[1], now

    def diagnostic_values(self) -> dict[str, object]:
        """Counters plus the mode, so that a report can tell compensated from baseline robots."""
        return {**super().diagnostic_values(), "mode": self.params["mode"], "delay_s": self.params["delay_s"]}

    def publish_command(self) -> None:
        if self.observation is None:
            self.counters.count("commands.skipped_no_observation")
            return
        now = self.now_s()
        state = compensator.recent_state(self.robot_state, self.robot_state_time, now,
                                         self.params["robot_state_timeout_s"])
        out = self.compensator.command(now, self.observation, self.predictions, self.pred_stamp, state,
                                       interval=self.stated_interval())
        if out.fallback_reason is not None:
            self.counters.count(f"fallback.{out.fallback_reason}")
            # normal at every sequence start (the learner needs a few frames), hence info, not warning
            self.counters.warn_throttled(f"fallback.{out.fallback_reason}",
                                         f"commanding the latest observation: {out.fallback_reason}", "info")
        self.counters.count(f"step_used.{out.step_used}")
        self.counters.count("commands.published")
        stamp = self.command_stamps.next(now)
        if self.command_pub is not None:
            self.command_pub.publish(messages.joint_state(stamp, ARM_JOINTS, out.angles))
        if self.trajectory_pub is not None:
            # stamp 0: the controller starts the trajectory when it arrives (one stamped in the past
            # could end in the past and be refused); the pose is reached trajectory_time_s later
            trajectory = command_trajectory(out.angles, self.params["trajectory_time_s"])
            self.trajectory_pub.publish(standard_messages.joint_trajectory(0.0, ARM_JOINTS, trajectory))
        if self.naoqi_pub is not None:
            self.publish_naoqi(now, out.angles, state)

    def publish_naoqi(self, now: float, angles: np.ndarray, robot_state: np.ndarray | None) -> None:
        """The command, clipped and rate-limited (the robot's reported pose limits the first one), to naoqi."""
        safe, limited = self.naoqi_safety.command(now, angles, robot_state)
        if limited:
            self.counters.count("naoqi.rate_limited")
        msg = naoqi_output.fill_message(self.naoqi_type(), safe, self.params["naoqi_speed"])
        msg.header.stamp = messages.to_time(self.command_stamps.last)
        self.naoqi_pub.publish(msg)
        self.counters.count("naoqi.published")


def take_queued(subscription: Any) -> list[Any]:
    """Every message already waiting in `subscription`'s queue, oldest first, taken as the executor takes
    them: a node that acts on the newest message only (a robot command) reads what queued behind the one
    it got, so that a backlog (after a stall) produces one action, not one per stale message."""
    queued = []
    with subscription.handle:
        while (taken := subscription.handle.take_message(subscription.msg_type, subscription.raw)) is not None:
            queued.append(taken[0])
    return queued


def main(args: list[str] | None = None) -> int:
    return run_node(DelayCompensatorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
