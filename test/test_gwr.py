"""The GWR step (Eqs. 1-4, insertion/removal rules), its parameters, and the loop reference."""

import math

import numpy as np
import pytest

from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.gwr import GWR
from gwr_predictor.learning.gwr_loop import LoopGWR
from gwr_predictor.learning.params import GWRParams

P = GWRParams()


def net(weights, edges=(), counters=None, **changes):
    return GWR.from_arrays(np.array(weights, float), P.replace(**changes) if changes else P,
                           edges=edges, counters=counters)


# --- parameters ---------------------------------------------------------------------------------
def test_defaults_are_table_one():
    assert (P.activation_threshold, P.firing_threshold, P.eps_b, P.eps_n) == (0.98, 0.1, 0.1, 0.01)
    assert (P.rho_b, P.rho_n, P.kappa, P.max_edge_age, P.max_neurons) == (0.3, 0.1, 1.05, 100, None)


@pytest.mark.parametrize("field, value", [
    ("activation_threshold", 1.0), ("activation_threshold", 0.0), ("firing_threshold", 1.5),
    ("eps_b", 0.0), ("eps_n", -0.1), ("rho_b", 2.0), ("kappa", 0.9), ("max_edge_age", 0),
    ("max_edge_age", 2.5), ("max_neurons", 1), ("eps_b", float("nan")), ("eps_b", True), ("eps_b", "0.1"),
])
def test_invalid_gwr_params_name_the_field_and_range(field, value):
    with pytest.raises(ValueError, match=rf"GWRParams\.{field} must be"):
        GWRParams(**{field: value})


def test_kappa_that_keeps_counters_above_firing_threshold_is_rejected():
    # h tends to 1 - 1/kappa = 0.2 > f_T = 0.1: no neuron could ever be inserted
    with pytest.raises(ValueError, match=r"kappa=1\.25 .*could ever be inserted"):
        GWRParams(kappa=1.25)


# --- Eq. 1 --------------------------------------------------------------------------------------
def test_activity_is_exp_of_minus_distance_to_bmu():
    g = net([[0.0, 0.0], [3.0, 4.0]])
    assert g.bmu([0.3, 0.4]) == (0, pytest.approx(0.5))
    assert g.activity([0.3, 0.4]) == pytest.approx(math.exp(-0.5))
    assert g.activity([3.0, 4.0]) == pytest.approx(1.0)


def test_bmu_matches_brute_force_after_growth_and_removals():
    rng = np.random.default_rng(3)
    g = GWR(4, P.replace(max_edge_age=15, activation_threshold=0.9), rng)
    for x in rng.normal(size=(3000, 4)) + rng.integers(0, 3, (3000, 1)):
        g.learn(x)
    for q in rng.normal(size=(200, 4)):
        assert g.bmu(q)[0] == int(np.argmin(np.linalg.norm(g.weights - q, axis=1)))


# --- Eq. 2: insertion ---------------------------------------------------------------------------
def test_insertion_puts_neuron_halfway_and_replaces_edge_by_two():
    g = net([[0.0, 0.0], [1.0, 0.0]], edges=[(0, 1, 7)], counters=[0.05, 0.05])
    b = g.learn([0.0, -0.5])  # a = exp(-0.5) < a_T and h_b < f_T
    assert b == 0 and g.n_neurons == 3 and g.last_inserted == 2
    np.testing.assert_array_equal(g.weights[2], [0.0, -0.25])
    np.testing.assert_array_equal(g.weights[0], [0.0, 0.0])  # no Eq. 4 update on insertion
    assert g.edge_age(0, 1) is None
    assert g.edge_age(2, 0) == 0 and g.edge_age(2, 1) == 0
    assert g.counters[2] == 1.0


def test_no_insertion_while_bmu_counter_is_above_firing_threshold():
    g = net([[0.0, 0.0], [1.0, 0.0]], counters=[0.5, 1.0])
    g.learn([0.0, -0.5])
    assert g.n_neurons == 2 and g.last_inserted == -1


def test_no_insertion_when_activity_reaches_threshold():
    g = net([[0.0, 0.0], [1.0, 0.0]], counters=[0.0, 0.0])
    g.learn([0.0, -0.01])  # exp(-0.01) = 0.990 >= 0.98
    assert g.n_neurons == 2


def test_max_neurons_is_never_exceeded():
    rng = np.random.default_rng(0)
    g = GWR(3, P.replace(max_neurons=7), rng)
    for x in rng.uniform(-50, 50, (2000, 3)):
        g.learn(x)
        assert g.n_neurons <= 7
    assert g.n_neurons == 7


