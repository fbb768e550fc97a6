"""One naming rule for nested settings (`gwr_predictor.parameters.tree`): the default's tree holds every
setting once, the flat names and defaults come from it, and a checkpoint stores it beside the state."""

from __future__ import annotations

import numpy as np
import pytest

from gwr_predictor.default_predictor import (
    DefaultParams,
    DefaultPredictor,
    DefaultPredictorError,
    GatedNetworkParams,
    make_default,
)
from gwr_predictor.learning.checkpoint import read_checkpoint, write_checkpoint
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.params import HierarchyParams
from gwr_predictor.parameters import tree
from gwr_predictor.parameters.spec import ParameterError
from gwr_predictor.registry import entry


def test_the_flat_names_are_the_trees_paths_and_the_defaults_its_values():
    params = DefaultParams()
    flat = tree.flatten(params)
    assert flat["network.order"] == params.network.order == 6  # the default's own network, not the class's 4
    assert flat["network.gwr.max_neurons"] == params.network.gwr.max_neurons == 1000
    assert flat["long_memory.longest_lag"] == 16 and flat["memory.longest_lag"] == 8
    assert flat["expert_gate.decay"] == 0.995 and flat["gate.decay"] == 0.97
    assert flat["rls_ar.order"] == 12 and flat["linear.order"] == 12
    assert "network.gwr.activation_threshold" not in flat  # hidden: the network's insertion rule cancels it
    assert not any(k.endswith((".horizon", ".n_joints", ".joints")) for k in flat)  # the shape is the top's
    # the registry, and so the node, the YAML and the docs, declare exactly these
    assert {s.name: s.default for s in entry("gwr_experts").settings()} == {k: v for k, v in flat.items()
                                                                          if k not in ("horizon", "n_joints")}


def test_replace_by_flat_name_rebuilds_the_tree_and_hands_the_shape_to_every_member():
    params = tree.replace(DefaultParams(horizon=4, n_joints=6), {"network.gwr.eps_b": 0.2, "memory.k": 5,
                                                                 "expert_gate.decay": 0.9, "network.order": 3.0})
    assert params.network.gwr.eps_b == 0.2 and params.memory.k == 5 and params.expert_gate.decay == 0.9
    assert params.network.order == 3 and isinstance(params.network.order, int)  # an integral float is taken
    assert params.network.horizon == params.memory.horizon == params.gate.horizon == params.spread.horizon == 4
    assert params.network.n_joints == params.expert_gate.joints == params.linear.joints == 6
    assert params.network.rate == 0.1  # untouched settings keep the tree's values
    assert tree.replace(DefaultParams(), tree.flatten(params)) == params


@pytest.mark.parametrize("flat, message", [
    ({"network.ordre": 3}, r"unknown parameters \['network.ordre'\]"),
    ({"memory.k": 0}, r"memory\.k"),
    ({"network.order": 2.5}, r"network\.order"),
    ({"long_memory.enabled": 1}, r"long_memory\.enabled"),
    ({"network.global_order": 9}, r"global_order 9 exceeds"),  # the member dataclass's own check
])
def test_a_bad_name_or_value_raises_the_trees_error_naming_it(flat, message):
    with pytest.raises(DefaultPredictorError, match=message):
        DefaultParams.from_flat(flat)


def test_the_hierarchy_uses_the_same_rule():
    paper = HierarchyParams.paper()
    assert HierarchyParams.from_flat(paper.to_flat()) == paper
    assert paper.to_flat()["gwr1.max_neurons"] == 0  # None is the spec's none value
    with pytest.raises(ParameterError, match="unknown parameters"):
        HierarchyParams.from_flat({"gwr4.eps_b": 0.1})


def test_the_gated_network_names_its_parts_as_the_default_does():
    names = {s.name for s in entry("gated_llm_gwr").settings()}
    assert {"network.order", "network.gwr.eps_b", "gate.decay"} <= names and "order" not in names
    assert GatedNetworkParams().network.order == 4  # the class's defaults: chosen for the network alone


def _stream(n: int = 80) -> np.ndarray:
    t = np.arange(n)[:, None] / 10.0
    return 0.4 * np.sin(t + np.linspace(0.0, 1.0, 8))


def test_a_checkpoint_stores_the_settings_tree_and_loads_the_composition_it_describes(tmp_path):
    model = make_default(settings={"network.order": 5, "long_memory.enabled": False, "memory.k": 4})
    for x in _stream():
        model.step(x)
    model.save(tmp_path / "m.npz")
    header, _ = read_checkpoint(tmp_path / "m.npz", DefaultPredictor.kind)
    assert header["settings"] == model.settings.to_flat() and header["settings"]["network.order"] == 5
    loaded = DefaultPredictor.load(tmp_path / "m.npz")
    assert loaded.settings == model.settings and "long_memory" not in loaded.experts.members
    x = _stream(81)[-1]
    np.testing.assert_array_equal(loaded.step(x), model.step(x))


def test_a_checkpoint_without_the_whole_tree_or_of_the_earlier_layout_is_refused(tmp_path):
    model = make_default()
    model.step(_stream(1)[0])
    model.save(tmp_path / "m.npz")
    header, arrays = read_checkpoint(tmp_path / "m.npz", DefaultPredictor.kind)
    del header["settings"]["memory.k"]
    write_checkpoint(tmp_path / "partial.npz", DefaultPredictor.kind, header, arrays)
    with pytest.raises(LearningError, match=r"lacks the settings \['memory.k'\]"):
        DefaultPredictor.load(tmp_path / "partial.npz")
    write_checkpoint(tmp_path / "earlier.npz", "RecognitionSwitch", {**header, "kind": "RecognitionSwitch"}, arrays)
    with pytest.raises(LearningError, match="saved by an earlier build") as refused:
        DefaultPredictor.load(tmp_path / "earlier.npz")
    assert not refused.value.kind_mismatch  # the node sets it aside rather than asking for another predictor
