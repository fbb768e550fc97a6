"""Node parameters: the YAMLs in config/ match what the nodes declare, and a bad value stops a node
with exit code 2 and a message naming the parameter and the allowed values."""

import importlib
from pathlib import Path

import pytest
import yaml
from ros_harness import ROOT

from gwr_predictor.nodes.gwr_hierarchy import predictor_specs
from gwr_predictor.nodes.pipeline_node import COMMON_PARAMS
from gwr_predictor.parameters.spec import ParameterError
from gwr_predictor.pipeline.params_file import flatten
from gwr_predictor.predictors.registry import learner_names

NODES = ["skeleton_source", "angle_extractor", "gwr_hierarchy", "delay_compensator", "nao_sim", "bag_recorder",
         "bag_player", "hri_bodies"]


def declared_specs(node: str) -> dict:
    """What the node can declare: its own parameters and, for the learner, every product predictor's
    settings (it declares the chosen one's)."""
    module = importlib.import_module(f"gwr_predictor.nodes.{node}")
    specs = [*COMMON_PARAMS, *module.PARAMS]
    if node == "gwr_hierarchy":
        specs += [s for name in learner_names() for s in module.predictor_specs(name)]
    return {s.name: s for s in specs}


def yaml_parameters(path: Path, node: str) -> dict:
    doc = yaml.safe_load(path.read_text())
    key = f"/**/{node}"
    assert key in doc, f"{path.name}: parameters must be under '{key}'"
    return flatten(doc[key]["ros__parameters"])


@pytest.mark.parametrize("node", NODES)
def test_config_yaml_names_only_declared_parameters_with_allowed_values(node):
    specs = declared_specs(node)
    values = yaml_parameters(ROOT / "config" / f"{node}.yaml", node)
    unknown = sorted(set(values) - set(specs))
    assert not unknown, f"config/{node}.yaml sets undeclared parameters {unknown} (ROS would ignore them)"
    for name, value in values.items():
        specs[name].check(value)  # raises ParameterError if not allowed


@pytest.mark.parametrize("path", sorted((ROOT / "config").glob("scenario_*.yaml")), ids=lambda p: p.name)
def test_scenario_yamls_name_only_declared_parameters(path):
    doc = yaml.safe_load(path.read_text())
    for key, section in doc.items():
        node = key.rsplit("/", 1)[-1]
        specs = declared_specs(node)
        values = flatten(section["ros__parameters"])
        assert set(values) <= set(specs), f"{path.name}: {node} has no parameters {sorted(set(values) - set(specs))}"
        for name, value in values.items():
            specs[name].check(value)


def test_out_of_range_value_is_refused_by_the_shared_check():
    spec = declared_specs("nao_sim")["delay_s"]
    with pytest.raises(ParameterError, match=r"'delay_s' = -1.0 is outside the allowed range \[0.0, 60.0\]"):
        spec.check(-1)


BAD_VALUES = [
    ("nao_sim", {"delay_s": -0.5}, "'delay_s' = -0.5 is outside the allowed range [0.0, 60.0]"),
    ("delay_compensator", {"mode": "sideways"},
     "'mode' = 'sideways' is not allowed: must be one of 'none', 'guarded', 'fixed'"),
    ("gwr_hierarchy", {"predictor": "hierarchy", "hierarchy.gwr1.activation_threshold": 1.5},
     "'hierarchy.gwr1.activation_threshold' = 1.5 is outside"),
    ("gwr_hierarchy", {"gwr_experts.network.order": 0},
     "'gwr_experts.network.order' = 0 is outside the allowed range [1, 32]"),
    ("gwr_hierarchy", {"predictor": "gated_llm_gwr", "gated_llm_gwr.order": 0},
     "'gated_llm_gwr.order' = 0 is outside the allowed range [1, 32]"),
    ("skeleton_source", {"rate_hz": 0.0}, "'rate_hz' = 0.0 is outside the allowed range [1.0, 1000.0]"),
    ("angle_extractor", {"max_gap_s": "soon"}, "'max_gap_s' must be a number"),
    ("bag_player", {"bag": ""}, "'bag' is empty"),
    ("bag_recorder", {"topics": ["mystery_topic"]}, "'topics': topic 'mystery_topic': unknown type"),
]


