"""The direct linear predictor and the recursive least squares under it (and under the default's
global read-out): exact fits, no peeking, gaps, padding, checkpoints."""

from __future__ import annotations

import numpy as np
import pytest
from fakes import damped_oscillation

from gwr_predictor.evaluation.online import compare_online, train_online
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.rls import RecursiveLeastSquares, window_features
from gwr_predictor.predictors.baselines import HoldLast
from gwr_predictor.predictors.direct_linear import DirectLinear, DirectLinearParams
from gwr_predictor.predictors.errors import PredictorError
from gwr_predictor.registry import make_predictor


def _damped(n: int = 400, seed: int = 0) -> np.ndarray:
    return damped_oscillation(n, seed, damping=0.99, stiffness=0.02, noise=0.002)


def test_rls_is_the_ridge_least_squares_fit():
    rng = np.random.default_rng(1)
    phi = rng.normal(size=(200, 5))
    y = phi @ rng.normal(size=(5, 3)) + rng.normal(scale=0.1, size=(200, 3))
    rls = RecursiveLeastSquares(5, 3, delta=10.0)
    for f, t in zip(phi, y, strict=True):
        rls.update(f, t)
    ridge = np.linalg.solve(phi.T @ phi + np.eye(5) / 10.0, phi.T @ y)
    np.testing.assert_allclose(rls.weights, ridge, atol=1e-9)
    np.testing.assert_allclose(rls.predict(phi[0]), phi[0] @ ridge, atol=1e-9)


def test_rls_with_forgetting_does_not_wind_up_on_data_that_excite_one_direction():
    rls = RecursiveLeastSquares(3, 1, forgetting=0.95, max_trace=1e3)
    for _ in range(500):
        rls.update(np.array([1.0, 0.0, 0.0]), np.array([2.0]))
    assert rls.resets > 0 and np.trace(rls.p) <= 1e3
    assert rls.predict(np.array([1.0, 0.0, 0.0]))[0] == pytest.approx(2.0, abs=1e-3)


def test_window_features_are_the_latest_changes_the_pose_and_a_bias():
    win = np.array([[3.0, 1.0], [2.0, 1.5], [0.0, 0.0]])  # newest first
    np.testing.assert_array_equal(window_features(win, 2), [1.0, -0.5, 3.0, 1.0, 1.0])
    np.testing.assert_array_equal(window_features(win, 1), [3.0, 1.0, 1.0])


def test_learns_a_linear_system_down_to_its_noise():
    """With a weak prior (large delta), the fit on 500 frames predicts the next 200 at the noise floor
    of the system (the driving noise accumulated over 6 steps)."""
    x = _damped(800)
    floor = 0.002 ** 2 * sum(sum(0.99 ** i for i in range(j)) ** 2 for j in range(1, 7))
    model = DirectLinear(DirectLinearParams(order=2, delta=1e4))
    train_online(model, [x[:500]], progress=False)
    res = compare_online({"hold": HoldLast(), "linear": model}, [x[500:]], learn=False, progress=False)
    assert res["linear"].stats.mse[-1] < 1.5 * floor < 0.1 * res["hold"].stats.mse[-1]


def test_predicts_from_the_first_frame_and_never_learns_padded_features():
    model = DirectLinear(DirectLinearParams(order=4))
    x = _damped(50)
    first = model.step(x[0])
    np.testing.assert_array_equal(first, np.repeat(x[:1], 6, axis=0))  # a fresh model: hold-last
    for f in x[1:]:
        model.step(f)
    # pairs are learned from frame order - 1 + horizon on: 50 - (4 - 1) - 6 = 41 updates
    assert model.rls.updates == 50 - 3 - 6


def test_no_peeking_and_gaps_clear_the_window():
    x = _damped(200)
    y = x.copy()
    y[120:] += 1.0
    a, b = DirectLinear(DirectLinearParams(order=2)), DirectLinear(DirectLinearParams(order=2))
    for t in range(120):
        pa, pb = a.step(x[t]), b.step(y[t])
    np.testing.assert_array_equal(pa, pb)
    assert a.step(None) is None
    updates = a.rls.updates
    for f in x[121:127]:  # after a gap: a fresh window, no pair spans the gap
        a.step(f)
    assert a.rls.updates == updates


def test_checkpoint_continues_bit_for_bit(tmp_path):
    x = _damped(300)
    a = DirectLinear(DirectLinearParams(order=3, forgetting=0.99))
    for f in x[:150]:
        a.step(f)
    a.save(tmp_path / "linear.npz")
    b = DirectLinear.load(tmp_path / "linear.npz")
    for f in x[150:]:
        np.testing.assert_array_equal(a.step(f), b.step(f))
    header, arrays = a.state()
    arrays["p"] = np.eye(2)
    with pytest.raises(LearningError, match="'p' has shape"):
        DirectLinear.from_state(header, arrays, "saved.npz")


def test_params_are_validated_with_the_field():
    with pytest.raises(PredictorError, match="order"):
        DirectLinearParams(order=0)
    with pytest.raises(PredictorError, match="forgetting"):
        DirectLinearParams(forgetting=0.5)


def test_registered_as_a_baseline():
    model = make_predictor("linear")
    assert isinstance(model, DirectLinear) and model.step(np.zeros(8)).shape == (6, 8)
