"""bag_recorder: records pipeline topics as received (raw CDR) into a rosbag2 MCAP bag.

No rosbag2_py on PyPI, so recording is the package's own job: raw subscriptions hand over the CDR
bytes from the wire, which `gwr_predictor.pipeline.bag_writer.BagWriter` stores unchanged. The bag is flushed
periodically (a crash loses at most one flush period; `bag_recovery.recover_bag` repairs it) and closed
properly on Ctrl-C and SIGTERM. An unwritable path or a full disk stops the node with exit code 1.

Each topic's entry in the bag carries the QoS profiles its publishers offer, read from the ROS
graph when the topic's first message arrives (as rosbag2 records them), so that `ros2 bag play`
and `bag_player` publish with them again.

Discovery is not instant (under load a participant may be found seconds after it started, and a
volatile stream published before that is lost to the recorder): the node logs `matched <topic>` when a
recorded topic's first publisher is matched, so that scripts start the data flow only once the
recorder hears every publisher (`gwr_wait_matched` in scripts/lib.sh).

`record_below` adds topics that appear while recording: every topic below those namespaces (a ROS4HRI
tracker's `/humans/bodies/<id>/...`, one per tracked person) is looked for in the graph every
`discovery_period_s` and recorded from then on with the type its publishers give (a type this machine
or the bag cannot hold is skipped once, with a warning: `topics.not_recordable`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import QoSProfile, ReliabilityPolicy

from gwr_predictor.parameters.spec import ParameterError, ParamSpec
from gwr_predictor.pipeline import bag_qos, bag_writer, conventions
from gwr_predictor.pipeline.errors import PipelineError

from . import messages, standard_messages
from .exits import NodeFatalError
from .pipeline_node import PipelineNode
from .qos import stream_qos
from .runner import run_node

PARAMS = (
    ParamSpec("path", "", "bag directory to create (must not exist); empty: recording_<date-time> in the working dir"),
    ParamSpec("topics", list(conventions.TOPIC_TYPES),
          "topics to record; relative names resolve in the node's namespace; the type comes from the last name "
          "segment (conventions.TOPIC_TYPES) or an explicit 'name@pkg/msg/Type'"),
    ParamSpec("flush_period_s", 1.0, "put everything received on disk this often (s)", 0.05, 3600.0),
    ParamSpec("queue_depth", conventions.QOS_DEPTH_RECORDER, "reliable keep-last depth per subscription", 1, 100000),
    ParamSpec("record_below", [], "also record every topic below these namespaces as it appears in the graph, with "
              "the type its publishers give (e.g. [/humans/bodies]: a ROS4HRI tracker's bodies)"),
    ParamSpec("discovery_period_s", 0.5, "how often the graph is searched for new topics below record_below (s)",
              0.05, 60.0),
)


def below(topic: str, namespaces: list[str]) -> bool:
    """`topic` lies below one of the absolute `namespaces`."""
    return any(topic.startswith(ns.rstrip("/") + "/") for ns in namespaces)


def topic_types(resolve: Callable[[str], str], names: list[str]) -> dict[str, str]:
    """{resolved topic: type} for the `topics` parameter; PipelineError naming a bad entry."""
    resolved: dict[str, str] = {}
    for entry in names:
        name, _, msgtype = entry.partition("@")
        if not msgtype:
            last = name.rstrip("/").rsplit("/", 1)[-1]
            msgtype = conventions.TOPIC_TYPES.get(last, conventions.OPTIONAL_TOPIC_TYPES.get(last, ""))
        if not msgtype:
            raise PipelineError(f"topic {entry!r}: unknown type; give it as 'name@pkg/msg/Type'")
        try:
            messages.message_class(msgtype)
        except PipelineError as exc:
            raise PipelineError(f"topic {entry!r}: {exc}") from None
        resolved[resolve(name)] = msgtype
    return resolved


def offered_profile(qos: QoSProfile) -> bag_qos.Qos:
    """An rclpy QoSProfile (as discovered for a publisher) -> the profile stored in the bag."""
    return bag_qos.qos_profile(history=qos.history.name, depth=qos.depth, reliability=qos.reliability.name,
                            durability=qos.durability.name, deadline_ns=qos.deadline.nanoseconds,
                            lifespan_ns=qos.lifespan.nanoseconds, liveliness=qos.liveliness.name,
                            liveliness_lease_ns=qos.liveliness_lease_duration.nanoseconds,
                            avoid_ros_namespace_conventions=qos.avoid_ros_namespace_conventions)


class BagRecorderNode(PipelineNode):
    NODE_NAME = "bag_recorder"

    def __init__(self) -> None:
        super().__init__(self.NODE_NAME, PARAMS)
        p = self.params
        path = Path(p["path"] or time.strftime("recording_%Y%m%d_%H%M%S"))
        try:
            topics = topic_types(self.resolve_topic_name, p["topics"])
        except PipelineError as exc:
            raise ParameterError(f"parameter 'topics': {exc}") from None
        if not topics:
            raise ParameterError("parameter 'topics' is empty: nothing to record")
        self.writer = bag_writer.BagWriter(path, topics, offered_qos=self.offered_qos)
        self.on_disk = 0  # messages written as of the last flush: what survives a SIGKILL
        self.failure: str | None = None
        try:
            self.writer.open()
        except PipelineError as exc:
            raise NodeFatalError(str(exc)) from None
        self.recorded: dict[str, Any] = {}  # topic -> its subscription
        self.matched: set[str] = set()
        self.not_recordable: set[str] = set()
        for topic, msgtype in topics.items():
            self.subscribe(topic, msgtype)
        self.before_clock: list[tuple[str, bytes]] = []  # use_sim_time: received before the first /clock
        # the wall clock: what a crash may lose is wall time, and under sim time /clock may stop
        self.create_timer(p["flush_period_s"], self.flush, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(f"recording {len(topics)} topics into {path}: {', '.join(topics)}")
        self.below = [self.resolve_topic_name(ns) for ns in p["record_below"]]
        if self.below:
            self.get_logger().info(f"and every topic that appears below {', '.join(self.below)}")
            self.discover()
            self.create_timer(p["discovery_period_s"], self.discover, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def subscribe(self, topic: str, msgtype: str, reliable: bool = True) -> None:
        """Record `topic` (raw) from now on: latched topics transient-local, the others keep-last queue_depth."""
        latched = topic.rsplit("/", 1)[-1] in conventions.LATCHED_TOPICS
        qos = standard_messages.latched_qos() if latched else stream_qos(self.params["queue_depth"], reliable=reliable)
        events = SubscriptionEventCallbacks(matched=lambda info, topic=topic: self.on_matched(topic, info))
        self.recorded[topic] = self.create_subscription(messages.message_class(msgtype), topic,
                                                        lambda raw, topic=topic: self.on_message(topic, raw), qos,
                                                        event_callbacks=events, raw=True)

    def on_matched(self, topic: str, info: Any) -> None:
        """`matched <topic>` once a topic's first publisher is matched (scripts wait for these lines)."""
        if topic not in self.matched and info.current_count > 0:
            self.matched.add(topic)
            self.get_logger().info(f"matched {topic}")

    def discover(self) -> None:
        """Record the topics below `record_below` that appeared since the last look (best effort if every
        publisher is: a reliable subscription would not match them)."""
        for topic, types in self.get_topic_names_and_types():
            if topic in self.recorded or topic in self.not_recordable or not below(topic, self.below):
                continue
            try:
                if len(types) != 1:
                    raise PipelineError(f"published with {len(types)} types {types}")
                messages.message_class(types[0])
                self.writer.add_topic(topic, types[0])
            except PipelineError as exc:
                self.not_recordable.add(topic)
                self.counters.count("topics.not_recordable")
                self.get_logger().warning(f"not recording {topic}: {exc}")
                continue
            offered = [info.qos_profile.reliability for info in self.get_publishers_info_by_topic(topic)]
            self.subscribe(topic, types[0], reliable=not offered or ReliabilityPolicy.BEST_EFFORT not in offered)
            self.counters.count("topics.discovered")
            self.get_logger().info(f"recording {topic} ({types[0]}) from now on")

    def offered_qos(self, topic: str) -> list[bag_qos.Qos]:
        """The QoS profiles the topic's publishers offer now (one per publisher, as the graph reports them)."""
        return [offered_profile(info.qos_profile) for info in self.get_publishers_info_by_topic(topic)]

    def on_message(self, topic: str, raw: bytes) -> None:
        """Store the bytes as received, stamped with the receive time (the node clock).

        Under use_sim_time, messages that arrive before the first /clock (the clock still at 0) are
        held and stamped with the first clock value, so that the bag's time line is the simulated one.
        """
        stamp = self.get_clock().now().nanoseconds
        self.counters.count(f"recorded.{topic}")
        if stamp == 0:
            self.before_clock.append((topic, bytes(raw)))
            self.counters.count("recorded_before_clock")
            return
        try:
            self.write_held(stamp)
            self.writer.write_raw(topic, stamp, raw)
        except PipelineError as exc:
            self.stop_recording(exc)

    def drain_progress(self) -> int:
        """Messages received so far (written, or held until the first /clock): on SIGINT/SIGTERM the
        node keeps taking queued messages while this grows, so what was published before the stop is
        in the bag."""
        return self.writer.total_written + len(self.before_clock)

    def write_held(self, stamp: int) -> None:
        """Write the messages held back until the clock started, at `stamp`."""
        held, self.before_clock = self.before_clock, []
        for topic, raw in held:
            self.writer.write_raw(topic, stamp, raw)

    def flush(self) -> None:
        """Put everything received on disk (a SIGKILL then loses at most one flush period)."""
        try:
            if self.before_clock and self.get_clock().now().nanoseconds:
                self.write_held(self.get_clock().now().nanoseconds)
            self.writer.flush()
        except PipelineError as exc:
            self.stop_recording(exc)
        self.on_disk = self.writer.total_written

    def stop_recording(self, exc: PipelineError) -> None:
        """A failed write or flush (full disk, I/O error): stop the node, exit code 1, never a
        bag reported as complete (the shutdown hook says it is not)."""
        self.failure = str(exc)
        raise NodeFatalError(f"recording stopped: {exc}") from None

    def diagnostic_values(self) -> dict[str, object]:
        """Counters plus how many messages are written and how many of them are safely on disk."""
        return {**super().diagnostic_values(), "messages.written": self.writer.total_written,
                "messages.on_disk": self.on_disk}

    def on_shutdown(self) -> None:
        """Write the MCAP summary and metadata.yaml so that the bag is complete."""
        if self.failure is not None:
            raise NodeFatalError(f"bag {self.writer.path} is INCOMPLETE ({self.failure}); {self.on_disk} messages "
                                 "were flushed before the failure: recover them with "
                                 f"gwr_predictor.pipeline.bag_recovery.recover_bag({str(self.writer.path)!r})")
        try:
            if self.before_clock:  # use_sim_time and no /clock ever: nothing better than 0
                self.get_logger().warning(f"no /clock during the recording: {len(self.before_clock)} messages "
                                          "stamped 0 in the bag")
                self.write_held(0)
            self.writer.close()
        except PipelineError as exc:
            raise NodeFatalError(str(exc)) from None
        total = self.writer.total_written
        self.get_logger().info(f"bag closed: {self.writer.path} ({total} messages)")


def main(args: list[str] | None = None) -> int:
    return run_node(BagRecorderNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
