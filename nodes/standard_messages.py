"""Standard ROS messages that viewers, controllers and other packages expect: MarkerArray, JointTrajectory,
PoseArray, robot_description.

Like `messages`, the only place that builds or reads these types; the geometry and the timing
come from the library (`gwr_predictor.pipeline.markers`, `.trajectory`, `gwr_predictor.data.k4abt`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point, Pose, PoseArray
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import ColorRGBA, String
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
from visualization_msgs.msg import Marker, MarkerArray

from gwr_predictor.pipeline import conventions
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.markers import Figure
from gwr_predictor.pipeline.trajectory import Trajectory

from .messages import from_time, to_time

__all__ = ["JointTrajectory", "Marker", "MarkerArray", "PoseArray", "String"]


def to_duration(seconds: float) -> Duration:
    """Seconds (finite, >= 0) -> builtin_interfaces/Duration."""
    if not math.isfinite(seconds) or seconds < 0.0:
        raise PipelineError(f"duration must be finite and >= 0, got {seconds}")
    stamp = to_time(seconds)
    return Duration(sec=stamp.sec, nanosec=stamp.nanosec)


def from_duration(d: Duration) -> float:
    """builtin_interfaces/Duration -> seconds (the same fields as a Time)."""
    return conventions.stamp_seconds(d)


# --- markers -----------------------------------------------------------------------------------


def _points(xyz: np.ndarray) -> list[Point]:
    return [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in np.asarray(xyz, dtype=np.float64)]


def _marker(stamp: float, frame_id: str, ns: str, marker_id: int, kind: int, xyz: np.ndarray,
            size: float, rgba: tuple[float, float, float, float], lifetime_s: float) -> Marker:
    m = Marker()
    m.header.stamp = to_time(stamp)
    m.header.frame_id = frame_id
    m.ns, m.id, m.type, m.action = ns, marker_id, kind, Marker.ADD
    m.pose.orientation.w = 1.0
    m.scale.x = m.scale.y = m.scale.z = size
    m.color = ColorRGBA(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])
    m.lifetime = to_duration(lifetime_s)
    m.points = _points(xyz)
    return m


def figure_markers(stamp: float, frame_id: str, ns: str, figure: Figure,
                   rgba: tuple[float, float, float, float], lifetime_s: float = 0.5,
                   joint_size: float = 0.05, line_width: float = 0.02) -> MarkerArray:
    """A figure as two markers of namespace `ns`: the joints (SPHERE_LIST, id 0) and the segments
    (LINE_LIST, id 1), stamped `stamp` in `frame_id`. The lifetime clears them when the input stops."""
    return MarkerArray(markers=[
        _marker(stamp, frame_id, ns, 0, Marker.SPHERE_LIST, figure.points, joint_size, rgba, lifetime_s),
        _marker(stamp, frame_id, ns, 1, Marker.LINE_LIST, figure.segments, line_width, rgba, lifetime_s),
    ])


def read_body_markers(msg: MarkerArray) -> tuple[float | None, str, np.ndarray, np.ndarray]:
    """A body-tracking MarkerArray -> (stamp of its first joint marker or None, its frame, ids (n,),
    positions (n, 3)). Only ADD markers count: DELETE / DELETEALL markers carry no joint. More than
    `conventions.MAX_MARKERS` markers raise PipelineError (reason `too_large`) before any is read."""
    conventions.check_size("markers", len(msg.markers), conventions.MAX_MARKERS)
    adds = [m for m in msg.markers if m.action == Marker.ADD]
    if not adds:
        return None, "", np.zeros(0, dtype=np.int64), np.zeros((0, 3))
    ids = np.fromiter((m.id for m in adds), dtype=np.int64, count=len(adds))
    xyz = np.array([(m.pose.position.x, m.pose.position.y, m.pose.position.z) for m in adds], dtype=np.float64)
    return from_time(adds[0].header.stamp), adds[0].header.frame_id, ids, xyz


def body_markers(stamp: float, frame_id: str, ids: Sequence[int], positions: np.ndarray,
                 lifetime_s: float = 0.25) -> MarkerArray:
    """What the Azure Kinect driver publishes: one SPHERE per joint, id = body * 100 + joint (tests, tools)."""
    markers = []
    for marker_id, (x, y, z) in zip(ids, np.asarray(positions, dtype=np.float64), strict=True):
        m = _marker(stamp, frame_id, "", int(marker_id), Marker.SPHERE, np.zeros((0, 3)), 0.05,
                    (0.2, 0.6, 1.0, 1.0), lifetime_s)
        m.pose.position.x, m.pose.position.y, m.pose.position.z = float(x), float(y), float(z)
        markers.append(m)
    return MarkerArray(markers=markers)


# --- skeleton poses -----------------------------------------------------------------------------


def pose_array(stamp: float, frame_id: str, positions: np.ndarray) -> PoseArray:
    """A skeleton frame (joints x 3) -> PoseArray with the capture stamp in its header, so that
    header-reading tools can use it: one pose per joint in the array's order, identity orientation
    (a tracker gives no joint orientation), NaN position for an untracked joint."""
    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise PipelineError(f"skeleton positions must be (joints, 3), got {positions.shape}")
    msg = PoseArray()
    msg.header.stamp = to_time(stamp)
    msg.header.frame_id = frame_id
    poses = []
    for x, y, z in positions.tolist():
        pose = Pose()
        pose.position.x, pose.position.y, pose.position.z = x, y, z
        poses.append(pose)  # Pose() starts with the identity quaternion (w = 1)
    msg.poses = poses
    return msg


def read_pose_array(msg: PoseArray) -> tuple[float, str, np.ndarray]:
    """PoseArray -> (stamp s, frame_id, positions (n, 3)); more than `conventions.MAX_JOINTS` poses raise
    PipelineError (reason `too_large`) before any is read."""
    conventions.check_size("poses", len(msg.poses), conventions.MAX_JOINTS)
    xyz = np.array([(p.position.x, p.position.y, p.position.z) for p in msg.poses], dtype=np.float64)
    return from_time(msg.header.stamp), msg.header.frame_id, xyz.reshape(-1, 3)


# --- trajectories ------------------------------------------------------------------------------


def joint_trajectory(stamp: float, names: Sequence[str], trajectory: Trajectory) -> JointTrajectory:
    """A library trajectory -> trajectory_msgs/JointTrajectory (positions only; stamp 0 = start on arrival)."""
    if trajectory.positions.shape[1] != len(names):
        raise PipelineError(f"{len(names)} joint names but trajectory points of {trajectory.positions.shape[1]}")
    msg = JointTrajectory()
    msg.header.stamp = to_time(stamp)
    msg.joint_names = list(names)
    msg.points = [JointTrajectoryPoint(positions=[float(v) for v in row], time_from_start=to_duration(float(t)))
                  for t, row in zip(trajectory.times_from_start, trajectory.positions, strict=True)]
    return msg


def read_joint_trajectory(msg: JointTrajectory) -> tuple[float, tuple[str, ...], Trajectory]:
    """JointTrajectory -> (stamp s, names, Trajectory); points whose size differs raise PipelineError."""
    names = tuple(msg.joint_names)
    rows = [np.asarray(p.positions, dtype=np.float64) for p in msg.points]
    if any(r.size != len(names) for r in rows):
        raise PipelineError(f"trajectory points must have {len(names)} positions")
    times = np.array([from_duration(p.time_from_start) for p in msg.points])
    positions = np.stack(rows) if rows else np.zeros((0, len(names)))
    return from_time(msg.header.stamp), names, Trajectory(times, positions)


# --- robot_description ---------------------------------------------------------------------------


def latched_qos() -> QoSProfile:
    """robot_state_publisher's QoS for robot_description: reliable, transient-local, depth 1, so a viewer
    (or a bag recorder) that starts later still receives the one message."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)