@pytest.mark.ros
@pytest.mark.parametrize(("node", "params", "message"), BAD_VALUES,
                         ids=[f"{b[0]}-{next(iter(b[1]))}" for b in BAD_VALUES])
def test_bad_parameter_stops_the_node_with_exit_code_2_naming_it(ros, node, params, message):
    code, output = ros.run(node, params=params, timeout=60)
    assert code == 2, output
    assert message in output
    assert "ready" not in output


@pytest.mark.ros
def test_the_learner_predicts_as_far_as_its_horizon(ros):
    """600 ms at 30 fps is 18 frames: the default learner starts with any horizon it accepts and
    publishes that many predicted frames (above 12 it refused to start, on its memories' `future`)."""
    import numpy as np
    from test_node_bad_input import FAST, joint_state

    from gwr_predictor.nodes import messages
    from gwr_predictor.nodes.messages import Float64MultiArray, JointState

    learner = ros.start_ready("gwr_hierarchy", params={**FAST, "horizon": 18})
    predictions = ros.probe.subscribe("/predictions", Float64MultiArray)
    pub = ros.probe.publisher("/arm_angles", JointState)
    ros.probe.wait_for_subscribers(pub)
    t = np.arange(40)[:, None]
    for i, row in enumerate(0.3 + 0.2 * np.sin(0.3 * t + np.arange(8)) * np.array([1, 1, -1, -1, 1, -1, 1, 1])):
        pub.publish(joint_state(100.0 + 0.1 * i, row))
        ros.probe.spin_for(0.02)
    ros.probe.spin_until(lambda: len(predictions) >= 10, 30, "10 predictions", [learner])
    _, _, values = messages.read_predictions(predictions[-1])
    assert values.shape == (18, 8) and np.all(np.isfinite(values))
    assert learner.running()


def test_pretrain_uses_the_nodes_yaml_and_writes_a_checkpoint_the_node_can_load(tmp_path):
    from gwr_predictor.commands.cli import main
    from gwr_predictor.commands.pretrain import node_parameters
    from gwr_predictor.learning.hierarchy import Hierarchy
    from gwr_predictor.learning.params import HierarchyParams
    from gwr_predictor.predictors.registry import settings_from_parameters

    yaml_path = ROOT / "config" / "gwr_hierarchy.yaml"
    flat = node_parameters(yaml_path)
    # the YAML's sections are every product predictor's defaults
    assert HierarchyParams.from_flat(settings_from_parameters("hierarchy", flat)) == HierarchyParams()
    for name in ("gated_llm_gwr", "gwr_experts"):
        default = {s.name: s.default for s in predictor_specs(name)}
        assert {k: v for k, v in flat.items() if k.startswith(f"{name}.")} == default
    custom = tmp_path / "custom.yaml"
    custom.write_text("/**/gwr_hierarchy:\n  ros__parameters:\n    predictor: hierarchy\n    horizon: 4\n"
                      "    hierarchy:\n      pgwr:\n        max_edge_age: 50\n")
    out = tmp_path / "model.npz"
    assert main(["pretrain", "-o", str(out), "--params-file", str(custom), "--patterns", "wave_one",
                 "--subjects", "1", "--repetitions", "1", "--epochs", "1", "--quiet"]) == 0
    model = Hierarchy.load(out)
    assert model.params.horizon == 4 and model.params.pgwr.max_edge_age == 50
    assert model.frames_seen > 30
    # without 'predictor' the node's default is trained; it takes the horizon from the YAML
    from gwr_predictor.default_predictor.recognition import RecognitionSwitch

    custom.write_text("/**/gwr_hierarchy:\n  ros__parameters:\n    horizon: 4\n"
                      "    gwr_experts:\n      network:\n        order: 5\n      expert_gate:\n        decay: 0.98\n")
    assert main(["pretrain", "-o", str(out), "--params-file", str(custom), "--patterns", "wave_one",
                 "--subjects", "1", "--repetitions", "1", "--epochs", "1", "--quiet"]) == 0
    default = RecognitionSwitch.load(out)
    experts = default.experts
    assert default.gate.params.horizon == 4 and experts.frames_seen > 30
    assert experts.members["network"].model.params.order == 5
    assert all(m.params.decay == 0.98 for m in experts.members.values())
