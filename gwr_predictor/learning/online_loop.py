"""What every online learner of the package shares: one frame per `step`, counted; a missing sample
(None or a non-finite value) as a gap; P.E./C.P.E. bookkeeping scored only when targets arrive;
sequence resets. The paper's hierarchy (`hierarchy.py`) and the default predictor
(`default_predictor/predictor.py`) build their own learning on it.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.pending import PendingPredictions
from gwr_predictor.learning.persistence import Persist, Persistent

#: The largest angle (rad, either sign) a learner learns from: no joint angle in radians comes near. A
#: frame with a larger one is a fault (a driver's garbage, an unset field), taken as a missing sample:
#: one frame of 1e100 rad would overflow the squares in the running statistics and leave every later
#: prediction NaN, and one of 1e20 rad would shut the gates for hours.
MAX_ANGLE_RAD = 100.0


def usable(frame: np.ndarray) -> bool:
    """Whether a frame of angles (rad) can be learned from: finite, and none beyond `MAX_ANGLE_RAD`.

    On plain floats (every member of a predictor checks each frame, and a handful of values costs less
    as a list than as numpy calls): a sum that is not finite holds a NaN or an inf (or values that large)."""
    values = frame.tolist()
    total = sum(values)
    return total - total == 0.0 and -MAX_ANGLE_RAD <= min(values) and max(values) <= MAX_ANGLE_RAD


def frame_or_none(x: np.ndarray | None, joints: int, error: type[Exception] = LearningError) -> np.ndarray | None:
    """The sample as a (joints,) float vector, or None for a missing one (None, non-finite, or not
    `usable`): a gap to learn around. A sample of another size is a caller's bug: `error`."""
    if x is None:
        return None
    frame = np.asarray(x, dtype=float)
    if frame.shape != (joints,):
        raise error(f"a frame must have shape ({joints},), got {frame.shape}")
    return frame if usable(frame) else None


class ErrorTracker(Persistent):
    """P.E./C.P.E. per horizon step (MSE, rad^2) and per-layer quantization errors (rad).

    Predictions wait in `pending.PendingPredictions` under the step they target, so a prediction is
    scored exactly when its target arrives. Squared errors are summed over joints here and divided
    by the joint count in `summary`.
    """

    PERSIST = Persist(arrays=("sse", "count"), values=("q_last", "q_sum", "q_count"), members={"_pending": ""})

    def __init__(self, horizon: int, n_joints: int, layers: tuple[str, ...]) -> None:
        self.horizon = horizon
        self.n_joints = n_joints
        self.layers = layers
        self._targets = np.empty((2, 1, n_joints))  # [P.E. target, C.P.E. target]
        self._pending = PendingPredictions(horizon, n_joints)
        self.reset()

    def reset(self) -> None:
        """Zero the accumulated errors (pending predictions stay)."""
        self.sse = np.zeros((2, self.horizon))  # rows: P.E., C.P.E.; summed over joints
        self.count = np.zeros(self.horizon, dtype=np.int64)
        self.q_last = {name: math.nan for name in self.layers}
        self.q_sum = {name: 0.0 for name in self.layers}
        self.q_count = {name: 0 for name in self.layers}

    def forget_pending(self) -> None:
        self._pending.drop()

    def expect(self, t: int, prediction: np.ndarray) -> None:
        """File the prediction (horizon, joints) made at step t: row k targets step t + k + 1."""
        self._pending.file(t, prediction)

    def score(self, t: int, frame: np.ndarray | None, represented: np.ndarray | None) -> None:
        """Score the predictions targeting step t (None: missing frame, they are dropped)."""
        predicted, valid = self._pending.take(t)
        if frame is not None and valid.any():
            if represented is frame:  # no lower layers (P.E. = C.P.E.): one difference for both rows
                diff = predicted - frame
            else:
                targets = self._targets
                targets[0, 0] = represented
                targets[1, 0] = frame
                diff = predicted - targets
            err = np.vecdot(diff, diff)
            if not valid.all():
                err *= valid
            self.sse += err
            self.count += valid

    def quantization(self, layer: str, distance_rad: float) -> None:
        self.q_last[layer] = distance_rad
        self.q_sum[layer] += distance_rad
        self.q_count[layer] += 1

    def summary(self) -> dict[str, Any]:
        with np.errstate(invalid="ignore", divide="ignore"):
            pe, cpe = self.sse / (self.count * self.n_joints)
        total = int(self.count.sum()) * self.n_joints
        return {
            "pe": pe.tolist(),
            "cpe": cpe.tolist(),
            "pe_mean": float(self.sse[0].sum() / total) if total else math.nan,
            "cpe_mean": float(self.sse[1].sum() / total) if total else math.nan,
            "scored": self.count.tolist(),
            "quantization_last": dict(self.q_last),
            "quantization_mean": {k: (self.q_sum[k] / self.q_count[k] if self.q_count[k] else math.nan)
                                  for k in self.layers},
        }


class OnlineLoop(Persistent):
    """Counters, gaps and error bookkeeping of an online learner; subclasses define `params` (with
    `n_joints`), `layer_names` and `_clear_sequence` (their windows and queues)."""

    layer_names: ClassVar[tuple[str, ...]]
    params: Any
    PERSIST = Persist(values=("_t", "_frames", "_missing", "_sequences", "_predictions"), members={"_errors": "err"})

    def _start_loop(self, horizon: int, n_joints: int) -> None:
        self._t = self._frames = self._missing = self._sequences = self._predictions = 0
        self._errors = ErrorTracker(horizon, n_joints, self.layer_names)

    def _clear_sequence(self) -> None:
        raise NotImplementedError

    def _as_frame(self, x: np.ndarray | None) -> np.ndarray | None:
        """`frame_or_none` for this learner's joints."""
        return frame_or_none(x, self.params.n_joints)

    def reset_sequence(self) -> None:
        """Sequence boundary: clear windows, queues and pending predictions (never what was learned)."""
        self._clear_sequence()
        self._errors.forget_pending()
        self._sequences += 1

    def reset_errors(self) -> None:
        """Zero the error statistics (the frame counters stay)."""
        self._errors.reset()

    @property
    def frames_seen(self) -> int:
        return self._frames

    def _counts(self) -> dict[str, int]:
        return {"steps": self._t, "frames": self._frames, "missing": self._missing,
                "sequences": self._sequences, "predictions": self._predictions}
