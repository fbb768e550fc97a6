"""Input scaling: the map from radians to the units the GWR layers measure distances in.

The activation threshold is absolute: a_T = 0.98 means "insert when the BMU is farther than
-ln 0.98 = 0.0202". On raw radians that is about one degree over all 8 joints together, below the
jitter of a skeleton tracker, and every layer would grow without bound. One factor,
`input_scale` (model units per radian), sets how many radians that distance stands for:
0.0202 / input_scale. The scaling is part of the model (its parameters are saved with it), so a
saved network is always read in the units it was trained in.

Optionally (`normalise_distance`) each layer divides its distances by sqrt(frames in its input),
so that a_T means the same per-frame RMS distance in GWR1 (1 frame), GWR2 (tau1 frames) and the
P-GWR (tau1 * tau2 frames) instead of letting the higher layers grow finer by the concatenation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gwr_predictor.joints.arm import ARM_JOINT_LIMITS, ARM_JOINTS


@dataclass(frozen=True)
class InputScaling:
    """Radians <-> model units for frames of `n_joints` angles."""

    input_scale: float
    n_joints: int
    normalise_distance: bool = False

    def distance_factor(self, frames: int) -> float:
        """Multiplier of a layer's Euclidean distance in its activity exp(-c ||x - w||)."""
        return 1.0 / math.sqrt(frames) if self.normalise_distance else 1.0

    def frame_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of one frame in model units: the Nao joint limits for the
        8 arm joints, [-pi, pi] otherwise. Random initial neurons are drawn inside them."""
        if self.n_joints == len(ARM_JOINTS):
            lo, hi = np.array([ARM_JOINT_LIMITS[n] for n in ARM_JOINTS]).T
        else:
            lo, hi = np.full(self.n_joints, -math.pi), np.full(self.n_joints, math.pi)
        return lo * self.input_scale, hi * self.input_scale

    def window_bounds(self, frames: int) -> tuple[np.ndarray, np.ndarray]:
        """`frame_bounds` tiled for a concatenation of `frames` frames."""
        lo, hi = self.frame_bounds()
        return np.tile(lo, frames), np.tile(hi, frames)
