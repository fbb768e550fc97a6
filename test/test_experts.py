"""The default's parts of its own: the snippet memory and the per-step weighting of the experts."""

from __future__ import annotations

import numpy as np
import pytest

from gwr_predictor.default_predictor import (
    DefaultPredictor,
    Experts,
    ExpertsParams,
    MemoryParams,
    TrajectoryMemory,
    make_default,
)
from gwr_predictor.default_predictor.errors import DefaultPredictorError
from gwr_predictor.default_predictor.memory import EXACT
from gwr_predictor.default_predictor.recognition import RecognitionSwitch
from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.evaluation.online import compare_online
from gwr_predictor.learning.params import MAX_HORIZON
from gwr_predictor.predictors.baselines import HoldLast
from gwr_predictor.registry import entry


def _movement(speed: float, n: int = 40) -> np.ndarray:
    """One smooth out-and-back movement of every joint, `speed` times as fast as at 1.0."""
    t = np.arange(n) * 0.1 * speed
    phase = np.clip(t / 3.0, 0.0, 1.0)
    return 0.2 + 0.6 * np.sin(np.pi * phase)[:, None] * np.linspace(0.5, 1.0, 8)[None, :]


def _mae_600(model, x: np.ndarray) -> float:
    """MAE at the last step over the frames where the model predicted."""
    errs = []
    for t, f in enumerate(x):
        out = model.step(f, learn=False)
        if out is not None and t + 6 < len(x):
            errs.append(np.abs(out[-1] - x[t + 6]).mean())
    return float(np.mean(errs))


def test_the_memory_anticipates_a_movement_it_has_seen_once():
    memory = TrajectoryMemory()
    first = _movement(1.0)
    for f in first:
        memory.step(f)
    assert memory.size > 10
    memory.reset_sequence()
    again = _movement(1.0) + np.random.default_rng(0).normal(scale=0.002, size=first.shape)  # never to the bit
    hold = float(np.mean(np.abs(again[:-6] - again[6:]).mean(axis=1)[4:]))
    assert _mae_600(memory, again) < 0.3 * hold  # measured 0.24 x


def test_a_replayed_recording_is_not_recalled_from_its_own_copy():
    """Training epochs replay recordings bit for bit: recalling a snippet's exact copy would score the
    memory as perfect there and give it the experts' weight on new performances; a copy is skipped."""
    memory = TrajectoryMemory()
    x = _movement(1.0) + np.random.default_rng(1).normal(scale=0.01, size=(40, 8))
    for f in x:
        memory.step(f)
    memory.reset_sequence()
    copied = []
    lag = memory.params.longest_lag
    for t, f in enumerate(x[:-6]):
        out = memory.step(f, learn=False)
        query = memory._query(memory._key(x[t - lag:t + 1])) if t >= lag else None
        if out is not None and query is not None and memory._distances(query).min() <= EXACT:
            copied.append(np.abs(out[-1] - x[t + 6]).max())
    assert len(copied) > 5
    assert np.median(copied) > 1e-3  # recalled from the copy: below 1e-5


def test_the_memory_reads_a_faster_performance_at_its_own_speed():
    """A performance 1.25 x as fast: reading the stored snippets at the estimated speed ratio beats
    reading them at the stored speed (the ratio fixed at 1)."""
    tuned, fixed = TrajectoryMemory(), TrajectoryMemory(MemoryParams(min_ratio=1.0, max_ratio=1.0))
    for model in (tuned, fixed):
        for f in _movement(1.0):
            model.step(f)
        model.reset_sequence()
    faster = _movement(1.25)
    assert _mae_600(tuned, faster) < 0.9 * _mae_600(fixed, faster)  # measured 0.81 x


def test_the_memory_grows_only_when_required_and_keeps_what_it_stored():
    memory = TrajectoryMemory(MemoryParams(capacity=500))
    for _ in range(3):
        for f in _movement(1.0):
            memory.step(f)
        memory.reset_sequence()
    once = TrajectoryMemory()
    for f in _movement(1.0):
        once.step(f)
    assert memory.size < 1.5 * once.size  # the same movement again adds (almost) nothing
    stored = memory.size
    assert memory.step(None) is None and memory.size == stored  # a gap ends the snippet, not the memory
    small = TrajectoryMemory(MemoryParams(capacity=5, k=3))
    for f in np.cumsum(np.random.default_rng(0).normal(scale=0.05, size=(200, 8)), axis=0):
        small.step(f)
    assert small.size == 5


