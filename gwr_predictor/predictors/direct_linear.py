"""One global linear map from the newest pose and its latest changes to the next `horizon` displacements.

Why: where a person has shown little (a new user's first minutes, a few takes of a task), the
local-linear P-GWR has hundreds of neurons with a handful of samples each, and one linear model fitted
by exact least squares to everything seen so far predicts better in squared error (measured on the
climbing takes of `experiment real`). The default predictor stacks the two
(`predictors/stack.py`); alone, this is also a baseline (`linear` in the registry).

It differs from RLS-AR (`baselines.RLSAutoregressive`) in what it fits, not in how:

    features  phi(t) = [x(t) - x(t-1), ..., x(t) - x(t-order+1), x(t), 1]
    outputs   y(t)   = [x(t+k) - x(t)]_{k=1..horizon}      (direct: one output block per step)

so every step is fitted for its own error instead of feeding one-step predictions back, and a fresh
model (W = 0) predicts "no movement", i.e. hold-last. The pair (phi(t-h), y(t-h)) is learned at frame t,
once its targets are observed (no peeking); a missing sample (None/NaN) clears the window and the
queue. Like RLS-AR, it predicts from the first frame of a sequence: until `order` frames are there the
window is padded with the first one (no change yet), and pairs whose features were padded are never
learned from. Learning is recursive least squares (`learning/rls.py`) with forgetting `forgetting` and
P(0) = `delta` I, reset when it winds up (trace above `max_trace`).
"""

from __future__ import annotations

import dataclasses
from collections import deque
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from gwr_predictor.learning.persistence import Checkpointed, Persist
from gwr_predictor.learning.rls import RecursiveLeastSquares, window_features
from gwr_predictor.parameters.spec import ParamSpec, check_fields
from gwr_predictor.pipeline.conventions import DEFAULT_HORIZON, MAX_HORIZON
from gwr_predictor.predictors.baselines import N_JOINTS, observation
from gwr_predictor.predictors.errors import PredictorError

_SPECS = {spec.name: spec for spec in (
    ParamSpec("order", 12, "frames the features span (order - 1 frame-to-frame changes + the newest pose)", 1, 64),
    ParamSpec("forgetting", 1.0, "RLS forgetting factor per learned pair (1: fit everything seen)", 0.9, 1.0),
    ParamSpec("delta", 1.0, "initial P = delta I (prior variance of the weights)", 0.0, lo_open=True),
    ParamSpec("max_trace", 1e6, "P is reset when its trace exceeds this (wind-up)", 0.0, lo_open=True),
    ParamSpec("horizon", DEFAULT_HORIZON, "frames predicted", 1, MAX_HORIZON),
    ParamSpec("joints", N_JOINTS, "joints per frame", 1),
)}


@dataclass(frozen=True)
class DirectLinearParams:
    """`order`: frames the features span (1: the newest pose and a bias only). `forgetting`: RLS
    forgetting per learned pair. `delta`: P(0) = delta I. `max_trace`: the wind-up guard. `horizon`,
    `joints`: the output's shape. The defaults are the `linear` baseline's in every report and the
    default predictor's, chosen by `gwr-predictor experiment tune` on the demonstrator's tuning recordings
    (seed 7, in no reported figure)."""

    SPECS: ClassVar[dict[str, ParamSpec]] = _SPECS
    order: int = _SPECS["order"].default
    forgetting: float = _SPECS["forgetting"].default
    delta: float = _SPECS["delta"].default
    max_trace: float = _SPECS["max_trace"].default
    horizon: int = _SPECS["horizon"].default
    joints: int = _SPECS["joints"].default

    def __post_init__(self) -> None:
        check_fields(self, _SPECS.values(), PredictorError)

    def replace(self, **changes: Any) -> DirectLinearParams:
        return dataclasses.replace(self, **changes)

    @property
    def features(self) -> int:
        return self.order * self.joints + 1


class DirectLinear(Checkpointed):
    """Online direct multi-step linear predictor (see the module docstring); the `Predictor` protocol."""

    kind: ClassVar[str] = "DirectLinear"
    PARAMS = DirectLinearParams
    PERSIST = Persist(arrays=("_win",), values=("_fill",), optional=("_last",), members={"rls": ""},
                      queues={"_hist": lambda m: (m.params.joints,), "_feats": lambda m: (m.params.features,)})
    # the sequence state `_clear_sequence` resets: window (newest first), its fill, the frames and the
    # features of the pairs still waiting for their targets, the last features predicted from
    _win: np.ndarray
    _fill: int
    _hist: deque[np.ndarray]
    _feats: deque[np.ndarray | None]
    _last: np.ndarray | None

    def __init__(self, params: DirectLinearParams | None = None) -> None:
        self.params = p = params or DirectLinearParams()
        self.rls = RecursiveLeastSquares(p.features, p.horizon * p.joints, p.forgetting, p.delta, p.max_trace)
        self._clear_sequence()

    # --- the online step ----------------------------------------------------------------------------
    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        """Observe x (rad; None/NaN = missing), learn the pair whose targets just completed, predict."""
        p = self.params
        frame = observation(x, p.joints)
        if frame is None:
            self._clear_sequence()
            return None
        win = self._win
        if self._fill == 0:
            win[...] = frame  # padded with the first frame: no change yet
        else:
            win[1:] = win[:-1]
            win[0] = frame
        self._fill = min(self._fill + 1, p.order)
        self._hist.append(frame)
        if learn and len(self._feats) == p.horizon and self._feats[0] is not None:
            frames = np.asarray(self._hist)  # x(t-h) ... x(t)
            self.rls.update(self._feats[0], (frames[1:] - frames[0]).reshape(-1))
        self._last = phi = window_features(win, p.order)
        self._feats.append(phi if self._fill == p.order else None)  # padded features are not learned from
        return self._forecast(phi)

    def predict(self) -> np.ndarray | None:
        """The prediction of the last `step` with the current weights; no state change."""
        return None if self._last is None else self._forecast(self._last)

    def reset_sequence(self) -> None:
        """Sequence boundary: clear the window and the queue of pairs (never the weights)."""
        self._clear_sequence()

    def _clear_sequence(self) -> None:
        p = self.params
        self._win = np.zeros((p.order, p.joints))  # newest first
        self._fill = 0
        self._hist = deque(maxlen=p.horizon + 1)
        self._feats = deque(maxlen=p.horizon)
        self._last = None

    def _forecast(self, phi: np.ndarray) -> np.ndarray:
        p = self.params
        out = self.rls.predict(phi).reshape(p.horizon, p.joints)
        out += self._win[0]
        return out

    def errors(self) -> dict[str, Any]:
        return {"updates": self.rls.updates, "resets": self.rls.resets}
