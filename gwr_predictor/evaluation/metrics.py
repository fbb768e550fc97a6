"""Error statistics of multi-step predictions: per-horizon MAE/MSE/std, trends and settling time.

Errors are in radians, per joint component: the MAE at horizon k is the mean of |y_hat - y| over
every scored frame and every joint, the MSE the mean of the squared differences, and the std is the
spread of the absolute errors. Accumulators are plain sums so that runs, passes and sequences can be
merged exactly (`HorizonStats.merge`) without keeping every error in memory.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gwr_predictor.evaluation.errors import EvaluationError
from gwr_predictor.learning.pending import target_steps


@dataclass(frozen=True)
class HorizonStats:
    """Sums of absolute and squared errors per (horizon step, joint), and how many were scored."""

    count: np.ndarray  # (h, J) int: scored components
    sum_abs: np.ndarray  # (h, J)
    sum_sq: np.ndarray  # (h, J)

    @classmethod
    def empty(cls, horizon: int, joints: int = 8) -> HorizonStats:
        if horizon < 1 or joints < 1:
            raise EvaluationError(f"horizon and joints must be >= 1, got {horizon}, {joints}")
        z = np.zeros((horizon, joints))
        return cls(np.zeros((horizon, joints), dtype=np.int64), z, z.copy())

    @property
    def horizon(self) -> int:
        return int(self.count.shape[0])

    def merge(self, other: HorizonStats) -> HorizonStats:
        if other.count.shape != self.count.shape:
            raise EvaluationError(f"cannot merge stats of shapes {self.count.shape} and {other.count.shape}")
        return HorizonStats(self.count + other.count, self.sum_abs + other.sum_abs, self.sum_sq + other.sum_sq)

    @property
    def n(self) -> np.ndarray:
        """Scored components per horizon step (h,)."""
        return self.count.sum(axis=1)

    @property
    def mae(self) -> np.ndarray:
        """Mean absolute error per horizon step (h,), NaN where nothing was scored."""
        return _ratio(self.sum_abs.sum(axis=1), self.n)

    @property
    def mse(self) -> np.ndarray:
        """Mean squared error per horizon step (h,)."""
        return _ratio(self.sum_sq.sum(axis=1), self.n)

    @property
    def std(self) -> np.ndarray:
        """Standard deviation of the absolute error per horizon step (h,)."""
        return np.sqrt(np.maximum(self.mse - self.mae**2, 0.0))

    @property
    def joint_mae(self) -> np.ndarray:
        """Mean absolute error per (horizon step, joint)."""
        return _ratio(self.sum_abs, self.count)

    def overall_mse(self) -> float:
        """MSE over every horizon step and joint together."""
        return float(_ratio(self.sum_sq.sum(), self.count.sum()))

    def to_dict(self) -> dict[str, list[float | None]]:
        return {"mae": _floats(self.mae), "mse": _floats(self.mse), "std": _floats(self.std),
                "n": [int(v) for v in self.n]}


@dataclass(frozen=True)
class IntervalStats:
    """Per (horizon step, joint): stated intervals scored, true angles inside them, and the sum of their widths
    (rad); sums, so that runs, passes and sequences merge exactly."""

    count: np.ndarray  # (h, J) int
    inside: np.ndarray  # (h, J) int
    sum_width: np.ndarray  # (h, J)

    @classmethod
    def empty(cls, horizon: int, joints: int = 8) -> IntervalStats:
        if horizon < 1 or joints < 1:
            raise EvaluationError(f"horizon and joints must be >= 1, got {horizon}, {joints}")
        zeros = np.zeros((horizon, joints), dtype=np.int64)
        return cls(zeros, zeros.copy(), np.zeros((horizon, joints)))

    def merge(self, other: IntervalStats) -> IntervalStats:
        if other.count.shape != self.count.shape:
            raise EvaluationError(f"cannot merge interval stats of shapes {self.count.shape} and {other.count.shape}")
        return IntervalStats(self.count + other.count, self.inside + other.inside, self.sum_width + other.sum_width)

    @property
    def coverage(self) -> np.ndarray:
        """Share of the true angles inside their stated interval per horizon step (h,), NaN where none scored."""
        return _ratio(self.inside.sum(axis=1), self.count.sum(axis=1))

    @property
    def width(self) -> np.ndarray:
        """Mean width (upper - lower, rad) of the scored intervals per horizon step (h,)."""
        return _ratio(self.sum_width.sum(axis=1), self.count.sum(axis=1))

    def to_dict(self) -> dict[str, list[float | None]]:
        return {"coverage": _floats(self.coverage), "width": _floats(self.width),
                "n": [int(v) for v in self.count.sum(axis=1)]}


def interval_stats(lower: np.ndarray, upper: np.ndarray, truth: np.ndarray) -> IntervalStats:
    """Stats of stated intervals [lower, upper] (N, h, J) against the truth (N, h, J); NaN anywhere: not scored.
    An angle on a bound is inside."""
    lower, upper, truth = (np.asarray(a, float) for a in (lower, upper, truth))
    if not lower.shape == upper.shape == truth.shape or truth.ndim != 3:
        raise EvaluationError(f"bounds {lower.shape}, {upper.shape} and truth {truth.shape} must all be (N, h, J)")
    ok = np.isfinite(lower) & np.isfinite(upper) & np.isfinite(truth)
    inside = ok & (truth >= lower) & (truth <= upper)
    return IntervalStats(ok.sum(axis=0).astype(np.int64), inside.sum(axis=0).astype(np.int64),
                         np.where(ok, upper - lower, 0.0).sum(axis=0))


def _ratio(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    num, den = np.asarray(num, float), np.asarray(den, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan)


def _floats(values: np.ndarray) -> list[float | None]:
    """JSON-friendly list: NaN becomes None."""
    return [None if not np.isfinite(v) else float(v) for v in np.asarray(values, float).ravel()]


def horizon_stats(predictions: np.ndarray, truth: np.ndarray) -> HorizonStats:
    """Stats of predictions (N, h, J) against truth (N, h, J); NaN in either is not scored."""
    predictions, truth = np.asarray(predictions, float), np.asarray(truth, float)
    if predictions.shape != truth.shape or predictions.ndim != 3:
        raise EvaluationError(f"predictions {predictions.shape} and truth {truth.shape} must both be (N, h, J)")
    err = predictions - truth
    ok = np.isfinite(err)
    err = np.where(ok, err, 0.0)
    return HorizonStats(ok.sum(axis=0).astype(np.int64), np.abs(err).sum(axis=0), (err**2).sum(axis=0))


def future_windows(values: np.ndarray, horizon: int) -> np.ndarray:
    """(T, J) -> (T, horizon, J): out[t, k] = values[t + 1 + k], the frame that row k of a prediction
    made at t targets (`pending.target_steps`), NaN past the end."""
    values = np.asarray(values, float)
    if values.ndim != 2:
        raise EvaluationError(f"expected a (T, J) array, got {values.shape}")
    t, j = values.shape
    padded = np.concatenate([values, np.full((horizon + 1, j), np.nan)])
    return padded[target_steps(np.arange(t), horizon)]


def moving_average(values: np.ndarray, window: int, centered: bool = False) -> np.ndarray:
    """Mean over `window` samples that ignores NaN (NaN only where the window is empty).

    Trailing (causal) by default; `centered` puts the window around each sample, which does not lag
    and so suits after-the-fact analysis such as settling times.
    """
    values = np.asarray(values, float)
    if window < 1:
        raise EvaluationError(f"window must be >= 1, got {window}")
    ok = np.isfinite(values)
    csum = np.concatenate([[0.0], np.cumsum(np.where(ok, values, 0.0))])
    ccnt = np.concatenate([[0], np.cumsum(ok)])
    idx = np.arange(values.size)
    hi = np.minimum(idx + 1 + (window // 2 if centered else 0), values.size)
    lo = np.maximum(hi - window, 0)
    return _ratio(csum[hi] - csum[lo], ccnt[hi] - ccnt[lo])


@dataclass(frozen=True)
class Trend:
    """Least-squares line through an error series: value ~ intercept + slope * frame."""

    slope: float
    intercept: float

    def __call__(self, frames: np.ndarray) -> np.ndarray:
        return self.intercept + self.slope * np.asarray(frames, float)


def linear_trend(values: np.ndarray, frames: np.ndarray | None = None) -> Trend:
    """Straight-line fit of the finite entries of `values` (the 'statistical trend' of the paper)."""
    values = np.asarray(values, float)
    frames = np.arange(values.size, dtype=float) if frames is None else np.asarray(frames, float)
    ok = np.isfinite(values) & np.isfinite(frames)
    if ok.sum() < 2:
        raise EvaluationError(f"a trend needs at least 2 finite values, got {int(ok.sum())}")
    x, y = frames[ok], values[ok]
    xm = x.mean()
    var = ((x - xm) ** 2).sum()
    slope = float(((x - xm) * (y - y.mean())).sum() / var) if var > 0 else 0.0
    return Trend(slope, float(y.mean() - slope * xm))


def settling_frame(values: np.ndarray, window: int = 20, tolerance: float = 0.2,
                   final_fraction: float = 0.3, floor: float = 0.0,
                   reference: np.ndarray | None = None) -> int | None:
    """First frame after which the smoothed error stays within `tolerance` of its settled level.

    The settled level is, by default, the median of the smoothed error over the last
    `final_fraction` of the series. When the same data are presented repeatedly, pass the error of
    the last presentation as `reference` (tiled over the series): the level is then compared frame
    by frame, which removes the rise and fall of the error with the movement itself. The band is
    level * (1 + tolerance) + floor (the floor keeps a near-zero level from making it vanish).
    Returns None when the error never settles (the last frame is outside the band).
    """
    values = np.asarray(values, float)
    if not 0.0 < final_fraction <= 1.0:
        raise EvaluationError(f"final_fraction must be in (0, 1], got {final_fraction}")
    smooth = moving_average(values, window, centered=True)
    ok = np.isfinite(smooth)
    if not ok.any():
        return None
    if reference is None:
        tail = smooth[int(np.floor(values.size * (1.0 - final_fraction))):]
        tail = tail[np.isfinite(tail)]
        level: np.ndarray | float = float(np.median(tail if tail.size else smooth[ok]))
    else:
        reference = np.asarray(reference, float)
        if reference.size == 0 or values.size % reference.size:
            raise EvaluationError(f"reference of {reference.size} frames does not tile {values.size} frames")
        level = moving_average(np.tile(reference, values.size // reference.size), window, centered=True)
        ok &= np.isfinite(level)
    band = level * (1.0 + tolerance) + floor
    outside = np.flatnonzero(ok & (smooth > band))
    if outside.size == 0:
        return int(np.flatnonzero(ok)[0])
    last = int(outside[-1])
    return None if last >= values.size - 1 else last + 1
