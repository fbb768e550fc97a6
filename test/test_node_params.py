"""Node parameters: the YAMLs in config/ match what the nodes declare, and a bad value stops a node
with exit code 2 and a message naming the parameter and the allowed values."""

import importlib
from pathlib import Path

import pytest
import yaml
from ros_harness import ROOT

from gwr_predictor.nodes.arm_predictor import predictor_specs
from gwr_predictor.nodes.pipeline_node import COMMON_PARAMS
from gwr_predictor.parameters.spec import ParameterError
from gwr_predictor.pipeline.params_file import flatten
from gwr_predictor.registry import learner_names

NODES = ["skeleton_source", "angle_extractor", "arm_predictor", "delay_compensator", "nao_sim", "bag_recorder",
         "bag_player", "hri_bodies"]


def declared_specs(node: str) -> dict:
    """What the node can declare: its own parameters and, for the learner, every product predictor's
    settings (it declares the chosen one's)."""
    module = importlib.import_module(f"gwr_predictor.nodes.{node}")
    specs = [*COMMON_PARAMS, *module.PARAMS]
    if node == "arm_predictor":
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
    ("arm_predictor", {"predictor": "hierarchy", "hierarchy.gwr1.activation_threshold": 1.5},
     "'hierarchy.gwr1.activation_threshold' = 1.5 is outside"),
    ("arm_predictor", {"gwr_experts.network.order": 0},
     "'gwr_experts.network.order' = 0 is outside the allowed range [1, 32]"),
    ("arm_predictor", {"predictor": "gated_llm_gwr", "gated_llm_gwr.network.order": 0},
     "'gated_llm_gwr.network.order' = 0 is outside the allowed range [1, 32]"),
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

    learner = ros.start_ready("arm_predictor", params={**FAST, "horizon": 18})
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
    from gwr_predictor.registry import settings_from_parameters

    yaml_path = ROOT / "config" / "arm_predictor.yaml"
    flat = node_parameters(yaml_path)
    # the YAML's sections are every product predictor's defaults
    assert HierarchyParams.from_flat(settings_from_parameters("hierarchy", flat)) == HierarchyParams()
    for name in ("gated_llm_gwr", "gwr_experts"):
        default = {s.name: s.default for s in predictor_specs(name)}
        assert {k: v for k, v in flat.items() if k.startswith(f"{name}.")} == default
    custom = tmp_path / "custom.yaml"
    custom.write_text("/**/arm_predictor:\n  ros__parameters:\n    predictor: hierarchy\n    horizon: 4\n"
                      "    hierarchy:\n      pgwr:\n        max_edge_age: 50\n")
    out = tmp_path / "model.npz"
    assert main(["pretrain", "-o", str(out), "--params-file", str(custom), "--patterns", "wave_one",
                 "--subjects", "1", "--repetitions", "1", "--epochs", "1", "--quiet"]) == 0
    model = Hierarchy.load(out)
    assert model.params.horizon == 4 and model.params.pgwr.max_edge_age == 50
    assert model.frames_seen > 30
    # without 'predictor' the node's default is trained; it takes the horizon from the YAML
    from gwr_predictor.default_predictor import DefaultPredictor

    custom.write_text("/**/arm_predictor:\n  ros__parameters:\n    horizon: 4\n"
                      "    gwr_experts:\n      network:\n        order: 5\n      expert_gate:\n        decay: 0.98\n")
    assert main(["pretrain", "-o", str(out), "--params-file", str(custom), "--patterns", "wave_one",
                 "--subjects", "1", "--repetitions", "1", "--epochs", "1", "--quiet"]) == 0
    default = DefaultPredictor.load(out)
    experts = default.experts
    assert default.gate.params.horizon == 4 and experts.frames_seen > 30
    assert experts.members["network"].model.params.order == 5
    assert all(m.params.decay == 0.98 for m in experts.members.values())


OLD_SECTION = "/**/gwr_hierarchy:\n  ros__parameters:\n    horizon: 0\n"  # refused wherever it applies


@pytest.mark.ros
def test_the_deprecated_executable_runs_the_learner_under_its_old_name_and_says_so(ros, tmp_path):
    """`gwr_hierarchy` (one more release): a params file's `gwr_hierarchy:` section still applies (its
    horizon 0 is refused, naming it), and the start logs the deprecation first."""
    old = tmp_path / "old.yaml"
    old.write_text(OLD_SECTION)
    code, output = ros.run("gwr_hierarchy", params_file=old, timeout=60)
    assert code == 2 and "'horizon' = 0 is outside" in output, output
    assert output.index("the executable 'gwr_hierarchy' is deprecated") < output.index("'horizon' = 0"), output
    assert "run 'arm_predictor'" in output


@pytest.mark.ros
def test_the_learner_warns_about_a_params_file_with_its_old_name_only(ros, tmp_path):
    """rcl skips a section of another node name without a word: the learner says so instead."""
    old = tmp_path / "old.yaml"
    old.write_text(OLD_SECTION)
    learner = ros.start("arm_predictor", params_file=old)  # the section is not applied: it starts
    ros.wait_for_log(learner, f"params file {old} has a section for 'gwr_hierarchy' and none for 'arm_predictor'")
    assert "ready" in learner.output() and "deprecated" not in learner.output()


def test_a_section_for_another_node_name_only_is_found(tmp_path):
    from gwr_predictor.pipeline.params_file import sections_for_other_name

    files = {"old.yaml": "/**/gwr_hierarchy", "both.yaml": "gwr_hierarchy", "ns.yaml": "/robot1/gwr_hierarchy",
             "all.yaml": "/**", "new.yaml": "arm_predictor"}
    argv = ["arm_predictor", "--ros-args"]
    for name, key in files.items():
        text = f"{key}:\n  ros__parameters:\n    seed: 1\n"
        if name == "both.yaml":
            text += "/**/arm_predictor:\n  ros__parameters:\n    seed: 2\n"
        (tmp_path / name).write_text(text)
        argv += ["--params-file", str(tmp_path / name)]
    assert sections_for_other_name(argv, "arm_predictor", "gwr_hierarchy") == [tmp_path / "old.yaml",
                                                                                tmp_path / "ns.yaml"]
    assert sections_for_other_name(argv, "gwr_hierarchy", "arm_predictor") == [tmp_path / "new.yaml"]


def test_pretrain_reads_the_learners_old_section_too_for_one_release(tmp_path, capsys):
    from gwr_predictor.commands.pretrain import node_parameters

    both = tmp_path / "both.yaml"
    both.write_text("/**/gwr_hierarchy:\n  ros__parameters:\n    horizon: 4\n    seed: 1\n"
                    "/**/arm_predictor:\n  ros__parameters:\n    seed: 2\n"
                    "/**:\n  ros__parameters:\n    learn: false\n")
    assert node_parameters(both) == {"learn": False, "horizon": 4, "seed": 2}  # the new name's section wins
    assert "section '/**/gwr_hierarchy' has the learner's old name" in capsys.readouterr().err
    assert node_parameters(ROOT / "config" / "arm_predictor.yaml")["predictor"] == "gwr_experts"
    assert "old name" not in capsys.readouterr().err
