"""The only place that builds or reads ROS messages: msg <-> conventions / numpy.

Nodes convert a message here, hand plain numpy to the library and convert the answer back, so
the layouts defined in `gwr_predictor.pipeline.conventions` are applied in exactly one spot.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping, Sequence

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from gwr_predictor.pipeline import conventions
from gwr_predictor.pipeline.conventions import ArrayDim, PackedArray
from gwr_predictor.pipeline.errors import PipelineError

# --- time ------------------------------------------------------------------------------------


def to_time(seconds: float) -> Time:
    """Seconds (float) -> builtin_interfaces/Time (`conventions.split_stamp`)."""
    sec, nanosec = conventions.split_stamp(seconds)
    return Time(sec=sec, nanosec=nanosec)


from_time = conventions.stamp_seconds  # builtin_interfaces/Time -> seconds (float)


def clock_msg(nanoseconds: int) -> Clock:
    """rosgraph_msgs/Clock at `nanoseconds` (exact: no float on the way)."""
    sec, nanosec = divmod(int(nanoseconds), 1_000_000_000)
    return Clock(clock=Time(sec=sec, nanosec=nanosec))


# --- labelled Float64MultiArray ----------------------------------------------------------------


def to_multiarray(packed: PackedArray) -> Float64MultiArray:
    """conventions.PackedArray -> Float64MultiArray (the layout's dims, offset and data)."""
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label=d.label, size=d.size, stride=d.stride) for d in packed.dims]
    msg.layout.data_offset = int(packed.data_offset)
    msg.data = np.ascontiguousarray(packed.data, dtype=np.float64)
    return msg


def from_multiarray(msg: Float64MultiArray) -> PackedArray:
    """Float64MultiArray -> conventions.PackedArray (no checks: the unpack functions check)."""
    dims = tuple(ArrayDim(d.label, int(d.size), int(d.stride)) for d in msg.layout.dim)
    return PackedArray(dims, int(msg.layout.data_offset), np.asarray(msg.data, dtype=np.float64))


def skeleton_msg(stamp: float, positions: np.ndarray,
                 names: tuple[str, ...] = conventions.SKELETON_JOINTS) -> Float64MultiArray:
    """One skeleton frame (joints x 3) -> the labelled skeleton array."""
    return to_multiarray(conventions.pack_skeleton(stamp, positions, names))


def read_skeleton(msg: Float64MultiArray) -> tuple[float, tuple[str, ...], np.ndarray]:
    """Skeleton array -> (stamp, joint names, positions joints x 3). Raises PipelineError."""
    return conventions.unpack_skeleton(from_multiarray(msg))


def predictions_msg(stamp: float, predictions: np.ndarray,
                    names: tuple[str, ...] = conventions.ARM_JOINTS) -> Float64MultiArray:
    """Predictions (horizon x joints) made at frame `stamp` -> the labelled prediction array."""
    return to_multiarray(conventions.pack_predictions(stamp, predictions, names))


def read_predictions(msg: Float64MultiArray) -> tuple[float, tuple[str, ...], np.ndarray]:
    """Prediction array -> (stamp, joint names, predictions horizon x joints). Raises PipelineError."""
    return conventions.unpack_predictions(from_multiarray(msg))


def interval_msg(stamp: float, lower: np.ndarray, upper: np.ndarray, nominal: float,
                 names: tuple[str, ...] = conventions.ARM_JOINTS) -> Float64MultiArray:
    """The interval stated with the predictions made at frame `stamp` -> the labelled interval array."""
    return to_multiarray(conventions.pack_interval(stamp, lower, upper, nominal, names))


def read_interval(msg: Float64MultiArray) -> tuple[float, tuple[str, ...], float, np.ndarray, np.ndarray]:
    """Interval array -> (stamp, joint names, stated share, lower, upper). Raises PipelineError."""
    return conventions.unpack_interval(from_multiarray(msg))


# --- JointState --------------------------------------------------------------------------------


def joint_state(stamp: float, names: Sequence[str], positions: np.ndarray, frame_id: str = "") -> JointState:
    """Names + positions (rad) -> JointState stamped `stamp` (seconds)."""
    positions = np.asarray(positions, dtype=np.float64).ravel()
    if positions.size != len(names):
        raise PipelineError(f"{len(names)} joint names but {positions.size} positions")
    msg = JointState()
    msg.header.stamp = to_time(stamp)
    msg.header.frame_id = frame_id
    msg.name = list(names)
    msg.position = positions
    return msg


def joint_state_fields(msg: JointState) -> tuple[float, tuple[str, ...], np.ndarray]:
    """JointState -> (stamp s, names, positions), unchecked (an input check checks them: `pipeline.input_rules`)."""
    return from_time(msg.header.stamp), tuple(msg.name), np.asarray(msg.position, dtype=np.float64)


def read_joint_state(msg: JointState) -> tuple[float, tuple[str, ...], np.ndarray]:
    """JointState -> (stamp s, names, positions). Raises PipelineError if names and positions differ in length."""
    names = tuple(msg.name)
    positions = np.asarray(msg.position, dtype=np.float64)
    if positions.size != len(names):
        raise PipelineError(f"{len(names)} joint names but {positions.size} positions")
    return from_time(msg.header.stamp), names, positions


select_joints = conventions.select_joints


# --- diagnostics -------------------------------------------------------------------------------

OK = DiagnosticStatus.OK
WARN = DiagnosticStatus.WARN
ERROR = DiagnosticStatus.ERROR


def diagnostic_status(name: str, values: Mapping[str, object], message: str = "",
                      level: bytes = DiagnosticStatus.OK, hardware_id: str = "") -> DiagnosticStatus:
    """One status with its key/values (values are stringified; floats with 6 significant digits)."""
    def text(v: object) -> str:
        return f"{v:.6g}" if isinstance(v, float) else str(v)

    return DiagnosticStatus(level=level, name=name, message=message, hardware_id=hardware_id,
                            values=[KeyValue(key=str(k), value=text(v)) for k, v in values.items()])


def diagnostic_array(stamp: float, statuses: Sequence[DiagnosticStatus]) -> DiagnosticArray:
    msg = DiagnosticArray()
    msg.header.stamp = to_time(stamp)
    msg.status = list(statuses)
    return msg


def read_diagnostics(msg: DiagnosticArray) -> dict[str, dict[str, str]]:
    """DiagnosticArray -> {status name: {key: value}} (later statuses of the same name win)."""
    return {s.name: {kv.key: kv.value for kv in s.values} for s in msg.status}


def message_class(type_name: str) -> type:
    """'sensor_msgs/msg/JointState' -> the message class (for typed or raw publishers/subscriptions)."""
    package, _, name = type_name.partition("/msg/")
    if not package or not name:
        raise PipelineError(f"message type must look like 'pkg/msg/Type', got {type_name!r}")
    try:
        return getattr(importlib.import_module(f"{package}.msg"), name)
    except (ImportError, AttributeError) as exc:
        raise PipelineError(f"unknown message type {type_name!r}: {exc}") from None
