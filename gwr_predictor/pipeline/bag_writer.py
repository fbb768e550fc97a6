"""Writing rosbag2 bags (metadata version 9, MCAP storage) with `rosbags`: `BagWriter`.

Why: the recorder node writes the CDR bytes it receives from DDS unchanged, into bags `ros2 bag`
accepts, with errors that name the file, and a recorder crash must cost seconds of data, not the
whole bag.

Crash safety: rosbags keeps the current MCAP chunk (up to 1 MiB) in memory and writes the
summary, footer and metadata.yaml only on close. `BagWriter.flush()` (or `flush_every`) closes the
pending chunk and flushes the file, so after a crash everything up to the last flush is on disk;
`bag_recovery.recover_bag()` rebuilds a valid bag (MCAP summary + metadata.yaml) from those chunks.

Offered QoS (`bag_qos`): each topic carries the QoS profiles its publishers offered, so the writer
adds a topic's connection when its first message arrives (the publishers are known by then) or,
without messages, on close.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.interfaces import Qos
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.errors import WriterError
from rosbags.rosbag2.storage_mcap import McapWriter

from gwr_predictor.pipeline.bag_messages import TYPESTORE, serialize
from gwr_predictor.pipeline.errors import PipelineError

#: what rosbag2 writes as `ros_distro` into a bag's metadata on Jazzy; rosbags writes "rosbags"
ROS_DISTRO = "jazzy"
_ROSBAGS_DISTRO = "ros_distro: rosbags"


def _close_as_rosbag2(writer: Writer) -> None:
    """Close `writer` with rosbag2's `ros_distro` (rosbags writes its own name) in the MCAP's rosbag2
    metadata record and in metadata.yaml, so tools that read it see a Jazzy bag."""
    rosbag2_distro = f"ros_distro: {ROS_DISTRO}"
    storage = writer.storage
    if storage is not None:
        close_storage = storage.close
        # the one hook into the metadata record rosbags writes as it closes
        storage.close = lambda version, metadata: close_storage(  # type: ignore[method-assign]
            version, metadata.replace(_ROSBAGS_DISTRO, rosbag2_distro))
    writer.close()
    tmp = writer.metapath.with_suffix(".yaml.tmp")
    tmp.write_text(writer.metapath.read_text(encoding="utf-8").replace(_ROSBAGS_DISTRO, rosbag2_distro),
                   encoding="utf-8")
    tmp.replace(writer.metapath)


class BagWriter:
    """A rosbag2 (version 9, MCAP) bag writer for a fixed set of topics; use as a context manager.

    `flush_every` > 0 flushes after that many messages (see the module docstring on crashes).
    `offered_qos(topic)`, when given, returns the QoS profiles the topic's publishers offer; it is
    asked when the topic's first message is written (or on close for a topic without messages).
    """

    def __init__(self, path: str | os.PathLike[str], topics: Mapping[str, str], *, flush_every: int = 0,
                 offered_qos: Callable[[str], Sequence[Qos]] | None = None) -> None:
        self.path = Path(path)
        if not topics:
            raise PipelineError(f"{self.path}: BagWriter needs at least one topic")
        for topic, msgtype in topics.items():
            self._check_type(topic, msgtype)
        if isinstance(flush_every, bool) or not isinstance(flush_every, int) or flush_every < 0:
            raise PipelineError(f"{self.path}: flush_every must be an int >= 0, got {flush_every!r}")
        self.topics = dict(topics)
        self.flush_every = flush_every
        self.offered_qos = offered_qos
        self.messages_written: dict[str, int] = dict.fromkeys(self.topics, 0)
        self._writer: Writer | None = None
        self._connections: dict[str, Any] = {}
        self._since_flush = 0

    @property
    def total_written(self) -> int:
        return sum(self.messages_written.values())

    def _check_type(self, topic: str, msgtype: str) -> None:
        if msgtype not in TYPESTORE.types:
            raise PipelineError(f"{self.path}: topic {topic!r} has type {msgtype!r}, unknown to the ROS 2 Jazzy store")

    def add_topic(self, topic: str, msgtype: str) -> None:
        """Declare one more topic while writing: one that appeared after the start (a tracked body's)."""
        self._check_type(topic, msgtype)
        self.topics.setdefault(topic, msgtype)
        self.messages_written.setdefault(topic, 0)

    def __enter__(self) -> BagWriter:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def open(self) -> None:
        if self.path.exists():
            raise PipelineError(f"{self.path}: bag path exists already; choose a new directory")
        try:
            writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
            writer.open()
        except (OSError, WriterError) as err:
            raise PipelineError(f"{self.path}: cannot create bag: {err}") from err
        self._writer = writer

    def _connection(self, topic: str) -> Any:
        """The topic's connection, added on first use with the QoS its publishers offer now."""
        conn = self._connections.get(topic)
        if conn is not None:
            return conn
        writer = self._require_open()
        msgtype = self.topics.get(topic)
        if msgtype is None:
            raise PipelineError(f"{self.path}: topic {topic!r} was not declared (declared: {sorted(self.topics)})")
        qos = list(self.offered_qos(topic)) if self.offered_qos is not None else []
        try:
            conn = writer.add_connection(topic, msgtype, typestore=TYPESTORE, offered_qos_profiles=qos)
        except (OSError, WriterError) as err:
            self._abort()
            raise PipelineError(f"{self.path}: cannot add topic {topic!r}: {err}") from err
        self._connections[topic] = conn
        return conn

    def write_raw(self, topic: str, timestamp_ns: int, data: bytes | memoryview) -> None:
        """Store CDR bytes as received from DDS (receive time `timestamp_ns`)."""
        writer = self._require_open()
        conn = self._connection(topic)
        if isinstance(timestamp_ns, bool) or not isinstance(timestamp_ns, (int, np.integer)) or timestamp_ns < 0:
            raise PipelineError(f"{self.path}: timestamp_ns must be an int >= 0, got {timestamp_ns!r}")
        try:
            writer.write(conn, int(timestamp_ns), data)
        except OSError as err:
            self._abort()
            raise PipelineError(f"{self.path}: write failed ({err.strerror or err}); bag aborted, "
                                f"recover what was flushed with recover_bag") from err
        self.messages_written[topic] += 1
        self._since_flush += 1
        if self.flush_every and self._since_flush >= self.flush_every:
            self.flush()

    def write(self, topic: str, timestamp_ns: int, msg: Any) -> None:
        """Serialise a rosbags message object with the topic's type and store it."""
        self.write_raw(topic, timestamp_ns, serialize(msg, self.topics.get(topic)))

    def flush(self) -> None:
        """Put every message written so far on disk as a complete MCAP chunk."""
        writer = self._require_open()
        storage = writer.storage  # an McapWriter once open (the storage plugin is MCAP)
        try:
            if isinstance(storage, McapWriter) and storage.chunk.bio.tell():
                storage.close_chunk()
            if isinstance(storage, McapWriter):
                storage.bio.flush()
                os.fsync(storage.bio.fileno())
        except OSError as err:
            self._abort()
            raise PipelineError(f"{self.path}: flush failed ({err.strerror or err}); bag aborted") from err
        self._since_flush = 0

    def close(self) -> None:
        """Write the MCAP summary and metadata.yaml (idempotent)."""
        if self._writer is None:
            return
        for topic in self.topics:  # topics without messages are listed too, as rosbag2 does
            self._connection(topic)
        writer, self._writer = self._writer, None
        try:
            _close_as_rosbag2(writer)
        except (OSError, WriterError) as err:
            writer.abort()
            raise PipelineError(f"{self.path}: closing the bag failed ({err}); recover with recover_bag") from err

    def _abort(self) -> None:
        writer, self._writer = self._writer, None
        if writer is not None:
            writer.abort()

    def _require_open(self) -> Writer:
        if self._writer is None:
            raise PipelineError(f"{self.path}: bag writer is not open (use it as a context manager)")
        return self._writer
