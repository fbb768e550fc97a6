"""The QoS a bag stores with each topic, as rosbag2 does: the profiles its publishers offered
(`offered_qos_profiles` in metadata.yaml and in the MCAP channel metadata), and the QoS to replay it
with (`replay_qos`), so that `ros2 bag play` and `bag_player` publish as the recorded publishers did.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

from gwr_predictor.pipeline.errors import PipelineError

_INFINITE_NS = 2**63 - 1  # RMW_DURATION_INFINITE


def _qos_time(ns: int) -> QosTime:
    sec, nsec = divmod(min(max(0, int(ns)), _INFINITE_NS), 1_000_000_000)
    return QosTime(sec, nsec)


def qos_profile(*, history: str, depth: int, reliability: str, durability: str, deadline_ns: int = _INFINITE_NS,
                lifespan_ns: int = _INFINITE_NS, liveliness: str = "automatic",
                liveliness_lease_ns: int = _INFINITE_NS, avoid_ros_namespace_conventions: bool = False) -> Qos:
    """One offered QoS profile as stored in a bag, from policy names ('keep_last', 'reliable', ...).

    Policy names are rclpy's enum names in any case, so a node converts with `policy.name`.
    PipelineError names a policy value that ROS 2 does not have.
    """
    def policy(enum: Any, kind: str, value: str) -> Any:
        try:
            return enum[str(value).upper()]
        except KeyError:
            raise PipelineError(f"QoS {kind} {value!r} is not one of {[m.name.lower() for m in enum]}") from None

    return Qos(policy(QosHistory, "history", history), max(0, int(depth)),
               policy(QosReliability, "reliability", reliability), policy(QosDurability, "durability", durability),
               _qos_time(deadline_ns), _qos_time(lifespan_ns), policy(QosLiveliness, "liveliness", liveliness),
               _qos_time(liveliness_lease_ns), bool(avoid_ros_namespace_conventions))


@dataclass(frozen=True)
class ReplayQos:
    """The QoS to publish a recorded topic with: policy names in lower case, depth."""

    reliability: str
    durability: str
    depth: int


def replay_qos(profiles: Iterable[Qos], default_depth: int) -> ReplayQos | None:
    """The publisher QoS that every recorded subscriber can match, as `ros2 bag play` chooses it.

    One profile (or several alike): its reliability and durability. Publishers that differed: the
    weakest offer, reliable only if every publisher was reliable and transient-local only if every
    one was, so that no subscriber that matched one of them is refused. Depth: the recorded one, or
    `default_depth` where DDS did not report it (depth 0). None without profiles (old bags): the
    caller keeps its default.
    """
    profiles = list(profiles)
    if not profiles:
        return None
    reliable = all(q.reliability == QosReliability.RELIABLE for q in profiles)
    transient = all(q.durability == QosDurability.TRANSIENT_LOCAL for q in profiles)
    depth = max(q.depth for q in profiles) or default_depth
    return ReplayQos("reliable" if reliable else "best_effort", "transient_local" if transient else "volatile",
                     depth)
