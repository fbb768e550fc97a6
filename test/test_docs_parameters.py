"""docs/parameters.md's tables are the nodes' declared parameters: a renamed parameter, a new
default or a new range breaks this test, not a reader."""

import importlib
import re
from pathlib import Path

import pytest

from gwr_predictor.parameters.spec import markdown_table
from gwr_predictor.registry import learner_names

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "parameters.md"
NODES = ["skeleton_source", "angle_extractor", "arm_predictor", "delay_compensator", "nao_sim", "bag_recorder",
         "bag_player", "hri_bodies"]


def documented_table(node: str) -> str:
    """The table right below the '## <node>' heading."""
    text = DOC.read_text(encoding="utf-8")
    match = re.search(rf"^## {node}\n\n((?:\|.*\n)+)", text, re.MULTILINE)
    assert match, f"docs/parameters.md has no '## {node}' heading followed by a table"
    return match.group(1).rstrip("\n")


def node_table(node: str) -> str:
    return markdown_table(importlib.import_module(f"gwr_predictor.nodes.{node}").PARAMS)


@pytest.mark.parametrize("node", NODES)
def test_the_documented_parameters_are_the_declared_ones(node):
    expected = node_table(node)
    documented = documented_table(node)
    assert documented == expected, f"replace the table under '## {node}' in docs/parameters.md with:\n{expected}"


@pytest.mark.parametrize("predictor", learner_names())
def test_each_product_predictors_settings_are_documented(predictor):
    """The learner declares the chosen predictor's own settings: one table per product predictor."""
    from gwr_predictor.nodes.arm_predictor import predictor_specs

    expected = markdown_table(predictor_specs(predictor))
    heading = f"arm_predictor: predictor {predictor}"
    assert documented_table(heading) == expected, f"replace the table under '## {heading}' with:\n{expected}"


def test_the_parameters_every_node_declares_are_documented():
    from gwr_predictor.nodes.pipeline_node import COMMON_PARAMS

    assert documented_table("every node") == markdown_table(COMMON_PARAMS)


def test_the_params_file_holds_each_predictors_settings_as_rendered_from_the_dataclasses():
    """config/arm_predictor.yaml's predictor sections are rendered from the settings dataclasses: a default
    changed there and not here (or here by hand) fails."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "parameter_reference.py")], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
