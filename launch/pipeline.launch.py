"""The live pipeline of scripts/run_pipeline.sh as a ROS 2 launch file, for full Jazzy installs.

    ros2 launch gwr_predictor pipeline.launch.py out:=/tmp/run1 [baseline:=false] [render:=true]
        [scenario:=/path/to/scenario.yaml] [checkpoint:=model.npz] [predictor:=NAME] [params_dir:=/path/to/config]
        [use_sim_time:=true]

Same nodes, the same <node>.yaml files (from share/gwr_predictor/config unless params_dir is
given), the same remaps and overrides as the script: bag_recorder (out/bag), nao_sim,
delay_compensator, the uncompensated nao_sim + delay_compensator (mode none) in /uncompensated
fed by the same angles, gwr_hierarchy (checkpoint out/model.npz), angle_extractor and
skeleton_source (waits for its 2 subscribers, the extractor and the recorder, so nothing is lost).
Launch has no PyPI wheel, so test/test_launch_file.py checks this file statically against the
script; the shell scripts remain the main way to run the pipeline.
"""

import os
import shutil

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch_ros.actions import Node

PACKAGE = "gwr_predictor"
BASELINE_NAMESPACE = "/uncompensated"
# the uncompensated pair reads the shared topics, not its namespace's
BASELINE_REMAPS = [("arm_angles", "/arm_angles"), ("predictions", "/predictions")]

ARGUMENTS = {
    "out": ("results/launch_run", "run folder: bag/ (recording) and model.npz (learner) go here"),
    "params_dir": ("", "folder with <node>.yaml (empty: the installed share/gwr_predictor/config)"),
    "predictor": ("", "the learner's model (gwr_hierarchy's `predictor`), after the params files; empty: theirs"),
    "checkpoint": ("", "start the learner from this model (copied to out/model.npz, which it then updates)"),
    "scenario": ("", "extra params file applied to every node after its own (e.g. config/scenario_*.yaml)"),
    "baseline": ("true", "also run the uncompensated robot in /uncompensated"),
    "render": ("false", "the compensated robot writes PNG pictures to out/frames"),
    "use_sim_time": ("false", "every node on /clock (e.g. from bag_player clock:=true)"),
}


def _true(text: str) -> bool:
    return text.strip().lower() in ("true", "1", "yes")


def pipeline_nodes(context, *_args, **_kwargs) -> list:
    """The nodes, built from the resolved launch arguments (so plain Python decides, as the script does)."""
    arg = context.launch_configurations
    out = os.path.abspath(arg["out"])
    params_dir = arg["params_dir"] or os.path.join(get_package_share_directory(PACKAGE), "config")
    scenario = [arg["scenario"]] if arg["scenario"] else []
    sim = {"use_sim_time": _true(arg["use_sim_time"])}
    os.makedirs(out, exist_ok=True)
    if os.path.exists(os.path.join(out, "bag")):
        raise RuntimeError(f"{out}/bag exists already: choose another out:=")
    if arg["checkpoint"]:
        shutil.copyfile(arg["checkpoint"], os.path.join(out, "model.npz"))

    def node(executable: str, name: str | None = None, namespace: str = "", remappings=(), **overrides) -> Node:
        params = [os.path.join(params_dir, f"{executable}.yaml"), *scenario, {**sim, **overrides}]
        return Node(package=PACKAGE, executable=executable, name=name or executable, namespace=namespace,
                    parameters=params, remappings=list(remappings), output="screen")

    nodes = [node("bag_recorder", path=os.path.join(out, "bag"))]
    frames = {"render_dir": os.path.join(out, "frames")} if _true(arg["render"]) else {}
    nodes += [node("nao_sim", **frames), node("delay_compensator")]
    if _true(arg["baseline"]):
        nodes += [node("nao_sim", namespace=BASELINE_NAMESPACE, remappings=BASELINE_REMAPS),
                  node("delay_compensator", namespace=BASELINE_NAMESPACE, remappings=BASELINE_REMAPS,
                       mode="none")]
    learner = {"checkpoint": os.path.join(out, "model.npz")}
    if arg["predictor"]:
        learner["predictor"] = arg["predictor"]
    nodes += [node("gwr_hierarchy", **learner),
              node("angle_extractor"),
              node("skeleton_source", wait_for_subscribers=2)]
    return nodes


def generate_launch_description() -> LaunchDescription:
    return LaunchDescription([
        *(DeclareLaunchArgument(name, default_value=default, description=text)
          for name, (default, text) in ARGUMENTS.items()),
        OpaqueFunction(function=pipeline_nodes),
    ])
