"""How far a follower (the robot) lags a reference (the person), and how closely it tracks it.

Why a shift search: the robot's error against the person mixes lag with shape errors; the lag is
the time shift that makes the two trajectories agree best, which is what delay compensation is
meant to remove.
"""

from __future__ import annotations

import math

import numpy as np

from gwr_predictor.robot.errors import RobotError


def _pair(reference: np.ndarray, follower: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    ref = np.asarray(reference, dtype=float)
    fol = np.asarray(follower, dtype=float)
    if ref.ndim == 1:
        ref = ref[:, None]
    if fol.ndim == 1:
        fol = fol[:, None]
    if ref.shape != fol.shape or ref.ndim != 2:
        raise RobotError(f"reference and follower must both be (T, J) of one shape, got {ref.shape} and {fol.shape}")
    return ref, fol


def shift_mse(reference: np.ndarray, follower: np.ndarray, max_shift: int) -> np.ndarray:
    """MSE(s) for s = -max_shift..max_shift of follower[t + s] against reference[t] (NaN rows skipped)."""
    ref, fol = _pair(reference, follower)
    n = ref.shape[0]
    out = np.full(2 * max_shift + 1, np.inf)
    for i, s in enumerate(range(-max_shift, max_shift + 1)):
        a = ref[max(0, -s): n - max(0, s)]
        b = fol[max(0, s): n - max(0, -s)]
        ok = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
        if ok.sum() >= 2:
            out[i] = float(np.mean((a[ok] - b[ok]) ** 2))
    return out


def estimate_lag(reference: np.ndarray, follower: np.ndarray, dt: float, max_lag_s: float) -> float:
    """Seconds by which `follower` lags `reference` (negative: it leads), |lag| <= max_lag_s.

    The integer shift with the least MSE, refined below one sample by the vertex of the parabola
    through the MSE at that shift and its two neighbours.
    """
    if not (dt > 0 and math.isfinite(dt)):
        raise RobotError(f"dt must be > 0, got {dt!r}")
    ref, _ = _pair(reference, follower)
    max_shift = round(max_lag_s / dt)
    if not (1 <= max_shift < ref.shape[0] - 2):
        raise RobotError(f"max_lag_s={max_lag_s!r} must span 1..{ref.shape[0] - 3} samples of dt={dt!r}")
    mse = shift_mse(reference, follower, max_shift)
    if not np.isfinite(mse).any():
        raise RobotError("no overlapping finite samples to compare")
    i = int(np.argmin(mse))
    frac = 0.0
    if 0 < i < mse.size - 1 and np.isfinite(mse[i - 1]) and np.isfinite(mse[i + 1]):
        curvature = mse[i - 1] - 2.0 * mse[i] + mse[i + 1]
        if curvature > 0:
            frac = 0.5 * (mse[i - 1] - mse[i + 1]) / curvature
    return (i - max_shift + frac) * dt


def tracking_error(reference: np.ndarray, follower: np.ndarray) -> dict[str, float]:
    """Mean absolute and root-mean-square error over all joints and samples (rad)."""
    ref, fol = _pair(reference, follower)
    diff = (fol - ref)[np.isfinite(fol).all(axis=1) & np.isfinite(ref).all(axis=1)]
    if diff.size == 0:
        raise RobotError("no finite samples to compare")
    return {"mae": float(np.mean(np.abs(diff))), "rmse": float(np.sqrt(np.mean(diff**2)))}
