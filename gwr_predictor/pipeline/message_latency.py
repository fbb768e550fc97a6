"""Latency and message loss of a recorded pipeline run, from the bag alone (pure numpy, no ROS).

Why from the bag: the recorder stamps every message with its receive time (the bag's log time,
node clock) and the data carry the frame's source stamp (the skeleton's capture time travels through
angles and predictions unchanged), so the delay from the sensor to each downstream message needs no
instrumentation inside the nodes. Every node publishes its counters on /diagnostics once more when
it stops, so the final counters in the bag give the exact number of messages each node published
and received: loss = published - received, per hop.

Definitions (seconds; reported as milliseconds):

- ``<topic> transit``: receive time - header stamp, for topics stamped when published
  (joint_commands, joint_states): middleware + recorder only.
- ``source -> <topic>``: receive time - the frame's source stamp (skeleton, arm_angles,
  predictions, joint_commands). For arm_angles this includes waiting for the third frame of the
  median-of-3 group (one skeleton period, 33 ms); for joint_commands it is the prediction's stamp.
- ``hop angle_extractor``: arm_angles receive - receive of the skeleton that completed the group
  (the first skeleton stamped after the group's middle frame).
- ``hop arm_predictor``: predictions receive - receive of the arm_angles frame with the same stamp.
- ``hop delay_compensator``: publish stamp of the command nearest to a prediction's receive (within
  half a frame period) - that receive; ``source -> joint_commands`` is that command's receive - the
  prediction's source stamp.

All receive times are the recorder's: a hop is the difference of two receive times, so it includes
the recorder's scheduling jitter (about a millisecond), not only the node's processing.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.files.json_safe import to_jsonable
from gwr_predictor.pipeline import bag_messages, bag_reader, conventions, namespaces

#: Percentiles reported for every latency.
PERCENTILES = (50, 90, 99)
_KEY_RESOLUTION = 1e-6  # stamps are matched to the microsecond (header stamps are integer ns)


@dataclass(frozen=True)
class LatencyStats:
    """Percentiles of one latency (seconds)."""

    n: int
    p50: float
    p90: float
    p99: float
    max: float
    mean: float

    def as_ms(self) -> dict[str, float | int]:
        return {"n": self.n, **{k: round(1e3 * getattr(self, k), 3) for k in ("p50", "p90", "p99", "max", "mean")}}


def latency_stats(values: Iterable[float]) -> LatencyStats:
    """p50/p90/p99/max/mean of finite values; NaN everywhere (n = 0) when there are none."""
    v = np.asarray(list(values) if not isinstance(values, np.ndarray) else values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return LatencyStats(0, *([float("nan")] * 5))
    p50, p90, p99 = (float(x) for x in np.percentile(v, PERCENTILES))
    return LatencyStats(int(v.size), p50, p90, p99, float(v.max()), float(v.mean()))


@dataclass
class TopicSeries:
    """Receive times and source stamps (s) of one topic, in receive order."""

    receive: np.ndarray
    stamp: np.ndarray


@dataclass(frozen=True)
class HopCount:
    """Messages one node published on a topic vs what the next node and the recorder got."""

    topic: str
    publisher: str
    published: int | None  # from the publisher's final counters; None if they are not in the bag
    recorded: int
    consumer: str | None = None
    consumed: int | None = None  # accepted + rejected by the consumer (its final counters)
    #: published before the publisher's first /diagnostics in the bag, and recorded after it: the
    #: recorder's loss is counted from then on (before, its subscription may not have matched yet,
    #: and volatile QoS resends nothing to a late joiner)
    published_early: int = 0
    recorded_after: int | None = None
    instances: int = 1  # processes of the publisher seen in the bag (restarts, other pipelines)
    consumer_instances: int = 1
    concurrent: bool = False  # two publishers or consumers of this hop ran at once: see hop_counts

    @property
    def lost_recorder(self) -> int | None:
        if self.published is None:
            return None
        recorded = self.recorded if self.recorded_after is None else self.recorded_after
        return self.published - self.published_early - recorded

    @property
    def lost_consumer(self) -> int | None:
        return None if self.published is None or self.consumed is None else self.published - self.consumed


@dataclass
class LatencyReport:
    """Everything `gwr-predictor latency` prints: latencies per hop and message counts per topic."""

    bag: Path
    duration_s: float
    latencies: dict[str, LatencyStats] = field(default_factory=dict)
    counts: list[HopCount] = field(default_factory=list)
    undecodable: dict[str, int] = field(default_factory=dict)  # {topic: messages skipped}
    namespace: str = ""  # the pipeline's ("" = root)

    @property
    def total_lost(self) -> int:
        """Messages published but neither recorded nor consumed (counting only known hops)."""
        lost = 0
        for c in self.counts:
            lost += max(0, c.lost_recorder or 0) + max(0, c.lost_consumer or 0)
        return lost

    def to_dict(self) -> dict[str, Any]:
        return {
            "bag": str(self.bag),
            "namespace": self.namespace,
            "duration_s": round(self.duration_s, 3),
            "latency_ms": {k: v.as_ms() for k, v in self.latencies.items()},
            "counts": [{"topic": c.topic, "publisher": c.publisher, "published": c.published,
                        "published_before_first_diagnostics": c.published_early, "recorded": c.recorded,
                        "recorded_after_first_diagnostics": c.recorded_after,
                        "lost_recorder": c.lost_recorder, "consumer": c.consumer,
                        "consumed": c.consumed, "lost_consumer": c.lost_consumer} for c in self.counts],
            "total_lost": self.total_lost,
            "undecodable_skipped": dict(self.undecodable),
        }

    def to_json(self) -> str:
        return json.dumps(to_jsonable(self.to_dict()), indent=2)

    def summary_lines(self) -> list[str]:
        lines = [f"bag {self.bag}" + (f" (pipeline {self.namespace})" if self.namespace else "")
                 + f": {self.duration_s:.1f} s",
                 f"{'latency (ms)':<46}{'n':>7}{'p50':>9}{'p90':>9}{'p99':>9}{'max':>9}"]
        for name, s in self.latencies.items():
            lines.append(f"{name:<46}{s.n:>7}{1e3 * s.p50:>9.2f}{1e3 * s.p90:>9.2f}{1e3 * s.p99:>9.2f}"
                         f"{1e3 * s.max:>9.2f}")
        lines.append(f"{'messages':<46}{'published':>10}{'early':>7}{'recorded':>10}{'lost':>6}{'consumed':>10}"
                     "  consumer")
        for c in self.counts:
            pub = "?" if c.published is None else str(c.published)
            lost = "?" if c.lost_recorder is None else str(c.lost_recorder)
            con = "-" if c.consumed is None else str(c.consumed)
            lines.append(f"{c.topic + ' (' + c.publisher + ')':<46}{pub:>10}{c.published_early:>7}{c.recorded:>10}"
                         f"{lost:>6}{con:>10}  {c.consumer or '-'}")
        lines.append(f"messages lost: {self.total_lost} (early: published before the publisher's first "
                     "/diagnostics, not counted for the recorder)")
        restarted = sorted({c.publisher for c in self.counts if c.instances > 1 and not c.concurrent})
        if restarted:
            lines.append("restarted during the run (every instance counted): " + ", ".join(restarted))
        mixed = sorted({c.topic for c in self.counts if c.concurrent})
        if mixed:
            lines.append("two instances of a node ran at once (two pipelines on one ROS_DOMAIN_ID?): consumer loss "
                         "not computed on " + ", ".join(mixed))
        if self.undecodable:
            lines.append("undecodable messages skipped: " + ", ".join(f"{t} {n}" for t, n in self.undecodable.items()))
        return lines


# --- reading --------------------------------------------------------------------------------------


def _source_stamp(msg: Any, msgtype: str) -> float:
    if msgtype == bag_messages.FLOAT64_MULTIARRAY:
        return float(msg.data[0]) if msg.layout.data_offset >= 1 and len(msg.data) >= 1 else float("nan")
    if hasattr(msg, "markers"):  # MarkerArray: the stamp is in each marker
        return bag_messages.stamp_seconds(msg.markers[0].header.stamp) if len(msg.markers) else float("nan")
    header = getattr(msg, "header", None)  # std_msgs/String (robot_description) has none
    return bag_messages.stamp_seconds(header.stamp) if header is not None else float("nan")


#: {node name: [(receive s, {key: value}, instance id), ...]} of the /diagnostics statuses in a bag,
#: in receive order (the instance id is the status's `instance` value: one per node process).
DiagnosticsHistory = dict[str, list[tuple[float, dict[str, str], str]]]
#: A restarted instance's last messages may reach the recorder this long after its last counters.
RESTART_GRACE_S = 0.5


def read_series(bag: str | os.PathLike[str]
                ) -> tuple[dict[str, TopicSeries], DiagnosticsHistory, float, dict[str, int]]:
    """({topic: TopicSeries}, every /diagnostics status per node, duration s, {topic: undecodable
    messages skipped}) of a pipeline bag; PipelineError if metadata.yaml disagrees with the file."""
    bag = Path(bag)
    info = bag_reader.bag_info(bag)
    rows: dict[str, tuple[list[float], list[float]]] = {}
    diagnostics: DiagnosticsHistory = {}
    undecodable: dict[str, int] = {}
    read: dict[str, int] = {}
    for m in bag_reader.read_bag(bag, undecodable=undecodable):
        read[m.topic] = read.get(m.topic, 0) + 1
        if m.msg is None:
            continue
        if m.msgtype == "diagnostic_msgs/msg/DiagnosticArray":
            if m.topic.endswith("/" + conventions.TOPIC_DIAGNOSTICS):
                for status in m.msg.status:
                    diagnostics.setdefault(status.name, []).append(
                        (m.timestamp_ns * 1e-9, values := {kv.key: kv.value for kv in status.values},
                         values.get(conventions.INSTANCE_KEY, "")))
            continue
        recv, stamps = rows.setdefault(m.topic, ([], []))
        recv.append(m.timestamp_ns * 1e-9)
        stamps.append(_source_stamp(m.msg, m.msgtype))
    bag_reader.check_counts(info, {t: read.get(t, 0) + undecodable.get(t, 0) for t in set(read) | set(undecodable)})
    series = {t: TopicSeries(np.asarray(r), np.asarray(s)) for t, (r, s) in rows.items()}
    return series, diagnostics, info.duration_s, undecodable


# --- computing ------------------------------------------------------------------------------------


def _keys(stamps: np.ndarray) -> np.ndarray:
    return np.round(stamps / _KEY_RESOLUTION).astype(np.int64)


def extractor_hop(skeleton: TopicSeries, angles: TopicSeries, max_gap_s: float = conventions.MAX_GAP_S
                  ) -> np.ndarray:
    """arm_angles receive - receive of the skeleton that completed its group (first one stamped after it)."""
    if skeleton.stamp.size == 0 or angles.stamp.size == 0:
        return np.zeros(0)
    order = np.argsort(skeleton.stamp, kind="stable")
    s_stamp, s_recv = skeleton.stamp[order], skeleton.receive[order]
    idx = np.searchsorted(s_stamp, angles.stamp + _KEY_RESOLUTION, side="left")
    ok = idx < s_stamp.size
    ok[ok] &= s_stamp[idx[ok]] - angles.stamp[ok] <= max_gap_s
    return angles.receive[ok] - s_recv[idx[ok]]


def same_stamp_hop(upstream: TopicSeries, downstream: TopicSeries) -> np.ndarray:
    """downstream receive - upstream receive of the message with the same source stamp."""
    first: dict[int, float] = {}
    for key, recv in zip(_keys(upstream.stamp).tolist(), upstream.receive.tolist(), strict=True):
        first.setdefault(key, recv)
    out = [recv - first[key] for key, recv in zip(_keys(downstream.stamp).tolist(), downstream.receive.tolist(),
                                                    strict=True) if key in first]
    return np.asarray(out, dtype=float)


def command_hop(predictions: TopicSeries, commands: TopicSeries, frame_period_s: float = 1.0 / conventions.ANGLE_FPS
                ) -> tuple[np.ndarray, np.ndarray]:
    """(compensator hop, source -> command) per prediction: the command published (its header stamp is
    the compensator's clock at publishing) nearest to the prediction's receive, within half a frame.

    Paired by the command's publish stamp, not its receive, because the recorder may handle the
    command before the prediction that caused it (separate subscriptions); the hop can therefore be
    slightly negative by the recorder's own scheduling jitter.
    """
    if predictions.receive.size == 0 or commands.receive.size == 0:
        return np.zeros(0), np.zeros(0)
    order = np.argsort(commands.stamp, kind="stable")
    c_stamp, c_recv = commands.stamp[order], commands.receive[order]
    p_recv, p_stamp = predictions.receive, predictions.stamp
    idx = np.searchsorted(c_stamp, p_recv)
    before = np.clip(idx - 1, 0, c_stamp.size - 1)
    after = np.clip(idx, 0, c_stamp.size - 1)
    nearest = np.where(np.abs(c_stamp[before] - p_recv) <= np.abs(c_stamp[after] - p_recv), before, after)
    ok = np.abs(c_stamp[nearest] - p_recv) <= 0.5 * frame_period_s
    return c_stamp[nearest[ok]] - p_recv[ok], c_recv[nearest[ok]] - p_stamp[ok]


def compute_latencies(series: Mapping[str, TopicSeries], namespace: str | None = None,
                      pipeline: str = "") -> dict[str, LatencyStats]:
    """Every latency of the module docstring that the bag has the topics for, in the pipeline of namespace
    `pipeline`; the robot's topics in `namespace` (default: the pipeline's)."""
    def topic(name: str, ns: str = pipeline) -> TopicSeries | None:
        return series.get(f"{ns}/{name}")

    namespace = pipeline if namespace is None else namespace

    empty = TopicSeries(np.zeros(0), np.zeros(0))
    skel = topic(conventions.TOPIC_SKELETON) or empty
    angles = topic(conventions.TOPIC_ANGLES) or empty
    preds = topic(conventions.TOPIC_PREDICTIONS) or empty
    cmds = topic(conventions.TOPIC_COMMAND, namespace) or empty
    states = topic(conventions.TOPIC_ROBOT_STATE, namespace) or empty
    out: dict[str, LatencyStats] = {}
    for name, s in (("skeleton", skel), ("arm_angles", angles), ("predictions", preds)):
        if s.receive.size:
            out[f"source -> {name}"] = latency_stats(s.receive - s.stamp)
    if angles.receive.size:
        out["hop angle_extractor"] = latency_stats(extractor_hop(skel, angles))
    if preds.receive.size:
        out["hop arm_predictor"] = latency_stats(same_stamp_hop(angles, preds))
    if cmds.receive.size:
        hop, total = command_hop(preds, cmds)
        out["hop delay_compensator"] = latency_stats(hop)
        out["source -> joint_commands"] = latency_stats(total)
        out["joint_commands transit"] = latency_stats(cmds.receive - cmds.stamp)
    if states.receive.size:
        out["joint_states transit"] = latency_stats(states.receive - states.stamp)
    return out


def _count(values: Mapping[str, str] | None, *keys: str, prefix: str | None = None) -> int | None:
    """Sum of counters `keys` (+ every key starting with `prefix`); None if the node is not in the bag."""
    if values is None:
        return None
    total = sum(_int(values.get(k)) for k in keys)
    if prefix:
        total += sum(_int(v) for k, v in values.items() if k.startswith(prefix))
    return total


Snapshot = tuple[float, dict[str, str]]


def instances(snaps: list[tuple[float, dict[str, str], str]] | None) -> list[list[Snapshot]]:
    """The statuses of one node name split into node processes (restarts, or two pipelines on one
    domain): by instance id, or, for bags recorded before the id existed, where a counter goes down."""
    if not snaps:
        return []
    if all(inst for _, _, inst in snaps):
        groups: dict[str, list[Snapshot]] = {}
        for recv, values, inst in snaps:
            groups.setdefault(inst, []).append((recv, values))
        return sorted(groups.values(), key=lambda g: g[0][0])
    out: list[list[Snapshot]] = [[]]
    for recv, values, _ in snaps:
        if out[-1] and any(_int(values.get(k)) < _int(v) for k, v in out[-1][-1][1].items()):
            out.append([])
        out[-1].append((recv, values))
    return out


def _int(value: str | None) -> int:
    try:
        return int(float(value)) if value is not None else 0
    except ValueError:
        return 0


def _windows(insts: list[list[Snapshot]]) -> list[tuple[float, float]]:
    """Receive-time spans of each instance (the one that reported last: open-ended)."""
    last = max(range(len(insts)), key=lambda i: insts[i][-1][0])
    return [(g[0][0], np.inf if i == last else g[-1][0] + RESTART_GRACE_S) for i, g in enumerate(insts)]


def concurrent(insts: list[list[Snapshot]]) -> bool:
    """Two processes of one node name reported at the same time (two pipelines on one domain)."""
    latest = -np.inf
    for first, last in sorted((g[0][0], g[-1][0]) for g in insts):
        if first < latest:
            return True
        latest = max(latest, last)
    return False


def _sum_final(insts: list[list[Snapshot]], *keys: str, prefix: str | None = None) -> int | None:
    return sum(_count(g[-1][1], *keys, prefix=prefix) or 0 for g in insts) if insts else None


def hop_counts(series: Mapping[str, TopicSeries], history: DiagnosticsHistory, namespace: str | None = None,
               pipeline: str = "") -> list[HopCount]:
    """Published (publishers' final counters) vs recorded (bag) vs consumed (consumers' final counters).

    A node restarted during the run counts with every instance (each one's final counters; the
    recorder's count over the time each one ran, from its first /diagnostics on). Two instances of
    one node at the same time (two pipelines sharing a domain) mix their streams: nothing tells
    which message came from which, so the consumer's loss is not computed (None) and the hop is
    marked `concurrent`. The hops are those of the pipeline in namespace `pipeline`; with a robot
    `namespace` other than the pipeline's, only that robot's hops (commands and states).
    """
    split = {name: instances(snaps) for name, snaps in history.items()}
    robot_only = namespace is not None and namespace != pipeline
    namespace = pipeline if namespace is None else namespace

    def own(name: str) -> str:  # the root pipeline's node names stay as they were printed (relative)
        return namespaces.in_pipeline(pipeline, name) if pipeline else name

    def consumed(consumer: str, *keys: str, prefix: str) -> tuple[int | None, int, bool]:
        insts = split.get(_fq(consumer), [])
        return _sum_final(insts, *keys, prefix=prefix), len(insts), concurrent(insts)

    def hop(topic: str, publisher: str, key: str, consumer: str | None = None,
            got: tuple[int | None, int, bool] = (None, 0, False)) -> HopCount:
        s = series.get(topic)
        recv = np.zeros(0) if s is None else s.receive
        insts = split.get(_fq(publisher), [])
        published = _sum_final(insts, key)
        early, after = 0, None
        if insts:
            early = sum(_count(g[0][1], key) or 0 for g in insts)
            inside = np.zeros(recv.size, dtype=bool)
            for lo, hi in _windows(insts):
                inside |= (recv >= lo) & (recv <= hi)
            after = int(np.sum(inside))
        mixed = concurrent(insts) or got[2]
        return HopCount(topic, publisher, published, int(recv.size), consumer, None if mixed else got[0], early,
                        after, instances=len(insts), consumer_instances=got[1], concurrent=mixed)

    comp, sim = f"{namespace}/delay_compensator", f"{namespace}/nao_sim"
    # a run of the learner's deprecated executable has its statuses under the old name
    learner = own(conventions.LEARNER_NODE)
    if _fq(learner) not in split and _fq(own(conventions.DEPRECATED_LEARNER_NODE)) in split:
        learner = own(conventions.DEPRECATED_LEARNER_NODE)
    counts = [
        hop(f"{pipeline}/skeleton", own("skeleton_source"), "frames.published", own("angle_extractor"),
            consumed(own("angle_extractor"), "skeleton.accepted", prefix="rejected.skeleton.")),
        hop(f"{pipeline}/arm_angles", own("angle_extractor"), "angles.published", learner,
            consumed(learner, "frames.learned", "frames.seen", prefix="rejected.arm_angles.")),
        hop(f"{pipeline}/arm_angles", own("angle_extractor"), "angles.published", comp,
            consumed(comp, "arm_angles.received", prefix="rejected.arm_angles.")),
        hop(f"{pipeline}/predictions", learner, "predictions.published", comp,
            consumed(comp, "predictions.received", prefix="rejected.predictions.")),
        hop(f"{pipeline}/predicted_angles", learner, "predictions.published"),
        hop(f"{namespace}/joint_commands", comp, "commands.published", sim,
            consumed(sim, "commands.accepted", prefix="rejected.joint_commands.")),
        hop(f"{namespace}/joint_states", sim, "states.published"),
    ]
    if robot_only:  # the angles and predictions hops belong to the pipeline's own robot
        counts = [c for c in counts if c.topic.startswith(namespace + "/")]
    return [c for c in counts if c.published is not None or c.recorded]


def _fq(name: str) -> str:
    return name if name.startswith("/") else "/" + name


def latency_report(bag: str | os.PathLike[str], namespace: str | None = None) -> LatencyReport:
    """Read a pipeline bag and compute latencies and message counts of the pipeline in `namespace` (by
    default the bag's only one). Raises PipelineError."""
    series, diagnostics, duration, undecodable = read_series(bag)
    pipeline = namespaces.choose_pipeline(series, namespace, bag)
    report = LatencyReport(Path(bag), duration, compute_latencies(series, pipeline=pipeline),
                           hop_counts(series, diagnostics, pipeline=pipeline), undecodable=undecodable,
                           namespace=pipeline)
    baseline = namespaces.in_pipeline(pipeline, "uncompensated")
    if f"{baseline}/{conventions.TOPIC_COMMAND}" in series:
        report.counts += hop_counts(series, diagnostics, baseline, pipeline)
    return report
