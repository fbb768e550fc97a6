"""Recruitment in the local-linear P-GWR (`recruit_surprise`): a consolidated neuron that a pair
surprises hands the pair to a new neuron instead of learning it, so a new movement through the poses
of an old one gets neurons of its own and the old one is not overwritten."""

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


def _net(recruit_surprise: float, consolidate_after: float = 200, max_neurons: int | None = None,
         recruit_after: int = 1) -> LocalLinearPGWR:
    """Two linked neurons far apart; GWR's own insertion never fires (a_T so low no distance reaches
    it), so any growth is recruitment."""
    return LocalLinearPGWR.from_parts(
        np.array([[0.0, 0.0, 0.0], [5.0, 5.0, 0.0]]), np.zeros((2, 2, 1)),
        GWRParams(activation_threshold=1e-9, max_neurons=max_neurons), edges=[(0, 1, 0)], counters=np.ones(2),
        match_dim=2, distance_factor=1.0, rate=0.1, delta=1e-4, visits=np.zeros(2),
        consolidate_after=consolidate_after, readout_mse=np.full(2, np.nan), recruit_surprise=recruit_surprise,
        recruit_after=recruit_after)


def _movement(seed: int, centre: float, level: float, n: int = 600) -> tuple[np.ndarray, np.ndarray]:
    x = np.random.default_rng(seed).normal(centre, 0.05, (n, 2))
    return x, level + x[:, :1]


def _mse(net: LocalLinearPGWR, x: np.ndarray, y: np.ndarray) -> float:
    return float(np.mean([(net.predict_local(xi)[0] - yi[0]) ** 2 for xi, yi in zip(x, y, strict=True)]))


def _learn(net: LocalLinearPGWR, x: np.ndarray, y: np.ndarray) -> list[int]:
    """Learn the pairs; the steps at which a neuron was recruited."""
    steps = []
    for i, (xi, yi) in enumerate(zip(x, y, strict=True)):
        before = net.recruited
        net.learn_local(xi, yi, 0.05)
        if net.recruited > before:
            steps.append(i)
    return steps


@pytest.mark.parametrize("recruit_after", [1, 2])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_new_movement_through_an_old_ones_poses_gets_neurons_of_its_own(seed, recruit_after):
    """A (level +1 around the origin) for 600 steps, then B (level -1, 0.3 rad away on each axis): the
    one neuron of the region has consolidated on A. Without recruitment it ends as a compromise, A's
    error over 4x what it was; with it, B gets a neuron of its own, A's error is what it was right
    after A, to the bit, and B's is near 0 (at the first surprise or the second in a row)."""
    xa, ya = _movement(seed, 0.0, 1.0)
    xb, yb = _movement(seed + 100, 0.3, -1.0)
    for surprise in (0.0, 6.0):
        net = _net(surprise, recruit_after=recruit_after)
        assert _learn(net, xa, ya) == []  # one movement: nothing surprises its own neuron
        a_learned = _mse(net, xa, ya)
        _learn(net, xb, yb)
        a_after, b_after = _mse(net, xa, ya), _mse(net, xb, yb)
        if surprise == 0:
            assert net.recruited == 0 and net.n_neurons == 2
            assert a_after > 4 * a_learned
        else:
            assert 1 <= net.recruited == net.n_neurons - 2 <= 5  # a neuron for B, not one per pair
            assert a_after == a_learned
            assert b_after < 0.01


