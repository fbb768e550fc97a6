"""`colcon build` of the package puts the node executables, configs and the ament index marker where
`ros2 run gwr_predictor <node>` and `ros2 launch` look, and the installed executables run."""

import os
import shutil
import signal
import subprocess
from pathlib import Path

import pytest
from ros_harness import BIN, ROOT

NODES = ["skeleton_source", "angle_extractor", "arm_predictor", "delay_compensator", "nao_sim", "bag_recorder",
         "bag_player", "hri_bodies"]
SKIP = shutil.ignore_patterns(".venv", ".git", "build", "install", "log", "results", ".test-logs", "__pycache__",
                              "*.egg-info", ".pytest_cache", ".ruff_cache")


@pytest.fixture
def installed(tmp_path: Path) -> Path:
    """colcon build of a copy of the package (the checkout stays clean); returns the install base."""
    shutil.copytree(ROOT, tmp_path / "src" / "gwr_predictor", ignore=SKIP)
    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    result = subprocess.run(
        [str(BIN / "colcon"), "build", "--base-paths", "src", "--build-base", "build", "--install-base", "install"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    return tmp_path / "install"


@pytest.mark.ros
@pytest.mark.slow
def test_colcon_install_has_every_node_config_and_index_marker(installed):
    lib = installed / "gwr_predictor" / "lib" / "gwr_predictor"
    share = installed / "gwr_predictor" / "share"
    for node in NODES:
        assert os.access(lib / node, os.X_OK), f"{node} missing from {lib}"
        assert (share / "gwr_predictor" / "config" / f"{node}.yaml").is_file()
    assert (share / "ament_index" / "resource_index" / "packages" / "gwr_predictor").is_file()
    assert (share / "gwr_predictor" / "package.xml").is_file()
    assert (share / "gwr_predictor" / "launch" / "pipeline.launch.py").is_file()  # where ros2 launch looks

    # the CLI from the install space: its subpackages (commands, learning, data...) are installed
    site = next((installed / "gwr_predictor" / "lib").glob("python3*/site-packages"))
    assert (site / "gwr_predictor" / "commands" / "pretrain.py").is_file()
    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    env["PYTHONPATH"] = str(site)  # what sourcing install/setup.bash does for this package
    cli = str(lib / "gwr-predictor")
    result = subprocess.run([cli, "--help"], env=env, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0 and "pretrain" in result.stdout, result.stdout + result.stderr
    model = installed.parent / "model.npz"
    result = subprocess.run([cli, "pretrain", "-o", str(model), "--patterns", "wave_one", "--subjects", "1",
                             "--repetitions", "1", "--epochs", "1", "--quiet"],
                            env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    assert model.stat().st_size > 0


@pytest.mark.ros
@pytest.mark.slow
def test_installed_executables_run_from_the_install_space(installed, ros):
    lib = installed / "gwr_predictor" / "lib" / "gwr_predictor"
    site = next((installed / "gwr_predictor" / "lib").glob("python3*/site-packages"))
    for node in NODES:  # the node modules are installed as gwr_predictor.nodes
        assert (site / "gwr_predictor" / "nodes" / f"{node}.py").is_file()
    # What sourcing install/setup.bash does for this package. (In this venv the editable install of
    # the checkout may still win the import; on a ROS install there is only the install space.)
    ros.env["PYTHONPATH"] = str(site)

    code, output = ros.run("angle_extractor", executable=str(lib / "angle_extractor"), params={"max_gap_s": -1.0})
    assert code == 2
    assert "'max_gap_s' = -1.0 is outside the allowed range [0.0, 3600.0]" in output

    diagnostics = ros.probe.subscribe_diagnostics()
    node = ros.start("delay_compensator", executable=str(lib / "delay_compensator"),
                     params_file=installed / "gwr_predictor" / "share" / "gwr_predictor" / "config" /
                     "delay_compensator.yaml")
    ros.wait_for_node(diagnostics, "/delay_compensator", timeout=60)
    assert diagnostics["/delay_compensator"]["mode"] == "guarded"
    code, killed = node.stop(signal.SIGINT)
    assert code == 0 and not killed
