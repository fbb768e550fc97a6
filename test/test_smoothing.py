"""Median of 3 frames: the paper's 30 -> 10 fps filter, batch and streaming, with its NaN rule."""

import numpy as np
import pytest

from gwr_predictor.data.errors import DataError
from gwr_predictor.data.smoothing import MedianOf3, median_of_3


def _frames(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, 15, 3)), np.arange(n) / 30.0


def test_batch_takes_the_median_of_each_group_of_three_and_the_middle_stamp():
    pos, t = _frames(10)
    out, stamps = median_of_3(pos, t)
    assert out.shape == (3, 15, 3)  # the trailing incomplete group is dropped
    for g in range(3):
        np.testing.assert_array_equal(out[g], np.median(pos[3 * g: 3 * g + 3], axis=0))
    np.testing.assert_allclose(stamps, t[[1, 4, 7]])


def test_a_single_frame_glitch_is_removed():
    pos = np.zeros((3, 15, 3))
    pos[1, 5] = [0.5, -0.3, 0.2]
    out, _ = median_of_3(pos, np.arange(3) / 30.0)
    np.testing.assert_array_equal(out[0], 0.0)


def test_joint_tracked_in_two_frames_gives_their_mean_and_in_one_frame_nan():
    pos = np.arange(3 * 2 * 3, dtype=float).reshape(3, 2, 3)
    pos[0, 0] = np.nan  # joint 0 lost in frame 0 only
    pos[0, 1, 2] = np.nan  # joint 1: one NaN coordinate makes the whole joint untracked ...
    pos[1, 1] = np.nan  # ... and it is lost in frame 1 too
    out, _ = median_of_3(pos, np.arange(3.0))
    np.testing.assert_allclose(out[0, 0], 0.5 * (pos[1, 0] + pos[2, 0]))
    assert np.isnan(out[0, 1]).all()


def test_streaming_equals_batch_including_nans():
    pos, t = _frames(31, seed=3)
    pos[np.random.default_rng(4).random(pos.shape[:2]) < 0.3] = np.nan
    batch, batch_t = median_of_3(pos, t)
    smoother = MedianOf3()
    outputs = [smoother.push(s, f) for s, f in zip(t, pos, strict=True)]
    got = [o for o in outputs if o is not None]
    assert [o is not None for o in outputs] == [i % 3 == 2 for i in range(31)]
    np.testing.assert_array_equal(np.stack([f for _, f in got]), batch)
    np.testing.assert_array_equal([s for s, _ in got], batch_t)
    assert smoother.pending == 1


def test_reset_drops_a_partial_group():
    smoother = MedianOf3()
    smoother.push(0.0, np.ones((15, 3)))
    smoother.reset()
    assert smoother.push(1.0, np.zeros((15, 3))) is None
    assert smoother.push(2.0, np.zeros((15, 3))) is None
    stamp, frame = smoother.push(3.0, np.zeros((15, 3)))
    assert stamp == 2.0 and not frame.any()


def test_mismatched_shapes_are_refused():
    with pytest.raises(DataError, match="timestamps"):
        median_of_3(np.zeros((6, 15, 3)), np.zeros(5))
    smoother = MedianOf3()
    smoother.push(0.0, np.zeros((15, 3)))
    with pytest.raises(DataError, match="frame shape"):
        smoother.push(1.0, np.zeros((14, 3)))
