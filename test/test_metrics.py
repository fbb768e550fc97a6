"""Per-horizon statistics, trends and settling on hand-made numbers."""

import numpy as np
import pytest

from gwr_predictor.evaluation.errors import EvaluationError
from gwr_predictor.evaluation.metrics import (
    HorizonStats,
    future_windows,
    horizon_stats,
    linear_trend,
    moving_average,
    settling_frame,
)


def test_horizon_stats_on_a_hand_made_case():
    truth = np.zeros((2, 2, 2))
    pred = np.array([[[1.0, -1.0], [2.0, 0.0]],
                     [[3.0, 1.0], [np.nan, 4.0]]])
    s = horizon_stats(pred, truth)
    np.testing.assert_array_equal(s.n, [4, 3])
    np.testing.assert_allclose(s.mae, [6 / 4, 6 / 3])
    np.testing.assert_allclose(s.mse, [12 / 4, 20 / 3])
    np.testing.assert_allclose(s.std, np.sqrt([3 - 1.5**2, 20 / 3 - 4]))
    np.testing.assert_allclose(s.joint_mae, [[2.0, 1.0], [2.0, 2.0]])
    assert s.overall_mse() == pytest.approx(32 / 7)


def test_merge_equals_scoring_everything_at_once():
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal((2, 5, 3, 8))
    whole = horizon_stats(a, b)
    parts = horizon_stats(a[:2], b[:2]).merge(horizon_stats(a[2:], b[2:]))
    np.testing.assert_allclose(parts.mae, whole.mae)
    np.testing.assert_allclose(parts.std, whole.std)
    with pytest.raises(EvaluationError):
        whole.merge(HorizonStats.empty(2))


def test_empty_stats_report_nan_and_json_none():
    s = HorizonStats.empty(3)
    assert np.isnan(s.mae).all()
    assert s.to_dict()["mae"] == [None, None, None]


def test_future_windows_shift_and_pad():
    v = np.arange(4.0)[:, None]
    f = future_windows(v, 2)
    np.testing.assert_array_equal(f[:, :, 0], [[1, 2], [2, 3], [3, np.nan], [np.nan, np.nan]])


def test_moving_average_ignores_nan():
    m = moving_average(np.array([1.0, np.nan, 3.0, 5.0]), 2)
    np.testing.assert_allclose(m, [1.0, 1.0, 3.0, 4.0])


def test_linear_trend_recovers_a_line():
    x = np.arange(50.0)
    y = 2.0 - 0.03 * x
    y[7] = np.nan
    tr = linear_trend(y)
    assert tr.slope == pytest.approx(-0.03)
    assert tr.intercept == pytest.approx(2.0)
    assert tr(10.0) == pytest.approx(1.7)
    with pytest.raises(EvaluationError):
        linear_trend(np.array([1.0, np.nan]))


def test_settling_frame_finds_the_end_of_the_transient():
    err = np.concatenate([np.linspace(1.0, 0.1, 60), np.full(240, 0.1)])
    s = settling_frame(err, window=10, tolerance=0.2)
    assert 55 <= s <= 62
    assert settling_frame(1.05 ** np.arange(100.0), window=5) is None  # still diverging at the end


def test_centered_moving_average_does_not_lag():
    step = np.r_[np.zeros(10), np.ones(10)]
    assert moving_average(step, 4)[11] == pytest.approx(0.5)
    assert moving_average(step, 4, centered=True)[11] == pytest.approx(1.0)


def test_settling_against_a_repeated_reference_ignores_the_shape_of_the_movement():
    shape = 0.2 + 0.15 * np.sin(np.linspace(0, 6 * np.pi, 100))  # error rises and falls with the motion
    learning = np.concatenate([shape + np.linspace(0.5, 0.0, 100) * (np.arange(100) < 40), shape, shape])
    s = settling_frame(learning, window=5, tolerance=0.1, reference=shape)
    assert 30 <= s <= 42
    assert settling_frame(np.tile(shape, 3), window=5, reference=shape) == 0
    with pytest.raises(EvaluationError, match="tile"):
        settling_frame(learning, reference=shape[:7])