def test_a_person_holding_a_pose_stops_adding_snippets_but_a_movement_from_it_is_stored():
    """The tracker's noise keeps the keys of one held pose apart (their changes are noise): every few frames
    one of them was new. With `still_radius` a still snippet is stored only where no still one holds a pose
    that near; the onset of a movement from the pose (a still key, a moving future) is no still snippet."""
    rng = np.random.default_rng(4)
    pose = np.array([1.4, 0.15, -1.2, -0.4, 1.4, -0.15, 1.2, 0.4])
    held = pose + rng.normal(0.0, 0.01, (3000, 8))
    sizes = {}
    for radius in (0.0, 2.0):
        memory = TrajectoryMemory(MemoryParams(still_radius=radius))
        for f in held[:1500]:
            memory.step(f)
        before = memory.size
        for f in held[1500:]:
            memory.step(f)
        sizes[radius] = (before, memory.size)
    grew = {r: after - before for r, (before, after) in sizes.items()}
    assert grew[0.0] > 100  # kept growing while the person stood still
    assert grew[2.0] < 0.1 * grew[0.0]
    onset = pose + np.linspace(0.0, 0.6, 30)[:, None] * np.linspace(1.0, -1.0, 8)  # a movement from the pose
    for f in onset:
        memory.step(f)
    moving = ~memory.still[:memory.size]
    assert moving[sizes[2.0][1]:].any()  # the frames before it, whose futures move, are stored as they are


def test_a_large_memory_searched_in_float32_first_recalls_what_an_exact_search_recalls(monkeypatch):
    """Above `FLOAT32_ABOVE` snippets a read measures every key in float32, then the nearest few exactly: the
    snippets it recalls are those an exact search recalls, and its predictions differ by rounding only."""
    from gwr_predictor.default_predictor import memory as memory_module

    x = np.cumsum(np.random.default_rng(2).normal(scale=0.02, size=(4200, 8)), axis=0)
    x[3000:3600] = x[1000:1600] + 0.001  # a stretch that comes again: the fit over its neighbours
    runs = {}
    for threshold in (memory_module.FLOAT32_ABOVE, 10**9):
        monkeypatch.setattr(memory_module, "FLOAT32_ABOVE", threshold)
        memory = TrajectoryMemory(MemoryParams(capacity=3000))
        preds = [memory.step(f) for f in x]
        runs[threshold] = (memory, np.array([np.full((6, 8), np.nan) if p is None else p for p in preds]))
    (fast, fast_preds), (exact, exact_preds) = runs.values()
    assert fast.size == exact.size == 3000 and fast.replaced > 0
    np.testing.assert_array_equal(fast.used[:3000], exact.used[:3000])  # the same snippets recalled, when
    np.testing.assert_array_equal(fast.keys[:3000], exact.keys[:3000])  # and the same ones stored
    np.testing.assert_allclose(fast_preds, exact_preds, rtol=0, atol=1e-12)


def test_a_full_memory_learns_a_new_movement_in_place_of_what_it_recalled_longest_ago():
    """At capacity a new snippet replaces the one recalled longest ago, so a movement first met once the
    memory is full is learned in place. Measured at 600 ms: 0.062 / 0.010 / 0.009 rad on its first three
    performances; a memory that stopped growing at capacity stayed at 0.216."""
    rng = np.random.default_rng(0)
    other = 0.1 + 0.5 * np.cos(np.linspace(0.0, np.pi, 40))[:, None] * np.linspace(1.0, 0.3, 8)[None, :]
    memory = TrajectoryMemory(MemoryParams(capacity=20))
    for _ in range(4):
        for f in _movement(1.0) + rng.normal(scale=0.002, size=(40, 8)):
            memory.step(f)
        memory.reset_sequence()
    assert memory.size == 20
    errors = []
    for _ in range(2):
        x = other + rng.normal(scale=0.002, size=other.shape)
        preds = [memory.step(f) for f in x]
        errors.append(np.mean([np.abs(p[-1] - x[t + 6]).mean() for t, p in enumerate(preds[:-6]) if p is not None]))
        memory.reset_sequence()
    assert memory.size == 20 and memory.replaced > 0
    assert errors[1] < 0.5 * errors[0] and errors[1] < 0.05


