"""The live pipeline of scripts/run_pipeline.sh as a ROS 2 launch file, for full Jazzy installs.

    ros2 launch gwr_predictor pipeline.launch.py out:=/tmp/run1 [baseline:=false] [render:=true]
        [scenario:=/path/to/scenario.yaml] [checkpoint:=model.npz] [predictor:=NAME] [params_dir:=/path/to/config]
        [use_sim_time:=true] [namespace:=robot1] [tf:=false] [camera_pose:="x y z roll pitch yaw"]
        [uncompensated_pose:="x y z roll pitch yaw"] [rviz:=true]
        [output:=naoqi|joint_trajectory|both] [robot_namespace:=/] [controller:=joint_trajectory_controller]
        [input:=demonstrator|skeleton|hri]

Same nodes, the same <node>.yaml files (from share/gwr_predictor/config unless params_dir is
given), the same remaps and overrides as the script: bag_recorder (out/bag), nao_sim,
delay_compensator, the uncompensated nao_sim + delay_compensator (mode none) in <ns>/uncompensated
fed by the same angles (<ns>/arm_angles, <ns>/predictions), arm_predictor (checkpoint out/model.npz),
angle_extractor and skeleton_source (waits for its 2 subscribers, the extractor and the recorder, so
nothing is lost). <ns> is the namespace of an enclosing PushRosNamespace, then `namespace:=`.

For viewers (tf:=true, the default): a robot_state_publisher per robot from the installed URDF (the
uncompensated one with frame_prefix `uncompensated/`), static transforms torso -> skeleton_camera
(`camera_pose`) and torso -> uncompensated/torso (`uncompensated_pose`), all on <ns>/tf and
<ns>/tf_static, so pipelines in different namespaces keep separate TF trees; rviz:=true opens
share/gwr_predictor/rviz/pipeline.rviz in <ns>.
A real robot (output:=naoqi: a Nao through naoqi_driver2; output:=joint_trajectory: a robot under
ros2_control): the compensated nao_sim and its robot_state_publisher are left out, since the robot's driver
publishes `joint_states` and the robot's TF; the compensator reads `<robot_namespace>/joint_states` and
commands `<robot_namespace>/joint_angles` (naoqi) or `<robot_namespace>/<controller>/joint_trajectory`,
and the TF nodes that remain (the camera, the uncompensated simulated Nao with its `uncompensated/` frames)
join the robot's tree on `<robot_namespace>/tf`. output:=both keeps nao_sim and also sends the trajectory.
Launch has no PyPI wheel, so test/test_launch_file.py checks this file statically against the
script; the shell scripts remain the main way to run the pipeline.
"""

import os
import shutil

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch_ros.actions import Node

from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.pipeline import tf_plan
from gwr_predictor.pipeline.conventions import TOPIC_TRAJECTORY_COMMAND as TRAJECTORY_TOPIC
from gwr_predictor.pipeline.markers import ROBOT_FRAME
from gwr_predictor.pipeline.markers import SKELETON_FRAME as CAMERA_FRAME
from gwr_predictor.pipeline.tf_plan import (
    BASELINE_FRAME_PREFIX,
    BASELINE_NAMESPACE,
    CAMERA_POSE,
    UNCOMPENSATED_POSE,
    in_namespace,
)

PACKAGE = "gwr_predictor"

