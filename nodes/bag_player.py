"""bag_player: replays a rosbag2 MCAP bag (directory or bare .mcap file) with its recorded timing,
publishing the raw CDR bytes with the QoS the recorded publishers offered.

Topic selection (`topics`), renaming (`remap`, e.g. "/skeleton:=/replayed/skeleton"), speed
(`rate`), an optional wait for subscribers, looping, and two ways to make nodes that compare
stamps with their clock (the delay compensator's staleness check) see a live stream:
- `restamp`: shift every stamp in the data (JointState headers, the stamp in data[0] of the
  labelled arrays, DiagnosticArray headers) by the offset between recording and replay;
- `clock`: publish /clock (rosgraph_msgs/Clock) with the recorded time, for nodes started with
  `use_sim_time:=true`; at `rate` 2 the simulated time runs twice as fast as the wall clock.
The player itself schedules by the wall clock (it is the time source). Exits with 0 at the end of
the bag.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from gwr_predictor.parameters.spec import ParameterError, ParamSpec
from gwr_predictor.pipeline import bag_qos, bag_reader, bag_replay
from gwr_predictor.pipeline.errors import PipelineError

from . import messages
from .exits import NodeFatalError
from .pipeline_node import PipelineNode
from .qos import stream_qos
from .runner import run_node

PARAMS = (
    ParamSpec("bag", "", "bag to replay: a rosbag2 directory (MCAP) or a bare .mcap file"),
    ParamSpec("rate", 1.0, "replay speed factor (2.0 = twice as fast)", 0.01, 1000.0),
    ParamSpec("topics", [], "topics to replay (names as recorded); empty: every topic with messages"),
    ParamSpec("remap", [], "renames 'recorded:=published', e.g. '/skeleton:=/replayed/skeleton'"),
    ParamSpec("start_delay_s", 0.0, "wait this long before the first message (s)", 0.0, 3600.0),
    ParamSpec("wait_for_subscribers", 0, "before starting, wait until every topic has this many subscribers", 0, 1000),
    ParamSpec("wait_timeout_s", 30.0, "give up waiting for subscribers after this long and play anyway (s)",
              0.0, 3600.0),
    ParamSpec("loop", False, "start again at the end of the bag"),
    ParamSpec("restamp", False, "shift the stamps inside the messages to the replay time"),
    ParamSpec("tick_s", 0.002, "scheduling period: messages go out at most this late (s)", 0.0005, 0.1),
    ParamSpec("clock", False, "publish /clock with the recorded time (for nodes with use_sim_time:=true)"),
    ParamSpec("clock_period_s", 0.005, "wall-clock period of /clock while playing (s); a node timer needs a "
              "period above clock_period_s * rate to keep its rate", 0.001, 1.0),
)

_RELIABILITY = {"reliable": ReliabilityPolicy.RELIABLE, "best_effort": ReliabilityPolicy.BEST_EFFORT}
_DURABILITY = {"volatile": DurabilityPolicy.VOLATILE, "transient_local": DurabilityPolicy.TRANSIENT_LOCAL}


def publisher_qos(offered: list[Any]) -> QoSProfile:
    """The recorded publishers' QoS (`bag_qos.replay_qos`), or the pipeline's stream QoS for bags without it."""
    chosen = bag_qos.replay_qos(offered, stream_qos().depth)
    if chosen is None:
        return stream_qos()
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=chosen.depth,
                      reliability=_RELIABILITY[chosen.reliability], durability=_DURABILITY[chosen.durability])


class BagPlayerNode(PipelineNode):
    NODE_NAME = "bag_player"

    def __init__(self) -> None:
        super().__init__(self.NODE_NAME, PARAMS)
        p = self.params
        if not p["bag"]:
            raise ParameterError("parameter 'bag' is empty: give the bag directory or .mcap file to replay")
        if p["clock"] and p["restamp"]:
            raise ParameterError("parameters 'clock' and 'restamp' exclude each other: with clock:=true the nodes "
                                 "run on the recorded time, so the stamps must stay as recorded")
        try:
            self.remaps = bag_replay.parse_remaps(p["remap"])
        except ValueError as exc:
            raise ParameterError(f"parameter 'remap': {exc}") from None
        self.bag = Path(p["bag"])
        try:
            info = bag_reader.bag_info(self.bag)
        except PipelineError as exc:
            raise NodeFatalError(str(exc)) from None
        stored = {topic for topic, (_, count) in info.topics.items() if count}
        wanted = set(p["topics"]) or stored
        missing = sorted(wanted - stored)
        if missing:
            raise ParameterError(f"parameter 'topics': no messages on {missing} in {self.bag} "
                                 f"(it has messages on {sorted(stored)})")
        self.topics = sorted(wanted)
        self.qos = {topic: publisher_qos(info.offered_qos.get(topic, [])) for topic in self.topics}
        self.publishers_ = {topic: self.create_publisher(messages.message_class(info.topics[topic][0]),
                                                         self.remaps.get(topic, topic), self.qos[topic])
                            for topic in self.topics}
        self.clock_pub = self.create_publisher(messages.Clock, "/clock", clock_qos()) if p["clock"] else None
        self.last_clock_wall = -math.inf
        self.messages: list[bag_reader.BagMessage] = []
        self.index = 0
        self.start_wall: float | None = None
        self.first_ns = 0
        self.restamp_offset = 0.0
        self.wait_started = time.monotonic()
        self.load()
        # the wall clock, also under use_sim_time: the player is the time source, not a consumer
        self.create_timer(p["tick_s"], self.tick, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(f"replaying {len(self.messages)} messages of {self.bag} "
                               f"({info.duration_s:.1f} s at rate {p['rate']}"
                               + (", publishing /clock" if p["clock"] else "") + ") on "
                               + ", ".join(f"{t}->{self.publishers_[t].topic_name} "
                                           f"({describe_qos(self.qos[t])})" for t in self.topics))

    def load(self) -> None:
        """Read the selected messages (raw) into memory: pipeline bags are a few MB."""
        undecodable: dict[str, int] = {}
        try:
            self.messages = list(bag_reader.read_bag(self.bag, self.topics, decode=False, undecodable=undecodable))
        except PipelineError as exc:
            raise NodeFatalError(str(exc)) from None
        for topic, n in undecodable.items():  # replaying them would hand the subscribers the same bytes
            self.counters.count(f"skipped.undecodable.{topic}", n)
            self.get_logger().warning(f"{self.bag}: {n} messages on {topic} do not decode: skipped")
        if not self.messages:
            raise NodeFatalError(f"{self.bag}: no messages on {self.topics}")
        self.first_ns = self.messages[0].timestamp_ns

    def ready(self) -> bool:
        """Subscribers are there (or we gave up waiting) and the start delay has passed."""
        p = self.params
        waited = time.monotonic() - self.wait_started
        if p["wait_for_subscribers"] and waited < p["wait_timeout_s"]:
            if any(pub.get_subscription_count() < p["wait_for_subscribers"] for pub in self.publishers_.values()):
                return False
        elif p["wait_for_subscribers"] and not getattr(self, "_warned_wait", False):
            self._warned_wait = True
            if any(pub.get_subscription_count() < p["wait_for_subscribers"] for pub in self.publishers_.values()):
                self.get_logger().warning(f"subscribers missing after {p['wait_timeout_s']} s; playing anyway")
        return waited >= p["start_delay_s"]

    def publish_clock(self, recorded_ns: int) -> None:
        """/clock at the recorded time `recorded_ns`, at most once per clock_period_s of wall time."""
        wall = time.monotonic()
        if self.clock_pub is None or wall - self.last_clock_wall < self.params["clock_period_s"]:
            return
        self.last_clock_wall = wall
        self.clock_pub.publish(messages.clock_msg(recorded_ns))
        self.counters.count("clock_published")

    def tick(self) -> None:
        """Publish every message whose (scaled) recorded time has come, after the clock."""
        if self.start_wall is None:
            self.publish_clock(self.first_ns)  # nodes see the start time while the player waits
            if not self.ready():
                return
            self.start_wall = time.monotonic()
            self.restamp_offset = self.now_s() - self.first_ns * 1e-9
        elapsed_ns = (time.monotonic() - self.start_wall) * self.params["rate"] * 1e9
        due = self.index < len(self.messages) and self.messages[self.index].timestamp_ns - self.first_ns <= elapsed_ns
        if due:
            self.last_clock_wall = -math.inf  # a message goes out: the clock first, so it is never behind
        self.publish_clock(self.first_ns + int(elapsed_ns))
        while self.index < len(self.messages) and self.messages[self.index].timestamp_ns - self.first_ns <= elapsed_ns:
            self.publish(self.messages[self.index])
            self.index += 1
        if self.index >= len(self.messages):
            self.end_of_bag()

    def publish(self, message: bag_reader.BagMessage) -> None:
        raw: Any = message.raw
        if self.params["restamp"]:
            raw = bag_replay.shift_stamp(raw, message.msgtype, self.restamp_offset)
        self.publishers_[message.topic].publish(raw)
        self.counters.count(f"published.{message.topic}")

    def end_of_bag(self) -> None:
        if self.params["loop"]:
            self.index, self.start_wall = 0, None
            self.wait_started = time.monotonic() - self.params["start_delay_s"]
            self.counters.count("loops")
            return
        for pub in self.publishers_.values():
            pub.wait_for_all_acked(Duration(seconds=2))  # reliable subscribers got everything
        self.get_logger().info(f"end of {self.bag}: {self.index} messages published")
        self.finish(0)


def clock_qos() -> QoSProfile:
    """/clock as rclcpp's ClockQoS: keep last 1, best effort (what rclpy's time source subscribes with);
    an old clock value is worth nothing once a newer one exists."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.VOLATILE)


def describe_qos(qos: QoSProfile) -> str:
    return f"{qos.reliability.name.lower()}, {qos.durability.name.lower()}, depth {qos.depth}"


def main(args: list[str] | None = None) -> int:
    return run_node(BagPlayerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
