"""A robot's day on small bounds: the default keeps learning at every bound, its storage is never
reallocated while it learns, and a model saved at its bounds continues bit for bit."""

from __future__ import annotations

import numpy as np

from gwr_predictor.default_predictor import make_default
from gwr_predictor.default_predictor.memory import MemoryParams, TrajectoryMemory
from gwr_predictor.registry import load_predictor

SMALL = {"network.gwr.max_neurons": 40, "memory.capacity": 120, "long_memory.capacity": 120}


def _new_motion(n: int, seed: int) -> np.ndarray:
    """Smooth motion that keeps being new (each joint's velocity a damped random walk)."""
    rng = np.random.default_rng(seed)
    out, v, pose = np.empty((n, 8)), np.zeros(8), np.zeros(8)
    for t, kick in enumerate(rng.normal(scale=0.01, size=(n, 8))):
        v = 0.9 * v + kick
        pose = 0.995 * pose + v
        out[t] = pose
    return out


def test_at_its_bounds_the_default_keeps_learning_in_storage_allocated_once():
    model = make_default(settings=SMALL)
    network = model.experts.members["network"].model.pgwr
    memories = [model.experts.members[n].model for n in ("memory", "long_memory")]
    storage = [network._wa, network._edges.ids, *(m.keys for m in memories), *(m.futures for m in memories)]
    x = _new_motion(2000, 0)
    predictions = [model.step(f) for f in x]
    assert network.n_neurons == 40 and network.evicted > 50
    assert all(m.size == 120 and m.replaced > 500 for m in memories)
    now = [network._wa, network._edges.ids, *(m.keys for m in memories), *(m.futures for m in memories)]
    assert all(a is b for a, b in zip(storage, now, strict=True))  # nothing reallocated while learning
    late = np.array(predictions[-500:])
    assert np.isfinite(late).all()
    mae, hold = np.abs(late[:-6, -1] - x[-494:]).mean(), np.abs(x[-500:-6] - x[-494:]).mean()
    assert mae < 0.8 * hold  # still predicting new motion better than holding the pose


def test_a_default_saved_at_its_bounds_continues_bit_for_bit(tmp_path):
    model = make_default(settings=SMALL)
    x = _new_motion(1500, 1)
    for f in x[:1000]:
        model.step(f)
    model.save(tmp_path / "model.npz")
    twin = load_predictor("gwr_experts", tmp_path / "model.npz")
    for f in x[1000:]:
        np.testing.assert_array_equal(model.step(f), twin.step(f))  # evictions and replacements alike
    assert model.experts.members["network"].model.pgwr.evicted > 0


def test_a_memory_is_allocated_once_at_its_capacity():
    memory = TrajectoryMemory(MemoryParams(capacity=50))
    keys = memory.keys
    for f in _new_motion(400, 2):
        memory.step(f)
    assert memory.size == 50 and memory.replaced > 0 and memory.keys is keys and len(keys) == 50