ARGUMENTS = {
    "out": ("results/launch_run", "run folder: bag/ (recording) and model.npz (learner) go here"),
    "params_dir": ("", "folder with <node>.yaml (empty: the installed share/gwr_predictor/config)"),
    "predictor": ("", "the learner's model (arm_predictor's `predictor`), after the params files; empty: theirs"),
    "checkpoint": ("", "start the learner from this model (copied to out/model.npz, which it then updates)"),
    "scenario": ("", "extra params file applied to every node after its own (e.g. config/scenario_*.yaml)"),
    "baseline": ("true", "also run the uncompensated robot in <namespace>/uncompensated"),
    "render": ("false", "the compensated robot writes PNG pictures to out/frames"),
    "use_sim_time": ("false", "every node on /clock (e.g. from bag_player clock:=true)"),
    "namespace": ("", "run the pipeline in this namespace (inside an enclosing PushRosNamespace's)"),
    "tf": ("true", "robot_state_publisher per robot and the static transforms, on <namespace>/tf"),
    "camera_pose": (CAMERA_POSE, f"'x y z roll pitch yaw' (m, rad) of {CAMERA_FRAME} in {ROBOT_FRAME}; "
                    "empty: no transform (your camera driver publishes it)"),
    "uncompensated_pose": (UNCOMPENSATED_POSE, f"'x y z roll pitch yaw' (m, rad) of {BASELINE_FRAME_PREFIX}"
                           f"{ROBOT_FRAME} in {ROBOT_FRAME}"),
    "rviz": ("false", "open rviz2 with share/gwr_predictor/rviz/pipeline.rviz in the pipeline's namespace"),
    "output": ("joint_state", "the compensated robot: joint_state (nao_sim), naoqi (a real Nao through "
               "naoqi_driver2), joint_trajectory (a robot under ros2_control), both (nao_sim and ros2_control); "
               "a real robot's driver publishes joint_states and TF, so no nao_sim or robot_state_publisher for it"),
    "robot_namespace": ("/", "where the real robot's driver runs: its joint_states, joint_angles, controllers "
                        "and TF (naoqi_driver2: the root)"),
    "controller": ("joint_trajectory_controller", "output joint_trajectory/both: the joint_trajectory_controller "
                   "in robot_namespace that takes the commands"),
    "input": ("demonstrator", "the person: demonstrator (skeleton_source + angle_extractor), skeleton (angle_extractor "
              "only: your tracker publishes <namespace>/skeleton), hri (hri_bodies: a ROS4HRI body tracker)"),
}
#: input -> the person's nodes (executable, overrides)
INPUTS = {"demonstrator": (("angle_extractor", {}), ("skeleton_source", {"wait_for_subscribers": 2})),
          "skeleton": (("angle_extractor", {}),), "hri": (("hri_bodies", {}),)}
#: output -> (the simulated Nao runs, the compensator's topics that go to the real robot)
OUTPUTS = {"joint_state": (True, ()), "both": (True, ("trajectory",)),
           "naoqi": (False, ("joint_states", "joint_angles")),
           "joint_trajectory": (False, ("joint_states", "trajectory"))}


class LaunchArgumentError(GwrPredictorError, ValueError):
    """A launch argument that cannot be used; the message names it."""


def _true(text: str) -> bool:
    return text.strip().lower() in ("true", "1", "yes")


def pipeline_namespace(pushed: str | None, argument: str) -> str:
    """The absolute namespace of the pipeline: `argument` inside the pushed one (an absolute `argument` wins)."""
    outer = "" if argument.startswith("/") else (pushed or "")
    parts = [p for ns in (outer, argument) for p in ns.split("/") if p]
    return "/" + "/".join(parts)


def robot_output(arg: dict, namespace: str) -> tuple[bool, dict, list[tuple[str, str]], str]:
    """(nao_sim drives the compensated robot, the compensator's overrides, its remaps to the real robot, the
    namespace of the TF tree: the pipeline's with nao_sim, else the robot driver's)."""
    output = arg["output"].strip()
    if output not in OUTPUTS:
        raise LaunchArgumentError(f"launch argument output:={output!r}: expected one of {sorted(OUTPUTS)}")
    simulated, real = OUTPUTS[output]
    robot = pipeline_namespace(None, "/" + arg["robot_namespace"].strip("/"))
    topics = {"joint_states": "joint_states", "joint_angles": "joint_angles",
              "trajectory": f"{arg['controller'].strip('/')}/joint_trajectory"}
    relative = {"joint_states": "joint_states", "joint_angles": "joint_angles",
                "trajectory": TRAJECTORY_TOPIC}
    remaps = [(relative[key], in_namespace(robot, topics[key])) for key in real]
    overrides = {} if output == "joint_state" else {"output": output}  # joint_state: delay_compensator.yaml's
    return simulated, overrides, remaps, namespace if simulated else robot