def test_a_recruited_neuron_sits_at_its_pair_with_its_parents_matrix_and_an_edge_to_it():
    xa, ya = _movement(0, 0.0, 1.0)
    net = _net(6.0)
    _learn(net, xa, ya)
    a_before, wo_before, w_before = net.matrices[0].copy(), net.weights_out[0].copy(), net.weights_in[0].copy()
    visits_before = net.visits[0]
    x, y = np.array([0.21, 0.19]), np.array([-0.8])
    assert net.learn_local(x, y, 0.05) == 0
    assert net.recruited == 1 and net.n_neurons == 3 and net.last_inserted == 2
    np.testing.assert_array_equal(net.weights_in[2], x)
    np.testing.assert_array_equal(net.weights_out[2], y)
    np.testing.assert_array_equal(net.matrices[2], a_before)
    assert net.edge_age(0, 2) == 0 and net.visits[2] == 0.0 and np.isnan(net.readout_mse[2])
    np.testing.assert_allclose(net.predict_local(x), y)  # it predicts its pair exactly
    # the surprised neuron learned nothing from the pair
    np.testing.assert_array_equal(net.matrices[0], a_before)
    np.testing.assert_array_equal(net.weights_out[0], wo_before)
    np.testing.assert_array_equal(net.weights_in[0], w_before)
    assert net.visits[0] == visits_before


@pytest.mark.parametrize("again", ["learn_local", "learn"])
def test_the_pair_learned_again_right_after_its_recruitment_finds_its_new_neuron(again):
    """Recruiting changes the network after the step's search, which is kept for the GWR step to
    reuse on the same query: it must not outlive the change (plain `learn` would reuse it)."""
    xa, ya = _movement(0, 0.0, 1.0)
    net = _net(6.0)
    _learn(net, xa, ya)
    net._search.kept_buf[:] = -1e9  # what an earlier, larger search could have left there
    x, y = np.array([0.21, 0.19]), np.array([-0.8])
    assert net.learn_local(x, y, 0.05) == 0 and net.recruited == 1
    b = net.learn_local(x, y, 0.05) if again == "learn_local" else net.learn(x, y)
    assert b == 2  # the recruited neuron, at distance 0


def test_one_odd_pair_is_ignored_and_only_a_second_in_a_row_recruits():
    """recruit_after 2: the first surprising pair moves nothing and does not count in the neuron's
    error; an ordinary pair in between resets the streak; two surprising pairs in a row recruit."""
    xa, ya = _movement(0, 0.0, 1.0)
    net = _net(6.0, recruit_after=2)
    _learn(net, xa, ya)
    odd_x, odd_y = np.array([0.02, -0.01]), np.array([-1.0])

    def frozen() -> tuple[np.ndarray, ...]:  # the surprised BMU's (its unconsolidated neighbour still learns)
        return net.weights[0].copy(), net.matrices[0].copy(), net.readout_mse[:1].copy()

    before = frozen()
    net.learn_local(odd_x, odd_y, 0.05)
    assert net.recruited == 0 and net.surprise_streaks[0] == 1
    for was, now in zip(before, frozen(), strict=True):
        np.testing.assert_array_equal(was, now)
    net.learn_local(xa[0], ya[0], 0.05)  # an ordinary pair: learned, and the streak starts over
    assert net.surprise_streaks[0] == 0 and net.recruited == 0
    net.learn_local(odd_x, odd_y, 0.05)
    assert net.recruited == 0 and net.surprise_streaks[0] == 1
    net.learn_local(odd_x + 0.01, odd_y, 0.05)
    assert net.recruited == 1 and net.surprise_streaks[0] == 0
    np.testing.assert_array_equal(net.weights_in[2], odd_x + 0.01)


def test_neurons_that_have_not_consolidated_learn_exactly_as_without_recruitment():
    """Consolidation after 2,000 visits: nobody consolidates in 1,200 steps, so nobody recruits and the
    network is the one learned without recruitment, weight for weight."""
    xa, ya = _movement(0, 0.0, 1.0)
    xb, yb = _movement(1, 0.2, -1.0)
    nets = [_net(s, consolidate_after=2000) for s in (0.0, 6.0)]
    for net in nets:
        _learn(net, np.vstack([xa, xb]), np.vstack([ya, yb]))
    plain, recruiting = nets
    assert recruiting.recruited == 0
    np.testing.assert_array_equal(plain.weights, recruiting.weights)
    np.testing.assert_array_equal(plain.matrices, recruiting.matrices)
    assert np.isfinite(recruiting.readout_mse[0]) and recruiting.readout_mse[0] > 0  # tracked all along


