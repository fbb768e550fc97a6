"""PendingPredictions: a prediction's row k is handed back exactly once, at step t + k + 1."""

from __future__ import annotations

import numpy as np

from gwr_predictor.evaluation.metrics import future_windows
from gwr_predictor.learning.pending import PendingPredictions, target_steps


def test_rows_come_back_at_the_step_they_target_and_only_once():
    h, j = 3, 2
    ring = PendingPredictions(h, j)
    preds = {t: np.arange(h * j, dtype=float).reshape(h, j) + 100 * t for t in range(6)}
    seen: dict[int, list[tuple[int, int]]] = {}
    for t in range(9):
        got, valid = ring.take(t)
        seen[t] = [(t - 1 - k, k) for k in range(h) if valid[k]]
        for k in np.flatnonzero(valid):
            np.testing.assert_array_equal(got[k], preds[t - 1 - k][k])
        if t in preds:
            ring.file(t, preds[t])
    assert seen[0] == [] and seen[1] == [(0, 0)] and seen[3] == [(2, 0), (1, 1), (0, 2)]
    assert seen[7] == [(5, 1), (4, 2)] and seen[8] == [(5, 2)]  # nothing filed after step 5
    assert not ring.take(8)[1].any()  # taken once


def test_drop_forgets_and_lead_dimensions_and_valid_masks_are_kept_apart():
    ring = PendingPredictions(2, 1, lead=(2,))
    ring.file(0, np.ones((2, 2, 1)), valid=np.array([[True, True], [False, True]]))
    _, valid = ring.take(1)
    np.testing.assert_array_equal(valid, [[True, False], [False, False]])
    ring.drop()
    assert not ring.take(2)[1].any()


def test_after_the_fact_windows_follow_the_same_rule():
    values = np.arange(10.0).reshape(5, 2)
    windows = future_windows(values, 3)
    steps = target_steps(np.arange(5), 3)
    for t in range(5):
        for k in range(3):
            expected = values[steps[t, k]] if steps[t, k] < 5 else np.full(2, np.nan)
            np.testing.assert_array_equal(windows[t, k], expected)
