"""The one way from skeletons to the learner's input: skeleton -> median of 3 -> arm angles -> clip.

The paper's vision module (Sec. IV): every 3 skeleton frames (30 fps) are smoothed into one by their
median, mapped to the 8 Nao arm angles and clipped into the joint limits, once, here. Offline
(`extract_angles`, whole sequences: datasets, `gwr-predictor angles`, `evaluate`) and streaming
(`frame_angles`, one smoothed frame: the angle_extractor node) share the mapping and the clip.
The unclipped angles are kept so that callers can report how much was clipped.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from gwr_predictor.data.angles import skeleton_to_angles
from gwr_predictor.data.smoothing import median_of_3
from gwr_predictor.joints.skeleton import SKELETON_JOINTS
from gwr_predictor.robot.nao import clip_to_limits


class ExtractedAngles(NamedTuple):
    """Stamps t (T,) s, angles (T, 8) rad clipped into the Nao limits, and the same angles unclipped."""

    t: np.ndarray
    angles: np.ndarray
    raw: np.ndarray

    @property
    def clipped(self) -> np.ndarray:
        """(T,) True where the clip changed a frame."""
        return np.any(self.angles != self.raw, axis=-1) & np.all(np.isfinite(self.raw), axis=-1)


def frame_angles(positions: np.ndarray, joint_names: Sequence[str] = SKELETON_JOINTS) -> tuple[np.ndarray, np.ndarray]:
    """One (smoothed) skeleton frame (joints x 3) -> (angles clipped, angles unclipped), each (8,);
    all NaN when the frame lacks a joint the arm angles need."""
    raw = skeleton_to_angles(positions, joint_names, clip=False)
    return clip_to_limits(raw), raw


def extract_angles(positions: np.ndarray, timestamps: np.ndarray, joint_names: Sequence[str] = SKELETON_JOINTS,
                   smooth: bool = True) -> ExtractedAngles:
    """A skeleton sequence (T, joints, 3) with stamps (T,) -> 10 fps arm angles (median of every 3
    frames; `smooth=False` keeps every frame), clipped into the Nao limits once."""
    pos, t = median_of_3(positions, timestamps) if smooth else (np.asarray(positions, float),
                                                                  np.asarray(timestamps, float))
    raw = skeleton_to_angles(pos, joint_names, clip=False)
    return ExtractedAngles(t, clip_to_limits(raw), raw)
