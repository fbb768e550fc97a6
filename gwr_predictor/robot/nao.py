"""Nao arm facts (published V4/V5 figures) and forward kinematics, shared by data, simulator, URDF.

Frames: torso origin, x forward, y left, z up. Angles in radians. The 8 joints the learner sees
are `ARM_JOINTS` (no wrist: skeleton trackers do not measure it; their names and limits are
`gwr_predictor.joints.arm`, re-exported here); the robot also has `WristYaw`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from gwr_predictor.joints.arm import ARM_JOINT_LIMITS, ARM_JOINT_SUFFIXES, ARM_JOINTS, SIDES
from gwr_predictor.robot.errors import RobotError

#: All 10 actuated arm joints of the robot model.
ROBOT_ARM_JOINTS: tuple[str, ...] = tuple(
    s + j for s in SIDES for j in (*ARM_JOINT_SUFFIXES, "WristYaw")
)
_WRIST_YAW_LIMITS = (-1.82387, 1.82387)

#: Joint limits (lower, upper) in radians, of the 8 arm joints and the wrists.
JOINT_LIMITS: dict[str, tuple[float, float]] = {
    name: ARM_JOINT_LIMITS.get(name, _WRIST_YAW_LIMITS) for name in ROBOT_ARM_JOINTS
}

#: Velocity limits in rad/s (wrist figure as for the elbow yaw).
VELOCITY_LIMITS: dict[str, float] = {
    s + j: v
    for s in SIDES
    for j, v in (("ShoulderPitch", 8.27), ("ShoulderRoll", 7.19), ("ElbowYaw", 8.27),
                 ("ElbowRoll", 7.19), ("WristYaw", 8.27))
}

#: Motor response latency of the real robot (s), the figure the paper simulates.
MOTOR_LATENCY_RANGE_S = (0.030, 0.040)

# Kinematic offsets (m) of the left arm; the right arm mirrors y.
SHOULDER_OFFSET = np.array([0.0, 0.098, 0.100])
ELBOW_OFFSET = np.array([0.105, 0.015, 0.0])
WRIST_OFFSET = np.array([0.05595, 0.0, 0.0])
HAND_OFFSET = np.array([0.05775, 0.0, -0.0123])
UPPER_ARM_LENGTH = float(np.linalg.norm(ELBOW_OFFSET))
FOREARM_LENGTH = float(np.linalg.norm(WRIST_OFFSET + HAND_OFFSET))

_MIRROR = np.array([1.0, -1.0, 1.0])


def limits_array(names: tuple[str, ...] = ARM_JOINTS) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper limits of `names` as two arrays, in that order."""
    lo = np.array([JOINT_LIMITS[n][0] for n in names])
    hi = np.array([JOINT_LIMITS[n][1] for n in names])
    return lo, hi


def clip_to_limits(angles: np.ndarray, names: tuple[str, ...] = ARM_JOINTS) -> np.ndarray:
    """Angles (..., len(names)) clipped into the robot's joint limits (NaN stays NaN)."""
    lo, hi = limits_array(names)
    return np.clip(angles, lo, hi)


def robot_arm_positions(angles: np.ndarray, wrist_yaw: np.ndarray | tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """The 8 `ARM_JOINTS` angles plus (left, right) WristYaw -> all 10 in `ROBOT_ARM_JOINTS` order: what a
    joint_states for every movable URDF joint carries (the learner never commands the wrists)."""
    angles = np.asarray(angles, dtype=float).ravel()
    if angles.size != len(ARM_JOINTS):
        raise RobotError(f"expected {len(ARM_JOINTS)} arm angles, got {angles.size}")
    wrists = np.asarray(wrist_yaw, dtype=float).ravel()
    if wrists.size != len(SIDES):
        raise RobotError(f"expected one WristYaw per side ({len(SIDES)}), got {wrists.size}")
    k = len(ARM_JOINT_SUFFIXES)
    return np.concatenate([angles[:k], wrists[:1], angles[k:], wrists[1:]])


def side_offsets(side: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Shoulder, elbow, wrist and hand offsets of one side ('L' or 'R')."""
    if side not in SIDES:
        raise RobotError(f"side must be 'L' or 'R', got {side!r}")
    m = np.ones(3) if side == "L" else _MIRROR
    return SHOULDER_OFFSET * m, ELBOW_OFFSET * m, WRIST_OFFSET * m, HAND_OFFSET * m


def rot_x(a: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) about x for angles a (...)."""
    a = np.asarray(a, dtype=float)
    c, s, o, z = np.cos(a), np.sin(a), np.ones_like(a), np.zeros_like(a)
    return np.stack([o, z, z, z, c, -s, z, s, c], axis=-1).reshape(a.shape + (3, 3))


def rot_y(a: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) about y for angles a (...)."""
    a = np.asarray(a, dtype=float)
    c, s, o, z = np.cos(a), np.sin(a), np.ones_like(a), np.zeros_like(a)
    return np.stack([c, z, s, z, o, z, -s, z, c], axis=-1).reshape(a.shape + (3, 3))


def rot_z(a: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) about z for angles a (...)."""
    a = np.asarray(a, dtype=float)
    c, s, o, z = np.cos(a), np.sin(a), np.ones_like(a), np.zeros_like(a)
    return np.stack([c, -s, z, s, c, z, z, z, o], axis=-1).reshape(a.shape + (3, 3))


class ArmPoints(NamedTuple):
    """Positions (..., 3) in the torso frame of one arm's joints and hand end point."""

    shoulder: np.ndarray
    elbow: np.ndarray
    wrist: np.ndarray
    hand: np.ndarray


def arm_forward_kinematics(side: str, angles: np.ndarray, wrist_yaw: np.ndarray | float = 0.0) -> ArmPoints:
    """Forward kinematics of one arm.

    `angles` (..., 4) are ShoulderPitch, ShoulderRoll, ElbowYaw, ElbowRoll of that side.
    Chain: Ry(pitch) Rz(roll) at the shoulder, then Rx(yaw) Rz(roll) at the elbow, Rx at the wrist.
    """
    angles = np.asarray(angles, dtype=float)
    if angles.shape[-1] != 4:
        raise RobotError(f"expected (..., 4) arm angles, got shape {angles.shape}")
    s_off, e_off, w_off, h_off = side_offsets(side)
    r_shoulder = rot_y(angles[..., 0]) @ rot_z(angles[..., 1])
    r_elbow = r_shoulder @ rot_x(angles[..., 2]) @ rot_z(angles[..., 3])
    r_wrist = r_elbow @ rot_x(np.broadcast_to(np.asarray(wrist_yaw, float), angles.shape[:-1]))
    shoulder = np.broadcast_to(s_off, angles.shape[:-1] + (3,)).copy()
    elbow = shoulder + r_shoulder @ e_off
    wrist = elbow + r_elbow @ w_off
    hand = wrist + r_wrist @ h_off
    return ArmPoints(shoulder, elbow, wrist, hand)


def forward_kinematics(angles: np.ndarray) -> dict[str, ArmPoints]:
    """FK of both arms from (..., 8) angles in `ARM_JOINTS` order: {'L': ArmPoints, 'R': ...}."""
    angles = np.asarray(angles, dtype=float)
    if angles.shape[-1] != len(ARM_JOINTS):
        raise RobotError(f"expected (..., {len(ARM_JOINTS)}) angles, got shape {angles.shape}")
    return {"L": arm_forward_kinematics("L", angles[..., :4]),
            "R": arm_forward_kinematics("R", angles[..., 4:])}
