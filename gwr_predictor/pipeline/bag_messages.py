"""The messages a bag holds, as `rosbags` objects: the ROS 2 Jazzy type store, the types the pipeline
records, builders and converters of JointState and labelled Float64MultiArray, CDR (de)serialisation.
Every bag module raises `PipelineError`.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_typestore

from gwr_predictor.pipeline import conventions
from gwr_predictor.pipeline.conventions import ArrayDim, PackedArray
from gwr_predictor.pipeline.errors import PipelineError

JOINT_STATE = "sensor_msgs/msg/JointState"
FLOAT64_MULTIARRAY = "std_msgs/msg/Float64MultiArray"
DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
#: The ROS 2 Jazzy message definitions (sensor_msgs, std_msgs, diagnostic_msgs, ...).
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)


def time_msg(seconds: float) -> Any:
    """Seconds -> a rosbags builtin_interfaces/Time (`conventions.split_stamp`)."""
    sec, nanosec = conventions.split_stamp(seconds)
    return TYPESTORE.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)


stamp_seconds = conventions.stamp_seconds


def joint_state_msg(names: Iterable[str], positions: np.ndarray, stamp: float, *,
                    velocities: np.ndarray | None = None, frame_id: str = "") -> Any:
    """A rosbags sensor_msgs/JointState (names, positions in rad, header stamp in seconds)."""
    names = list(names)
    pos = np.ascontiguousarray(positions, dtype=np.float64).ravel()
    if pos.size != len(names):
        raise PipelineError(f"JointState needs one position per name: {len(names)} names, {pos.size} positions")
    vel = np.empty(0) if velocities is None else np.ascontiguousarray(velocities, dtype=np.float64).ravel()
    t = TYPESTORE.types
    header = t["std_msgs/msg/Header"](stamp=time_msg(stamp), frame_id=frame_id)
    return t[JOINT_STATE](header=header, name=names, position=pos, velocity=vel, effort=np.empty(0))


def joint_state_arrays(msg: Any) -> tuple[float, tuple[str, ...], np.ndarray]:
    """JointState -> (stamp seconds, names, positions)."""
    return stamp_seconds(msg.header.stamp), tuple(msg.name), np.asarray(msg.position, dtype=float)


def multiarray_msg(packed: PackedArray) -> Any:
    """conventions.PackedArray -> rosbags std_msgs/Float64MultiArray."""
    t = TYPESTORE.types
    dims = [t["std_msgs/msg/MultiArrayDimension"](label=d.label, size=d.size, stride=d.stride) for d in packed.dims]
    layout = t["std_msgs/msg/MultiArrayLayout"](dim=dims, data_offset=packed.data_offset)
    return t[FLOAT64_MULTIARRAY](layout=layout, data=np.ascontiguousarray(packed.data, dtype=np.float64))


def packed_array(msg: Any) -> PackedArray:
    """Float64MultiArray -> conventions.PackedArray (unpack with conventions.unpack_*)."""
    dims = tuple(ArrayDim(d.label, int(d.size), int(d.stride)) for d in msg.layout.dim)
    return PackedArray(dims, int(msg.layout.data_offset), np.asarray(msg.data, dtype=float))


def serialize(msg: Any, msgtype: str | None = None) -> bytes:
    """CDR bytes of a rosbags message object (what DDS would carry)."""
    return bytes(TYPESTORE.serialize_cdr(msg, msgtype or msg.__msgtype__))


def deserialize(raw: bytes, msgtype: str) -> Any:
    return TYPESTORE.deserialize_cdr(raw, msgtype)
