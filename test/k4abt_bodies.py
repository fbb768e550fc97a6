"""Recorded-looking Azure Kinect body-tracking data for tests, written from the sensor's geometry only.

Positions are what the Azure Kinect driver publishes: metres in the depth camera frame (x to the
sensor's right, y down, z forward), a person standing `distance` in front of the sensor and facing
it, so the person's LEFT side is at +x. Joint indices are the K4ABT SDK's (k4abt_joint_id_t),
written out here by number rather than taken from gwr_predictor, so that a wrong table there fails.
"""

from __future__ import annotations

import numpy as np

PELVIS, SPINE_NAVEL, NECK = 0, 1, 3
SHOULDER_LEFT, ELBOW_LEFT, WRIST_LEFT, HAND_LEFT = 5, 6, 7, 8
SHOULDER_RIGHT, ELBOW_RIGHT, WRIST_RIGHT, HAND_RIGHT = 12, 13, 14, 15
HIP_LEFT, HIP_RIGHT, HEAD = 18, 22, 26


def body(distance: float = 2.0, left_arm: str = "forward", lateral: float = 0.0) -> dict[int, np.ndarray]:
    """{joint index: (3,) position} of one person; legs are not tracked (no markers), like a close crop.

    left_arm: "forward" (pointing at the sensor), "sideways" (raised to the person's left) or "down".
    The right arm always hangs down.
    """
    def p(x: float, y: float, dz: float = 0.0) -> np.ndarray:
        return np.array([x + lateral, y, distance + dz])

    joints = {
        PELVIS: p(0.0, 0.10), SPINE_NAVEL: p(0.0, -0.05), NECK: p(0.0, -0.45), HEAD: p(0.0, -0.62),
        SHOULDER_LEFT: p(0.18, -0.40), SHOULDER_RIGHT: p(-0.18, -0.40),
        HIP_LEFT: p(0.10, 0.10), HIP_RIGHT: p(-0.10, 0.10),
        ELBOW_RIGHT: p(-0.18, -0.12, -0.02), WRIST_RIGHT: p(-0.18, 0.12, -0.08), HAND_RIGHT: p(-0.18, 0.20, -0.10),
    }
    if left_arm == "forward":  # towards the sensor: -z
        joints |= {ELBOW_LEFT: p(0.18, -0.40, -0.28), WRIST_LEFT: p(0.18, -0.40, -0.53),
                   HAND_LEFT: p(0.18, -0.40, -0.60)}
    elif left_arm == "sideways":  # away from the body on the person's left: +x
        joints |= {ELBOW_LEFT: p(0.46, -0.40, -0.01), WRIST_LEFT: p(0.70, -0.38, -0.12),
                   HAND_LEFT: p(0.77, -0.38, -0.14)}
    else:
        joints |= {ELBOW_LEFT: p(0.18, -0.12, -0.02), WRIST_LEFT: p(0.18, 0.12, -0.08),
                   HAND_LEFT: p(0.18, 0.20, -0.10)}
    return joints


def markers(bodies: dict[int, dict[int, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """{body id: joints} -> (marker ids = body * 100 + joint, positions (n, 3)), as one driver message."""
    ids, xyz = [], []
    for body_id, joints in bodies.items():
        for joint, pos in joints.items():
            ids.append(body_id * 100 + joint)
            xyz.append(pos)
    return np.array(ids, dtype=np.int64), np.array(xyz, dtype=np.float64)
