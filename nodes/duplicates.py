"""Two pipelines on one ROS domain mix their streams: a node that sees a second, older instance of
itself (same name and namespace) on /diagnostics, and confirms it in the ROS graph, stops
(`stop_if_duplicate`, on by default).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable

from rclpy.node import Node

from gwr_predictor.pipeline import conventions
from gwr_predictor.pipeline.input_rules import RejectionCounter

from . import messages
from .qos import status_qos


def started_ns(instance_id: str) -> int | None:
    """The start time (ns) in an instance id `host:pid:start_ns`, None if it has another form."""
    try:
        return int(instance_id.rsplit(":", 1)[1])
    except (IndexError, ValueError):
        return None


def _qualified(namespace: str, name: str) -> str:
    return namespace.rstrip("/") + "/" + name


#: A second instance must send this many statuses, over at least this long, before this one stops.
DUPLICATE_MIN_STATUSES = 3
DUPLICATE_MIN_SPAN_S = 2.0
#: Topics every node may have: an endpoint on them says nothing about which node it is.
_COMMON_TOPICS = frozenset({conventions.DIAGNOSTICS_TOPIC, "/rosout", "/parameter_events", "/clock"})


class InstanceSightings:
    """First sighting and count of the statuses of each other instance id (at most `limit` ids, the
    oldest forgotten first, so that a flood of made-up ids costs no memory)."""

    def __init__(self, limit: int = 32) -> None:
        self._seen: dict[str, tuple[float, int]] = {}
        self._limit = limit

    def add(self, instance: str, now: float) -> bool:
        """Count one status of `instance` at `now`; True once it has been seen repeatedly over a period."""
        first, count = self._seen.pop(instance, (now, 0))
        self._seen[instance] = (first, count + 1)
        while len(self._seen) > self._limit:
            del self._seen[next(iter(self._seen))]
        return count + 1 >= DUPLICATE_MIN_STATUSES and now - first >= DUPLICATE_MIN_SPAN_S


class DuplicateWatch:
    """Stops the node (through `stop`, with the reason) if a second instance of it (name and namespace)
    that started first really runs on the same domain: it listens to /diagnostics for statuses of the
    node's own name that carry another instance id.

    One status is a stranger's word, so three kinds of evidence are needed: statuses of that
    instance repeated over `DUPLICATE_MIN_SPAN_S`; a second node of this name in the ROS graph (a
    bag replaying old /diagnostics adds none); and that second node on this node's own topics.
    A convenience against two pipelines on one domain, not security: a hostile peer can fake all
    three (SROS2 is the answer to those).
    """

    def __init__(self, node: Node, counters: RejectionCounter, instance_id: str, started: int,
                 stop: Callable[[str], None]) -> None:
        self._node = node
        self._counters = counters
        self._instance_id = instance_id
        self._started_ns = started
        self._stop = stop
        self._sightings = InstanceSightings()
        node.create_subscription(messages.DiagnosticArray, conventions.DIAGNOSTICS_TOPIC, self.check, status_qos())

    def check(self, msg: messages.DiagnosticArray) -> None:
        """Stop if a second instance of this node that started first really runs."""
        me = self._node.get_fully_qualified_name()
        for status in msg.status:
            if status.name != me:
                continue
            instance = next((kv.value for kv in status.values if kv.key == conventions.INSTANCE_KEY), "")
            if not instance or instance == self._instance_id:
                continue
            other = started_ns(instance)
            if other is None or (other, instance) > (self._started_ns, self._instance_id):
                continue  # the other one is the newcomer: it stops
            if not self._sightings.add(instance, time.monotonic()):
                continue
            if not self._second_instance_on_own_topics(me):
                self._counters.count("duplicate.unconfirmed")
                self._counters.warn_throttled("duplicate.unconfirmed", f"statuses of another {me} (instance "
                                              f"{instance}) but no second {me} on this node's topics: ignored")
                continue
            self._stop(f"another {me} (instance {instance}) runs on ROS_DOMAIN_ID="
                       f"{os.environ.get('ROS_DOMAIN_ID', '0')}: two pipelines on one domain mix their "
                       "streams; stopping this one (set ROS_DOMAIN_ID to a free domain)")
            return

    def _second_instance_on_own_topics(self, me: str) -> bool:
        """True if the graph holds two nodes named `me` and, on a topic this node publishes (or, for a
        node that only listens, subscribes to), two endpoints of nodes named `me`."""
        node = self._node
        if sum(1 for n, ns in node.get_node_names_and_namespaces() if _qualified(ns, n) == me) < 2:
            return False
        topics = {p.topic_name for p in node.publishers} - _COMMON_TOPICS
        endpoints = node.get_publishers_info_by_topic
        if not topics:
            topics = {s.topic_name for s in node.subscriptions} - _COMMON_TOPICS
            endpoints = node.get_subscriptions_info_by_topic
        return any(sum(1 for e in endpoints(t) if _qualified(e.node_namespace, e.node_name) == me) >= 2
                   for t in topics)
