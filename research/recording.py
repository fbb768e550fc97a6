"""A predictor wrapper that keeps what it predicted, so that an experiment can score subsets of frames
(per repetition, per phase) or see when a prediction was exactly hold-last, from the one evaluation loop."""

from __future__ import annotations

from typing import Any

import numpy as np


class Recorded:
    """`model` unchanged, plus `outputs`: per step its prediction (None where it made none),
    `held`: per step whether that prediction was exactly the newest observed pose at every step, and for a
    model that states an interval (`protocol.Spreading`, which the wrapper then is too) `intervals`: per
    step its (lower, upper) bounds (None where it stated none)."""

    def __init__(self, model: Any) -> None:
        self.model = model
        self.outputs: list[np.ndarray | None] = []
        self.held: list[bool] = []
        self.intervals: list[tuple[np.ndarray, np.ndarray] | None] = []
        self._last: np.ndarray | None = None

    @property
    def interval_nominal(self) -> float:
        """The wrapped model's stated share (AttributeError, so not `Spreading`, for a model that states none)."""
        return float(self.model.interval_nominal)

    def interval(self) -> tuple[np.ndarray, np.ndarray] | None:
        return self.intervals[-1] if self.intervals else None

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        if x is not None:
            self._last = np.asarray(x, dtype=float)
        out = self.model.step(x, learn=learn)
        self.outputs.append(None if out is None else np.array(out, dtype=float))
        self.held.append(out is not None and self._last is not None and bool(np.all(out == self._last)))
        if callable(getattr(self.model, "interval", None)):
            self.intervals.append(self.model.interval())
        return out

    def bounds(self, horizon: int, joints: int) -> np.ndarray:
        """(2, steps, horizon, joints) the stated [lower, upper] per step, NaN where none was stated."""
        out = np.full((2, len(self.intervals), horizon, joints), np.nan)
        for t, stated in enumerate(self.intervals):
            if stated is not None:
                out[0, t], out[1, t] = stated[0][:horizon], stated[1][:horizon]
        return out

    def reset_sequence(self) -> None:
        self._last = None
        self.model.reset_sequence()

    def predictions(self, horizon: int, joints: int) -> np.ndarray:
        """(steps, horizon, joints), NaN where no prediction was made."""
        out = np.full((len(self.outputs), horizon, joints), np.nan)
        for t, o in enumerate(self.outputs):
            if o is not None:
                out[t] = o[:horizon]
        return out

    def held_share(self) -> float | None:
        """Share of the steps with a prediction whose prediction was exactly hold-last."""
        made = sum(o is not None for o in self.outputs)
        return sum(self.held) / made if made else None
