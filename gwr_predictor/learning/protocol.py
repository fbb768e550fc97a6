"""The one `Predictor` protocol every online predictor of the package follows, and `Learner`, the
predictors among them that can be saved.

The hierarchy, the flat P-GWR, the baselines and the blends all take one sample per frame and
return their predictions for the next `horizon` frames (`Spreading`: those that also state an interval
around each, the default and the baselines `hold` and `rls_ar`), so the evaluation loop, the closed loop
with the simulated robot, the blend and the learner node can use any of them (the registry,
`gwr_predictor/registry`, builds them by name).
"""

from __future__ import annotations

import os
from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class Predictor(Protocol):
    """One frame in, predictions for the next frames out.

    `step(x, learn)`: `x` the (joints,) sample of this frame, or None (or non-finite) for a missing
    frame; `learn=False` predicts without changing the model. Returns (horizon, joints) predictions
    for frames t+1..t+horizon (NaN rows where a step has none), or None before the first prediction.
    `reset_sequence()`: the next sample starts a new sequence (no learning across the boundary).
    """

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None: ...

    def reset_sequence(self) -> None: ...


@runtime_checkable
class Learner(Predictor, Protocol):
    """A predictor that grows a model worth keeping (the registry's `learner_names()`): its neurons
    can be counted and its whole state written to a checkpoint that its loader reads back.

    `horizon`: frames predicted (a loaded checkpoint's, whatever the caller asked for).
    `neuron_counts`: neurons per layer, or None where the model inside has none to count.
    `save(path)`: the whole state, atomically, to continue bit for bit.
    """

    @property
    def horizon(self) -> int: ...

    @property
    def neuron_counts(self) -> tuple[int, ...] | None: ...

    def save(self, path: str | os.PathLike[str]) -> None: ...


@runtime_checkable
class Spreading(Predictor, Protocol):
    """A predictor that states with every prediction how far off it may be: a central interval per horizon
    step and joint that should hold the true angle on a share `interval_nominal` of its predictions.

    `interval()`: (lower, upper), each (horizon, joints) rad, of the prediction the last `step` returned;
    None where it returned none.
    """

    @property
    def interval_nominal(self) -> float: ...

    def interval(self) -> tuple[np.ndarray, np.ndarray] | None: ...