def test_a_bounded_network_is_allocated_once_at_its_bound_and_an_unbounded_one_doubles():
    rng = np.random.default_rng(0)
    bounded, unbounded = GWR(2, P.replace(max_neurons=100), rng), GWR(2, P, rng)
    storage = bounded._wa
    capacities = set()
    for x in rng.uniform(-50, 50, (3000, 2)):
        bounded.learn(x)
        unbounded.learn(x)
        capacities.add(unbounded.capacity)
        assert bounded._wa is storage  # never reallocated while learning
    assert bounded.n_neurons == bounded.capacity == 100 and bounded.evicted > 0
    assert unbounded.n_neurons > 128 and {64, 128, 256} <= capacities


# --- eviction at max_neurons ----------------------------------------------------------------------
def _blob(rng, centre, n=60):
    return rng.normal(centre, 0.05, (n, 2))


def test_at_its_bound_a_network_keeps_learning_new_regions_and_forgets_what_never_came_back():
    """A recurring region stays represented while one-off regions pass through a full network: each new
    one is learned (it evicts the neurons matched longest ago, the older one-offs'), never the recurring."""
    rng = np.random.default_rng(3)
    g = GWR(2, P.replace(max_neurons=24, activation_threshold=0.9), rng)
    home = (0.0, 0.0)
    for x in _blob(rng, home, 400):
        g.learn(x)
    for k in range(1, 30):  # a new region each time, the home region in between
        new = (10.0 * k, -10.0 * k)
        for x in _blob(rng, new):
            g.learn(x)
        assert g.n_neurons <= 24
        assert g.bmu(np.array(new))[1] < 0.5  # the new region is learned at the bound
        assert g.bmu(np.array(home))[1] < 0.2  # and the recurring one was not what made room
        for x in _blob(rng, home, 20):
            g.learn(x)
    assert g.evicted > 20
    assert g.bmu(np.array(home))[1] < 0.2  # what recurs stays
    assert g.bmu(np.array([10.0, -10.0]))[1] > 5.0  # the first one-off region, never back, is gone
    assert np.isin(np.arange(g.n_neurons), g.edge_array()[:, :2]).all()  # every neuron still has an edge


def test_eviction_never_takes_the_bmu_its_second_or_its_neighbours():
    """Every neuron but the BMU's block was matched more recently, yet the room is made outside it."""
    g = net([[0.0], [1.0], [2.0], [50.0]], edges=[(0, 1, 0), (0, 2, 0), (1, 3, 0)], counters=[0.05] * 4,
            max_neurons=4, activation_threshold=0.5)
    g._matched[:4] = [0, 0, 0, 5]  # the block [0, 1, 2] (BMU 0, its neighbours; second 1) matched longest ago
    g.clock = 5
    g.learn(np.array([-3.0]))
    assert g.evicted == 1 and g.n_neurons == 4
    kept = sorted(g.weights[:, 0].tolist())
    assert kept[0] < -1.0 and 50.0 not in kept  # the new neuron in, neuron 3 out
    assert g.last_matched.max() == g.clock == 6


def test_a_network_saved_at_its_bound_continues_bit_for_bit_evictions_included():
    rng = np.random.default_rng(5)
    g = GWR(2, P.replace(max_neurons=20, activation_threshold=0.9), rng)
    data = rng.uniform(-20, 20, (1200, 2))
    for x in data[:600]:
        g.learn(x)
    h = GWR.from_state(g.state())
    for x in data[600:]:
        assert g.learn(x) == h.learn(x)
    assert g.evicted == h.evicted > 100
    np.testing.assert_array_equal(g.weights, h.weights)
    np.testing.assert_array_equal(g.last_matched, h.last_matched)
    np.testing.assert_array_equal(g.edge_array(), h.edge_array())


@pytest.mark.parametrize("last_matched", [[-1] * 2, [0.5, 0], [0, 1, 2], [9, 0]])
def test_a_record_of_last_matches_that_does_not_fit_is_refused(last_matched):
    g = net([[0.0], [1.0]], edges=[(0, 1, 0)])
    state = {**g.state(), "last_matched": np.array(last_matched), "clock": 3}
    with pytest.raises(LearningError, match="last-matched steps"):
        GWR.from_state(state)


