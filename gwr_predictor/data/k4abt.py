"""Azure Kinect / Orbbec body tracking (K4ABT) -> the pipeline's 15-joint skeleton.

The Azure Kinect ROS driver (and Orbbec's K4A-compatible wrapper) publish every tracked body as
`visualization_msgs/MarkerArray` on `body_tracking_data`: one SPHERE marker per joint, marker id
= body id * 100 + joint index in the 32-joint K4ABT order below, position in metres in the depth
camera's frame (x right, y down, z forward as seen from the sensor), stamp = capture time.

This module is the ROS-free half: given the marker ids and positions of one message it groups
them per body, picks the body nearest to the sensor (the person facing the robot, not someone
walking past behind) and maps its joints to `conventions.SKELETON_JOINTS` in the skeleton camera
convention (x towards the person's right = sensor's left, y up, z into the scene), i.e. rotated
by 180 degrees about the optical axis. A proper rotation: the arm angles do not depend on it, but
the skeleton topic and its markers keep one convention whatever the tracker.

The mapping (docs/data.md lists it too): OpenNI's "hand" is where the forearm ends, so it is
K4ABT's WRIST (HAND and HANDTIP are the palm and fingers, noisier); "torso" is SPINE_NAVEL;
"foot" is the ANKLE. Joints of the body without a marker are NaN (untracked), as in skeleton files.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS

#: The 32 joints of the Azure Kinect Body Tracking SDK, in index order (k4abt_joint_id_t).
K4ABT_JOINTS: tuple[str, ...] = (
    "PELVIS", "SPINE_NAVEL", "SPINE_CHEST", "NECK",
    "CLAVICLE_LEFT", "SHOULDER_LEFT", "ELBOW_LEFT", "WRIST_LEFT", "HAND_LEFT", "HANDTIP_LEFT", "THUMB_LEFT",
    "CLAVICLE_RIGHT", "SHOULDER_RIGHT", "ELBOW_RIGHT", "WRIST_RIGHT", "HAND_RIGHT", "HANDTIP_RIGHT",
    "THUMB_RIGHT",
    "HIP_LEFT", "KNEE_LEFT", "ANKLE_LEFT", "FOOT_LEFT",
    "HIP_RIGHT", "KNEE_RIGHT", "ANKLE_RIGHT", "FOOT_RIGHT",
    "HEAD", "NOSE", "EYE_LEFT", "EAR_LEFT", "EYE_RIGHT", "EAR_RIGHT",
)
N_JOINTS = len(K4ABT_JOINTS)
#: Marker id = body id * ID_STRIDE + joint index (the drivers' convention).
ID_STRIDE = 100

#: Each pipeline skeleton joint and the K4ABT joint it is read from (left/right are the person's).
SKELETON_FROM_K4ABT: dict[str, str] = {
    "head": "HEAD",
    "neck": "NECK",
    "torso": "SPINE_NAVEL",
    "left_shoulder": "SHOULDER_LEFT",
    "left_elbow": "ELBOW_LEFT",
    "left_hand": "WRIST_LEFT",
    "right_shoulder": "SHOULDER_RIGHT",
    "right_elbow": "ELBOW_RIGHT",
    "right_hand": "WRIST_RIGHT",
    "left_hip": "HIP_LEFT",
    "left_knee": "KNEE_LEFT",
    "left_foot": "ANKLE_LEFT",
    "right_hip": "HIP_RIGHT",
    "right_knee": "KNEE_RIGHT",
    "right_foot": "ANKLE_RIGHT",
}
_SOURCE_INDEX = np.array([K4ABT_JOINTS.index(SKELETON_FROM_K4ABT[n]) for n in SKELETON_JOINTS], dtype=int)
#: Depth camera frame (x right, y down, z forward) -> skeleton convention (x left, y up, z forward).
CAMERA_TO_SKELETON = np.diag([-1.0, -1.0, 1.0])
_PELVIS = K4ABT_JOINTS.index("PELVIS")


class K4abtError(GwrPredictorError, ValueError):
    """Marker ids or positions that cannot be body-tracking joints; the message says which."""


class TrackedBody(NamedTuple):
    """The body chosen from one message: its id, 15 skeleton joints (m, skeleton convention), how many
    bodies the message held, and how many of its markers had a joint index beyond the 32 known ones."""

    body_id: int
    positions: np.ndarray
    n_bodies: int
    unknown_markers: int


def group_bodies(ids: np.ndarray, positions: np.ndarray) -> tuple[dict[int, np.ndarray], int]:
    """Marker ids (n,) and positions (n, 3) -> ({body id: (32, 3) joints, NaN where absent}, unknown count).

    Markers whose joint index is 32..99 are not K4ABT joints: counted, not used. Negative ids are an error.
    """
    ids = np.asarray(ids, dtype=np.int64).ravel()
    positions = np.asarray(positions, dtype=np.float64)
    if positions.shape != (ids.size, 3):
        raise K4abtError(f"{ids.size} marker ids but positions of shape {positions.shape}")
    if np.any(ids < 0):
        raise K4abtError(f"negative marker ids {ids[ids < 0][:5].tolist()}: expected body * {ID_STRIDE} + joint")
    body, joint = np.divmod(ids, ID_STRIDE)
    known = joint < N_JOINTS
    bodies: dict[int, np.ndarray] = {}
    for b in np.unique(body[known]):
        sel = known & (body == b)
        joints = np.full((N_JOINTS, 3), np.nan)
        joints[joint[sel]] = positions[sel]
        bodies[int(b)] = joints
    return bodies, int(np.count_nonzero(~known))


def body_distance(joints: np.ndarray) -> float:
    """Distance (m) of a body from the sensor: its pelvis, or the mean of its tracked joints without one."""
    pelvis = joints[_PELVIS]
    if np.all(np.isfinite(pelvis)):
        return float(np.linalg.norm(pelvis))
    finite = np.all(np.isfinite(joints), axis=1)
    return float(np.linalg.norm(joints[finite].mean(axis=0))) if finite.any() else np.inf


def to_skeleton(joints: np.ndarray) -> np.ndarray:
    """(32, 3) K4ABT joints in the depth camera frame -> (15, 3) `SKELETON_JOINTS` in the skeleton convention."""
    return joints[_SOURCE_INDEX] @ CAMERA_TO_SKELETON.T


def from_skeleton(positions: np.ndarray) -> np.ndarray:
    """The inverse, for tests and tools: (15, 3) skeleton -> (32, 3) K4ABT joints (NaN for the 17 unmapped)."""
    joints = np.full((N_JOINTS, 3), np.nan)
    joints[_SOURCE_INDEX] = np.asarray(positions, dtype=np.float64) @ CAMERA_TO_SKELETON
    return joints


def nearest_body(ids: np.ndarray, positions: np.ndarray) -> TrackedBody | None:
    """The body nearest to the sensor as a pipeline skeleton, or None when the message holds no body."""
    bodies, unknown = group_bodies(ids, positions)
    if not bodies:
        return None
    body_id = min(bodies, key=lambda b: (body_distance(bodies[b]), b))
    return TrackedBody(body_id, to_skeleton(bodies[body_id]), len(bodies), unknown)
