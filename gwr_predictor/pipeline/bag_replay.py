"""What the bag player does to a recorded message, without ROS: topic remaps and moved stamps."""

from __future__ import annotations

import numpy as np

from gwr_predictor.parameters.spec import ParameterError
from gwr_predictor.pipeline.bag_messages import (
    DIAGNOSTIC_ARRAY,
    FLOAT64_MULTIARRAY,
    JOINT_STATE,
    deserialize,
    serialize,
    stamp_seconds,
    time_msg,
)


def parse_remaps(entries: list[str]) -> dict[str, str]:
    """['a:=b', ...] -> {'/a': '/b'}; ParameterError naming a malformed entry."""
    remaps = {}
    for entry in entries:
        src, sep, dst = entry.partition(":=")
        if not sep or not src.strip() or not dst.strip():
            raise ParameterError(f"remap entry {entry!r} must look like 'from:=to'")
        remaps["/" + src.strip().lstrip("/")] = "/" + dst.strip().lstrip("/")
    return remaps


def shift_stamp(raw: bytes, msgtype: str, offset_s: float) -> bytes:
    """The CDR bytes of a message whose stamps are moved by `offset_s` (other types unchanged):
    JointState and DiagnosticArray headers (clamped at 0), the stamp in data[0] of a labelled array.

    Re-encoded with rosbags (exact sizes, so that a recorder can store the result again), not with
    rclpy's serializer, which may append padding that rosbags rejects.
    """
    if msgtype not in (JOINT_STATE, FLOAT64_MULTIARRAY, DIAGNOSTIC_ARRAY):
        return raw
    msg = deserialize(raw, msgtype)
    if msgtype == FLOAT64_MULTIARRAY:
        if msg.layout.data_offset >= 1 and len(msg.data) >= 1:
            data = np.array(msg.data, dtype=np.float64)
            data[0] += offset_s
            msg.data = data
    else:
        msg.header.stamp = time_msg(max(0.0, stamp_seconds(msg.header.stamp) + offset_s))
    return serialize(msg, msgtype)
