"""The package layout that colcon, ament and `ros2 run` rely on."""

import ast
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_package_xml_is_format_3_ament_python():
    root = ET.parse(ROOT / "package.xml").getroot()
    assert root.get("format") == "3"
    assert root.findtext("name") == "gwr_predictor"
    assert root.find("export/build_type").text == "ament_python"
    deps = {e.text for e in root.findall("exec_depend")}
    assert {"rclpy", "std_msgs", "sensor_msgs"} <= deps


def test_setup_cfg_puts_scripts_where_ros2_run_looks():
    text = (ROOT / "setup.cfg").read_text()
    assert "script_dir=$base/lib/gwr_predictor" in text
    assert "install_scripts=$base/lib/gwr_predictor" in text
    assert (ROOT / "resource" / "gwr_predictor").is_file()


def test_every_node_console_script_has_a_module_with_main():
    tree = ast.parse((ROOT / "setup.py").read_text())
    nodes = next(n for n in ast.walk(tree) if isinstance(n, ast.Assign) and n.targets[0].id == "NODES")
    names = [e.value for e in nodes.value.elts]
    assert len(names) >= 5
    for name in names:
        src = ROOT / "nodes" / f"{name}.py"
        assert src.is_file(), f"console script {name} has no nodes/{name}.py"
        mod = ast.parse(src.read_text())
        assert any(isinstance(f, ast.FunctionDef) and f.name == "main" for f in mod.body), name
    deprecated = next(n for n in ast.walk(tree) if isinstance(n, ast.Assign) and n.targets[0].id == "DEPRECATED")
    for old, target in ast.literal_eval(deprecated.value).items():  # old executable names, for one release
        module, function = target.split(":")
        mod = ast.parse((ROOT / "nodes" / f"{module}.py").read_text())
        assert old not in names and any(isinstance(f, ast.FunctionDef) and f.name == function for f in mod.body), old


def test_library_never_imports_rclpy():
    for path in (ROOT / "gwr_predictor").rglob("*.py"):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                mods = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                mods = [node.module or ""]
            else:
                continue
            for m in mods:
                top = m.split(".")[0]
                assert top not in {"rclpy", "sensor_msgs", "std_msgs", "diagnostic_msgs"}, (
                    f"{path.relative_to(ROOT)} imports {m}: the library must stay ROS-free")


def test_every_public_name_of_the_package_and_its_subpackages_resolves():
    import importlib

    for pkg in ("gwr_predictor", "gwr_predictor.learning", "gwr_predictor.predictors", "gwr_predictor.evaluation",
                "gwr_predictor.data", "gwr_predictor.robot", "gwr_predictor.pipeline"):
        module = importlib.import_module(pkg)
        for name in module.__all__:
            assert getattr(module, name) is not None, f"{pkg}.{name}"
    import gwr_predictor

    starters = {"make_predictor", "load_predictor", "register", "Predictor", "GwrPredictorError"}
    assert starters <= set(gwr_predictor.__all__)


def test_the_learner_imports_no_data_pipeline_or_robot_code():
    """learning/ is the method alone: it reads no files (but its checkpoints), knows no messages and no robot."""
    found = set()
    for path in (ROOT / "gwr_predictor" / "learning").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            found |= {(path.name, n) for n in names
                      if n.startswith(("gwr_predictor.data", "gwr_predictor.pipeline", "gwr_predictor.robot"))}
    assert not found, sorted(found)
