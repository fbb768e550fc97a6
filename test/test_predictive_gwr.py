"""Predictive GWR (Eqs. 8-10): matching on the regressor, dual update, prediction, multi-step."""

import numpy as np
import pytest

from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.params import GWRParams
from gwr_predictor.learning.predictive_gwr import PredictiveGWR

P = GWRParams()


def pnet(w_in, w_out, counters=None, edges=()):
    weights = np.concatenate([np.array(w_in, float), np.array(w_out, float)], axis=1)
    return PredictiveGWR.from_arrays(weights, P, match_dim=len(w_in[0]), counters=counters, edges=edges)


def test_bmu_is_chosen_on_the_regressor_only():
    g = pnet([[0.0, 0.0], [1.0, 1.0]], [[100.0], [-100.0]])
    b = g.learn([0.05, 0.0], [-100.0])  # x_out equals neuron 1's output, x_in is nearest neuron 0
    assert b == 0


def test_input_and_output_weights_both_move_by_eq9():
    g = pnet([[0.0, 0.0], [1.0, 1.0]], [[2.0], [5.0]], counters=[0.5, 1.0])
    g.learn([0.01, 0.0], [4.0])  # a >= a_T: update, no insertion
    rate = P.eps_b * 0.5
    np.testing.assert_allclose(g.weights_in[0], [rate * 0.01, 0.0])
    np.testing.assert_allclose(g.weights_out[0], [2.0 + rate * (4.0 - 2.0)])


def test_insertion_halves_both_parts():
    g = pnet([[0.0, 0.0], [1.0, 1.0]], [[2.0], [5.0]], counters=[0.05, 0.05])
    g.learn([0.0, -0.5], [4.0])
    assert g.n_neurons == 3
    np.testing.assert_array_equal(g.weights_in[2], [0.0, -0.25])
    np.testing.assert_array_equal(g.weights_out[2], [3.0])


def test_prediction_is_output_weight_of_regressor_bmu():
    g = pnet([[0.0, 0.0], [1.0, 1.0]], [[2.0, 3.0], [5.0, 6.0]])
    np.testing.assert_array_equal(g.predict([0.9, 0.8]), [5.0, 6.0])
    np.testing.assert_array_equal(g.predict([0.1, -0.2]), [2.0, 3.0])
    with pytest.raises(LearningError):
        g.predict([0.0, 0.0, 0.0])


def _trajectory(n: int) -> np.ndarray:
    """8 joints on one smooth periodic movement (period 25 frames), radians."""
    t = np.arange(n)[:, None]
    phase = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    amp = np.linspace(0.3, 1.0, 8)
    return amp * np.sin(2 * np.pi * t / 25 + phase) + 0.3 * amp * np.sin(4 * np.pi * t / 25 + 2 * phase)


def _regressor(frames: np.ndarray, t: int, p: int) -> np.ndarray:
    return frames[t - p + 1:t + 1][::-1].ravel()  # newest first


@pytest.mark.parametrize("mode", ["recursive", "vector"])
def test_learns_periodic_trajectory_online_and_predicts_six_ahead(mode):
    p, h, scale = 3, 6, 0.5
    frames = _trajectory(1300) * scale
    out_dim = 8 * (h if mode == "vector" else 1)
    g = PredictiveGWR(8 * p, out_dim, P, np.random.default_rng(0), init_low=-scale, init_high=scale)
    for t in range(p - 1, 1000):  # online: each pair is learned once its target has been seen
        target = frames[t + 1:t + 1 + (h if mode == "vector" else 1)].ravel()
        g.learn(_regressor(frames, t, p), target)
    errors, hold = [], []
    for t in range(1000, 1290):
        if mode == "vector":
            pred = g.predict(_regressor(frames, t, p)).reshape(h, 8)
        else:
            window = list(frames[t - p + 1:t + 1])
            pred = []
            for _ in range(h):  # feed each prediction back into the regressor
                y = g.predict(np.concatenate(window[::-1]))
                pred.append(y)
                window = window[1:] + [y]
        errors.append(np.mean((np.array(pred)[-1] - frames[t + h]) ** 2))
        hold.append(np.mean((frames[t] - frames[t + h]) ** 2))
    assert np.mean(errors) < 0.02 * np.mean(hold)


def test_blended_output_weights_the_k_nearest_by_inverse_distance():
    g = pnet([[0.0, 0.0], [1.0, 0.0], [5.0, 0.0]], [[2.0], [8.0], [100.0]])
    np.testing.assert_array_equal(g.blended_output(np.array([0.25, 0.0]), 1), [2.0])  # k = 1: Eq. 10
    # distances 0.25 and 0.75: weights 4 and 4/3, i.e. 3/4 and 1/4
    np.testing.assert_allclose(g.blended_output(np.array([0.25, 0.0]), 2, record=True), [0.75 * 2 + 0.25 * 8])
    assert g.last_distance == pytest.approx(0.25)
    np.testing.assert_array_equal(g.blended_output(np.array([1.0, 0.0]), 3), [8.0])  # exact hit takes all
    k_capped_at_n = (2 * 2 + 2 * 8 + 100 / 4.5) / (4 + 1 / 4.5)
    assert g.blended_output(np.array([0.5, 0.0]), 10) == pytest.approx(k_capped_at_n)
