"""The orchestration scripts' command line: `--help` prints the usage text (never code) and an
option given without its value stops with a message naming it (not bash's "unbound variable")."""

import subprocess

import pytest
from ros_harness import ROOT

SCRIPTS = ["demo.sh", "run_pipeline.sh", "bench_live.sh"]


def run(script: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(ROOT / "scripts" / script), *args], capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("script", SCRIPTS)
def test_help_prints_the_usage_text_only(script):
    result = run(script, "--help")
    assert result.returncode == 0, result.stderr
    assert f"usage: scripts/{script}" in result.stdout
    assert "--seconds N" in result.stdout
    for code in ("set -euo", "HERE=", "source \"$HERE", "#!"):
        assert code not in result.stdout


@pytest.mark.parametrize("script", SCRIPTS)
def test_option_without_value_names_it(script):
    result = run(script, "--seconds")
    assert result.returncode == 1
    assert "--seconds needs a" in result.stderr
    assert "unbound variable" not in result.stderr


def test_run_pipeline_takes_a_predictor():
    result = run("run_pipeline.sh", "--help")
    assert "--predictor NAME" in result.stdout
    assert "needs a value" in run("run_pipeline.sh", "--predictor").stderr
