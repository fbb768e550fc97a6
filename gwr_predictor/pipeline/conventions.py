"""Every message convention of the pipeline in one place: topics, joint names, array layouts.

Nodes and tests import from here, so that a rename happens once. The pipeline flows one way:
skeleton -> angles -> predictor -> predictions -> compensator -> robot.

"Custom arrays" are std_msgs/Float64MultiArray messages whose layout dims are labelled. A
MultiArray has no header, so the stamp of the frame travels in the data itself: the layout's
`data_offset` is 1 and `data[0]` is the stamp in seconds (float64, the source clock). Dim labels
carry the names: the joint dim's label is ``"joint:" + "|".join(names)``. The interval stated with the
predictions of a frame carries its stated share in its first dim's label: ``"interval:0.8"`` (rows lower,
upper), then the horizon and joint dims as the predictions' own.

This module is pure Python/numpy; `gwr_predictor.nodes.messages` turns these into msg objects.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gwr_predictor.joints.arm import ARM_JOINTS
from gwr_predictor.joints.names import MAX_JOINTS as MAX_JOINTS
from gwr_predictor.joints.names import MAX_NAME_CHARS as MAX_NAME_CHARS
from gwr_predictor.joints.skeleton import ANGLE_FPS as ANGLE_FPS
from gwr_predictor.joints.skeleton import SKELETON_FPS as SKELETON_FPS
from gwr_predictor.joints.skeleton import SKELETON_JOINTS as SKELETON_JOINTS
from gwr_predictor.learning.params import DEFAULT_HORIZON as DEFAULT_HORIZON
from gwr_predictor.learning.params import MAX_HORIZON
from gwr_predictor.pipeline.errors import PipelineError

# --- topics (relative names, so a namespace or remapping moves the whole pipeline) -------------
TOPIC_SKELETON = "skeleton"  # Float64MultiArray, skeleton layout, 30 fps
TOPIC_ANGLES = "arm_angles"  # sensor_msgs/JointState, ARM_JOINTS, 10 fps
TOPIC_PREDICTIONS = "predictions"  # Float64MultiArray, prediction layout (horizon x joint)
TOPIC_PREDICTION_INTERVAL = "prediction_interval"  # Float64MultiArray, interval layout (bound x horizon x joint)
TOPIC_PREDICTED_ANGLES = "predicted_angles"  # JointState: the h-step-ahead prediction
TOPIC_COMMAND = "joint_commands"  # JointState: what the robot is told to execute
TOPIC_ROBOT_STATE = "joint_states"  # JointState: what the simulated Nao reports
TOPIC_LEARNER_STATUS = "learner_status"  # diagnostic_msgs/DiagnosticArray, about 1 Hz
TOPIC_DIAGNOSTICS = "diagnostics"  # diagnostic_msgs/DiagnosticArray: rejection counters of all nodes
#: Diagnostics go to the absolute /diagnostics whatever a node's namespace (diagnostic_aggregator listens
#: there); the status name (the node's fully qualified name) tells the namespaces apart.
DIAGNOSTICS_TOPIC = "/" + TOPIC_DIAGNOSTICS
#: /diagnostics key whose value names the node process (host:pid:start ns), so that readers of a
#: recording tell a restarted node, or a second pipeline's node of the same name, from the first.
INSTANCE_KEY = "instance"
# --- standard views and interfaces (RViz, Foxglove, ros2_control, body trackers) ----------------
TOPIC_SKELETON_MARKERS = "skeleton_markers"  # visualization_msgs/MarkerArray: joints + bones, capture stamp
TOPIC_SKELETON_POSES = "skeleton_poses"  # geometry_msgs/PoseArray: the skeleton, SKELETON_JOINTS order, header stamp
TOPIC_PREDICTED_TRAJECTORY = "predicted_trajectory"  # trajectory_msgs/JointTrajectory: t+1..t+h
#: JointTrajectory twins of the interval: its lower and upper bounds at the predicted trajectory's stamp and times
TOPIC_PREDICTED_TRAJECTORY_LOWER = "predicted_trajectory_lower"
TOPIC_PREDICTED_TRAJECTORY_UPPER = "predicted_trajectory_upper"
TOPIC_PREDICTED_ARM_MARKERS = "predicted_arm_markers"  # MarkerArray: the Nao's arms at t+h, frame torso
TOPIC_ROBOT_DESCRIPTION = "robot_description"  # std_msgs/String: the URDF, transient-local
TOPIC_BODY_TRACKING = "body_tracking_data"  # MarkerArray in: Azure Kinect / Orbbec body tracking
#: The compensator's optional command output for ros2_control (relative: remap or namespace it).
TOPIC_TRAJECTORY_COMMAND = "joint_trajectory_controller/joint_trajectory"

#: All pipeline topics with their ROS type names (for recorders and bag checks).
TOPIC_TYPES: dict[str, str] = {
    TOPIC_SKELETON: "std_msgs/msg/Float64MultiArray",
    TOPIC_ANGLES: "sensor_msgs/msg/JointState",
    TOPIC_PREDICTIONS: "std_msgs/msg/Float64MultiArray",
    TOPIC_PREDICTION_INTERVAL: "std_msgs/msg/Float64MultiArray",
    TOPIC_PREDICTED_ANGLES: "sensor_msgs/msg/JointState",
    TOPIC_COMMAND: "sensor_msgs/msg/JointState",
    TOPIC_ROBOT_STATE: "sensor_msgs/msg/JointState",
    TOPIC_LEARNER_STATUS: "diagnostic_msgs/msg/DiagnosticArray",
    TOPIC_DIAGNOSTICS: "diagnostic_msgs/msg/DiagnosticArray",
    TOPIC_SKELETON_MARKERS: "visualization_msgs/msg/MarkerArray",
    TOPIC_SKELETON_POSES: "geometry_msgs/msg/PoseArray",
    TOPIC_PREDICTED_TRAJECTORY: "trajectory_msgs/msg/JointTrajectory",
    TOPIC_PREDICTED_TRAJECTORY_LOWER: "trajectory_msgs/msg/JointTrajectory",
    TOPIC_PREDICTED_TRAJECTORY_UPPER: "trajectory_msgs/msg/JointTrajectory",
    TOPIC_PREDICTED_ARM_MARKERS: "visualization_msgs/msg/MarkerArray",
    TOPIC_ROBOT_DESCRIPTION: "std_msgs/msg/String",
}
#: Topics a recorder should subscribe to transient-local (their one message is latched, as
#: robot_state_publisher does with robot_description).
LATCHED_TOPICS = frozenset({TOPIC_ROBOT_DESCRIPTION})
#: Types of topics the pipeline can publish or read but does not by default (for `name@type`-free recording).
OPTIONAL_TOPIC_TYPES: dict[str, str] = {
    "joint_trajectory": "trajectory_msgs/msg/JointTrajectory",
    TOPIC_BODY_TRACKING: "visualization_msgs/msg/MarkerArray",
}

# --- skeleton joints (OpenNI/NITE, 15 joints): SKELETON_JOINTS, SKELETON_FPS, ANGLE_FPS -------
# declared in `gwr_predictor.joints.skeleton`, where the data's sources read them too.

# --- bounds on what a message may make a node allocate (checked where the message is unpacked) ---
# MAX_JOINTS (joint names in one skeleton, prediction or joint state) and MAX_NAME_CHARS (characters in
# one joint name) are declared in `gwr_predictor.joints.names`, where a tracker's joint states meet them too.
#: Markers in one body-tracking MarkerArray (32 joints x 6 bodies is 192).
MAX_MARKERS = 4096
#: MAX_HORIZON (rows of a prediction) comes from the learner's own limit, `learning.params`.

JOINT_DIM_PREFIX = "joint:"
XYZ_LABEL = "xyz"
HORIZON_LABEL = "horizon"
INTERVAL_PREFIX = "interval:"


def check_size(what: str, n: int, limit: int) -> None:
    """PipelineError with reason `too_large` when a message declares more than `limit` of `what`: refused
    before anything is sized by it, and counted apart from other layout errors."""
    if n > limit:
        raise PipelineError(f"{n} {what} exceeds the limit of {limit}", reason="too_large")


def check_joint_names(names: Sequence[str]) -> None:
    """Joint names as a message gives them: at most MAX_JOINTS, none longer than MAX_NAME_CHARS, none
    empty or twice (a joint named twice has no one position). Raises PipelineError (reason `too_large`
    for the bounds)."""
    check_size("joint names", len(names), MAX_JOINTS)
    longest = max(map(len, names), default=0)
    check_size("characters in a joint name", longest, MAX_NAME_CHARS)
    if len(set(names)) != len(names):
        twice = next(n for n, count in Counter(names).items() if count > 1)
        raise PipelineError(f"joint name {twice!r} appears twice")
    if not all(names):
        raise PipelineError("empty joint name")


@dataclass(frozen=True)
class ArrayDim:
    """One MultiArrayDimension as plain data."""

    label: str
    size: int
    stride: int


@dataclass(frozen=True)
class PackedArray:
    """A Float64MultiArray as plain data: dims, data_offset and the flat data."""

    dims: tuple[ArrayDim, ...]
    data_offset: int
    data: np.ndarray


def joint_label(names: tuple[str, ...] | list[str]) -> str:
    return JOINT_DIM_PREFIX + "|".join(names)


def parse_joint_label(label: str) -> tuple[str, ...]:
    """The joint names of a `joint:a|b|...` label, checked by `check_joint_names`."""
    if not label.startswith(JOINT_DIM_PREFIX):
        raise PipelineError(f"joint dim label must start with {JOINT_DIM_PREFIX!r}, got {label[:40]!r}")
    check_size("characters in a joint label", len(label), len(JOINT_DIM_PREFIX) + MAX_JOINTS * (MAX_NAME_CHARS + 1))
    names = tuple(label[len(JOINT_DIM_PREFIX):].split("|"))
    if any(not n for n in names):
        raise PipelineError(f"empty joint name in label {label[:80]!r}")
    check_joint_names(names)
    return names


def pack_skeleton(stamp: float, positions: np.ndarray,
                  names: tuple[str, ...] = SKELETON_JOINTS) -> PackedArray:
    """One skeleton frame (joints x 3, metres, camera frame) -> labelled array with its stamp."""
    positions = np.asarray(positions, dtype=np.float64)
    if positions.shape != (len(names), 3):
        raise PipelineError(f"skeleton positions must be ({len(names)}, 3), got {positions.shape}")
    dims = (ArrayDim(joint_label(names), len(names), 3 * len(names)), ArrayDim(XYZ_LABEL, 3, 3))
    return PackedArray(dims, 1, np.concatenate(([float(stamp)], positions.ravel())))


def unpack_skeleton(packed: PackedArray) -> tuple[float, tuple[str, ...], np.ndarray]:
    """Labelled array -> (stamp, joint names, positions joints x 3). Raises PipelineError."""
    dims = packed.dims
    if len(dims) != 2 or dims[1].label != XYZ_LABEL or dims[1].size != 3:
        raise PipelineError(f"skeleton layout must be [joint:..., xyz(3)], got {[d.label[:20] for d in dims]}")
    names = parse_joint_label(dims[0].label)
    if dims[0].size != len(names):
        raise PipelineError(f"joint dim size {dims[0].size} != {len(names)} names in its label")
    return _unpack(packed, names, 3)


def _unpack(packed: PackedArray, names: tuple[str, ...], width: int) -> tuple[float, tuple[str, ...], np.ndarray]:
    rows = packed.dims[0].size
    data = np.asarray(packed.data, dtype=np.float64)
    expected = packed.data_offset + rows * width
    if packed.data_offset != 1:
        raise PipelineError(f"data_offset must be 1 (the stamp), got {packed.data_offset}")
    if data.size != expected:
        raise PipelineError(f"expected {expected} values (1 stamp + {rows}x{width}), got {data.size}")
    return float(data[0]), names, data[1:].reshape(rows, width)


def pack_predictions(stamp: float, predictions: np.ndarray,
                     names: tuple[str, ...] = ARM_JOINTS) -> PackedArray:
    """Predictions (horizon x joints, rad) for t+1..t+h made at frame `stamp` -> labelled array."""
    predictions = np.asarray(predictions, dtype=np.float64)
    if predictions.ndim != 2 or predictions.shape[1] != len(names):
        raise PipelineError(f"predictions must be (horizon, {len(names)}), got {predictions.shape}")
    h, j = predictions.shape
    dims = (ArrayDim(HORIZON_LABEL, h, h * j), ArrayDim(joint_label(names), j, j))
    return PackedArray(dims, 1, np.concatenate(([float(stamp)], predictions.ravel())))


def unpack_predictions(packed: PackedArray) -> tuple[float, tuple[str, ...], np.ndarray]:
    """Labelled array -> (stamp, joint names, predictions horizon x joints). Raises PipelineError."""
    dims = packed.dims
    if len(dims) != 2 or dims[0].label != HORIZON_LABEL:
        raise PipelineError(f"prediction layout must be [horizon, joint:...], got {[d.label[:20] for d in dims]}")
    stamp, names, rows = _horizon_rows(packed, dims[0], dims[1], 1, "prediction")
    return stamp, names, rows[0]


def _horizon_rows(packed: PackedArray, horizon: ArrayDim, joints: ArrayDim, planes: int, what: str
                  ) -> tuple[float, tuple[str, ...], np.ndarray]:
    """(stamp, joint names, the values as (planes, horizon, joints)) of an array whose last two dims are a
    horizon and labelled joints, after checking both against the data. Raises PipelineError."""
    names = parse_joint_label(joints.label)
    if joints.size != len(names):
        raise PipelineError(f"joint dim size {joints.size} != {len(names)} names in its label")
    h = horizon.size
    check_size(f"{what} rows (horizon)", h, MAX_HORIZON)
    data = np.asarray(packed.data, dtype=np.float64)
    expected = 1 + planes * h * len(names)
    if packed.data_offset != 1 or data.size != expected or h < 1:
        raise PipelineError(f"expected data_offset 1 and {expected} values, got {packed.data_offset} and {data.size}")
    return float(data[0]), names, data[1:].reshape(planes, h, len(names))


def pack_interval(stamp: float, lower: np.ndarray, upper: np.ndarray, nominal: float,
                  names: tuple[str, ...] = ARM_JOINTS) -> PackedArray:
    """The central interval stated with the predictions made at frame `stamp`: its bounds (horizon x joints,
    rad, each) and the share of true angles it should hold -> labelled array [interval:<share>(2), horizon,
    joint:...], rows lower then upper."""
    lower, upper = np.asarray(lower, dtype=np.float64), np.asarray(upper, dtype=np.float64)
    if lower.shape != upper.shape or lower.ndim != 2 or lower.shape[1] != len(names):
        raise PipelineError(f"interval bounds must both be (horizon, {len(names)}), got {lower.shape} and "
                            f"{upper.shape}")
    if not 0.0 < nominal < 1.0:
        raise PipelineError(f"an interval's stated share must be in (0, 1), got {nominal}")
    h, j = lower.shape
    dims = (ArrayDim(f"{INTERVAL_PREFIX}{nominal!r}", 2, 2 * h * j), ArrayDim(HORIZON_LABEL, h, h * j),
            ArrayDim(joint_label(names), j, j))
    return PackedArray(dims, 1, np.concatenate(([float(stamp)], lower.ravel(), upper.ravel())))


def unpack_interval(packed: PackedArray) -> tuple[float, tuple[str, ...], float, np.ndarray, np.ndarray]:
    """Labelled interval array -> (stamp, joint names, stated share, lower, upper (horizon x joints each)).
    Raises PipelineError."""
    dims = packed.dims
    if len(dims) != 3 or not dims[0].label.startswith(INTERVAL_PREFIX) or dims[1].label != HORIZON_LABEL:
        raise PipelineError(f"interval layout must be [interval:<share>, horizon, joint:...], got "
                            f"{[d.label[:20] for d in dims]}")
    try:
        nominal = float(dims[0].label[len(INTERVAL_PREFIX):])
    except ValueError:
        raise PipelineError(f"interval label {dims[0].label[:40]!r} does not state a share") from None
    if not 0.0 < nominal < 1.0 or dims[0].size != 2:
        raise PipelineError(f"an interval has 2 bounds and a share in (0, 1), got {dims[0].size} and {nominal}")
    stamp, names, bounds = _horizon_rows(packed, dims[1], dims[2], 2, "interval")
    return stamp, names, nominal, bounds[0], bounds[1]


# --- pipeline timing and QoS (used by the nodes in gwr_predictor.nodes) --------------------------
#: A stamp gap larger than this ends a sequence: the learner resets its temporal windows.
MAX_GAP_S = 0.5
#: Keep-last queue depths: data streams hold about a second at 30 fps; status topics the ROS default.
QOS_DEPTH_STREAM = 50
QOS_DEPTH_STATUS = 10
#: The bag recorder's subscription queue (raw CDR): several seconds of every stream.
QOS_DEPTH_RECORDER = 500
#: The learner node (learns the person's arm movements and predicts them), and the name it had before: its
#: deprecated executable `gwr_hierarchy` starts it under that name, so that params-file sections, parameter
#: calls and recorded /diagnostics of that name still match (removed in the next release).
LEARNER_NODE = "arm_predictor"
DEPRECATED_LEARNER_NODE = "gwr_hierarchy"
#: Key/value names in the learner status (DiagnosticArray on TOPIC_LEARNER_STATUS).
LEARNER_STATUS_NAME = "learner"  # the status name is "<node>/learner"
NEURON_KEYS = {"gwr1": "neurons.gwr1", "gwr2": "neurons.gwr2", "pgwr": "neurons.pgwr"}


# --- stamps: the one conversion between float seconds and builtin_interfaces/Time fields ---------


def split_stamp(seconds: float) -> tuple[int, int]:
    """Seconds -> (sec, nanosec) of a builtin_interfaces/Time; negative or non-finite stamps are a
    caller bug (PipelineError, a ValueError)."""
    if not math.isfinite(seconds) or seconds < 0.0:
        raise PipelineError(f"stamp must be finite and >= 0, got {seconds}")
    sec = math.floor(seconds)
    nanosec = round((seconds - sec) * 1e9)
    if nanosec >= 1_000_000_000:
        sec, nanosec = sec + 1, nanosec - 1_000_000_000
    return sec, nanosec


def stamp_seconds(stamp: object) -> float:
    """A builtin_interfaces/Time (rclpy's or rosbags', anything with sec and nanosec) -> seconds."""
    return stamp.sec + stamp.nanosec * 1e-9  # type: ignore[attr-defined]


# --- joint selection ---------------------------------------------------------------------------


def select_joints(names: Sequence[str], positions: np.ndarray, wanted: Sequence[str]) -> np.ndarray:
    """Positions of `wanted` in that order, from a message with `names` in any order.

    Raises PipelineError naming the missing joints (reason `missing_joints`) or a duplicated name; extra
    joints are ignored (a full-body JointState carries more than the arms).
    """
    check_joint_names(names)
    index = {name: i for i, name in enumerate(names)}
    missing = [n for n in wanted if n not in index]
    if missing:
        raise PipelineError(f"missing joints {missing}", reason="missing_joints")
    return np.asarray([positions[index[n]] for n in wanted], dtype=np.float64)