def tf_nodes(arg: dict, share: str, namespace: str, sim: dict, baseline: bool, simulated: bool = True,
             tree: str | None = None) -> list:
    """The tf2 nodes of `tf_plan` (a robot_state_publisher per simulated robot, the static transforms) and RViz;
    every TF topic in the namespace `tree` (the pipeline's by default; a real robot's driver's, so the camera
    and the uncompensated robot hang off the real robot's frames)."""
    tree = namespace if tree is None else tree
    with open(os.path.join(share, "urdf", "nao.urdf"), encoding="utf-8") as f:
        urdf = f.read()
    try:
        plan = tf_plan.tf_nodes(urdf, namespace, baseline=baseline, simulated=simulated, tree=tree,
                                camera_pose=arg["camera_pose"], uncompensated_pose=arg["uncompensated_pose"])
    except GwrPredictorError as exc:
        raise LaunchArgumentError(f"launch argument {exc}") from None
    nodes = [Node(package=n.package, executable=n.executable, name=n.name, namespace=n.namespace,
                  remappings=list(n.remaps), parameters=[{**sim, **n.parameters}], arguments=list(n.arguments),
                  output="screen") for n in plan]
    if _true(arg["rviz"]):
        nodes.append(Node(package="rviz2", executable="rviz2", name="rviz2", namespace=namespace,
                          arguments=["-d", os.path.join(share, "rviz", "pipeline.rviz")],
                          remappings=list(tf_plan.tf_remaps(tree)), parameters=[sim], output="screen"))
    return nodes


def pipeline_nodes(context, *_args, **_kwargs) -> list:
    """The nodes, built from the resolved launch arguments (so plain Python decides, as the script does)."""
    arg = context.launch_configurations
    out = os.path.abspath(arg["out"])
    share = get_package_share_directory(PACKAGE)
    params_dir = arg["params_dir"] or os.path.join(share, "config")
    scenario = [arg["scenario"]] if arg["scenario"] else []
    sim = {"use_sim_time": _true(arg["use_sim_time"])}
    namespace = pipeline_namespace(arg.get("ros_namespace"), arg["namespace"])
    baseline = _true(arg["baseline"])
    simulated, output, robot_remaps, tree = robot_output(arg, namespace)
    os.makedirs(out, exist_ok=True)
    if os.path.exists(os.path.join(out, "bag")):
        raise LaunchArgumentError(f"launch argument out:={arg['out']!r}: {out}/bag exists already; choose another "
                                  "out:=")
    if arg["checkpoint"]:
        shutil.copyfile(arg["checkpoint"], os.path.join(out, "model.npz"))

    def node(executable: str, name: str | None = None, node_namespace: str = namespace, remappings=(),
             **overrides) -> Node:
        params = [os.path.join(params_dir, f"{executable}.yaml"), *scenario, {**sim, **overrides}]
        return Node(package=PACKAGE, executable=executable, name=name or executable, namespace=node_namespace,
                    parameters=params, remappings=list(remappings), output="screen")

    nodes = [node("bag_recorder", path=os.path.join(out, "bag"))]
    frames = {"render_dir": os.path.join(out, "frames")} if _true(arg["render"]) else {}
    nodes += [node("nao_sim", **frames)] if simulated else []
    nodes += [node("delay_compensator", remappings=robot_remaps, **output)]
    if baseline:
        # the uncompensated pair reads the pipeline's shared topics, not its own namespace's
        uncompensated = in_namespace(namespace, BASELINE_NAMESPACE)
        shared = [(topic, in_namespace(namespace, topic)) for topic in ("arm_angles", "predictions")]
        nodes += [node("nao_sim", node_namespace=uncompensated, remappings=shared),
                  node("delay_compensator", node_namespace=uncompensated, remappings=shared, mode="none")]
    learner = {"checkpoint": os.path.join(out, "model.npz")}
    if arg["predictor"]:
        learner["predictor"] = arg["predictor"]
    person = arg["input"].strip()
    if person not in INPUTS:
        raise LaunchArgumentError(f"launch argument input:={person!r}: expected one of {sorted(INPUTS)}")
    nodes += [node("arm_predictor", **learner)] + [node(executable, **extra) for executable, extra in INPUTS[person]]
    if _true(arg["tf"]):
        nodes += tf_nodes(arg, share, namespace, sim, baseline, simulated, tree)
    return nodes


def generate_launch_description() -> LaunchDescription:
    return LaunchDescription([
        *(DeclareLaunchArgument(name, default_value=default, description=text)
          for name, (default, text) in ARGUMENTS.items()),
        OpaqueFunction(function=pipeline_nodes),
    ])
