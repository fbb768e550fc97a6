"""The one online evaluation loop: every method sees the same frames, one at a time, and is scored
on the same predictions.

At frame t a predictor is given only x(t) (None for a missing sample) and returns its predictions for
t+1..t+h. The loop keeps the truth to itself and scores those predictions against the true frames
t+1..t+h of the same sequence; a target that is missing (NaN) or past the end is not scored. With
several predictors, a frame counts only where every one of them predicted, so the numbers in one
table always come from exactly the same (frame, horizon, joint) entries. A predictor that states an
interval with every prediction (`protocol.Spreading`) is also scored on how often the true angle falls
inside it and how wide it is, on the same frames (`OnlineResult.interval`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from tqdm import tqdm

from gwr_predictor.evaluation.errors import EvaluationError
from gwr_predictor.evaluation.metrics import HorizonStats, IntervalStats, future_windows, horizon_stats, interval_stats
from gwr_predictor.learning.protocol import Predictor, Spreading
from gwr_predictor.pipeline.conventions import DEFAULT_HORIZON


@dataclass(frozen=True)
class Trace:
    """Per-frame errors in feeding order: Euclidean norm over joints for each horizon step (NaN =
    not scored)."""

    pass_index: np.ndarray  # (N,)
    sequence_index: np.ndarray  # (N,)
    frame: np.ndarray  # (N,) index within its sequence
    error: np.ndarray  # (N, h)


@dataclass
class OnlineResult:
    """What one predictor scored in one evaluation run."""

    horizon: int
    stats: HorizonStats
    pass_stats: list[HorizonStats]
    frames: int = 0  # frames fed, all passes
    scored_frames: int = 0  # frames whose predictions were scored
    predicted_frames: int = 0  # frames where the predictor returned a full prediction
    seconds: float = 0.0  # time spent inside step()
    trace: Trace | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    #: for a predictor that states an interval (`protocol.Spreading`): its stated share and how its intervals did
    interval_nominal: float | None = None
    interval: IntervalStats | None = None

    @property
    def coverage(self) -> float:
        return self.predicted_frames / self.frames if self.frames else 0.0

    def summary(self) -> dict[str, Any]:
        out = {**self.stats.to_dict(), "frames": self.frames, "scored_frames": self.scored_frames,
               "coverage": round(self.coverage, 4), "us_per_frame": 1e6 * self.seconds / max(self.frames, 1)}
        if self.interval is not None:
            out["interval"] = {"nominal": self.interval_nominal, **self.interval.to_dict()}
        return out


def as_angles(sequence: Any) -> np.ndarray:
    """A (T, J) float array from an array or anything with an `angles` attribute (AngleSequence)."""
    arr = np.asarray(getattr(sequence, "angles", sequence), dtype=float)
    if arr.ndim != 2 or arr.shape[0] < 1:
        raise EvaluationError(f"a sequence must be a non-empty (T, J) array, got shape {arr.shape}")
    return arr


def run_sequence(predictor: Predictor, inputs: np.ndarray, horizon: int, learn: bool = True
                 ) -> tuple[np.ndarray, float]:
    """Feed one sequence frame by frame; returns predictions (T, horizon, J) (NaN = none) and seconds."""
    preds, _, seconds = run_with_intervals(predictor, inputs, horizon, learn)
    return preds, seconds


def run_with_intervals(predictor: Predictor, inputs: np.ndarray, horizon: int, learn: bool = True
                       ) -> tuple[np.ndarray, np.ndarray | None, float]:
    """`run_sequence`, plus the stated intervals (2, T, horizon, J) [lower, upper] (NaN = none) of a
    `Spreading` predictor (None for another); the seconds count its `step` only."""
    t_len, joints = inputs.shape
    preds = np.full((t_len, horizon, joints), np.nan)
    spreads = isinstance(predictor, Spreading)
    bounds = np.full((2, t_len, horizon, joints), np.nan) if spreads else None
    missing = ~np.isfinite(inputs).all(axis=1)
    predictor.reset_sequence()
    seconds = 0.0
    for t in range(t_len):
        start = time.perf_counter()
        out = predictor.step(None if missing[t] else inputs[t], learn=learn)
        seconds += time.perf_counter() - start
        if out is None:
            continue
        out = np.asarray(out, dtype=float)
        if out.ndim != 2 or out.shape[0] < horizon or out.shape[1] != joints:
            raise EvaluationError(f"{type(predictor).__name__}.step returned shape {out.shape}; "
                                  f"need at least ({horizon}, {joints})")
        preds[t] = out[:horizon]
        if bounds is not None:
            stated = predictor.interval()  # type: ignore[attr-defined]
            if stated is not None:
                bounds[0, t], bounds[1, t] = stated[0][:horizon], stated[1][:horizon]
    return preds, bounds, seconds


def compare_online(predictors: Mapping[str, Predictor], sequences: Sequence[Any], *, learn: bool = True,
                   horizon: int = DEFAULT_HORIZON, passes: int = 1, trace: bool = False, progress: bool = True,
                   desc: str = "evaluate") -> dict[str, OnlineResult]:
    """Run every predictor over `sequences` (`passes` times, in order) and score them side by side.

    `sequences` are the inputs and the truth (NaN rows = missing samples, so a missing sample is
    never a target). Each sequence starts with `reset_sequence()`.
    """
    if not predictors:
        raise EvaluationError("no predictors to evaluate")
    if horizon < 1 or passes < 1:
        raise EvaluationError(f"need horizon >= 1, passes >= 1; got {horizon}, {passes}")
    inputs = [as_angles(s) for s in sequences]
    joints = inputs[0].shape[1]
    if any(a.shape[1] != joints for a in inputs):
        raise EvaluationError("all sequences must have the same number of joints")
    futures = [future_windows(a, horizon) for a in inputs]
    results = {name: OnlineResult(horizon, HorizonStats.empty(horizon, joints), []) for name in predictors}
    for name, predictor in predictors.items():
        if isinstance(predictor, Spreading):
            results[name].interval_nominal = float(predictor.interval_nominal)
            results[name].interval = IntervalStats.empty(horizon, joints)
    traces: dict[str, list[np.ndarray]] = {name: [] for name in predictors}
    total = passes * sum(a.shape[0] for a in inputs) * len(predictors)
    with tqdm(total=total, desc=desc, unit="frame", disable=not progress, leave=False, mininterval=0.5) as bar:
        for _ in range(passes):
            pass_stats = {name: HorizonStats.empty(horizon, joints) for name in predictors}
            for seq, future in zip(inputs, futures, strict=True):
                preds, bounds = {}, {}
                for name, predictor in predictors.items():
                    preds[name], bounds[name], seconds = run_with_intervals(predictor, seq, horizon, learn)
                    results[name].seconds += seconds
                    bar.update(seq.shape[0])
                present = {name: np.isfinite(pr).all(axis=(1, 2)) for name, pr in preds.items()}
                common = np.logical_and.reduce(list(present.values()))
                for name, pr in preds.items():
                    res = results[name]
                    res.frames += seq.shape[0]
                    res.predicted_frames += int(present[name].sum())
                    res.scored_frames += int(common.sum())
                    pass_stats[name] = pass_stats[name].merge(horizon_stats(pr[common], future[common]))
                    stated = bounds[name]
                    if stated is not None and res.interval is not None:
                        res.interval = res.interval.merge(interval_stats(stated[0, common], stated[1, common],
                                                                         future[common]))
                    if trace:
                        err = np.linalg.norm(pr - future, axis=2)
                        err[~common] = np.nan
                        traces[name].append(err)
            for name, res in results.items():
                res.pass_stats.append(pass_stats[name])
                res.stats = res.stats.merge(pass_stats[name])
    if trace:
        lengths = [a.shape[0] for a in inputs] * passes
        meta = (np.repeat(np.arange(passes), sum(a.shape[0] for a in inputs)),
                np.concatenate([np.full(n, i % len(inputs)) for i, n in enumerate(lengths)]),
                np.concatenate([np.arange(n) for n in lengths]))
        for name, res in results.items():
            res.trace = Trace(*meta, np.concatenate(traces[name]))
    return results


def evaluate_online(predictor: Predictor, sequences: Sequence[Any], *, learn: bool = True,
                    horizon: int = DEFAULT_HORIZON, passes: int = 1, progress: bool = True,
                    **kwargs: Any) -> OnlineResult:
    """`compare_online` for a single predictor."""
    return compare_online({"model": predictor}, sequences, learn=learn, horizon=horizon, passes=passes,
                          progress=progress, **kwargs)["model"]


def train_online(predictor: Predictor, sequences: Sequence[Any], passes: int = 1, progress: bool = True,
                 desc: str = "train") -> int:
    """Learn from `sequences` without scoring (cheaper than evaluating); returns frames fed."""
    inputs = [as_angles(s) for s in sequences]
    frames = passes * sum(a.shape[0] for a in inputs)
    with tqdm(total=frames, desc=desc, unit="frame", disable=not progress, leave=False, mininterval=0.5) as bar:
        for _ in range(passes):
            for seq in inputs:
                missing = ~np.isfinite(seq).all(axis=1)
                predictor.reset_sequence()
                for t in range(seq.shape[0]):
                    predictor.step(None if missing[t] else seq[t], learn=True)
                bar.update(seq.shape[0])
    return frames
