"""launch/pipeline.launch.py starts the graph of scripts/run_pipeline.sh (checked statically).

`launch` and `launch_ros` have no PyPI wheels, so the launch file is imported with stand-ins for
them that record what it builds; the graph is compared with what the script starts, parsed from
the script itself: the same executables, node names, namespaces, remaps, parameter files and
overrides, for each combination of baseline/render/scenario/namespace. The package's share/ is built
from setup.py's data_files, so the launch file reads what colcon would install (URDF, configs, RViz).
"""

import ast
import importlib.util
import os
import re
import shlex
import subprocess
import sys
import types
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
LAUNCH_FILE = ROOT / "launch" / "pipeline.launch.py"
SCRIPT = ROOT / "scripts" / "run_pipeline.sh"
CONFIG = ROOT / "config"


class Recorded:
    """A stand-in for a launch action or description: keeps its arguments."""

    def __init__(self, *args, **kwargs) -> None:
        self.args, self.kwargs = args, kwargs


def installed_data_files() -> list[tuple[str, list[str]]]:
    """setup.py's data_files (setup() replaced by a recorder, run in the repository like colcon does)."""
    import setuptools

    captured: dict = {}
    cwd = os.getcwd()
    original = setuptools.setup
    try:
        os.chdir(ROOT)
        setuptools.setup = lambda **kw: captured.update(kw)
        exec(compile((ROOT / "setup.py").read_text(), str(ROOT / "setup.py"), "exec"), {"__name__": "setup"})
    finally:
        setuptools.setup = original
        os.chdir(cwd)
    return captured["data_files"]


@pytest.fixture(scope="module")
def share_dir(tmp_path_factory) -> Path:
    """share/gwr_predictor as setup.py installs it: links to the repository's files."""
    prefix = tmp_path_factory.mktemp("install")
    for dest, files in installed_data_files():
        for f in files:
            target = prefix / dest / Path(f).name
            target.parent.mkdir(parents=True, exist_ok=True)
            target.symlink_to(ROOT / f)
    return prefix / "share" / "gwr_predictor"