# --- Eq. 3: firing counters ---------------------------------------------------------------------
def test_counters_of_bmu_and_neighbours_decay_by_eq3():
    h0 = [0.8, 0.6, 0.4]
    g = net([[0.0], [1.0], [5.0]], edges=[(0, 1, 0)], counters=h0)
    g.learn([0.0])
    p = P
    assert g.counters[0] == pytest.approx(h0[0] + p.rho_b * p.kappa * (1 - h0[0]) - p.rho_b)
    assert g.counters[1] == pytest.approx(h0[1] + p.rho_n * p.kappa * (1 - h0[1]) - p.rho_n)
    assert g.counters[2] == h0[2]  # not a neighbour of the BMU


def test_counter_drops_below_firing_threshold_after_eight_firings_not_seven():
    g = net([[0.0], [100.0]])
    trace = []
    for _ in range(8):
        g.learn([0.0])  # a = 1: the BMU only trains
        trace.append(float(g.counters[0]))
    assert trace[6] == pytest.approx(0.11502, abs=1e-5) and trace[6] >= P.firing_threshold
    assert trace[7] == pytest.approx(0.09379, abs=1e-5) and trace[7] < P.firing_threshold


def test_fresh_neuron_trains_eight_times_before_it_can_insert():
    g = net([[0.0], [100.0]])
    sizes = []
    for _ in range(9):
        g.learn([5.0])  # always far: a << a_T
        sizes.append(g.n_neurons)
    assert sizes == [2] * 8 + [3]


# --- Eq. 4: weight update -----------------------------------------------------------------------
def test_bmu_and_neighbours_move_by_eps_times_counter():
    h0 = [0.5, 0.7, 0.9]
    g = net([[0.0, 0.0], [0.0, 1.0], [5.0, 5.0]], edges=[(0, 1, 3)], counters=h0)
    x = np.array([0.01, 0.0])  # a >= a_T: no insertion
    g.learn(x)
    np.testing.assert_allclose(g.weights[0], 0.0 + P.eps_b * h0[0] * (x - 0.0))
    np.testing.assert_allclose(g.weights[1], [0.0, 1.0] + P.eps_n * h0[1] * (x - [0.0, 1.0]))
    np.testing.assert_array_equal(g.weights[2], [5.0, 5.0])


# --- edges: creation, ageing, removal -----------------------------------------------------------
def test_edge_between_bmus_is_created_then_refreshed_and_bmu_edges_age():
    g = net([[0.0], [0.5], [-3.0], [9.0]], edges=[(0, 2, 4), (2, 3, 6)])
    g.learn([0.0])  # b = 0, s = 1
    assert g.edge_age(0, 1) == 0
    assert g.edge_age(0, 2) == 5  # edge of the BMU aged
    assert g.edge_age(2, 3) == 6  # not an edge of the BMU
    g.learn([0.01])
    assert g.edge_age(0, 1) == 0 and g.edge_age(0, 2) == 6


def test_old_edge_removed_and_isolated_neuron_compacted_away():
    # 0-1 is about to exceed max age; 1 has no other edge -> removed, last neuron (3) moves into slot 1
    g = net([[0.0], [5.0], [0.1], [9.0]], edges=[(0, 1, 100), (0, 2, 0), (2, 3, 0)])
    b = g.learn([0.0])
    assert b == 0 and g.n_neurons == 3
    np.testing.assert_allclose(g.weights.ravel(), [0.0, 9.0, 0.1 - P.eps_n * 0.1])  # 2 moved as a neighbour
    assert g.edge_array().tolist() == [[0, 2, 0], [1, 2, 0]]


def test_neuron_that_keeps_another_edge_survives_edge_removal():
    g = net([[0.0], [5.0], [0.1], [9.0]], edges=[(0, 1, 100), (0, 2, 0), (1, 3, 0)])
    g.learn([0.0])
    assert g.n_neurons == 4 and g.edge_age(0, 1) is None and g.edge_age(1, 3) == 0


def test_removal_that_moves_the_bmu_returns_its_new_index():
    # the BMU is the last neuron, so compacting neuron 0 away moves it to slot 0
    g = net([[5.0], [0.1], [0.0]], edges=[(2, 0, 100), (2, 1, 0)])
    b = g.learn([0.0])
    assert g.n_neurons == 2 and b == 0 and g.weights[b, 0] == pytest.approx(0.0)


