"""Median of every 3 frames (30 fps -> 10 fps), the paper's noise filter, in batch and streaming form.

Frames are grouped as [0, 1, 2], [3, 4, 5], ...; a trailing incomplete group is dropped. The stamp of
a group is the stamp of its middle frame (the time the median best describes). NaN rule, per joint
and frame: a joint counts as tracked in a frame only when all of its coordinates are finite; the
output takes, per coordinate, the median of the tracked values when all 3 frames are tracked, their
mean (the median of two) when 2 are, and NaN when fewer than 2 are. Works for any frame shape
(J, 3) or (J,) -- the last axis is treated as the coordinates of one joint.
"""

from __future__ import annotations

import numpy as np

from gwr_predictor.data.errors import DataError

GROUP = 3
MIN_TRACKED = 2


def _median_groups(frames: np.ndarray) -> np.ndarray:
    """(G, 3, ...) groups -> (G, ...) NaN-aware medians following the module's rule."""
    tracked = np.all(np.isfinite(frames), axis=-1, keepdims=True)
    masked = np.where(tracked, frames, np.nan)
    ordered = np.sort(masked, axis=1)  # NaN sorts last
    count = np.broadcast_to(tracked, frames.shape).sum(axis=1)
    two = 0.5 * (ordered[:, 0] + ordered[:, 1])
    return np.where(count == 3, ordered[:, 1], np.where(count == MIN_TRACKED, two, np.nan))


def median_of_3(positions: np.ndarray, timestamps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (T, ...) and stamps (T,) -> (T // 3, ...) medians and their middle-frame stamps."""
    positions = np.asarray(positions, dtype=np.float64)
    timestamps = np.asarray(timestamps, dtype=np.float64)
    if positions.ndim < 2:
        raise DataError(f"positions must be (frames, ..., coords), got shape {positions.shape}")
    if timestamps.shape != positions.shape[:1]:
        raise DataError(f"timestamps must be ({positions.shape[0]},), got {timestamps.shape}")
    g = positions.shape[0] // GROUP
    groups = positions[: g * GROUP].reshape(g, GROUP, *positions.shape[1:])
    return _median_groups(groups), timestamps[1: g * GROUP: GROUP].copy()


class MedianOf3:
    """Streaming `median_of_3`: every third `push` returns the smoothed (stamp, frame), else None."""

    def __init__(self) -> None:
        self._frames: list[np.ndarray] = []
        self._stamps: list[float] = []

    def push(self, stamp: float, frame: np.ndarray) -> tuple[float, np.ndarray] | None:
        frame = np.asarray(frame, dtype=np.float64)
        if frame.ndim < 1:
            raise DataError(f"frame must have at least one axis (coords), got shape {frame.shape}")
        if self._frames and frame.shape != self._frames[0].shape:
            raise DataError(f"frame shape {frame.shape} differs from the group's {self._frames[0].shape}")
        self._frames.append(frame)
        self._stamps.append(float(stamp))
        if len(self._frames) < GROUP:
            return None
        out = _median_groups(np.stack(self._frames)[None])[0]
        stamp_out = self._stamps[1]
        self.reset()
        return stamp_out, out

    def reset(self) -> None:
        """Forget a partial group (e.g. after a gap in the stream)."""
        self._frames.clear()
        self._stamps.clear()

    @property
    def pending(self) -> int:
        """Frames waiting for their group to complete."""
        return len(self._frames)
