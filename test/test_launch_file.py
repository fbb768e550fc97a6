"""launch/pipeline.launch.py starts the graph of scripts/run_pipeline.sh (checked statically).

`launch` and `launch_ros` have no PyPI wheels, so the launch file is imported with stand-ins for
them that record what it builds; the graph is compared with what the script starts, parsed from
the script itself: the same executables, node names, namespaces, remaps, parameter files and
overrides, for each combination of baseline/render/scenario.
"""

import ast
import importlib.util
import re
import shlex
import sys
import types
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAUNCH_FILE = ROOT / "launch" / "pipeline.launch.py"
SCRIPT = ROOT / "scripts" / "run_pipeline.sh"
CONFIG = ROOT / "config"


class Recorded:
    """A stand-in for a launch action or description: keeps its arguments."""

    def __init__(self, *args, **kwargs) -> None:
        self.args, self.kwargs = args, kwargs


@pytest.fixture
def launch_module(monkeypatch):
    """The launch file, imported with recording stand-ins for launch, launch_ros and ament_index_python."""
    stubs = {
        "launch": {"LaunchDescription": type("LaunchDescription", (Recorded,), {})},
        "launch.actions": {"DeclareLaunchArgument": type("DeclareLaunchArgument", (Recorded,), {}),
                           "OpaqueFunction": type("OpaqueFunction", (Recorded,), {})},
        "launch_ros": {},
        "launch_ros.actions": {"Node": type("Node", (Recorded,), {})},
        "ament_index_python": {},
        "ament_index_python.packages": {"get_package_share_directory": lambda pkg: str(ROOT)},
    }
    for name, attrs in stubs.items():
        module = types.ModuleType(name)
        module.__dict__.update(attrs)
        monkeypatch.setitem(sys.modules, name, module)
    spec = importlib.util.spec_from_file_location("pipeline_launch", LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def launched_nodes(module, **arguments: str) -> list[dict]:
    """Run the launch description with `arguments` over the declared defaults; the nodes it starts."""
    description = module.generate_launch_description()
    (actions,) = description.args
    declared = {a.args[0]: a.kwargs["default_value"] for a in actions if type(a).__name__ == "DeclareLaunchArgument"}
    assert set(arguments) <= set(declared), f"undeclared launch arguments {set(arguments) - set(declared)}"
    (opaque,) = [a for a in actions if type(a).__name__ == "OpaqueFunction"]
    context = types.SimpleNamespace(launch_configurations={**declared, **arguments})
    nodes = []
    for node in opaque.kwargs["function"](context):
        kw = node.kwargs
        *files, overrides = kw["parameters"]
        nodes.append({"executable": kw["executable"], "name": kw["name"], "namespace": kw["namespace"] or "/",
                      "remaps": sorted(kw["remappings"]), "files": files,
                      "overrides": {k: v for k, v in overrides.items() if k != "use_sim_time"},
                      "use_sim_time": overrides["use_sim_time"], "package": kw["package"]})
    return nodes


def script_nodes(out: str, params_dir: str, baseline: bool, render: bool, scenario: str,
                 predictor: str = "") -> list[dict]:
    """The nodes run_pipeline.sh starts (its start_node lines), with its arrays and if-blocks evaluated."""
    variables = {"predictor": predictor}
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
            arrays[assign.group(1)] = shlex.split(assign.group(2).replace("$out", out))
            continue
        append = re.match(r'\[ -z "\$(\w+)" \] \|\| (\w+)\+=\((.*)\)$', line)  # [ -z "$v" ] || arr+=(...)
        if append:
            if variables[append.group(1)]:
                arrays[append.group(2)] += shlex.split(append.group(3).replace(f"${append.group(1)}",
                                                                               variables[append.group(1)]))
            continue
        assert not re.search(r"\w\+?=\(", line), f"run_pipeline.sh line not understood by this parser: {line}"
        if not line.startswith("start_node ") or line.startswith("start_node()"):
            continue
        words = []
        for word in shlex.split(line.replace("$out", out))[1:]:
            array = re.fullmatch(r"\$\{(\w+)\[@\]\}", word)
            words += arrays[array.group(1)] if array else [word]
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
    (True, True, "config/scenario_variable_delay.yaml", "blend_flat_rls"),
])
def test_launch_file_starts_the_graph_of_run_pipeline(launch_module, tmp_path, baseline, render, scenario,
                                                      predictor):
    out = str(tmp_path / "run")
    launched = launched_nodes(launch_module, out=out, baseline=str(baseline).lower(), render=str(render).lower(),
                              scenario=scenario, predictor=predictor)
    same_graph(launched, script_nodes(out, str(CONFIG), baseline, render, scenario, predictor))
    assert {n["package"] for n in launched} == {"gwr_predictor"}
    assert not any(n["use_sim_time"] for n in launched)


def test_launch_file_names_only_existing_executables_and_parameter_files(launch_module, tmp_path):
    setup = ast.parse((ROOT / "setup.py").read_text())
    (nodes_list,) = [n.value for n in ast.walk(setup) if isinstance(n, ast.Assign)
                     and any(getattr(t, "id", "") == "NODES" for t in n.targets)]
    console_scripts = set(ast.literal_eval(nodes_list))
    launched = launched_nodes(launch_module, out=str(tmp_path / "run"), use_sim_time="true")
    assert {n["executable"] for n in launched} <= console_scripts
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
    (learner,) = [n for n in script_nodes("/o", "/c", True, False, "", "rls_ar") if n["label"] == "gwr_hierarchy"]
    assert learner["overrides"] == {"checkpoint": "/o/model.npz", "predictor": "rls_ar"}
