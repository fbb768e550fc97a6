"""hri_bodies: a ROS4HRI (REP-155) body tracker -> the 8 Nao arm angles as JointState on `arm_angles`.

Follows the bodies a tracker such as hri_fullbody lists on `/humans/bodies/tracked` (hri_msgs/IdsList),
picks one (`body_id`, or `selection`: the first tracked, or the nearest by its
`/humans/bodies/<id>/position`), subscribes to its `/humans/bodies/<id>/joint_states` (the human
kinematic model) and publishes what the angle_extractor publishes: the 8 Nao arm angles, median of
every 3 frames by default, clipped into the Nao limits, stamped with the tracker's stamp. The mapping
and its checks are library code (`gwr_predictor.data.hri_bodies`, docs/real_robot.md).

hri_msgs is imported when the node starts; without it (it has no wheel) the node reads the tracked
ids from the ROS graph instead: every `<bodies_namespace>/<id>/joint_states` topic with a publisher.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from geometry_msgs.msg import PointStamped

from gwr_predictor.data import hri_bodies
from gwr_predictor.data.errors import DataError
from gwr_predictor.data.smoothing import MedianOf3
from gwr_predictor.parameters.spec import ParameterError, ParamSpec
from gwr_predictor.pipeline import conventions
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.robot.nao import ARM_JOINTS

from . import messages
from .pipeline_node import PipelineNode
from .qos import status_qos, stream_qos
from .runner import run_node

PARAMS = (
    ParamSpec("body_id", "", "follow only this body (its joint_states are subscribed at once, no tracked list "
              "needed); empty: choose among the tracked bodies by 'selection'"),
    ParamSpec("selection", "first", "first: keep the followed body while it is tracked, else the first tracked; "
              "nearest: the body nearest to the camera by its <id>/position (PointStamped)",
              choices=hri_bodies.SELECTIONS),
    ParamSpec("switch_margin_m", 0.2, "nearest: another body takes over only if it is nearer by more than this (m)",
              0.0, 100.0),
    ParamSpec("bodies_namespace", hri_bodies.BODIES_NAMESPACE, "namespace of the REP-155 body topics (absolute, as "
              "the trackers publish them)"),
    ParamSpec("discovery_period_s", 1.0, "without hri_msgs: how often the tracked ids are read from the ROS graph (s)",
              0.05, 60.0),
    ParamSpec("median_of_3", True, "publish the median of every 3 frames (30 fps -> 10 fps, as the angle_extractor); "
              "false for a tracker that runs at about 10 fps"),
    ParamSpec("max_gap_s", conventions.MAX_GAP_S,
              "a stamp gap larger than this starts a new sequence (the smoothing group restarts)", 0.0, 3600.0),
    ParamSpec("input_reliability", "reliable", "QoS of the joint_states subscription; best_effort also matches "
              "trackers that publish best-effort", choices=("reliable", "best_effort")),
    ParamSpec("camera_frame", "", "nearest: the frame of the bodies' positions (the camera's); positions in another "
              "frame are rejected; empty: the frame of the first position received"),
)


class HriBodiesNode(PipelineNode):
    NODE_NAME = "hri_bodies"

    def __init__(self) -> None:
        super().__init__(self.NODE_NAME, PARAMS)
        p = self.params
        if p["body_id"] and not hri_bodies.valid_body_id(p["body_id"]):
            raise ParameterError(f"parameter 'body_id' = {p['body_id']!r}: letters, digits and _ only (a topic name)")
        self.namespace = p["bodies_namespace"]
        self.qos = stream_qos(reliable=p["input_reliability"] == "reliable")
        self.smoother = MedianOf3()
        self.stamps = self.stamp_check()
        self.current: str | None = None
        self.joint_states_sub: Any = None
        self.position_subs: dict[str, Any] = {}
        self.distances: dict[str, float] = {}
        self.position_frame: str = p["camera_frame"]
        self.angles_pub = self.create_publisher(messages.JointState, conventions.TOPIC_ANGLES, stream_qos())
        if p["body_id"]:
            self.follow(p["body_id"])
        elif (ids_type := self.ids_list_type()) is not None:
            self.create_subscription(ids_type, f"{self.namespace.rstrip('/')}/{hri_bodies.TRACKED_TOPIC}",
                                     lambda msg: self.on_tracked(list(msg.ids)), status_qos())
        else:
            self.get_logger().info(f"{hri_bodies.IDS_LIST_TYPE} is not installed: the tracked bodies are read from "
                                   f"the ROS graph ({self.namespace}/<id>/joint_states topics with a publisher)")
            self.create_timer(p["discovery_period_s"], self.discover)

    @staticmethod
    def ids_list_type() -> type | None:
        """hri_msgs/IdsList if installed (the one optional import of this node), else None."""
        try:
            return messages.message_class(hri_bodies.IDS_LIST_TYPE)
        except PipelineError:
            return None

    def discover(self) -> None:
        """The tracked list from the graph: joint_states topics below the namespace that have a publisher."""
        topics = [name for name, types in self.get_topic_names_and_types()
                  if "sensor_msgs/msg/JointState" in types and self.count_publishers(name) > 0]
        self.on_tracked(hri_bodies.ids_from_topics(topics, self.namespace))

    def on_tracked(self, ids: list[str]) -> None:
        """A tracked list: keep positions of the tracked bodies (nearest), then follow the chosen one."""
        invalid = [i for i in ids if not hri_bodies.valid_body_id(i)]
        if invalid:
            self.counters.reject("tracked.invalid_ids", f"body ids {invalid[:3]} cannot name topics; ignored")
        if self.params["selection"] == "nearest":
            self.track_positions([i for i in ids if i not in invalid])
        chosen = hri_bodies.choose_body(ids, self.current, self.params["selection"], self.distances,
                                        self.params["switch_margin_m"])
        if chosen is None:
            self.counters.count("tracked.no_body")
        if chosen != self.current:
            self.follow(chosen)

    def track_positions(self, ids: list[str]) -> None:
        """Subscribe to the position of every tracked body, and drop those no longer tracked."""
        for gone in set(self.position_subs) - set(ids):
            self.destroy_subscription(self.position_subs.pop(gone))
            self.distances.pop(gone, None)
        for body in set(ids) - set(self.position_subs):
            topic = hri_bodies.body_topic(self.namespace, body, hri_bodies.POSITION_TOPIC)
            self.position_subs[body] = self.create_subscription(
                PointStamped, topic, lambda msg, body=body: self.on_position(body, msg), self.qos)

    def on_position(self, body: str, msg: PointStamped) -> None:
        """A body's distance from its position, if in the frame the others are in (distances in different
        frames cannot be compared)."""
        frame = msg.header.frame_id
        if not frame or (self.position_frame and frame != self.position_frame):
            self.counters.reject("position.frame_id", f"body {body}: position in frame {frame[:80]!r}, not in "
                                 f"{self.position_frame or 'a named frame'!r} (parameter camera_frame)")
            return
        self.position_frame = frame
        distance = float(np.linalg.norm([msg.point.x, msg.point.y, msg.point.z]))
        if np.isfinite(distance):
            self.distances[body] = distance
        else:
            self.counters.reject("position.non_finite", f"body {body}: NaN or inf position")

    def follow(self, body: str | None) -> None:
        """Switch the joint_states subscription to `body` (None: follow nobody); the sequence starts over."""
        if self.joint_states_sub is not None:
            self.destroy_subscription(self.joint_states_sub)
            self.joint_states_sub = None
        if self.current is not None:
            self.counters.count("body.switches")
        self.current = body
        self.smoother.reset()
        self.stamps = self.stamp_check()
        if body is None:
            return
        topic = hri_bodies.body_topic(self.namespace, body, hri_bodies.JOINT_STATES_TOPIC)
        self.joint_states_sub = self.create_subscription(
            messages.JointState, topic, lambda msg: self.on_joint_states(body, msg), self.qos)
        self.get_logger().info(f"following body {body} ({topic})")

    def on_joint_states(self, body: str, msg: messages.JointState) -> None:
        """One frame of the followed body: checked, smoothed, mapped to the Nao arm angles, published."""
        if body != self.current:
            return  # queued before a switch
        stamp, names, positions = messages.joint_state_fields(msg)
        try:
            hri_bodies.check_frame(msg.header.frame_id, body)
            human = hri_bodies.body_arm_joints(names, positions, body)
        except DataError as exc:
            self.counters.reject(f"joint_states.{exc.reason}", str(exc))
            return
        previous = self.stamps.last
        if not self.check_stamp(self.stamps, "joint_states", stamp):
            return
        if previous is not None and not 0.0 < stamp - previous <= self.params["max_gap_s"]:
            self.smoother.reset()
            self.counters.count("sequence_gaps")
        self.counters.count("joint_states.accepted")
        smoothed = self.smoother.push(stamp, human) if self.params["median_of_3"] else (stamp, human)
        if smoothed is not None:
            self.publish_angles(*smoothed)

    def publish_angles(self, stamp: float, human: np.ndarray) -> None:
        angles, raw = hri_bodies.body_to_nao(human)
        if np.any(angles != raw):
            self.counters.count("angles.clipped_to_limits")
        self.angles_pub.publish(messages.joint_state(stamp, ARM_JOINTS, angles))
        self.counters.count("angles.published")

    def diagnostic_values(self) -> dict[str, object]:
        """Counters plus the followed body, so that a report shows whom the robot imitates."""
        return {**super().diagnostic_values(), "body": self.current or ""}


def main(args: list[str] | None = None) -> int:
    return run_node(HriBodiesNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