def test_a_full_memory_continues_bit_for_bit_from_its_checkpoint(tmp_path):
    """What it recalled when comes back with the snippets, so the same ones are replaced after a restore;
    a file without the snippets' use times is refused, naming them."""
    from gwr_predictor.learning.checkpoint import read_checkpoint, write_checkpoint
    from gwr_predictor.learning.errors import LearningError

    x = np.cumsum(np.random.default_rng(1).normal(scale=0.05, size=(300, 8)), axis=0)
    memory = TrajectoryMemory(MemoryParams(capacity=30))
    for f in x[:150]:
        memory.step(f)
    assert memory.replaced > 0
    memory.save(tmp_path / "m.npz")
    again = TrajectoryMemory.load(tmp_path / "m.npz")
    for f in x[150:]:
        np.testing.assert_array_equal(memory.step(f), again.step(f))
    assert again.replaced == memory.replaced
    np.testing.assert_array_equal(again.keys[:30], memory.keys[:30])
    header, arrays = read_checkpoint(tmp_path / "m.npz", TrajectoryMemory.kind)
    write_checkpoint(tmp_path / "former.npz", TrajectoryMemory.kind, header,
                     {k: v for k, v in arrays.items() if k != "used"})
    with pytest.raises(LearningError, match=r"missing arrays.*used"):
        TrajectoryMemory.load(tmp_path / "former.npz")


def test_the_memory_measures_distance_by_its_weighted_keys_however_it_got_them(tmp_path):
    """The search works on the keys weighted once when stored (one matrix-vector product per search):
    they must stay the keys' own through growth, replacement at capacity and a restore."""
    x = np.cumsum(np.random.default_rng(2).normal(scale=0.05, size=(400, 8)), axis=0)
    memory = TrajectoryMemory(MemoryParams(capacity=300, velocity_weight=0.3))
    for f in x:
        memory.step(f)
    assert memory.replaced > 0 and memory.size == 300 and len(memory.keys) > 256  # grown, then full
    memory.save(tmp_path / "m.npz")
    again = TrajectoryMemory.load(tmp_path / "m.npz")
    key = memory._key(x[-9:] + 0.01)
    for m in (memory, again):
        direct = np.sum(((m.keys[:m.size] - key) * m._key_weights) ** 2, axis=1)
        np.testing.assert_allclose(m._distances(m._query(key)), direct, rtol=1e-9, atol=1e-12)
        assert m._distances(m._query(m.keys[7])).min() <= EXACT  # its own copy


def test_the_default_reports_what_its_snippet_memories_hold():
    model = make_default(settings={"memory.capacity": 40})
    for f in np.cumsum(np.random.default_rng(3).normal(scale=0.05, size=(120, 8)), axis=0):
        model.step(f)
    held = model.errors()["snippets"]
    assert set(held) == {"memory", "long_memory"}
    assert held["memory"]["stored"] == 40 and held["memory"]["replaced"] > 0
    assert 40 < held["long_memory"]["stored"] <= 120 and held["long_memory"]["replaced"] == 0


def test_the_memory_keys_hold_the_changes_over_lags_that_double():
    assert MemoryParams().lags == (1, 2, 4, 8) and MemoryParams(longest_lag=4).lags == (1, 2, 4)
    with pytest.raises(DefaultPredictorError, match="longest_lag 6 is not a power of two"):
        MemoryParams(longest_lag=6)


def test_the_fit_reads_the_neighbours_futures_at_the_present_key():
    """Neighbours whose futures are an affine function of their keys' offsets: the fit recovers the value
    at offset 0, which their weighted mean misses by the slope times their centroid's offset."""
    rng = np.random.default_rng(3)
    memory = TrajectoryMemory(MemoryParams(ridge=1e-9))
    k, dims = 32, 8
    offsets = rng.normal(size=(k, dims)) + 1.0  # the neighbours lie to one side of the present key
    at_zero, slope = rng.normal(size=(6, 8)), rng.normal(scale=0.2, size=(dims, 48))
    read = (at_zero.reshape(-1) + offsets @ slope).reshape(k, 6, 8)
    w = rng.uniform(0.5, 1.0, k)
    w /= w.sum()
    np.testing.assert_allclose(memory._fit(w, offsets, read), at_zero, atol=1e-6)
    assert np.abs(np.einsum("k,khj->hj", w, read) - at_zero).max() > 0.5


