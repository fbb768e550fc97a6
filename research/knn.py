"""Offline k-nearest-neighbour regression on windows: a reference for how predictable the future is.

Fitted once on *other* recordings (e.g. the other takes of the same task), never learning online:
the input is the last `span` frames (the current pose and the displacements of the earlier
frames from it), the output the mean of the k most similar training windows' futures, expressed
as displacements from their current pose and added to ours. If this reference cannot beat
holding the last pose, little of the future is in the past frames of this kind of motion at all.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence

import numpy as np

from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.pipeline.conventions import DEFAULT_HORIZON


class KnnError(GwrPredictorError, ValueError):
    """Training data or parameters the k-NN reference cannot use."""


def windows(seq: np.ndarray, span: int, horizon: int) -> tuple[np.ndarray, np.ndarray]:
    """Features (N, span*J) and future displacements (N, horizon, J) of every complete window of a
    (T, J) sequence (windows touching a NaN frame are left out)."""
    seq = np.asarray(seq, dtype=np.float64)
    t, j = seq.shape
    n = t - span - horizon + 1
    if n <= 0:
        return np.empty((0, span * j)), np.empty((0, horizon, j))
    idx = np.arange(n)[:, None] + np.arange(span + horizon)[None]
    block = seq[idx]  # (n, span + horizon, J)
    ok = np.isfinite(block).all(axis=(1, 2))
    block = block[ok]
    return features(block[:, :span]), block[:, span:] - block[:, span - 1: span]


def features(past: np.ndarray) -> np.ndarray:
    """(N, span, J) past frames -> (N, span*J): the current pose, then each earlier frame minus it."""
    current = past[:, -1]
    return np.concatenate([current, (past[:, :-1] - current[:, None]).reshape(len(past), -1)], axis=1)


class KnnPredictor:
    """k-NN on windows fitted on `train` sequences; `step` never learns (an offline reference)."""

    def __init__(self, train: Sequence[np.ndarray], k: int = 5, span: int = 5, horizon: int = DEFAULT_HORIZON
                 ) -> None:
        if k < 1 or span < 1 or horizon < 1:
            raise KnnError(f"need k, span, horizon >= 1, got {k}, {span}, {horizon}")
        parts = [windows(np.asarray(getattr(s, "angles", s)), span, horizon) for s in train]
        self.x_ = np.concatenate([p[0] for p in parts]) if parts else np.empty((0, 0))
        self.y_ = np.concatenate([p[1] for p in parts]) if parts else np.empty((0, horizon, 0))
        if len(self.x_) < k:
            raise KnnError(f"k-NN needs at least k={k} training windows, got {len(self.x_)}")
        self.k, self.span, self.horizon = k, span, horizon
        self._sq = np.einsum("ij,ij->i", self.x_, self.x_)
        self._past: deque[np.ndarray] = deque(maxlen=span)

    def reset_sequence(self) -> None:
        self._past.clear()

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        """The next `horizon` frames after x, once `span` consecutive frames were seen."""
        if x is None:
            self._past.clear()
            return None
        self._past.append(np.asarray(x, dtype=np.float64))
        if len(self._past) < self.span:
            return None
        f = features(np.stack(self._past)[None])[0]
        d = self._sq - 2.0 * self.x_ @ f
        near = np.argpartition(d, self.k - 1)[: self.k]
        return self._past[-1] + self.y_[near].mean(axis=0)
