"""Commands for a real Nao through naoqi_driver2, made safe before they leave the computer; no ROS here.

naoqi_driver2 executes `naoqi_bridge_msgs/msg/JointAnglesWithSpeed` messages received on
`joint_angles` (header, joint_names string[], joint_angles float32[], speed float32 = fraction of
each joint's maximum speed, relative uint8 = 0 for absolute angles) by calling ALMotion's
setAngles: the joints move towards the angles at that fraction of their top speed and hold them.

`SafeArmCommands` is the last step before hardware. Each command is
1. clipped into the Nao's joint limits (`nao.JOINT_LIMITS`), whatever the predictor proposed;
2. rate-limited: no joint moves more than `max_joint_speed` x (time since the last command sent)
   away from that last command (the elapsed time counts at most `max_step_s`, so a command after a
   pause cannot jump); the first command is limited from the robot's reported pose when one is
   given, otherwise it only gets the clip and naoqi's own speed fraction.
It never sends anything on its own: when commands stop, naoqi holds the last pose (docs/real_robot.md).
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gwr_predictor.parameters.spec import ParamSpec
from gwr_predictor.robot.errors import RobotError
from gwr_predictor.robot.nao import ARM_JOINTS, VELOCITY_LIMITS, clip_to_limits

#: Relative, so that a namespaced pipeline drives the naoqi_driver2 of its own namespace.
TOPIC_JOINT_ANGLES = "joint_angles"
MESSAGE_TYPE = "naoqi_bridge_msgs/msg/JointAnglesWithSpeed"

PARAM_SPECS = {
    "naoqi_speed": ParamSpec("naoqi_speed", 0.3, "naoqi output: JointAnglesWithSpeed.speed, the fraction of each "
                             "joint's top speed naoqi moves at (0.3 x 7.19 rad/s = 2.2 rad/s)", 0.0, 1.0, lo_open=True),
    "max_joint_speed": ParamSpec("max_joint_speed", 2.0, "naoqi output: no joint is commanded further than this "
                                 "many rad/s x the time since the last command (rate limit before the robot)",
                                 0.0, max(VELOCITY_LIMITS.values()), lo_open=True),
    "max_step_s": ParamSpec("max_step_s", 0.2, "naoqi output: the rate limit counts at most this much time since the "
                            "last command, so that the first command after a pause moves only this far", 0.001, 10.0),
}


def message_type() -> type:
    """The JointAnglesWithSpeed class, imported only when the naoqi output is chosen."""
    package, _, name = MESSAGE_TYPE.partition("/msg/")
    try:
        return getattr(importlib.import_module(f"{package}.msg"), name)
    except (ImportError, AttributeError) as exc:
        raise RobotError(f"output 'naoqi' needs the {MESSAGE_TYPE} message ({exc}): install naoqi_bridge_msgs "
                         "(apt: ros-jazzy-naoqi-bridge-msgs) and source its setup file") from None


def speed_warning(naoqi_speed: float, max_joint_speed: float, names: Sequence[str] = ARM_JOINTS) -> str | None:
    """A warning when naoqi's speed fraction is slower than the rate limit lets commands move: the
    robot then lags behind the commands, which adds to the delay being compensated."""
    slowest = min(VELOCITY_LIMITS[n] for n in names)
    if naoqi_speed * slowest >= max_joint_speed:
        return None
    return (f"naoqi_speed {naoqi_speed} moves the slowest arm joint at {naoqi_speed * slowest:.2f} rad/s, below "
            f"max_joint_speed {max_joint_speed} rad/s: the robot will lag behind the commands")


@dataclass
class SafeArmCommands:
    """Clip + rate limit of arm commands relative to the last one sent (see the module docstring)."""

    max_joint_speed: float
    max_step_s: float = 0.2
    names: tuple[str, ...] = ARM_JOINTS
    last_angles_: np.ndarray | None = field(default=None, init=False)
    last_time_: float | None = field(default=None, init=False)

    def __post_init__(self) -> None:
        for spec, value in ((PARAM_SPECS["max_joint_speed"], self.max_joint_speed),
                            (PARAM_SPECS["max_step_s"], self.max_step_s)):
            spec.check(value, owner=type(self).__name__)

    def command(self, now_s: float, target: np.ndarray,
                robot_pose: np.ndarray | None = None) -> tuple[np.ndarray, bool]:
        """The angles to send now for `target` (rad, `names` order) and whether the rate limit changed them.

        `robot_pose` (the robot's reported angles) is the reference of the first command only."""
        target = np.asarray(target, dtype=np.float64).ravel()
        if target.size != len(self.names) or not np.all(np.isfinite(target)):
            raise RobotError(f"a command needs {len(self.names)} finite angles, got {target}")
        goal = clip_to_limits(target, self.names)
        reference, elapsed = self.last_angles_, self.max_step_s
        if reference is None and robot_pose is not None and np.all(np.isfinite(robot_pose)):
            reference = clip_to_limits(np.asarray(robot_pose, dtype=np.float64).ravel(), self.names)
        elif self.last_time_ is not None:
            elapsed = min(max(now_s - self.last_time_, 0.0), self.max_step_s)
        out = goal
        if reference is not None:
            step = self.max_joint_speed * elapsed
            out = np.clip(goal, reference - step, reference + step)
        self.last_angles_, self.last_time_ = out, now_s
        return out, bool(np.any(out != goal))


def fill_message(msg: Any, angles: np.ndarray, speed: float, names: Sequence[str] = ARM_JOINTS) -> Any:
    """Set the JointAnglesWithSpeed fields of `msg` (absolute angles as float32); the caller stamps the header."""
    msg.joint_names = list(names)
    msg.joint_angles = [float(v) for v in np.asarray(angles, dtype=np.float32)]
    msg.speed = float(speed)
    msg.relative = 0
    return msg