def test_the_memory_fits_only_where_the_motion_is_familiar():
    """Where the nearest key lies beyond `fit_radius` x the motion scale, the read-out is the k nearest
    averaged, to the bit; where it lies within, the fit."""
    rng = np.random.default_rng(4)
    fitted, averaged = TrajectoryMemory(), TrajectoryMemory(MemoryParams(fit_k=0))
    x = np.concatenate([_movement(s, 50) + rng.normal(scale=0.01, size=(50, 8)) for s in (1.0, 0.9, 1.1, 1.0)])
    x = np.concatenate([x, 0.5 + np.cumsum(rng.normal(scale=0.05, size=(60, 8)), axis=0)])  # then a new motion
    familiar, unfamiliar = [], 0
    for f in x:
        a, b = fitted.step(f), averaged.step(f)
        if a is None:
            continue
        assert fitted.familiarity == averaged.familiarity  # the same snippets stored
        if fitted.familiarity > fitted.params.fit_radius:
            np.testing.assert_array_equal(a, b)
            unfamiliar += 1
        else:
            familiar.append(np.abs(a - b).max())
    assert len(familiar) > 50 and np.median(familiar) > 1e-3 and unfamiliar > 10


def _two_approaches(performances: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Two movements that differ in where they came from 12-19 frames before they part: one joint comes
    in from +0.6 or -0.6 rad, the arm is still for 12 frames, then another joint goes the way the first
    came from, each as often in a random order. Returns the frames and, per frame, the side (+1 or -1)
    where the 12 still frames end (0 elsewhere)."""
    rng = np.random.default_rng(seed)
    frames, parting = [], []
    for side in rng.permutation(np.resize([-1.0, 1.0], performances)):
        come, still, go, back = np.zeros((8, 8)), np.zeros((12, 8)), np.zeros((10, 8)), np.zeros((6, 8))
        come[:, 0] = side * np.linspace(0.6, 0.0, 8)
        go[:, 1] = side * np.linspace(0.06, 0.6, 10)
        back[:, 1] = side * np.linspace(0.5, 0.0, 6)
        frames += [come, still, go, back]
        parting += [np.zeros(8), side * (np.arange(12) == 11), np.zeros(10), np.zeros(6)]
    x = 0.3 + np.concatenate(frames)
    return x + rng.normal(scale=0.003, size=x.shape), np.concatenate(parting)


def test_the_long_memory_tells_apart_movements_that_agree_over_the_short_memorys_span():
    """Where two movements agree over the last 12 frames and part after, the short memory's key (changes
    over up to 8 frames) cannot tell which comes; the default's long memory (16 frames) recalls it:
    the share of the parting joint's next 6 frames' travel each anticipates, on the side it goes."""
    x, parting = _two_approaches(30)
    made = make_default().experts.members
    share = {}
    for name in ("memory", "long_memory"):
        memory, told, went = TrajectoryMemory(made[name].model.params), [], []
        for t, f in enumerate(x[:-6]):
            out = memory.step(f)
            if t > len(x) // 3 and parting[t] and out is not None:
                told.append(parting[t] * (out[-1, 1] - f[1]))
                went.append(parting[t] * (x[t + 6, 1] - f[1]))
        share[name] = float(np.sum(told) / np.sum(went))
    assert len(told) >= 18
    assert share["long_memory"] > 0.2 and abs(share["memory"]) < 0.1, share


def test_the_default_without_its_long_memory_is_the_four_experts():
    """`long_memory.enabled` false is the default of round 11: the same four experts, to the bit."""
    x, _ = _two_approaches(6)
    four = make_default(settings={"long_memory.enabled": False})
    made = make_default()
    assert set(made.experts.members) - set(four.experts.members) == {"long_memory"}
    members = {n: m for n, m in made.experts.members.items() if n != "long_memory"}
    by_hand = RecognitionSwitch(Experts(members, made.experts.params), made.params, made.gate.params)
    for f in x:
        np.testing.assert_array_equal(four.step(f), by_hand.step(f))
    longer = make_default(settings={"long_memory.longest_lag": 32, "long_memory.k": 4})
    long, short = (longer.experts.members[n].model.params for n in ("long_memory", "memory"))
    assert (long.longest_lag, long.k, short.longest_lag, short.k) == (32, 4, 8, 3)
    with pytest.raises(GwrPredictorError, match=r"long_memory\.enabled"):
        make_default(settings={"long_memory.enabled": "yes"})


def test_the_memory_never_reads_the_future():
    x = _movement(1.0, 60)
    y = x.copy()
    y[45:] += 1.0
    a, b = TrajectoryMemory(), TrajectoryMemory()
    for t in range(45):
        pa, pb = a.step(x[t]), b.step(y[t])
        assert (pa is None and pb is None) or np.array_equal(pa, pb)


class _Constant:
    """A member that predicts `offset` away from the newest pose at every step."""

    def __init__(self, offset: float) -> None:
        self.offset = offset

    def step(self, x, learn=True):
        return None if x is None else np.repeat(np.asarray(x)[None] + self.offset, 6, axis=0)

    def reset_sequence(self) -> None:
        pass


def test_the_weights_go_to_the_member_that_has_been_right():
    """On a ramp of 0.01 rad per frame, the member predicting the ramp gets nearly all the weight."""
    class Ramp(_Constant):
        def step(self, x, learn=True):
            return None if x is None else np.asarray(x)[None] + 0.01 * np.arange(1, 7)[:, None]

    experts = Experts({"wrong": _Constant(-0.05), "ramp": Ramp(0.0)})
    ramp = 0.01 * np.arange(100)[:, None] * np.ones(8)
    for f in ramp:
        out = experts.step(f)
    w = experts.weights()
    assert np.all(w[1] > 0.999)
    np.testing.assert_allclose(out, ramp[-1] + 0.01 * np.arange(1, 7)[:, None], atol=1e-6)
    assert experts.scored.min() > 0


def test_weights_stay_finite_at_any_power_and_unscored_members_share_the_mean():
    experts = Experts({"a": _Constant(0.0), "b": _Constant(0.1)}, ExpertsParams(power=64.0))
    w = experts.weights()
    np.testing.assert_array_equal(w, 0.5)  # nothing scored: equal weights
    for f in np.zeros((20, 8)):
        experts.step(f)
    w = experts.weights()
    assert np.isfinite(w).all() and np.allclose(w.sum(axis=0), 1.0) and np.all(w[0] > 0.99)


def test_a_weighed_prediction_counts_its_weight_in_the_record():
    """An owner weighs predictions it judges to say less: weight w adds w x the squared error and w to the
    decayed count when they are scored; 0 adds nothing (the record only forgets)."""
    records = {}
    for w in (1.0, 0.25, 0.0):
        experts = Experts({"off": _Constant(0.1)}, ExpertsParams(decay=0.9))
        for t in range(12):
            experts.step(np.zeros(8))
            if t == 0:
                experts.weigh_last(w)
        records[w] = experts.sse[0].copy(), experts.weight[0].copy()
    later = 0.9 ** (10 - np.arange(6))  # step k of the first prediction: scored at frame k + 1, then forgotten
    for w in (1.0, 0.25):
        np.testing.assert_allclose(records[w][0] - records[0.0][0], w * 0.01 * later)  # error 0.1 rad
        np.testing.assert_allclose(records[w][1] - records[0.0][1], w * later)
    for bad in (float("nan"), -0.1, 1.5):
        with pytest.raises(DefaultPredictorError, match="record weight"):
            experts.weigh_last(bad)


def test_a_member_without_a_prediction_is_left_out():
    class Silent(_Constant):
        def step(self, x, learn=True):
            return None

    experts = Experts({"silent": Silent(0.0), "hold": _Constant(0.0)})
    out = experts.step(np.ones(8))
    np.testing.assert_array_equal(out, np.ones((6, 8)))


@pytest.mark.parametrize("settings, members", [
    ({}, {"network", "linear", "rls_ar", "memory", "long_memory"}),
    ({"long_memory.enabled": False}, {"network", "linear", "rls_ar", "memory"}),  # as saved before the long memory
])
def test_the_experts_checkpoint_continues_bit_for_bit(tmp_path, settings, members):
    """Every member, its gate and the weighting come back: the loaded default predicts what the
    uninterrupted one does, frame for frame, and holds as many snippets and neurons. A default saved with
    four experts (before the long memory) comes back with them: nothing it learned is dropped and no
    untrained expert is added."""
    model = make_default(settings=settings)
    x = np.concatenate([_movement(s, 50) for s in (1.0, 0.9, 1.1, 1.0)])
    for f in x[:150]:
        model.step(f)
    model.save(tmp_path / "m.npz")
    again = DefaultPredictor.load(tmp_path / "m.npz")
    assert set(again.experts.members) == set(model.experts.members) == members
    memory = again.experts.members["memory"].model
    assert memory.size == model.experts.members["memory"].model.size > 0
    recognised = model.recognised
    for f in x[150:]:
        np.testing.assert_array_equal(model.step(f), again.step(f))
    assert again.recognised == model.recognised > recognised  # the restored switch chose ungated
    assert again.neuron_counts == model.neuron_counts and again.frames_seen == model.frames_seen
    assert again.ungated_gate._scored.any()  # the ungated weighting's last gate came back with its record


def test_the_default_wins_on_a_repeated_movement_varied_in_speed():
    x = np.concatenate([_movement(s, 50) for s in (1.0, 0.9, 1.1, 1.0, 0.85, 1.15)])
    res = compare_online({"hold": HoldLast(), "default": make_default()}, [x], progress=False)
    assert res["default"].stats.mae[-1] < 0.6 * res["hold"].stats.mae[-1]


def test_the_default_takes_its_settings_by_flat_name():
    specs = {s.name for s in entry("gwr_experts").settings()}
    assert {"network.order", "network.gwr.eps_b", "memory.k", "experts.power", "expert_gate.decay",
            "gate.confidence", "recognition.radius"} <= specs
    model = make_default(settings={"memory.k": 5, "experts.power": 2.0, "network.order": 3,
                                   "network.gwr.eps_b": 0.2, "expert_gate.decay": 0.9, "gate.confidence": 1.5,
                                   "recognition.radius": 2.0})
    experts = model.experts
    assert [g.params.confidence for g in model.gates] == [1.5, 1.5] and model.params.radius == 2.0
    assert experts.members["memory"].model.params.k == 5 and experts.params.power == 2.0
    network = experts.members["network"].model.params
    assert network.order == 3 and network.gwr.eps_b == 0.2
    assert all(m.params.decay == 0.9 for m in experts.members.values())
    with pytest.raises(DefaultPredictorError, match=r"memory\.kk"):
        make_default(settings={"memory.kk": 5})
    with pytest.raises(GwrPredictorError, match=r"memory\.k"):
        make_default(settings={"memory.k": 0})


@pytest.mark.parametrize("horizon", [1, 6, 12, 13, 18, MAX_HORIZON])
def test_the_default_predicts_any_horizon_a_tracker_rate_asks_for(horizon):
    """600 ms ahead is 6 frames at 10 fps and 18 at 30 fps: the memories store what the fastest read-out
    of the horizon needs (at least the 12 tuned at 6) and every member takes any horizon the learner
    node accepts, so no horizon fails on a setting nobody set."""
    model = make_default(horizon=horizon)
    memory = model.experts.members["memory"].model
    assert memory.params.stored_future == max(12, int(np.ceil(horizon * 1.6)))
    x = np.concatenate([_movement(1.0, 120), _movement(1.3, 120)])
    outs = [model.step(f) for f in x]
    assert outs[-1].shape == (horizon, 8) and np.all(np.isfinite(outs[-1]))
    assert memory.size > 0 and memory.futures.shape[1] == memory.params.stored_future + 1


def test_a_memory_future_shorter_than_the_horizon_is_refused_by_name():
    with pytest.raises(DefaultPredictorError, match="future 10 is shorter than the horizon 18"):
        MemoryParams(horizon=18, future=10)
    assert MemoryParams(horizon=18, future=18).stored_future == 18  # what is set is what is stored
