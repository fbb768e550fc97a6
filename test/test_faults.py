"""Sensor faults: whole one-second chunks removed to a chosen fraction, per-joint dropouts."""

import numpy as np
import pytest

from gwr_predictor.data.errors import DataError
from gwr_predictor.data.faults import CHUNK_FRAMES, drop_chunks, joint_dropouts


def _runs(removed: np.ndarray) -> list[int]:
    """Lengths of the runs of True."""
    edges = np.diff(np.concatenate(([0], removed.astype(int), [0])))
    return list(np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1))


@pytest.mark.parametrize("n", [37, 100, 523])
@pytest.mark.parametrize("fraction", [0.0, 0.05, 0.3, 0.5, 0.95, 1.0])
def test_removes_the_asked_fraction_within_one_chunk_in_whole_chunks(n, fraction):
    keep = drop_chunks(n, fraction, rng=np.random.default_rng(n))
    assert keep.dtype == bool and keep.shape == (n,)
    removed = ~keep
    assert abs(removed.mean() - fraction) <= CHUNK_FRAMES / n
    assert all(r % CHUNK_FRAMES == 0 for r in _runs(removed))


def test_chunk_size_is_a_parameter():
    keep = drop_chunks(200, 0.4, chunk=7, rng=1)
    assert (~keep).sum() == 7 * round(0.4 * 200 / 7)
    assert all(r % 7 == 0 for r in _runs(~keep))


def test_same_seed_same_mask_and_other_seeds_differ():
    a = drop_chunks(300, 0.3, rng=5)
    np.testing.assert_array_equal(a, drop_chunks(300, 0.3, rng=5))
    assert not np.array_equal(a, drop_chunks(300, 0.3, rng=6))


def test_chunks_land_anywhere_not_on_a_fixed_grid():
    rng = np.random.default_rng(0)
    masks = np.stack([drop_chunks(100, 0.2, rng=rng) for _ in range(4000)])
    per_frame = 1.0 - masks.mean(axis=0)
    # Uniform placement: frames at least a chunk from the ends are lost about equally often,
    # and the end frames can be lost too (less often: fewer chunk positions cover them).
    interior = per_frame[CHUNK_FRAMES:-CHUNK_FRAMES]
    assert np.all(np.abs(interior - 0.2) < 0.04)
    assert per_frame[0] > 0 and per_frame[-1] > 0
    starts = {int(np.flatnonzero(np.diff(np.concatenate(([1], m.astype(int)))) == -1)[0]) for m in masks}
    assert len(starts) > 30


@pytest.mark.parametrize("bad", [-0.1, 1.5, float("nan"), "0.3"])
def test_fraction_outside_zero_one_is_refused(bad):
    with pytest.raises(DataError, match=r"fraction must be in \[0, 1\]"):
        drop_chunks(100, bad)


def test_bad_frame_and_chunk_counts_are_refused():
    with pytest.raises(DataError, match="n_frames"):
        drop_chunks(-1, 0.1)
    with pytest.raises(DataError, match="chunk"):
        drop_chunks(10, 0.1, chunk=0)


def test_joint_dropouts_blank_whole_joints_of_chosen_joints_only():
    pos = np.random.default_rng(0).normal(size=(400, 15, 3))
    out = joint_dropouts(pos, rate=0.02, max_span=8, rng=1, joints=[4, 5])
    lost = np.isnan(out)
    assert lost.any()
    assert (lost.all(axis=2) == lost.any(axis=2)).all()  # all three coordinates together
    assert not lost[:, [j for j in range(15) if j not in (4, 5)]].any()
    np.testing.assert_array_equal(out[~lost], pos[~lost])
    assert not np.isnan(pos).any()  # the input is not modified


def test_joint_dropout_share_follows_rate_and_span():
    pos = np.zeros((20000, 2, 3))
    rate, span = 0.01, 9
    lost = np.isnan(joint_dropouts(pos, rate=rate, max_span=span, rng=3)[..., 0]).mean()
    mean_span = (span + 1) / 2
    expected = 1 - (1 - rate) ** mean_span  # chance that some start in the last spans covers a frame
    assert abs(lost - expected) < 0.25 * expected
    assert not np.isnan(joint_dropouts(pos, rate=0.0, rng=3)).any()


def test_joint_dropouts_refuse_bad_arguments():
    with pytest.raises(DataError, match="positions"):
        joint_dropouts(np.zeros((5, 3)), 0.1)
    with pytest.raises(DataError, match="rate"):
        joint_dropouts(np.zeros((5, 15, 3)), 2.0)
    with pytest.raises(DataError, match="joints"):
        joint_dropouts(np.zeros((5, 15, 3)), 0.1, joints=[15])
