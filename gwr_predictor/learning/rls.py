"""Recursive least squares for a linear map with many outputs that share one regressor.

Why one shared P: every output (every joint at every horizon step) sees the same features, so one
inverse-covariance estimate serves them all and an update costs O(d^2 + d m) for d features and m
outputs. With forgetting on data that excite few directions (a person at rest), P winds up; it is
reset to its prior when its trace passes `max_trace`, and the weights are reset if they ever stop
being finite. Used by the direct linear predictor (`predictors/direct_linear.py`) and by the default
predictor's global read-out (`default_predictor/predictor.py`).
"""

from __future__ import annotations

import math

import numpy as np

from gwr_predictor.learning.persistence import Persist, Persistent


class RecursiveLeastSquares(Persistent):
    """y = phi @ W, fitted to every (phi, y) pair seen, older pairs down-weighted by `forgetting`.

    P(0) = `delta` I is the prior variance of the weights (their ridge penalty is 1 / delta); W(0) = 0.
    """

    PERSIST = Persist(arrays=("weights", "p"), values=("updates", "resets"))

    def __init__(self, features: int, outputs: int, forgetting: float = 1.0, delta: float = 1.0,
                 max_trace: float = 1e6) -> None:
        self.forgetting, self.delta, self.max_trace = float(forgetting), float(delta), float(max_trace)
        self.weights = np.zeros((features, outputs))
        self.p = self.delta * np.eye(features)
        self.updates = self.resets = 0

    def predict(self, phi: np.ndarray) -> np.ndarray:
        """phi @ W (a new array)."""
        return phi @ self.weights

    def update(self, phi: np.ndarray, y: np.ndarray) -> None:
        """One step towards the least-squares fit of the pair (phi, y)."""
        lam = self.forgetting
        p_phi = self.p @ phi
        gain = p_phi / (lam + float(phi @ p_phi))  # a float: the sum without a numpy scalar's overhead
        err = y - phi @ self.weights
        column = gain[:, None]
        self.weights += column * err
        self.p -= column * p_phi
        self.updates += 1
        if lam < 1.0:  # without forgetting P only shrinks: no wind-up to watch for
            self.p /= lam
            if not math.isfinite(self.p.sum()) or self.p.trace() > self.max_trace:
                self._reset_p()
        if not math.isfinite(np.add.reduce(err)):  # `err.sum()` without its Python wrapper
            self.weights[...] = 0.0
            self._reset_p()

    def _reset_p(self) -> None:
        self.p = self.delta * np.eye(self.p.shape[0])
        self.resets += 1


def window_features(window: np.ndarray, order: int) -> np.ndarray:
    """[x(t) - x(t-1), ..., x(t) - x(t-order+1), x(t), 1] of a newest-first window of poses (rad): the
    latest changes of the pose and the pose itself, the features both linear read-outs fit."""
    newest = window[0]
    return np.concatenate([(newest - window[1:order]).reshape(-1), newest, (1.0,)])
