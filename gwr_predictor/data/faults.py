"""Simulated sensor faults: lost one-second chunks (the paper's Sec. VI-C) and per-joint dropouts.

`drop_chunks` returns a keep-mask rather than editing data, so the same loss can be applied to
angles, stamps and targets alike. `joint_dropouts` blanks single joints of a skeleton for short
spans, like a tracker that loses a hand behind the body; NaN means "not tracked" everywhere.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gwr_predictor.data.errors import DataError
from gwr_predictor.joints.skeleton import ANGLE_FPS

#: One second of 10 fps frames, the chunk the paper removes.
CHUNK_FRAMES = int(ANGLE_FPS)


def _rng(rng: np.random.Generator | int | None) -> np.random.Generator:
    return rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)


def _check_int(name: str, value: int, low: int) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise DataError(f"{name} must be an integer >= {low}, got {value!r}")


def drop_chunks(n_frames: int, fraction: float, chunk: int = CHUNK_FRAMES,
                rng: np.random.Generator | int | None = None) -> np.ndarray:
    """Keep-mask (n_frames,) with whole `chunk`-frame runs removed at random offsets.

    round(fraction * n_frames / chunk) chunks are removed (never overlapping, possibly adjacent),
    so the removed share is within half a chunk of `fraction` -- less only if whole chunks no
    longer fit. Placement is uniform over all such arrangements.
    """
    _check_int("n_frames", n_frames, 0)
    _check_int("chunk", chunk, 1)
    if isinstance(fraction, bool) or not isinstance(fraction, (int, float)) or not 0.0 <= fraction <= 1.0:
        raise DataError(f"fraction must be in [0, 1], got {fraction!r}")
    k = min(round(fraction * n_frames / chunk), n_frames // chunk)
    keep = np.ones(n_frames, dtype=bool)
    if k == 0:
        return keep
    spare = n_frames - k * chunk  # kept frames, shared out between the k + 1 gaps (stars and bars)
    bars = np.sort(_rng(rng).choice(spare + k, size=k, replace=False))
    starts = bars - np.arange(k) + np.arange(k) * chunk
    removed = (starts[:, None] + np.arange(chunk)).ravel()
    keep[removed] = False
    return keep


def joint_dropouts(positions: np.ndarray, rate: float, max_span: int = 15,
                   rng: np.random.Generator | int | None = None,
                   joints: Sequence[int] | None = None) -> np.ndarray:
    """Copy of positions (T, J, 3) with random joints NaN for random spans.

    In every frame each joint (of `joints`, default all) starts a dropout with probability `rate`,
    lasting 1..`max_span` frames (uniform); overlapping dropouts merge.
    """
    pos = np.array(positions, dtype=np.float64)
    if pos.ndim != 3 or pos.shape[2] != 3:
        raise DataError(f"positions must be (frames, joints, 3), got shape {pos.shape}")
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0.0 <= rate <= 1.0:
        raise DataError(f"rate must be in [0, 1], got {rate!r}")
    _check_int("max_span", max_span, 1)
    n, j = pos.shape[:2]
    cols = np.arange(j) if joints is None else np.asarray(joints, dtype=int)
    if cols.size and (cols.min() < 0 or cols.max() >= j):
        raise DataError(f"joints must be indices in [0, {j - 1}], got {cols.tolist()}")
    gen = _rng(rng)
    starts = gen.random((n, cols.size)) < rate
    ends = np.where(starts, np.arange(n)[:, None] + gen.integers(1, max_span + 1, (n, cols.size)), 0)
    dropped = np.maximum.accumulate(ends, axis=0) > np.arange(n)[:, None]
    sub = pos[:, cols]
    sub[dropped] = np.nan
    pos[:, cols] = sub
    return pos
