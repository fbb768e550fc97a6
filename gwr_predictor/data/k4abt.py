"""Azure Kinect / Orbbec body tracking (K4ABT) -> the pipeline's 15-joint skeleton.

The Azure Kinect ROS driver (and Orbbec's K4A-compatible wrapper) publish every tracked body as
`visualization_msgs/MarkerArray` on `body_tracking_data`: one SPHERE marker per joint, marker id
= body id * 100 + joint index in the 32-joint K4ABT order below, position in metres in the depth
camera's frame (x right, y down, z forward as seen from the sensor), stamp = capture time.

This module is the ROS-free half: given the marker ids and positions of one message it groups
them per body, picks the body nearest to the sensor (the person facing the robot, not someone
walking past behind) and maps its joints to `joints.skeleton.SKELETON_JOINTS` in the skeleton camera
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

from gwr_predictor.data.errors import DataError
from gwr_predictor.joints.skeleton import SKELETON_JOINTS

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


class TrackedBody(NamedTuple):
    """The body chosen from one message: its id, 15 skeleton joints (m, skeleton convention), how many
    bodies the message held, and how many of its markers had a joint index beyond the 32 known ones."""

    body_id: int
    positions: np.ndarray
    n_bodies: int
    unknown_markers: int


class _Slots(NamedTuple):
    """One row per (body, joint) present, sorted by body then joint; the later marker of a duplicate wins."""

    body: np.ndarray  # (m,) body ids
    joint: np.ndarray  # (m,) K4ABT joint indices
    positions: np.ndarray  # (m, 3)
    group: np.ndarray  # (m,) index of the row's body in `bodies`
    bodies: np.ndarray  # (b,) the distinct body ids, ascending


def _slots(ids: np.ndarray, positions: np.ndarray) -> tuple[_Slots, int]:
    """Markers -> their (body, joint) slots and the count of unknown joint indices, by one sort.

    One sort instead of one scan of every marker per body: a message with many bodies costs
    O(n log n), not O(n x bodies).
    """
    ids = np.asarray(ids, dtype=np.int64).ravel()
    positions = np.asarray(positions, dtype=np.float64)
    if positions.shape != (ids.size, 3):
        raise DataError(f"{ids.size} marker ids but positions of shape {positions.shape}")
    if np.any(ids < 0):
        raise DataError(f"negative marker ids {ids[ids < 0][:5].tolist()}: expected body * {ID_STRIDE} + joint")
    body, joint = np.divmod(ids, ID_STRIDE)
    known = joint < N_JOINTS
    order = np.flatnonzero(known)
    order = order[np.lexsort((order, joint[order], body[order]))]
    body, joint, positions = body[order], joint[order], positions[order]
    last = np.ones(body.size, dtype=bool)  # the last marker of each (body, joint) run
    last[:-1] = (body[1:] != body[:-1]) | (joint[1:] != joint[:-1])
    body, joint, positions = body[last], joint[last], positions[last]
    first_of_body = np.ones(body.size, dtype=bool)
    first_of_body[1:] = body[1:] != body[:-1]
    group = np.cumsum(first_of_body) - 1
    return _Slots(body, joint, positions, group, body[first_of_body]), int(np.count_nonzero(~known))


def _joints(slots: _Slots, index: int) -> np.ndarray:
    """(32, 3) joints of the body at `index` of `slots.bodies`, NaN where absent."""
    lo, hi = np.searchsorted(slots.group, [index, index + 1])
    joints = np.full((N_JOINTS, 3), np.nan)
    joints[slots.joint[lo:hi]] = slots.positions[lo:hi]
    return joints


def group_bodies(ids: np.ndarray, positions: np.ndarray) -> tuple[dict[int, np.ndarray], int]:
    """Marker ids (n,) and positions (n, 3) -> ({body id: (32, 3) joints, NaN where absent}, unknown count).

    Markers whose joint index is 32..99 are not K4ABT joints: counted, not used. Negative ids are an error.
    """
    slots, unknown = _slots(ids, positions)
    return {int(b): _joints(slots, i) for i, b in enumerate(slots.bodies)}, unknown


def _distances(slots: _Slots) -> np.ndarray:
    """`body_distance` of every body at once: its pelvis, or the mean of its tracked joints; inf without."""
    n = slots.bodies.size
    tracked = np.all(np.isfinite(slots.positions), axis=1)
    group = slots.group[tracked]
    count = np.bincount(group, minlength=n)
    sums = np.stack([np.bincount(group, weights=slots.positions[tracked, k], minlength=n) for k in range(3)], axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        distance = np.where(count > 0, np.linalg.norm(sums / count[:, None], axis=1), np.inf)
    pelvis = tracked & (slots.joint == _PELVIS)
    distance[slots.group[pelvis]] = np.linalg.norm(slots.positions[pelvis], axis=1)
    return distance


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
    slots, unknown = _slots(ids, positions)
    if not slots.bodies.size:
        return None
    nearest = int(np.lexsort((slots.bodies, _distances(slots)))[0])  # nearest, then the lowest id
    return TrackedBody(int(slots.bodies[nearest]), to_skeleton(_joints(slots, nearest)), int(slots.bodies.size),
                       unknown)
