"""Baselines: exact on the signals they model, RLS learns a known process, none learns from gaps."""

import numpy as np
import pytest

from gwr_predictor.evaluation.online import compare_online
from gwr_predictor.predictors.baselines import (
    ConstantVelocity,
    HoldLast,
    RLSAutoregressive,
    RLSParams,
    make_baselines,
)
from gwr_predictor.predictors.errors import PredictorError


def _ramp(n=30, joints=8):
    return 0.3 + 0.05 * np.arange(n)[:, None] * np.linspace(-1, 1, joints)[None, :]


def test_hold_last_repeats_the_last_observed_pose_through_gaps():
    hold = HoldLast(horizon=4)
    assert hold.step(None) is None
    x = np.arange(8.0)
    assert np.array_equal(hold.step(x), np.tile(x, (4, 1)))
    assert np.array_equal(hold.step(None), np.tile(x, (4, 1)))
    assert np.array_equal(hold.step(np.full(8, np.nan)), np.tile(x, (4, 1)))
    hold.reset_sequence()
    assert hold.step(None) is None


def test_constant_velocity_is_exact_on_a_ramp_even_across_a_gap():
    ramp = _ramp()
    cv = ConstantVelocity(horizon=5)
    for t in range(10):
        pred = cv.step(ramp[t])
    np.testing.assert_allclose(pred, ramp[10:15], atol=1e-12)
    cv.step(None)  # frame 10 missing
    cv.step(None)  # frame 11 missing
    np.testing.assert_allclose(cv.step(None), ramp[13:18], atol=1e-12)
    np.testing.assert_allclose(cv.step(ramp[13]), ramp[14:19], atol=1e-12)


def test_a_longer_velocity_window_is_still_exact_on_a_ramp_and_averages_noise():
    ramp = _ramp()
    cv = ConstantVelocity(horizon=3, window=5)
    for t in range(8):
        pred = cv.step(None if t == 5 else ramp[t])
    np.testing.assert_allclose(pred, ramp[8:11], atol=1e-12)
    rng = np.random.default_rng(0)
    noisy = ramp + 0.02 * rng.standard_normal(ramp.shape)
    errs = {}
    for w in (2, 6):
        cv = ConstantVelocity(horizon=6, window=w)
        errs[w] = np.mean([np.abs(cv.step(noisy[t])[-1] - ramp[t + 6]).mean() for t in range(len(ramp) - 6)][6:])
    assert errs[6] < 0.5 * errs[2]


def test_constant_velocity_holds_after_a_single_frame():
    cv = ConstantVelocity(horizon=3)
    x = np.ones(8)
    np.testing.assert_array_equal(cv.step(x), np.tile(x, (3, 1)))


def test_rls_recovers_a_known_vector_ar2_process():
    rng = np.random.default_rng(3)
    joints, n = 3, 4000
    a1 = 0.6 * np.eye(joints) + 0.1 * rng.standard_normal((joints, joints))
    a2 = -0.3 * np.eye(joints)
    c = np.array([0.1, -0.2, 0.05])
    x = np.zeros((n, joints))
    for t in range(2, n):
        x[t] = a1 @ x[t - 1] + a2 @ x[t - 2] + c + 0.05 * rng.standard_normal(joints)
    rls = RLSAutoregressive(RLSParams(order=2, forgetting=1.0, delta=100.0), horizon=1, joints=joints)
    for t in range(n):
        rls.step(x[t])
    w = rls.weights_
    np.testing.assert_allclose(w[:joints].T, a1, atol=0.05)
    np.testing.assert_allclose(w[joints:2 * joints].T, a2, atol=0.05)
    np.testing.assert_allclose(w[-1], c, atol=0.02)
    assert rls.updates_ == n - 2  # the first regressor is padded, so learning starts at frame 2


def test_rls_predicts_a_sinusoid_far_better_than_hold():
    t = np.arange(400) * 0.1
    seqs = [np.stack([np.sin(2 * np.pi * 0.4 * t + j + i) for j in range(8)], axis=1) for i in range(3)]
    res = compare_online(make_baselines(horizon=6, order=5), seqs, passes=2, progress=False)
    assert res["rls_ar"].pass_stats[1].mae[5] < 0.1 * res["hold"].pass_stats[1].mae[5]


def test_rls_never_learns_from_missing_samples_or_when_frozen():
    rls = RLSAutoregressive(RLSParams(order=3), horizon=2)
    x = _ramp(20)
    for t in range(10):
        rls.step(x[t])
    updates = rls.updates_
    assert updates == 10 - 3
    w = rls.weights_.copy()
    rls.step(None)  # imputed, not learned
    for t in range(11, 14):  # regressor still holds the imputed frame: no learning yet
        rls.step(x[t])
    assert rls.updates_ == updates
    rls.step(x[14])
    assert rls.updates_ == updates + 1
    w = rls.weights_.copy()
    for t in range(15, 20):
        rls.step(x[t], learn=False)
    np.testing.assert_array_equal(rls.weights_, w)


def test_rls_guard_keeps_p_bounded_on_constant_input():
    rls = RLSAutoregressive(RLSParams(order=2, forgetting=0.95, max_trace=1e4), horizon=3)
    x = np.full(8, 0.2)
    for _ in range(2000):
        pred = rls.step(x)
    assert np.trace(rls.p_) <= 1e4
    assert rls.resets_ > 0
    np.testing.assert_allclose(pred, np.tile(x, (3, 1)), atol=1e-6)


@pytest.mark.parametrize("kwargs", [{"order": 0}, {"forgetting": 1.5}, {"delta": 0.0}, {"prior": "mean"}])
def test_rls_params_are_validated(kwargs):
    with pytest.raises(PredictorError):
        RLSParams(**kwargs)


def test_wrong_sample_shape_is_rejected():
    with pytest.raises(PredictorError, match="shape"):
        HoldLast().step(np.zeros(5))
    with pytest.raises(PredictorError):
        ConstantVelocity(horizon=0)
    with pytest.raises(PredictorError, match="window"):
        ConstantVelocity(window=1)


def test_rls_state_round_trip_continues_bit_for_bit():
    rng = np.random.default_rng(3)
    frames = np.sin(np.arange(120)[:, None] * np.array([0.1, 0.23, 0.31])) + 0.01 * rng.standard_normal((120, 3))
    frames[40] = np.nan
    a = RLSAutoregressive(RLSParams(order=3, forgetting=0.995), horizon=4, joints=3)
    for x in frames[:60]:
        a.step(x)
    header, arrays = a.state()
    b = RLSAutoregressive.from_state(header, arrays)
    for x in frames[60:]:
        np.testing.assert_array_equal(a.step(x), b.step(x))
    assert (a.updates_, a.resets_) == (b.updates_, b.resets_)
    with pytest.raises(PredictorError, match="'p'"):
        RLSAutoregressive.from_state(header, {**arrays, "p": np.eye(2)})