# --- behaviour on known distributions -----------------------------------------------------------
@pytest.mark.parametrize("a_t", [0.9, 0.95])
def test_circle_is_covered_within_insertion_distance_by_expected_count(a_t):
    rng = np.random.default_rng(1)
    g = GWR(2, P.replace(activation_threshold=a_t, max_edge_age=50), rng)
    theta = rng.uniform(0, 2 * np.pi, 12000)
    for x in np.stack([np.cos(theta), np.sin(theta)], axis=1):
        g.learn(x)
    delta = -math.log(a_t)
    probe = np.linspace(0, 2 * np.pi, 720)
    probe = np.stack([np.cos(probe), np.sin(probe)], axis=1)
    gaps = np.linalg.norm(probe[:, None] - g.weights[None], axis=2).min(axis=1)
    assert gaps.max() < delta
    assert 0.8 * 2 * np.pi / delta < g.n_neurons < 1.5 * 2 * np.pi / delta


@pytest.mark.parametrize("a_t, low, high", [(0.7, 4, 4), (0.98, 40, 400)])
def test_clusters_get_one_prototype_each_unless_threshold_is_finer_than_them(a_t, low, high):
    rng = np.random.default_rng(2)
    centres = np.array([[0, 0], [4, 0], [0, 4], [4, 4]], float)
    g = GWR(2, P.replace(activation_threshold=a_t, max_edge_age=50), rng, init_low=-1, init_high=5)
    data = centres[rng.integers(0, 4, 4000)] + rng.uniform(-0.05, 0.05, (4000, 2))
    for x in data:
        g.learn(x)
    used = {g.bmu(x)[0] for x in data[-500:]}
    assert low <= len(used) <= high


# --- inputs, determinism, persistence -----------------------------------------------------------
@pytest.mark.parametrize("x", [[0.0], [0.0, 0.0, 0.0], [np.nan, 0.0], [np.inf, 0.0]])
def test_bad_inputs_raise_input_error(x):
    g = net([[0.0, 0.0], [1.0, 1.0]])
    with pytest.raises(LearningError):
        g.learn(x)


def test_same_seed_gives_identical_networks():
    data = np.random.default_rng(9).normal(size=(500, 3))
    nets = [GWR(3, P, np.random.default_rng(s)) for s in (4, 4, 5)]
    for x in data:
        for g in nets:
            g.learn(x)
    np.testing.assert_array_equal(nets[0].weights, nets[1].weights)
    assert not np.array_equal(nets[0].weights[:2], nets[2].weights[:2])


def test_state_round_trip_continues_identically():
    rng = np.random.default_rng(0)
    data = rng.normal(size=(600, 3))
    g = GWR(3, P.replace(max_edge_age=20), rng)
    for x in data[:300]:
        g.learn(x)
    h = GWR.from_state(g.state())
    for x in data[300:]:
        assert g.learn(x) == h.learn(x)
    np.testing.assert_array_equal(g.weights, h.weights)
    np.testing.assert_array_equal(g.edge_array(), h.edge_array())


# --- the loop reference -------------------------------------------------------------------------
@pytest.mark.parametrize("params", [
    P.replace(max_edge_age=2, activation_threshold=0.8),  # short edge life: many removals
    P.replace(max_edge_age=2, activation_threshold=0.8, rho_b=1.0, rho_n=0.9),  # rho * kappa > 1: clipping
], ids=["table1", "clipped-counters"])
def test_vectorised_gwr_matches_loop_reference_step_for_step(params):
    fast = GWR(3, params, np.random.default_rng(7))
    slow = LoopGWR(3, params, np.random.default_rng(7))
    rng = np.random.default_rng(8)
    data = rng.normal(0, 0.3, (3000, 3)) + rng.integers(0, 4, (3000, 1))
    removals = inserts = 0
    for x in data:
        before = fast.n_neurons
        assert fast.learn(x) == slow.learn(x)
        assert fast.n_neurons == slow.n_neurons
        inserts += fast.last_inserted >= 0
        removals += fast.n_neurons < before + (fast.last_inserted >= 0)
        np.testing.assert_allclose(fast.weights, slow.weights, rtol=0, atol=1e-12)
        np.testing.assert_allclose(fast.counters, slow.h, rtol=0, atol=1e-12)
    edges = sorted((i, j, a) for i, nb in enumerate(slow.nbrs) for j, a in nb.items() if i < j)
    assert fast.edge_array().tolist() == [list(e) for e in edges]
    assert inserts > 100 and removals > 10 and fast.n_neurons > 64  # growth past the first capacity
    assert ((fast.counters >= 0) & (fast.counters <= 1)).all()
