"""The skeleton every source delivers (the demonstrator, skeleton files, mocap, body trackers): its 15
joints in this order and its frame rate, and the rate of the arm angles a median of 3 makes of it.

In `joints`, below data and pipeline: the data's sources produce this skeleton, the pipeline's
messages carry it (`pipeline.conventions` names it for the nodes), and neither imports the other for it.
"""

from __future__ import annotations

# --- skeleton joints (OpenNI/NITE, 15 joints) --------------------------------------------------
SKELETON_JOINTS: tuple[str, ...] = (
    "head", "neck", "torso",
    "left_shoulder", "left_elbow", "left_hand",
    "right_shoulder", "right_elbow", "right_hand",
    "left_hip", "left_knee", "left_foot",
    "right_hip", "right_knee", "right_foot",
)

SKELETON_FPS = 30.0
ANGLE_FPS = 10.0
