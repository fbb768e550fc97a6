"""bag_player: replays a rosbag2 MCAP bag with its recorded timing, publishing the raw CDR bytes.

Topic selection (`topics`), renaming (`remap`, e.g. "/skeleton:=/replayed/skeleton"), speed
(`rate`), an optional wait for subscribers, looping, and `restamp`: shift every stamp in the data
(JointState headers, the stamp in data[0] of the labelled arrays, DiagnosticArray headers) by the
offset between recording and replay, so that nodes which compare stamps with their clock (the
delay compensator's staleness check) see a live stream. Exits with 0 at the end of the bag.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from rclpy.duration import Duration

from gwr_predictor.parameter_spec import ParamSpec
from gwr_predictor.pipeline import bags

from . import messages
from .node_base import NodeFatalError, ParameterError, PipelineNode, run_node, stream_qos

PARAMS = (
    ParamSpec("bag", "", "bag directory to replay (rosbag2, MCAP)"),
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
)

class BagPlayerNode(PipelineNode):
    NODE_NAME = "bag_player"

    def __init__(self) -> None:
        super().__init__(self.NODE_NAME, PARAMS)
        p = self.params
        if not p["bag"]:
            raise ParameterError("parameter 'bag' is empty: give the bag directory to replay")
        try:
            self.remaps = bags.parse_remaps(p["remap"])
        except ValueError as exc:
            raise ParameterError(f"parameter 'remap': {exc}") from None
        self.bag = Path(p["bag"])
        try:
            info = bags.bag_info(self.bag)
        except bags.BagError as exc:
            raise NodeFatalError(str(exc)) from None
        stored = {topic for topic, (_, count) in info.topics.items() if count}
        wanted = set(p["topics"]) or stored
        missing = sorted(wanted - stored)
        if missing:
            raise ParameterError(f"parameter 'topics': no messages on {missing} in {self.bag} "
                                 f"(it has messages on {sorted(stored)})")
        self.topics = sorted(wanted)
        self.publishers_ = {topic: self.create_publisher(messages.message_class(info.topics[topic][0]),
                                                         self.remaps.get(topic, topic), stream_qos())
                            for topic in self.topics}
        self.messages: list[bags.BagMessage] = []
        self.index = 0
        self.start_wall: float | None = None
        self.first_ns = 0
        self.restamp_offset = 0.0
        self.wait_started = time.monotonic()
        self.load()
        self.create_timer(p["tick_s"], self.tick)
        self.get_logger().info(f"replaying {len(self.messages)} messages of {self.bag} "
                               f"({info.duration_s:.1f} s at rate {p['rate']}) on "
                               + ", ".join(f"{t}->{self.publishers_[t].topic_name}" for t in self.topics))

    def load(self) -> None:
        """Read the selected messages (raw) into memory: pipeline bags are a few MB."""
        undecodable: dict[str, int] = {}
        try:
            self.messages = list(bags.read_bag(self.bag, self.topics, decode=False, undecodable=undecodable))
        except bags.BagError as exc:
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

    def tick(self) -> None:
        """Publish every message whose (scaled) recorded time has come."""
        if self.start_wall is None:
            if not self.ready():
                return
            self.start_wall = time.monotonic()
            self.restamp_offset = self.now_s() - self.first_ns * 1e-9
        elapsed_ns = (time.monotonic() - self.start_wall) * self.params["rate"] * 1e9
        while self.index < len(self.messages) and self.messages[self.index].timestamp_ns - self.first_ns <= elapsed_ns:
            self.publish(self.messages[self.index])
            self.index += 1
        if self.index >= len(self.messages):
            self.end_of_bag()

    def publish(self, message: bags.BagMessage) -> None:
        raw: Any = message.raw
        if self.params["restamp"]:
            raw = bags.shift_stamp(raw, message.msgtype, self.restamp_offset)
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


def main(args: list[str] | None = None) -> int:
    return run_node(BagPlayerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
