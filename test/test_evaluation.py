"""The evaluation loop: causal feeding, correct alignment of predictions and truth, same frames."""

import numpy as np
import pytest

from gwr_predictor.evaluation.online import (
    EvaluationError,
    Predictor,
    compare_online,
    evaluate_online,
    train_online,
)
from gwr_predictor.predictors.baselines import ConstantVelocity, HoldLast


def _ramp(n=20, slope=0.1):
    return slope * np.arange(n)[:, None] * np.ones(8)[None, :]


class Recorder:
    """Holds the last pose and remembers what it was shown and whether it was asked to learn."""

    def __init__(self, horizon=3):
        self.horizon, self.seen, self.learn_flags, self.resets = horizon, [], [], 0
        self._last = None

    def step(self, x, learn=True):
        self.seen.append(None if x is None else np.array(x))
        self.learn_flags.append(learn)
        if x is not None:
            self._last = np.array(x)
        return None if self._last is None else np.tile(self._last, (self.horizon, 1))

    def reset_sequence(self):
        self.resets += 1
        self._last = None


class Cheat:
    """Reads the data it should not have: predicts data[t + 1 + k + shift] at frame t."""

    def __init__(self, data, horizon, shift=0):
        self.data, self.horizon, self.shift, self.t = data, horizon, shift, -1

    def step(self, x, learn=True):
        self.t += 1
        idx = np.clip(self.t + 1 + self.shift + np.arange(self.horizon), 0, len(self.data) - 1)
        return self.data[idx]

    def reset_sequence(self):
        self.t = -1


def test_predictors_see_exactly_one_new_frame_per_step_and_a_reset_per_sequence():
    seqs = [_ramp(6), _ramp(4) + 5.0]
    rec = Recorder()
    assert isinstance(rec, Predictor)
    evaluate_online(rec, seqs, horizon=3, passes=2, learn=False, progress=False)
    expected = [row for _ in range(2) for s in seqs for row in s]
    assert len(rec.seen) == len(expected)
    for got, want in zip(rec.seen, expected, strict=True):
        np.testing.assert_array_equal(got, want)
    assert rec.resets == 4
    assert not any(rec.learn_flags)


def test_per_horizon_mae_of_hold_on_a_ramp():
    res = evaluate_online(HoldLast(3), [_ramp(20, 0.1)], horizon=3, progress=False)
    np.testing.assert_allclose(res.stats.mae, [0.1, 0.2, 0.3])
    np.testing.assert_allclose(res.stats.std, [0.0, 0.0, 0.0], atol=1e-6)  # sqrt of a rounding residue
    np.testing.assert_array_equal(res.stats.n, [19 * 8, 18 * 8, 17 * 8])


def test_an_oracle_scores_zero_and_an_off_by_one_oracle_does_not():
    data = np.random.default_rng(1).standard_normal((30, 8))
    exact = evaluate_online(Cheat(data, 4), [data], horizon=4, progress=False)
    late = evaluate_online(Cheat(data, 4, shift=-1), [data], horizon=4, progress=False)
    np.testing.assert_allclose(exact.stats.mae, 0.0, atol=1e-12)
    assert (late.stats.mae > 0.5).all()


def test_missing_samples_are_given_as_none_and_never_scored_as_targets():
    data = _ramp(10)
    data[4] = np.nan
    rec = Recorder(horizon=2)
    res = evaluate_online(rec, [data], horizon=2, progress=False)
    assert rec.seen[4] is None
    # horizon 1: targets 1..9 minus the missing frame 4 -> 8 frames
    np.testing.assert_array_equal(res.stats.n, [8 * 8, 7 * 8])


class Late(HoldLast):
    """Returns nothing for the first `n` frames of each sequence."""

    def __init__(self, horizon, n):
        super().__init__(horizon)
        self.n, self.t = n, 0

    def step(self, x, learn=True):
        self.t += 1
        out = super().step(x, learn)
        return None if self.t <= self.n else out

    def reset_sequence(self):
        super().reset_sequence()
        self.t = 0


def test_methods_are_scored_on_the_same_frames():
    seqs = [np.sin(np.arange(40)[:, None] * 0.2 + np.arange(8)[None, :])]
    res = compare_online({"late": Late(3, 5), "cv": ConstantVelocity(3)}, seqs, horizon=3, progress=False)
    np.testing.assert_array_equal(res["late"].stats.n, res["cv"].stats.n)
    assert res["late"].scored_frames == 40 - 5
    assert res["late"].coverage == pytest.approx(35 / 40)
    assert res["cv"].coverage == 1.0


def test_trace_has_one_row_per_fed_frame():
    seqs = [_ramp(7), _ramp(5)]
    res = evaluate_online(HoldLast(2), seqs, horizon=2, passes=2, trace=True, progress=False)
    tr = res.trace
    assert tr.error.shape == (24, 2)
    np.testing.assert_array_equal(tr.pass_index, [0] * 12 + [1] * 12)
    np.testing.assert_array_equal(tr.sequence_index[:12], [0] * 7 + [1] * 5)
    np.testing.assert_allclose(tr.error[0], [0.1 * np.sqrt(8), 0.2 * np.sqrt(8)])
    assert np.isnan(tr.error[6]).all()  # the last frame of a sequence has no future
    assert len(res.pass_stats) == 2


def test_bad_inputs_raise_evaluation_errors():
    with pytest.raises(EvaluationError, match="at least"):
        evaluate_online(HoldLast(2), [_ramp(5)], horizon=3, progress=False)
    with pytest.raises(EvaluationError):
        evaluate_online(HoldLast(2), [np.zeros(5)], horizon=2, progress=False)


def test_train_online_feeds_every_frame_with_learning_on():
    rec = Recorder()
    assert train_online(rec, [_ramp(5), _ramp(3)], passes=2, progress=False) == 16
    assert all(rec.learn_flags) and rec.resets == 4