def test_at_max_neurons_a_recruit_takes_the_place_of_the_neuron_matched_longest_ago():
    """Full (3 neurons): B's recruit evicts the neuron that never matched (not A's, nor its neighbour), and
    B is learned as below the bound while A's read-out stays as it was."""
    xa, ya = _movement(0, 0.0, 1.0)
    xb, yb = _movement(1, 0.3, -1.0)
    net = LocalLinearPGWR.from_parts(
        np.array([[0.0, 0.0, 0.0], [5.0, 5.0, 0.0], [-9.0, -9.0, 0.0]]), np.zeros((3, 2, 1)),
        GWRParams(activation_threshold=1e-9, max_neurons=3), edges=[(0, 1, 0)], counters=np.ones(3),
        match_dim=2, distance_factor=1.0, rate=0.1, delta=1e-4, visits=np.zeros(3), consolidate_after=200,
        readout_mse=np.full(3, np.nan), recruit_surprise=6.0)
    _learn(net, xa, ya)
    a_learned = _mse(net, xa, ya)
    _learn(net, xb, yb)
    assert net.recruited >= 1 and net.evicted == net.recruited and net.n_neurons == 3
    assert np.abs(net.weights_in - [-9.0, -9.0]).sum(axis=1).min() > 1.0  # the neuron that never matched is gone
    assert _mse(net, xa, ya) == a_learned and _mse(net, xb, yb) < 0.01


def _switching(frames: int) -> np.ndarray:
    """One movement for half the frames, then another through the same poses at another speed."""
    t = np.arange(frames)[:, None] * 0.1
    phase = np.arange(8)[None, :]
    x = 0.5 * np.sin(2 * np.pi * 0.4 * t + phase)
    x[frames // 2:] = 0.5 * np.sin(2 * np.pi * 0.9 * t[frames // 2:] + phase)
    return x


def _trained(params: LocalLinearParams, frames: int = 1200) -> tuple[LocalLinearPredictor, np.ndarray]:
    x = _switching(frames + 200)
    model = LocalLinearPredictor(params, seed=0)
    for f in x[:frames]:
        model.step(f)
    return model, x[frames:]


RECRUITING = LocalLinearParams(consolidate_after=5, recruit_surprise=2.0)


def test_a_recruiting_checkpoint_continues_bit_for_bit(tmp_path):
    model, rest = _trained(RECRUITING)
    assert model.pgwr.recruited > 0 and model.errors()["recruited"] == model.pgwr.recruited
    model.save(tmp_path / "m.npz")
    again = LocalLinearPredictor.load(tmp_path / "m.npz")
    assert again.pgwr.recruited == model.pgwr.recruited
    for f in rest:
        np.testing.assert_array_equal(model.step(f), again.step(f))
    assert again.pgwr.recruited == model.pgwr.recruited


def test_recruitment_without_its_errors_or_with_bad_ones_is_refused():
    model, _ = _trained(RECRUITING, frames=100)
    header, arrays = model.state()
    with pytest.raises(LearningError, match=r"missing arrays \['readout_mse'\]"):
        LocalLinearPredictor.from_state(header, {k: v for k, v in arrays.items() if k != "readout_mse"})
    with pytest.raises(LearningError, match="read-out errors"):
        LocalLinearPredictor.from_state(header, {**arrays, "readout_mse": np.full_like(arrays["readout_mse"], -1.0)})
    with pytest.raises(LearningError, match="surprise streaks"):
        LocalLinearPredictor.from_state(header, {**arrays, "surprise_streaks": arrays["surprise_streaks"][:-1]})
    with pytest.raises(DefaultPredictorError, match=r"LocalLinearParams\.recruit_surprise must be"):
        LocalLinearParams(recruit_surprise=-1.0)
    with pytest.raises(DefaultPredictorError, match=r"LocalLinearParams\.recruit_after must be"):
        LocalLinearParams(recruit_after=0)
