"""package.xml declares what the code imports, with keys that rosdep can resolve on Jazzy."""

import ast
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RUNTIME_DIRS = ("gwr_predictor", "nodes", "launch")

# Python import -> rosdep key (checked against ros/rosdistro rosdep/python.yaml, 2026-12).
PYTHON_KEYS = {
    "numpy": "python3-numpy",
    "yaml": "python3-yaml",
    "matplotlib": "python3-matplotlib",
    "PIL": "python3-pil",
    "tqdm": "python3-tqdm",
    "threadpoolctl": "python3-threadpoolctl",
    "pybullet": "python3-pybullet-pip",
    "rosbags": "python3-rosbags-pip",
    "mcap": "mcap-ros2-support",  # the key that brings the mcap package (mcap-ros2-support depends on it)
}
# Imports with no rosdep key anywhere: installed with pip, as the README says.
PIP_ONLY = {"imageio_ffmpeg": "imageio-ffmpeg"}
# ROS packages: the import name is the package name (and the rosdep key).
ROS_PACKAGES = {
    "rclpy", "builtin_interfaces", "rcl_interfaces", "std_msgs", "sensor_msgs", "diagnostic_msgs",
    "visualization_msgs", "trajectory_msgs", "rosgraph_msgs", "geometry_msgs",
    "launch", "launch_ros", "ament_index_python",  # launch/pipeline.launch.py
}


def runtime_imports() -> set[str]:
    """Top-level third-party modules imported anywhere in the installed code."""
    found: set[str] = set()
    for folder in RUNTIME_DIRS:
        for path in (ROOT / folder).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.Import):
                    found |= {alias.name.split(".")[0] for alias in node.names}
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    found.add(node.module.split(".")[0])
    return {m for m in found if m not in sys.stdlib_module_names and m != "gwr_predictor"}


def launched_packages() -> set[str]:
    """Packages whose nodes a launch file starts (`package="..."` of its calls, and the TF nodes of
    `pipeline/tf_plan.py` it and run_pipeline.sh --tf start), other than this one."""
    from gwr_predictor.pipeline import tf_plan

    found = {node.package for node in tf_plan.tf_nodes("<robot/>", "/")}
    for path in (ROOT / "launch").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call):
                found |= {k.value.value for k in node.keywords if k.arg == "package"
                          and isinstance(k.value, ast.Constant) and isinstance(k.value.value, str)}
    return found - {"gwr_predictor"}


def exec_depends() -> set[str]:
    root = ET.parse(ROOT / "package.xml").getroot()
    return {e.text.strip() for e in root.findall("exec_depend")}


def test_every_runtime_import_is_known():
    unknown = runtime_imports() - set(PYTHON_KEYS) - set(PIP_ONLY) - ROS_PACKAGES
    assert not unknown, f"imported but not mapped to a rosdep key (add one here and in package.xml): {unknown}"


def test_every_runtime_import_has_its_exec_depend():
    deps = exec_depends()
    imports = runtime_imports()
    needed = {PYTHON_KEYS[m] for m in imports if m in PYTHON_KEYS} | (imports & ROS_PACKAGES)
    assert needed - deps == set(), f"missing <exec_depend> in package.xml: {sorted(needed - deps)}"


def test_every_launched_package_has_its_exec_depend():
    """robot_state_publisher, tf2_ros and rviz2 are started, not imported: rosdep must still install them."""
    launched = launched_packages()
    assert {"robot_state_publisher", "tf2_ros", "rviz2"} <= launched
    assert launched - exec_depends() == set(), f"missing <exec_depend>: {sorted(launched - exec_depends())}"


def test_no_exec_depend_without_a_use():
    used = ({PYTHON_KEYS[m] for m in runtime_imports() if m in PYTHON_KEYS} | (runtime_imports() & ROS_PACKAGES)
            | launched_packages())
    assert exec_depends() - used == set(), f"stale <exec_depend>: {sorted(exec_depends() - used)}"


def test_pip_only_dependencies_are_named_in_the_readme_and_never_as_made_up_keys():
    deps = exec_depends()
    assert not any(d.endswith("-pip") and d not in PYTHON_KEYS.values() for d in deps), deps
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for module, dist in PIP_ONLY.items():
        if module in runtime_imports():
            assert re.search(rf"pip install [^\n`]*\b{dist}==", readme), f"README must say how to pip install {dist}"


def test_license_file_matches_package_xml():
    root = ET.parse(ROOT / "package.xml").getroot()
    assert root.findtext("license") == "Apache-2.0"
    text = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert "Apache License" in text and "Version 2.0" in text
