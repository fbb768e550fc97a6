"""Predictions waiting for the frame they target: one rule, online and after the fact.

A prediction made at step t is h rows; row k (0-based) targets step t + k + 1 (`target_steps`).
Online, `PendingPredictions` files each row under the step it targets (a ring of h slots), so the
predictions due at a frame are one vectorised look-up, taken exactly once, when that frame arrives:
the hierarchy's P.E./C.P.E. (`learning.online_loop.ErrorTracker`), the blend's running MSEs
(`research.blend`) and the default predictor's gate (`default_predictor.gate`) are scored this way.
After the fact, `evaluation.metrics.future_windows` lines a whole recorded sequence up with the same
rule, for the evaluation loop (`evaluation.online`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from gwr_predictor.learning.persistence import Persist, Persistent, require_finite


def every(mask: np.ndarray) -> bool:
    """`mask.all()` (nothing zero) without a ufunc reduction: several times cheaper on the small masks a
    frame tests (which predictions are due, which are finite)."""
    return np.count_nonzero(mask) == mask.size


def some(mask: np.ndarray) -> bool:
    """`mask.any()` without a ufunc reduction (see `every`)."""
    return np.count_nonzero(mask) > 0


def target_steps(t: int | np.ndarray, horizon: int) -> np.ndarray:
    """The steps targeted by the h rows of a prediction made at step t: t + 1 ... t + h."""
    return np.asarray(t)[..., None] + 1 + np.arange(horizon)


class PendingPredictions(Persistent):
    """Predictions not yet scored, filed by the step they target.

    `pending[..., s, k, :]` is row k of the prediction whose row k targets a step t with
    t % horizon == s; `valid[..., s, k]` says whether it is there. Leading dimensions (`lead`, e.g.
    the blend's members) are filed and taken together. `take(t)` must be called at every step
    (observed or not): it hands back what targets t and empties those entries, so a slot is free
    again when the next prediction files into it.
    """

    PERSIST = Persist(arrays=("pending", "valid"), nan_ok=("pending",))  # what is not valid may be anything

    def __init__(self, horizon: int, joints: int, lead: tuple[int, ...] = ()) -> None:
        self.horizon = horizon
        self._k = np.arange(horizon)
        self._slots = [target_steps(t, horizon) % horizon for t in range(horizon)]  # by t % horizon
        self.pending = np.zeros((*lead, horizon, horizon, joints))
        self.valid = np.zeros((*lead, horizon, horizon), dtype=bool)

    def file(self, t: int, prediction: np.ndarray, valid: np.ndarray | bool = True) -> None:
        """File the prediction (*lead, horizon, joints) made at step t (`valid` (*lead, horizon))."""
        slots = self._slots[t % self.horizon]
        self.pending[..., slots, self._k, :] = prediction
        self.valid[..., slots, self._k] = valid

    def take(self, t: int) -> tuple[np.ndarray, np.ndarray]:
        """The predictions (*lead, horizon, joints) targeting step t, row k made k + 1 steps ago, and
        their `valid` mask (a copy); the slot is emptied."""
        s = t % self.horizon
        valid = self.valid[..., s, :].copy()
        self.valid[..., s, :] = False
        return self.pending[..., s, :, :], valid

    def _load_extra(self, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> None:
        require_finite(self.pending[self.valid], "pending")  # a prediction waiting to be scored

    def drop(self) -> None:
        """Forget every pending prediction (a sequence boundary)."""
        self.valid[...] = False
