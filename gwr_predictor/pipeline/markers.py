"""What the viewers draw (RViz, Foxglove): the skeleton and the predicted arm as points and segments.

Pure numpy: `gwr_predictor.nodes.standard_messages` turns these into `visualization_msgs/MarkerArray`
(a SPHERE_LIST of the joints and a LINE_LIST of the bones, both in one named frame with the capture
stamp). Untracked (NaN) joints are left out, and so is every bone touching one, so a viewer never
draws a line to the origin.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from gwr_predictor.pipeline.conventions import SKELETON_JOINTS
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.robot.nao import ARM_JOINTS, forward_kinematics

#: Frame of the skeleton markers: the skeleton camera convention (x towards the person's right, y up,
#: z from the sensor into the scene). Set RViz's / Foxglove's fixed frame to it, or publish a TF.
SKELETON_FRAME = "skeleton_camera"
#: Frame of the predicted-arm markers: the Nao URDF's base link, so they overlay the robot model.
ROBOT_FRAME = "torso"

#: Bones of the 15-joint skeleton, as pairs of joint names.
SKELETON_BONES: tuple[tuple[str, str], ...] = (
    ("head", "neck"), ("neck", "torso"),
    ("neck", "left_shoulder"), ("left_shoulder", "left_elbow"), ("left_elbow", "left_hand"),
    ("neck", "right_shoulder"), ("right_shoulder", "right_elbow"), ("right_elbow", "right_hand"),
    ("torso", "left_hip"), ("left_hip", "left_knee"), ("left_knee", "left_foot"),
    ("torso", "right_hip"), ("right_hip", "right_knee"), ("right_knee", "right_foot"),
    ("left_hip", "right_hip"),
)


class Figure(NamedTuple):
    """Points (n, 3) to draw as spheres and segments (2m, 3): consecutive pairs are the ends of a line."""

    points: np.ndarray
    segments: np.ndarray


def _bone_index(names: tuple[str, ...]) -> np.ndarray:
    index = {n: i for i, n in enumerate(names)}
    return np.array([(index[a], index[b]) for a, b in SKELETON_BONES if a in index and b in index],
                    dtype=int).reshape(-1, 2)


_DEFAULT_BONES = _bone_index(SKELETON_JOINTS)


def skeleton_figure(positions: np.ndarray, names: tuple[str, ...] = SKELETON_JOINTS) -> Figure:
    """One skeleton frame (joints x 3, m) -> its tracked joints and the bones between tracked joints."""
    positions = np.asarray(positions, dtype=np.float64)
    if positions.shape != (len(names), 3):
        raise PipelineError(f"skeleton positions must be ({len(names)}, 3), got {positions.shape}")
    bones = _DEFAULT_BONES if names == SKELETON_JOINTS else _bone_index(names)
    tracked = np.all(np.isfinite(positions), axis=1)
    bones = bones[tracked[bones].all(axis=1)]
    return Figure(positions[tracked], positions[bones.ravel()])


def arm_figure(angles: np.ndarray) -> Figure:
    """8 arm angles (`ARM_JOINTS` order) -> the Nao's shoulders, elbows and hands (torso frame, m) and
    the two arms as segments shoulder-elbow, elbow-hand: how the robot would stand in that pose."""
    angles = np.asarray(angles, dtype=np.float64).ravel()
    if angles.size != len(ARM_JOINTS):
        raise PipelineError(f"expected {len(ARM_JOINTS)} arm angles, got {angles.size}")
    arms = forward_kinematics(angles)
    points = np.stack([p for side in ("L", "R") for p in (arms[side].shoulder, arms[side].elbow, arms[side].hand)])
    segments = points[[0, 1, 1, 2, 3, 4, 4, 5]]
    return Figure(points, segments)
