"""Motion streams the benchmarks feed: made on the spot, never a recording."""

from __future__ import annotations

import numpy as np


def random_walk_stream(n_frames: int, seed: int = 0) -> np.ndarray:
    """(n_frames, 8) smooth motion that never repeats: each joint's velocity a damped random walk."""
    rng = np.random.default_rng(seed)
    kicks = rng.normal(scale=0.01, size=(n_frames, 8))
    velocity, pose, out = np.zeros(8), np.zeros(8), np.empty((n_frames, 8))
    for t in range(n_frames):
        velocity = 0.9 * velocity + kicks[t]
        pose = 0.995 * pose + velocity
        out[t] = pose
    return out
