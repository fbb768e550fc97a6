"""The QoS of every topic the nodes publish or read: chosen once, documented in docs/pipeline.md."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from gwr_predictor.pipeline import conventions


def stream_qos(depth: int = conventions.QOS_DEPTH_STREAM, reliable: bool = True) -> QoSProfile:
    """Data streams (skeleton, angles, predictions, commands, joint states).

    Reliable by default: the learner should see every frame and a replay should reproduce a run;
    keep-last with a queue of about a second absorbs bursts without unbounded memory; volatile,
    because a late joiner has no use for old frames.
    """
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.VOLATILE)


def status_qos() -> QoSProfile:
    """Status topics (diagnostics, learner status): ROS defaults (reliable, keep last 10)."""
    return stream_qos(conventions.QOS_DEPTH_STATUS)