@pytest.fixture
def launch_module(monkeypatch, share_dir):
    """The launch file, imported with recording stand-ins for launch, launch_ros and ament_index_python."""
    stubs = {
        "launch": {"LaunchDescription": type("LaunchDescription", (Recorded,), {})},
        "launch.actions": {"DeclareLaunchArgument": type("DeclareLaunchArgument", (Recorded,), {}),
                           "OpaqueFunction": type("OpaqueFunction", (Recorded,), {})},
        "launch_ros": {},
        "launch_ros.actions": {"Node": type("Node", (Recorded,), {})},
        "ament_index_python": {},
        "ament_index_python.packages": {"get_package_share_directory": lambda pkg: str(share_dir)},
    }
    for name, attrs in stubs.items():
        module = types.ModuleType(name)
        module.__dict__.update(attrs)
        monkeypatch.setitem(sys.modules, name, module)
    spec = importlib.util.spec_from_file_location("pipeline_launch", LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def launched_nodes(module, pushed_namespace: str | None = None, **arguments: str) -> list[dict]:
    """Run the launch description with `arguments` over the declared defaults (inside a PushRosNamespace
    of `pushed_namespace`, which launch_ros keeps absolute in the `ros_namespace` configuration); the
    nodes it starts."""
    description = module.generate_launch_description()
    (actions,) = description.args
    declared = {a.args[0]: a.kwargs["default_value"] for a in actions if type(a).__name__ == "DeclareLaunchArgument"}
    assert set(arguments) <= set(declared), f"undeclared launch arguments {set(arguments) - set(declared)}"
    (opaque,) = [a for a in actions if type(a).__name__ == "OpaqueFunction"]
    configurations = {**declared, **arguments}
    if pushed_namespace is not None:
        configurations["ros_namespace"] = pushed_namespace
    context = types.SimpleNamespace(launch_configurations=configurations)
    nodes = []
    for node in opaque.kwargs["function"](context):
        kw = node.kwargs
        *files, overrides = kw["parameters"]
        nodes.append({"executable": kw["executable"], "name": kw["name"],
                      "namespace": node_namespace(pushed_namespace, kw["namespace"]),
                      "remaps": sorted(kw.get("remappings", [])), "files": files,
                      "overrides": {k: v for k, v in overrides.items() if k != "use_sim_time"},
                      "use_sim_time": overrides["use_sim_time"], "package": kw["package"],
                      "arguments": kw.get("arguments", [])})
    return nodes


def node_namespace(pushed: str | None, namespace: str) -> str:
    """What launch_ros makes of a Node's namespace inside a PushRosNamespace: relative ones are prefixed."""
    if namespace.startswith("/"):
        return namespace.rstrip("/") or "/"
    joined = "/".join(p for p in ((pushed or "").strip("/"), namespace.strip("/")) if p)
    return "/" + joined


def pipeline_only(nodes: list[dict]) -> list[dict]:
    """The package's own nodes (what run_pipeline.sh starts), without the TF and viewer nodes."""
    return [n for n in nodes if n["package"] == "gwr_predictor"]


def script_nodes(out: str, params_dir: str, baseline: bool, render: bool, scenario: str,
                 predictor: str = "", namespace: str = "") -> list[dict]:
    """The nodes run_pipeline.sh starts (its start_node lines), with its arrays and if-blocks evaluated.
    `namespace` is the script's normalised --namespace: "" (the root) or "/a/b"."""
    variables = {"predictor": predictor, "namespace": namespace, "out": out}

    def expand(text: str) -> str:
        return re.sub(r"\$(\w+)", lambda m: variables[m.group(1)], text)

    arrays: dict[str, list[str]] = {"frames": []}
    nodes = []
    active = [True]
    conditions = {'"$baseline" = 1': baseline, '"$render" = 1': render}
    for line in SCRIPT.read_text().splitlines():
        line = line.strip()
        block = re.match(r"if \[ (.*) \]; then(.*?)(; fi)?$", line)
        if block and block.group(1) in conditions:
            if block.group(3):  # one-line if
                if not (active[-1] and conditions[block.group(1)]):
                    continue
                line = block.group(2).strip()
            else:
                active.append(active[-1] and conditions[block.group(1)])
                continue
        elif line == "fi" and len(active) > 1:
            active.pop()
            continue
        if not active[-1]:
            continue
        assign = re.match(r"(\w+)=\((.*)\)$", line)
        if assign:
            arrays[assign.group(1)] = [expand(w) for w in shlex.split(assign.group(2))]
            continue
        append = re.match(r'\[ -z "\$(\w+)" \] \|\| (\w+)\+=\((.*)\)$', line)  # [ -z "$v" ] || arr+=(...)
        if append:
            if variables[append.group(1)]:
                arrays[append.group(2)] += [expand(w) for w in shlex.split(append.group(3))]
            continue
        assert not re.search(r"\w\+?=\(", line), f"run_pipeline.sh line not understood by this parser: {line}"
        if not line.startswith("start_node ") or line.startswith("start_node()"):
            continue
        words = []
        for word in shlex.split(line)[1:]:
            array = re.fullmatch(r"\$\{(\w+)\[@\]\}", word)
            words += arrays[array.group(1)] if array else [expand(word)]
        label, executable, *extra = words
        remaps, overrides, namespace = [], {}, "/"
        for flag, value in zip(extra[::2], extra[1::2], strict=True):
            key, _, val = value.partition(":=")
            if flag == "-r" and key == "__ns":
                namespace = val
            elif flag == "-r":
                remaps.append((key, val))
            else:
                assert flag == "-p", line
                overrides[key] = int(val) if val.isdigit() else val
        files = [f"{params_dir}/{executable}.yaml", *([scenario] if scenario else [])]
        nodes.append({"executable": executable, "name": executable, "namespace": namespace,
                      "remaps": sorted(remaps), "files": files, "overrides": overrides, "label": label})
    return nodes


def same_graph(launched: list[dict], scripted: list[dict]) -> None:
    key = lambda n: (n["namespace"], n["executable"])  # noqa: E731
    assert sorted(map(key, launched)) == sorted(map(key, scripted))
    by_key = {key(n): n for n in launched}
    for expected in scripted:
        got = by_key[key(expected)]
        for field in ("name", "remaps", "files", "overrides"):
            assert got[field] == expected[field], f"{expected['label']}: {field} {got[field]} != {expected[field]}"


@pytest.mark.parametrize("baseline,render,scenario,predictor", [
    (True, False, "", ""), (False, False, "", ""),
    (True, True, "config/scenario_variable_delay.yaml", "hierarchy"),
])
def test_launch_file_starts_the_graph_of_run_pipeline(launch_module, tmp_path, baseline, render, scenario,
                                                      predictor):
    out = str(tmp_path / "run")
    launched = launched_nodes(launch_module, out=out, baseline=str(baseline).lower(), render=str(render).lower(),
                              scenario=scenario, predictor=predictor, params_dir=str(CONFIG))
    same_graph(pipeline_only(launched), script_nodes(out, str(CONFIG), baseline, render, scenario, predictor))
    assert not any(n["use_sim_time"] for n in launched)


def test_launch_file_names_only_existing_executables_and_parameter_files(launch_module, tmp_path):
    setup = ast.parse((ROOT / "setup.py").read_text())
    (nodes_list,) = [n.value for n in ast.walk(setup) if isinstance(n, ast.Assign)
                     and any(getattr(t, "id", "") == "NODES" for t in n.targets)]
    console_scripts = set(ast.literal_eval(nodes_list))
    launched = launched_nodes(launch_module, out=str(tmp_path / "run"), use_sim_time="true", rviz="true")
    assert {n["executable"] for n in pipeline_only(launched)} <= console_scripts
    # other packages' nodes (TF, RViz) come from packages package.xml declares, so rosdep installs them
    root = ET.parse(ROOT / "package.xml").getroot()
    assert {n["package"] for n in launched} - {"gwr_predictor"} <= {e.text for e in root.findall("exec_depend")}
    for node in launched:
        for path in node["files"]:
            assert Path(path).is_file(), f"{node['executable']}: parameter file {path} missing"
        assert node["use_sim_time"] is True
    # the installed share/ holds the launch file and the configs it reads
    text = (ROOT / "setup.py").read_text()
    assert '(f"share/{PACKAGE}/launch", glob("launch/*.launch.py"))' in text
    assert '(f"share/{PACKAGE}/config", glob("config/*.yaml"))' in text


def test_script_parser_sees_every_node_of_the_script():
    """The comparison above is only as good as the parse: it must find all the script's start_node calls."""
    scripted = script_nodes("/o", "/c", baseline=True, render=True, scenario="")
    calls = re.findall(r"^\s*(?:if .*then )?start_node (\S+)", SCRIPT.read_text(), re.M)
    assert sorted(n["label"] for n in scripted) == sorted(calls) and len(calls) == 8
    (uncompensated,) = [n for n in scripted if n["label"] == "delay_compensator_uncompensated"]
    assert uncompensated["namespace"] == "/uncompensated" and uncompensated["overrides"] == {"mode": "none"}
    assert ("arm_angles", "/arm_angles") in uncompensated["remaps"]
    (learner,) = [n for n in script_nodes("/o", "/c", True, False, "", "rls_ar") if n["label"] == "arm_predictor"]
    assert learner["overrides"] == {"checkpoint": "/o/model.npz", "predictor": "rls_ar"}


@pytest.mark.parametrize("pushed,argument,expected", [
    ("/robot1", "", "/robot1"),          # PushRosNamespace('robot1') around the include
    (None, "robot1", "/robot1"),         # namespace:=robot1
    ("/lab", "robot1/", "/lab/robot1"),  # both: the argument inside the pushed namespace
])
def test_launch_file_runs_under_any_namespace_like_run_pipeline(launch_module, tmp_path, pushed, argument, expected):
    out = str(tmp_path / "run")
    launched = launched_nodes(launch_module, pushed_namespace=pushed, out=out, params_dir=str(CONFIG),
                              **({"namespace": argument} if argument else {}))
    same_graph(pipeline_only(launched), script_nodes(out, str(CONFIG), True, False, "", namespace=expected))
    # nothing of the pipeline is left in the root namespace, and the baseline reads its own pipeline's topics
    assert {n["namespace"] for n in launched} == {expected, f"{expected}/uncompensated"}
    for node in (n for n in pipeline_only(launched) if n["namespace"] == f"{expected}/uncompensated"):
        assert node["remaps"] == [("arm_angles", f"{expected}/arm_angles"), ("predictions", f"{expected}/predictions")]


def test_script_takes_a_namespace_and_refuses_a_bad_one():
    text = SCRIPT.read_text()
    assert "--namespace NS" in text
    scripted = script_nodes("/o", "/c", baseline=True, render=False, scenario="", namespace="/robot2")
    assert {n["namespace"] for n in scripted} == {"/robot2", "/robot2/uncompensated"}
    lib = ROOT / "scripts" / "lib.sh"
    for given, normalised in (("robot2", "/robot2"), ("/a/b/", "/a/b"), ("", "")):
        result = subprocess.run(["bash", "-c", f'source "{lib}"; gwr_namespace "$1"', "_", given],
                                capture_output=True, text=True, timeout=10)
        assert (result.returncode, result.stdout) == (0, normalised)
    bad = subprocess.run(["bash", "-c", f'source "{lib}"; gwr_namespace "$1"', "_", "2robots"],
                         capture_output=True, text=True, timeout=10)
    assert bad.returncode == 1 and "is not a ROS namespace" in bad.stderr


def rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """tf2's fixed-axis roll, pitch, yaw as a matrix (columns: the child's axes in the parent)."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return rz @ ry @ rx


def static_transforms(nodes: list[dict]) -> dict[str, tuple[str, np.ndarray, np.ndarray]]:
    """child frame -> (parent, translation, rotation) of every static_transform_publisher."""
    found = {}
    for node in (n for n in nodes if n["executable"] == "static_transform_publisher"):
        args = dict(zip(node["arguments"][::2], node["arguments"][1::2], strict=True))
        pose = [float(args[k]) for k in ("--x", "--y", "--z", "--roll", "--pitch", "--yaw")]
        found[args["--child-frame-id"]] = (args["--frame-id"], np.array(pose[:3]), rotation(*pose[3:]))
    return found


@pytest.mark.parametrize("pushed", [None, "/robot1"])
def test_launch_file_publishes_tf_for_both_robots_and_the_camera(launch_module, share_dir, tmp_path, pushed):
    launched = launched_nodes(launch_module, pushed_namespace=pushed, out=str(tmp_path / "run"))
    ns = pushed or ""
    state_publishers = {n["namespace"]: n for n in launched if n["executable"] == "robot_state_publisher"}
    sims = {n["namespace"] for n in launched if n["executable"] == "nao_sim"}
    # one per robot, next to its nao_sim: robot_state_publisher's relative joint_states is that robot's
    assert set(state_publishers) == sims == {ns or "/", f"{ns}/uncompensated"}
    urdf = (ROOT / "gwr_predictor" / "robot" / "nao.urdf").read_text()
    for namespace, node in state_publishers.items():
        assert node["package"] == "robot_state_publisher" and node["overrides"]["robot_description"] == urdf
        prefix = "uncompensated/" if namespace.endswith("/uncompensated") else ""
        assert node["overrides"]["frame_prefix"] == prefix
    # every TF publisher writes the pipeline's own tf / tf_static, so two pipelines keep two trees
    tf_nodes = [n for n in launched if n["package"] in ("robot_state_publisher", "tf2_ros")]
    assert len(tf_nodes) == 4
    for node in tf_nodes:
        assert node["remaps"] == [("/tf", f"{ns}/tf"), ("/tf_static", f"{ns}/tf_static")]
    transforms = static_transforms(launched)
    # the skeleton markers' frame hangs off the robot; by default the camera looks forward from the torso
    parent, xyz, rot = transforms["skeleton_camera"]
    assert parent == "torso"
    np.testing.assert_allclose(rot @ [0, 0, 1], [1, 0, 0], atol=1e-4)  # into the scene = the robot's forward
    np.testing.assert_allclose(rot @ [0, 1, 0], [0, 0, 1], atol=1e-4)  # camera up = the robot's up
    parent, xyz, rot = transforms["uncompensated/torso"]
    assert parent == "torso" and np.linalg.norm(xyz) > 0.3  # the two robots side by side, not inside each other
    assert not any(n["executable"] == "rviz2" for n in launched)


def test_launch_file_camera_pose_rviz_and_tf_arguments(launch_module, share_dir, tmp_path):
    launched = launched_nodes(launch_module, out=str(tmp_path / "a"), camera_pose="1.5 0 0.3 1.5708 0 -1.5708",
                              rviz="true", baseline="false")
    _, xyz, rot = static_transforms(launched)["skeleton_camera"]
    np.testing.assert_allclose(xyz, [1.5, 0, 0.3])
    np.testing.assert_allclose(rot @ [0, 0, 1], [-1, 0, 0], atol=1e-4)  # a sensor ahead, looking back
    np.testing.assert_allclose(rot @ [0, 1, 0], [0, 0, 1], atol=1e-4)
    assert set(static_transforms(launched)) == {"skeleton_camera"}  # no baseline robot to place
    (rviz,) = [n for n in launched if n["executable"] == "rviz2"]
    config = Path(rviz["arguments"][rviz["arguments"].index("-d") + 1])
    assert config.is_file() and config.parent.parent == share_dir
    assert rviz["remaps"] == [("/tf", "/tf"), ("/tf_static", "/tf_static")]
    no_camera = launched_nodes(launch_module, out=str(tmp_path / "b"), camera_pose="")
    assert "skeleton_camera" not in static_transforms(no_camera)
    no_tf = launched_nodes(launch_module, out=str(tmp_path / "c"), tf="false")
    assert {n["package"] for n in no_tf} == {"gwr_predictor"}
    with pytest.raises(ValueError, match="camera_pose"):
        launched_nodes(launch_module, out=str(tmp_path / "d"), camera_pose="1 2 3")


def test_rviz_config_shows_the_person_the_prediction_and_both_robots():
    (path,) = [ROOT / f for dest, files in installed_data_files() if dest.endswith("/rviz") for f in files]
    config = yaml.safe_load(path.read_text())
    manager = config["Visualization Manager"]
    topic = lambda d: d.get("Topic", d.get("Description Topic", {})).get("Value")  # noqa: E731
    displays = {d["Class"].rsplit("/", 1)[-1] + ":" + str(topic(d)): d for d in manager["Displays"] if d.get("Enabled")}
    # relative topics: they resolve in RViz's namespace, the pipeline's
    assert {"MarkerArray:skeleton_markers", "MarkerArray:predicted_arm_markers", "RobotModel:robot_description",
            "RobotModel:uncompensated/robot_description"} <= set(displays)
    assert displays["RobotModel:robot_description"]["TF Prefix"] == ""
    # RViz joins prefix and link with "/": the frames robot_state_publisher's frame_prefix makes
    assert displays["RobotModel:uncompensated/robot_description"]["TF Prefix"] + "/" == "uncompensated/"
    for key in ("RobotModel:robot_description", "RobotModel:uncompensated/robot_description"):
        assert displays[key]["Description Topic"]["Durability Policy"] == "Transient Local"  # latched URDF
    assert manager["Global Options"]["Fixed Frame"] == "torso"


# --- a real robot: output naoqi (naoqi_driver2) or joint_trajectory (ros2_control) ---------------------


def nao_links() -> set[str]:
    """The Nao's frames: the links of the URDF, named as naoqi_driver2 names the robot's TF frames."""
    root = ET.parse(ROOT / "gwr_predictor" / "robot" / "nao.urdf").getroot()
    return {link.get("name") for link in root.findall("link")}


def resolved(namespace: str, name: str) -> str:
    return name if name.startswith("/") else f"{namespace.rstrip('/')}/{name}"


@pytest.mark.parametrize("argument,ns", [("", "/"), ("robot1", "/robot1")])
def test_launch_file_drives_a_real_nao_without_clashing_with_naoqi_driver2(launch_module, share_dir, tmp_path,
                                                                          argument, ns):
    """naoqi_driver2 runs in the root namespace and publishes /joint_states and the Nao's TF frames itself."""
    launched = launched_nodes(launch_module, out=str(tmp_path / "run"), output="naoqi", params_dir=str(CONFIG),
                              **({"namespace": argument} if argument else {}))
    baseline = resolved(ns, "uncompensated")
    # the compensated robot is the real one: no simulator, no state publisher of its own frames
    assert [n["namespace"] for n in launched if n["executable"] == "nao_sim"] == [baseline]
    publishers = {resolved(n["namespace"], topic) for n in launched
                  if n["executable"] in ("nao_sim", "robot_state_publisher") for topic in ("joint_states",
                                                                                          "robot_description")}
    assert not publishers & {"/joint_states", "/robot_description"}
    links = nao_links()
    frames = {n["overrides"]["frame_prefix"] + link for n in launched if n["executable"] == "robot_state_publisher"
              for link in links}
    frames |= set(static_transforms(launched))
    assert frames and not frames & links  # every frame of ours is prefixed or the camera's
    (comp,) = [n for n in launched if n["executable"] == "delay_compensator" and n["namespace"] == ns]
    assert comp["overrides"] == {"output": "naoqi"}
    assert comp["remaps"] == [("joint_angles", "/joint_angles"), ("joint_states", "/joint_states")]
    # what TF remains joins the driver's tree (the camera on the real torso), whatever the pipeline's namespace
    assert static_transforms(launched)["skeleton_camera"][0] == "torso"
    for node in (n for n in launched if n["package"] in ("robot_state_publisher", "tf2_ros")):
        assert node["remaps"] == [("/tf", "/tf"), ("/tf_static", "/tf_static")]
    # the rest of the pipeline is the script's, less the compensated nao_sim
    scripted = [n for n in script_nodes(str(tmp_path / "run"), str(CONFIG), True, False, "",
                                        namespace="" if ns == "/" else ns)
                if n["label"] not in ("nao_sim", "delay_compensator")]
    same_graph([n for n in pipeline_only(launched) if n is not comp], scripted)


def test_launch_file_drives_ros2_control_and_both(launch_module, tmp_path):
    launched = launched_nodes(launch_module, out=str(tmp_path / "a"), output="joint_trajectory",
                              controller="arm_controller", robot_namespace="nao", baseline="false")
    assert not [n for n in launched if n["executable"] == "nao_sim"]
    (comp,) = [n for n in launched if n["executable"] == "delay_compensator"]
    assert comp["overrides"] == {"output": "joint_trajectory"}
    assert comp["remaps"] == [("joint_states", "/nao/joint_states"),
                              ("joint_trajectory_controller/joint_trajectory", "/nao/arm_controller/joint_trajectory")]
    assert {n["executable"] for n in launched if n["package"] != "gwr_predictor"} == {"static_transform_publisher"}
    both = launched_nodes(launch_module, out=str(tmp_path / "b"), output="both")
    (comp,) = [n for n in both if n["executable"] == "delay_compensator" and n["namespace"] == "/"]
    assert comp["remaps"] == [("joint_trajectory_controller/joint_trajectory",
                               "/joint_trajectory_controller/joint_trajectory")]
    assert {n["namespace"] for n in both if n["executable"] in ("nao_sim", "robot_state_publisher")} == \
        {"/", "/uncompensated"}  # the simulated robot stays
    with pytest.raises(ValueError, match="output"):
        launched_nodes(launch_module, out=str(tmp_path / "c"), output="naoqi2")


def test_launch_file_takes_the_person_from_a_tracker(launch_module, tmp_path):
    """A real robot imitates a real person: the demonstrator's nodes give way to a tracker's."""
    people = {}
    for person in ("demonstrator", "skeleton", "hri"):
        launched = launched_nodes(launch_module, out=str(tmp_path / person), input=person, output="naoqi",
                                  params_dir=str(CONFIG))
        people[person] = {n["executable"] for n in launched} & {"skeleton_source", "angle_extractor", "hri_bodies"}
        assert {n["executable"] for n in launched} >= {"bag_recorder", "arm_predictor", "delay_compensator"}
    assert people == {"demonstrator": {"skeleton_source", "angle_extractor"}, "skeleton": {"angle_extractor"},
                      "hri": {"hri_bodies"}}
    with pytest.raises(ValueError, match="input"):
        launched_nodes(launch_module, out=str(tmp_path / "x"), input="kinect")


# --- the scripts' TF (run_pipeline.sh --tf): the launch file's TF nodes, started with ros2 run ------------

FAKE_ROS2 = """#!/bin/bash
# a stand-in for the ros2 command of a ROS 2 install: packages are there; `run` logs its arguments and waits
[ "$1" = pkg ] && exit 0
printf '%s\\0' "$@" >> "$FAKE_ROS2_LOG"; printf '\\n' >> "$FAKE_ROS2_LOG"
exec python3 -c "import signal, time; signal.signal(signal.SIGINT, signal.SIG_DFL); time.sleep(600)"
"""  # (a node resets SIGINT, which bash ignores in background jobs)


def test_run_pipeline_tf_starts_the_launch_files_tf_nodes_with_ros2_run(launch_module, tmp_path):
    bin_dir, log = tmp_path / "bin", tmp_path / "ros2.log"
    bin_dir.mkdir()
    (bin_dir / "ros2").write_text(FAKE_ROS2)
    (bin_dir / "ros2").chmod(0o755)
    env = {**os.environ, "PATH": f"{bin_dir}:{os.environ['PATH']}", "FAKE_ROS2_LOG": str(log)}
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)
    steps = (f'source "{ROOT}/scripts/env.sh"; source "{ROOT}/scripts/lib.sh"; gwr_tf_check; '
             'gwr_start_tf "$1" /robot1 1; sleep 1; gwr_stop_all')
    result = subprocess.run(["bash", "-c", steps, "_", str(tmp_path / "run")], env=env, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    started = set()
    for line in log.read_text().splitlines():
        argv = line.split("\0")[:-1]
        assert argv[0] == "run", argv
        package, executable, *rest = argv[1:]
        cut = rest.index("--ros-args")
        ros = dict(zip(rest[cut + 1::2], rest[cut + 2::2], strict=True)) if "--params-file" in rest else {}
        remaps = [a for flag, a in zip(rest[cut + 1::2], rest[cut + 2::2], strict=True) if flag == "-r"]
        rules = dict(r.split(":=") for r in remaps)
        params = (yaml.safe_load(Path(ros["--params-file"]).read_text())["/**"]["ros__parameters"]
                  if "--params-file" in ros else {})
        started.add((package, executable, rules.pop("__node"), rules.pop("__ns"), tuple(sorted(rules.items())),
                     tuple(rest[:cut]), params.get("frame_prefix"), params.get("robot_description")))
    launched = launched_nodes(launch_module, out=str(tmp_path / "launch"), namespace="robot1")
    expected = {(n["package"], n["executable"], n["name"], n["namespace"], tuple(n["remaps"]), tuple(n["arguments"]),
                 n["overrides"].get("frame_prefix"), n["overrides"].get("robot_description"))
                for n in launched if n["package"] in ("robot_state_publisher", "tf2_ros")}
    assert len(expected) == 4 and started == expected


def test_run_pipeline_tf_without_a_ros_install_stops_at_start_saying_what_is_needed(tmp_path):
    env = {**os.environ, "PATH": "/usr/bin:/bin"}  # no ros2 command
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)
    result = subprocess.run(["bash", str(SCRIPT), "--tf", "--out", str(tmp_path / "run")], env=env,
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 1
    assert "--tf needs robot_state_publisher and tf2_ros" in result.stderr and "tf2_msgs" in result.stderr
    assert not (tmp_path / "run").exists()  # nothing started
    assert "Without it nothing publishes TF" in subprocess.run(["bash", str(SCRIPT), "--help"], capture_output=True,
                                                               text=True, timeout=60).stdout
