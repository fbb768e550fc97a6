"""The TF of a pipeline: which tf2 nodes let RViz draw the robots and the person, for the launch file and the scripts.

tf2_msgs has no PyPI wheel, so the package's own nodes cannot publish TF; robot_state_publisher and tf2_ros's
static_transform_publisher do, where a ROS 2 install provides them. One plan, two users:
launch/pipeline.launch.py turns each `TfNode` into a launch_ros Node, and `scripts/run_pipeline.sh --tf`
starts them with `ros2 run` (`python -m gwr_predictor.pipeline.tf_plan`, which writes their parameter files).

The plan: a robot_state_publisher next to each simulated Nao (it reads that robot's `joint_states`), the
uncompensated one with frame prefix `uncompensated/`; static transforms torso -> skeleton_camera (the
camera) and torso -> uncompensated/torso (the second robot beside the first). Every TF topic goes to the
namespace `tree`: the pipeline's own, so pipelines in different namespaces keep separate trees, or, with a
real robot, its driver's, so the camera and the simulated baseline hang off the real robot's frames.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.markers import ROBOT_FRAME
from gwr_predictor.pipeline.markers import SKELETON_FRAME as CAMERA_FRAME
from gwr_predictor.robot.urdf import default_urdf_path

#: the uncompensated pair's namespace, inside the pipeline's; its TF frames carry this prefix
BASELINE_NAMESPACE = "uncompensated"
BASELINE_FRAME_PREFIX = f"{BASELINE_NAMESPACE}/"
#: the skeleton camera above the robot looking forward: camera z (into the scene) along the robot's x, camera
#: y (up) along its z, 1 m above the floor (the demonstrator's sensor height; the Nao's torso is 0.333 m
#: above its soles), so the person stands on the robot's floor, 2-2.4 m in front of it, facing it
CAMERA_POSE = "0 0 0.667 1.5708 0 1.5708"
#: the uncompensated robot stands 0.5 m to the compensated robot's right
UNCOMPENSATED_POSE = "0 -0.5 0 0 0 0"
POSE_KEYS = ("--x", "--y", "--z", "--roll", "--pitch", "--yaw")


@dataclass(frozen=True)
class TfNode:
    """One tf2 node as launch_ros's Node takes it (plus a label unique in a pipeline, for logs and files)."""

    label: str
    package: str
    executable: str
    name: str
    namespace: str
    remaps: tuple[tuple[str, str], ...]
    parameters: dict[str, Any] = field(default_factory=dict)
    arguments: tuple[str, ...] = ()


def in_namespace(namespace: str, name: str) -> str:
    """`name` resolved in the absolute `namespace` (the root included)."""
    return f"{namespace.rstrip('/')}/{name}"


def tf_remaps(tree: str) -> tuple[tuple[str, str], ...]:
    return ("/tf", in_namespace(tree, "tf")), ("/tf_static", in_namespace(tree, "tf_static"))


def pose_arguments(name: str, text: str) -> list[str]:
    """'x y z roll pitch yaw' -> static_transform_publisher's --x ... --yaw arguments; PipelineError naming `name`."""
    values = text.split()
    try:
        numbers = [float(v) for v in values]
    except ValueError:
        numbers = []
    if len(numbers) != len(POSE_KEYS):
        raise PipelineError(f"{name}:={text!r}: expected 6 numbers 'x y z roll pitch yaw'")
    return [item for key, value in zip(POSE_KEYS, values, strict=True) for item in (key, value)]


def tf_nodes(urdf: str, namespace: str, *, baseline: bool = True, simulated: bool = True, tree: str | None = None,
             camera_pose: str = CAMERA_POSE, uncompensated_pose: str = UNCOMPENSATED_POSE) -> list[TfNode]:
    """The tf2 nodes of the pipeline in `namespace` (see the module docstring); `simulated` False: the
    compensated robot is a real one whose driver publishes its TF (no state publisher for it); an empty
    `camera_pose`: no camera transform (a camera driver publishes it)."""
    tree = namespace if tree is None else tree
    remaps = tf_remaps(tree)

    def state_publisher(label: str, robot_namespace: str, prefix: str) -> TfNode:
        return TfNode(label, "robot_state_publisher", "robot_state_publisher", "robot_state_publisher",
                      robot_namespace, remaps, {"robot_description": urdf, "frame_prefix": prefix})

    def static_transform(name: str, pose: str, parent: str, child: str) -> TfNode:
        return TfNode(name, "tf2_ros", "static_transform_publisher", name, namespace, remaps,
                      arguments=(*pose_arguments(name, pose), "--frame-id", parent, "--child-frame-id", child))

    nodes = [state_publisher("robot_state_publisher", namespace, "")] if simulated else []
    if camera_pose.strip():
        nodes.append(static_transform("camera_pose", camera_pose, ROBOT_FRAME, CAMERA_FRAME))
    if baseline:
        nodes += [state_publisher("robot_state_publisher_uncompensated", in_namespace(namespace, BASELINE_NAMESPACE),
                                  BASELINE_FRAME_PREFIX),
                  static_transform("uncompensated_pose", uncompensated_pose, ROBOT_FRAME,
                                   BASELINE_FRAME_PREFIX + ROBOT_FRAME)]
    return nodes


def ros2_run(node: TfNode, params_file: Path | None) -> list[str]:
    """The `ros2 run` command line of `node` (its parameters in `params_file`)."""
    argv = ["ros2", "run", node.package, node.executable, *node.arguments, "--ros-args",
            "-r", f"__node:={node.name}", "-r", f"__ns:={node.namespace}"]
    for src, dst in node.remaps:
        argv += ["-r", f"{src}:={dst}"]
    if params_file is not None:
        argv += ["--params-file", str(params_file)]
    return argv


def write_commands(nodes: list[TfNode], folder: Path) -> list[str]:
    """One line per node, `label command...` (shell-quoted), its parameter file written into `folder`."""
    folder.mkdir(parents=True, exist_ok=True)
    lines = []
    for node in nodes:
        params = None
        if node.parameters:
            params = folder / f"{node.label}.yaml"
            params.write_text(yaml.safe_dump({"/**": {"ros__parameters": node.parameters}}), encoding="utf-8")
        lines.append(f"{node.label} {shlex.join(ros2_run(node, params))}")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gwr_predictor.pipeline.tf_plan",
                                     description="the ros2 run commands of a pipeline's TF nodes")
    parser.add_argument("--namespace", default="/")
    parser.add_argument("--out", type=Path, required=True, help="folder for the nodes' parameter files")
    parser.add_argument("--no-baseline", action="store_true")
    args = parser.parse_args(argv)
    try:
        urdf = Path(default_urdf_path()).read_text(encoding="utf-8")
        nodes = tf_nodes(urdf, "/" + args.namespace.strip("/"), baseline=not args.no_baseline)
        print("\n".join(write_commands(nodes, args.out)))
    except (OSError, GwrPredictorError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
