"""Consolidation of the local-linear P-GWR's neurons (`consolidate_after`): a neuron's output function
stops being rewritten by whatever it saw last and keeps the average of everything it has seen, as a
model trained on all the data at once would; old checkpoints keep the behaviour they were written with."""

from __future__ import annotations

import numpy as np
import pytest

from gwr_predictor.default_predictor import (
    LocalLinearParams,
    LocalLinearPGWR,
    LocalLinearPredictor,
)
from gwr_predictor.default_predictor.errors import DefaultPredictorError
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.params import GWRParams


def _one_region_net(consolidate_after: float) -> LocalLinearPGWR:
    """Two linked neurons, no growth: every input near the origin has neuron 0 as its BMU."""
    return LocalLinearPGWR.from_parts(
        np.array([[0.0, 0.0, 0.0], [5.0, 5.0, 0.0]]), np.zeros((2, 2, 1)), GWRParams(max_neurons=2),
        edges=[(0, 1, 0)], counters=np.ones(2), match_dim=2, distance_factor=1.0, rate=0.1, delta=1e-4,
        visits=np.zeros(2), consolidate_after=consolidate_after)


def _mse(net: LocalLinearPGWR, x: np.ndarray, y: np.ndarray) -> float:
    return float(np.mean([(net.predict_local(xi)[0] - yi[0]) ** 2 for xi, yi in zip(x, y, strict=True)]))


def _two_movements(seed: int, n: int = 600) -> tuple[np.ndarray, ...]:
    """The same regressors, two futures (level +1 or -1, same slope): an ambiguous region shared by
    two movements, where the best a model of both can do is their average."""
    rng = np.random.default_rng(seed)
    xa, xb = rng.normal(0.0, 0.1, (n, 2)), rng.normal(0.0, 0.1, (n, 2))
    return xa, 1.0 + xa[:, :1], xb, -1.0 + xb[:, :1]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_movement_learned_first_keeps_what_a_model_of_both_gives_it(seed):
    """A for 600 steps, then B for 600 in the same region: without consolidation the neuron ends as
    B's model (A's error three times what a model trained on both has); with it, each movement's
    error is within 20 % of the trained-together model's."""
    xa, ya, xb, yb = _two_movements(seed)
    order = np.random.default_rng([seed, 1]).permutation(2 * len(xa))
    xs, ys = np.vstack([xa, xb]), np.vstack([ya, yb])
    for consolidate_after in (0, 200):
        seq, together = _one_region_net(consolidate_after), _one_region_net(consolidate_after)
        for x, y in zip(xs, ys, strict=True):  # A, then B
            seq.learn_local(x, y, 0.05)
        for i in order:
            together.learn_local(xs[i], ys[i], 0.05)
        a_seq, b_seq = _mse(seq, xa, ya), _mse(seq, xb, yb)
        a_tog, b_tog = _mse(together, xa, ya), _mse(together, xb, yb)
        if consolidate_after == 0:
            assert a_seq > 2.5 * a_tog  # forgotten
        else:
            assert a_seq <= 1.2 * a_tog and b_seq <= 1.2 * b_tog
        assert seq.visits.tolist() == [1200.0, 0.0]


def test_rates_fall_as_one_over_visits_past_the_knee_and_a_new_neuron_starts_at_full_rate():
    net = _one_region_net(50)
    net._visits[:2] = [25.0, 40.0]
    net._most_visits = 40.0
    assert net._block_plasticity(np.array([0, 1])) is None  # nobody past the knee: full rates
    net._visits[1] = net._most_visits = 400.0
    np.testing.assert_allclose(net._block_plasticity(np.array([0, 1])), [1.0, 0.125])
    np.testing.assert_allclose(net._block_plasticity(np.array([1])), [0.125])
    grown = LocalLinearPredictor(LocalLinearParams(consolidate_after=5), seed=0)
    t = np.arange(400)[:, None] * 0.1
    for frame in 0.5 * np.sin(2 * np.pi * 0.4 * t + np.arange(8)[None, :]):
        grown.step(frame)
        if grown.pgwr.last_inserted >= 0:
            assert grown.pgwr.visits[grown.pgwr.last_inserted] == 0.0
    assert grown.pgwr.visits.sum() == grown.frames_seen - grown.params.order - grown.params.horizon + 1


def _trained(params: LocalLinearParams, frames: int = 300) -> tuple[LocalLinearPredictor, np.ndarray]:
    t = np.arange(frames + 200)[:, None] * 0.1
    x = 0.5 * np.sin(2 * np.pi * 0.4 * t + np.arange(8)[None, :])
    model = LocalLinearPredictor(params, seed=0)
    for f in x[:frames]:
        model.step(f)
    return model, x[frames:]


def test_a_consolidating_checkpoint_continues_bit_for_bit(tmp_path):
    model, rest = _trained(LocalLinearParams(consolidate_after=5))
    assert model.pgwr.visits.max() > 5  # consolidation is at work
    model.save(tmp_path / "m.npz")
    again = LocalLinearPredictor.load(tmp_path / "m.npz")
    for f in rest:
        np.testing.assert_array_equal(model.step(f), again.step(f))


def test_consolidation_without_visit_counts_or_with_bad_ones_is_refused():
    model, _ = _trained(LocalLinearParams(consolidate_after=50), frames=60)
    header, arrays = model.state()
    with pytest.raises(LearningError, match=r"missing arrays \['visits'\]"):
        LocalLinearPredictor.from_state(header, {k: v for k, v in arrays.items() if k != "visits"})
    with pytest.raises(LearningError, match="visit counts"):
        LocalLinearPredictor.from_state(header, {**arrays, "visits": -arrays["visits"] - 1})
    with pytest.raises(DefaultPredictorError, match=r"LocalLinearParams\.consolidate_after must be"):
        LocalLinearParams(consolidate_after=-1)


class _Unhanded(LocalLinearPGWR):
    """The GWR step recomputes the plasticity itself (what `learn_local` hands it)."""

    def _step_rates(self, block, h, prepared=None):
        return super()._step_rates(block, h, None)


def test_what_learning_hands_the_gwr_step_equals_recomputing_it_through_insertions():
    """A growing network (insertions between consolidating steps): the shortcut gives the same network."""
    rng = np.random.default_rng(0)
    t = np.arange(3000) * 0.2
    x = np.stack([np.sin(t), np.cos(0.7 * t), np.sin(1.3 * t)], axis=1) + rng.normal(0, 0.05, (3000, 3))
    y = np.roll(x, -1, axis=0)[:, :2]
    nets = []
    for cls in (LocalLinearPGWR, _Unhanded):
        net = cls(3, 2, GWRParams(activation_threshold=0.5), np.random.default_rng(1), consolidate_after=20)
        late_insertions = 0
        for xi, yi in zip(x, y, strict=True):
            net.learn_local(xi, yi, 0.05)
            late_insertions += net.last_inserted >= 0 and net.visits.max() > 20
        nets.append(net)
    a, b = nets
    assert a.n_neurons == b.n_neurons > 10 and late_insertions > 5
    np.testing.assert_allclose(a.weights, b.weights, atol=1e-9)
    np.testing.assert_allclose(a.matrices, b.matrices, atol=1e-9)
