"""Predictions and commands as joint trajectories (what ros2_control's joint_trajectory_controller takes).

Pure numpy; `gwr_predictor.nodes.standard_messages.joint_trajectory` builds the
`trajectory_msgs/JointTrajectory`. Two uses:
- the learner's prediction P(t+1..t+h), made at frame t: the trajectory's stamp is t and point k
  (k = 1..h) is at time_from_start k * frame period, so a plotter shows where the arm is predicted
  to be and when;
- the compensator's command to a real robot: one point, the pose to reach, `time_from_start`
  after "now" (stamp 0 = start on arrival, the controller's convention), so the controller moves
  there smoothly within one command period and the next command replaces the rest of the motion.
  This is the real robot's input as far as this package reaches, so the pose is clipped into the
  Nao's joint limits here, the one clip of that path (the simulated robot clips at
  `SimulatedRobot.command`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.robot.nao import ARM_JOINTS, clip_to_limits


class Trajectory(NamedTuple):
    """Points (n, joints) in radians and their times from the trajectory's start (n,) in seconds."""

    times_from_start: np.ndarray
    positions: np.ndarray


def prediction_trajectory(predictions: np.ndarray, frame_period_s: float) -> Trajectory:
    """P(t+1..t+h) (h, joints) -> a trajectory with point k at k * frame_period_s (k = 1..h)."""
    predictions = np.asarray(predictions, dtype=np.float64)
    if predictions.ndim != 2 or predictions.shape[0] < 1:
        raise PipelineError(f"predictions must be (horizon >= 1, joints), got {predictions.shape}")
    if not frame_period_s > 0.0:
        raise PipelineError(f"frame period must be > 0 s, got {frame_period_s}")
    times = frame_period_s * np.arange(1, predictions.shape[0] + 1, dtype=np.float64)
    return Trajectory(times, predictions)


def command_trajectory(angles: np.ndarray, time_from_start_s: float,
                       names: tuple[str, ...] = ARM_JOINTS) -> Trajectory:
    """One commanded pose of the joints `names` -> a one-point trajectory reaching it, clipped into
    the joint limits, `time_from_start_s` after its start."""
    angles = np.asarray(angles, dtype=np.float64).ravel()
    if not time_from_start_s > 0.0:
        raise PipelineError(f"time_from_start must be > 0 s, got {time_from_start_s}")
    return Trajectory(np.array([float(time_from_start_s)]), clip_to_limits(angles, names)[None, :])
