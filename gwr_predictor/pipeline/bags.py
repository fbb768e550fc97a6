"""rosbag2 bags with MCAP storage, written and read with `rosbags` (no rosbag2_py on PyPI).

Why this module: the recorder node writes the CDR bytes it receives from DDS unchanged, the player
and the reports read them back, and both need the same guarantees: bags `ros2 bag` accepts
(metadata version 9, storage mcap), errors that name the file, and a recorder crash that costs
seconds of data, not the whole bag.

Crash safety: rosbags keeps the current MCAP chunk (up to 1 MiB) in memory and writes the
summary, footer and metadata.yaml only on close. `BagWriter.flush()` (or `flush_every`) closes the
pending chunk and flushes the file, so after a crash everything up to the last flush is on disk;
`recover_bag()` rebuilds a valid bag (MCAP summary + metadata.yaml) from those chunks.

Offered QoS: as rosbag2 does, each topic carries the QoS profiles its publishers offered
(`offered_qos_profiles` in metadata.yaml and in the MCAP channel metadata), so that `ros2 bag play`
and `bag_player` replay with them (`replay_qos`). The writer therefore adds a topic's connection
when its first message arrives (the publishers are known by then) or, without messages, on close.

Reading accepts a bag directory or a bare `.mcap` file (e.g. one copied out of a bag).
"""

from __future__ import annotations

import os
import shutil
import struct
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path, PurePath
from typing import Any, NamedTuple

import numpy as np
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.rosbag2.errors import ReaderError, WriterError
from rosbags.rosbag2.metadata import parse_qos
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.typesys import Stores, get_typestore

from gwr_predictor.files.user_files import open_to_read, regular_file_size
from gwr_predictor.files.yaml_safe import load_yaml
from gwr_predictor.parameters.spec import ParameterError
from gwr_predictor.pipeline import conventions
from gwr_predictor.pipeline.conventions import ArrayDim, PackedArray
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.mcap_limits import MAGIC as MCAP_MAGIC
from gwr_predictor.pipeline.mcap_limits import MAX_CHUNK_BYTES, check_mcap

JOINT_STATE = "sensor_msgs/msg/JointState"
FLOAT64_MULTIARRAY = "std_msgs/msg/Float64MultiArray"
DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
_MCAP_MAGIC = MCAP_MAGIC

#: what rosbag2 writes as `ros_distro` into a bag's metadata on Jazzy; rosbags writes "rosbags"
ROS_DISTRO = "jazzy"
_ROSBAGS_DISTRO = "ros_distro: rosbags"
#: A bag's metadata.yaml: about 1 kB per topic (with its QoS profiles) and 150 bytes per split file.
MAX_METADATA_BYTES = 1 << 20
#: The ROS 2 Jazzy message definitions (sensor_msgs, std_msgs, diagnostic_msgs, ...).
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)


#: PipelineError, for a bag that cannot be written or read; the message names the bag path and the cause.
BagError = PipelineError


class BagMessage(NamedTuple):
    """One stored message: raw CDR bytes and, when the type is known, the decoded object."""

    topic: str
    msgtype: str
    timestamp_ns: int
    raw: bytes
    msg: Any


@dataclass(frozen=True)
class BagInfo:
    """What a bag holds: topics with type and count, time span, storage."""

    path: Path
    storage: str
    message_count: int
    start_ns: int
    end_ns: int
    topics: dict[str, tuple[str, int]]
    #: topic -> the QoS profiles its publishers offered while recording (empty: not recorded)
    offered_qos: dict[str, list[Qos]] = field(default_factory=dict)

    @property
    def duration_s(self) -> float:
        return max(0, self.end_ns - self.start_ns) / 1e9


# --- message helpers ----------------------------------------------------------------------------


def _stamp(seconds: float) -> Any:
    """Seconds -> a rosbags builtin_interfaces/Time (`conventions.split_stamp`)."""
    sec, nanosec = conventions.split_stamp(seconds)
    return TYPESTORE.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)


stamp_seconds = conventions.stamp_seconds


def joint_state_msg(names: Iterable[str], positions: np.ndarray, stamp: float, *,
                    velocities: np.ndarray | None = None, frame_id: str = "") -> Any:
    """A rosbags sensor_msgs/JointState (names, positions in rad, header stamp in seconds)."""
    names = list(names)
    pos = np.ascontiguousarray(positions, dtype=np.float64).ravel()
    if pos.size != len(names):
        raise BagError(f"JointState needs one position per name: {len(names)} names, {pos.size} positions")
    vel = np.empty(0) if velocities is None else np.ascontiguousarray(velocities, dtype=np.float64).ravel()
    t = TYPESTORE.types
    header = t["std_msgs/msg/Header"](stamp=_stamp(stamp), frame_id=frame_id)
    return t[JOINT_STATE](header=header, name=names, position=pos, velocity=vel, effort=np.empty(0))


def joint_state_arrays(msg: Any) -> tuple[float, tuple[str, ...], np.ndarray]:
    """JointState -> (stamp seconds, names, positions)."""
    return stamp_seconds(msg.header.stamp), tuple(msg.name), np.asarray(msg.position, dtype=float)


def multiarray_msg(packed: PackedArray) -> Any:
    """conventions.PackedArray -> rosbags std_msgs/Float64MultiArray."""
    t = TYPESTORE.types
    dims = [t["std_msgs/msg/MultiArrayDimension"](label=d.label, size=d.size, stride=d.stride) for d in packed.dims]
    layout = t["std_msgs/msg/MultiArrayLayout"](dim=dims, data_offset=packed.data_offset)
    return t[FLOAT64_MULTIARRAY](layout=layout, data=np.ascontiguousarray(packed.data, dtype=np.float64))


def packed_array(msg: Any) -> PackedArray:
    """Float64MultiArray -> conventions.PackedArray (unpack with conventions.unpack_*)."""
    dims = tuple(ArrayDim(d.label, int(d.size), int(d.stride)) for d in msg.layout.dim)
    return PackedArray(dims, int(msg.layout.data_offset), np.asarray(msg.data, dtype=float))


def serialize(msg: Any, msgtype: str | None = None) -> bytes:
    """CDR bytes of a rosbags message object (what DDS would carry)."""
    return bytes(TYPESTORE.serialize_cdr(msg, msgtype or msg.__msgtype__))


def deserialize(raw: bytes, msgtype: str) -> Any:
    return TYPESTORE.deserialize_cdr(raw, msgtype)


# --- offered QoS ---------------------------------------------------------------------------------

_INFINITE_NS = 2**63 - 1  # RMW_DURATION_INFINITE


def _qos_time(ns: int) -> QosTime:
    sec, nsec = divmod(min(max(0, int(ns)), _INFINITE_NS), 1_000_000_000)
    return QosTime(sec, nsec)


def qos_profile(*, history: str, depth: int, reliability: str, durability: str, deadline_ns: int = _INFINITE_NS,
                lifespan_ns: int = _INFINITE_NS, liveliness: str = "automatic",
                liveliness_lease_ns: int = _INFINITE_NS, avoid_ros_namespace_conventions: bool = False) -> Qos:
    """One offered QoS profile as stored in a bag, from policy names ('keep_last', 'reliable', ...).

    Policy names are rclpy's enum names in any case, so a node converts with `policy.name`.
    BagError names a policy value that ROS 2 does not have.
    """
    def policy(enum: Any, kind: str, value: str) -> Any:
        try:
            return enum[str(value).upper()]
        except KeyError:
            raise BagError(f"QoS {kind} {value!r} is not one of {[m.name.lower() for m in enum]}") from None

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


# --- writing ------------------------------------------------------------------------------------


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
            raise BagError(f"{self.path}: BagWriter needs at least one topic")
        for topic, msgtype in topics.items():
            self._check_type(topic, msgtype)
        if isinstance(flush_every, bool) or not isinstance(flush_every, int) or flush_every < 0:
            raise BagError(f"{self.path}: flush_every must be an int >= 0, got {flush_every!r}")
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
            raise BagError(f"{self.path}: topic {topic!r} has type {msgtype!r}, unknown to the ROS 2 Jazzy store")

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
            raise BagError(f"{self.path}: bag path exists already; choose a new directory")
        try:
            writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
            writer.open()
        except (OSError, WriterError) as err:
            raise BagError(f"{self.path}: cannot create bag: {err}") from err
        self._writer = writer

    def _connection(self, topic: str) -> Any:
        """The topic's connection, added on first use with the QoS its publishers offer now."""
        conn = self._connections.get(topic)
        if conn is not None:
            return conn
        writer = self._require_open()
        msgtype = self.topics.get(topic)
        if msgtype is None:
            raise BagError(f"{self.path}: topic {topic!r} was not declared (declared: {sorted(self.topics)})")
        qos = list(self.offered_qos(topic)) if self.offered_qos is not None else []
        try:
            conn = writer.add_connection(topic, msgtype, typestore=TYPESTORE, offered_qos_profiles=qos)
        except (OSError, WriterError) as err:
            self._abort()
            raise BagError(f"{self.path}: cannot add topic {topic!r}: {err}") from err
        self._connections[topic] = conn
        return conn

    def write_raw(self, topic: str, timestamp_ns: int, data: bytes | memoryview) -> None:
        """Store CDR bytes as received from DDS (receive time `timestamp_ns`)."""
        writer = self._require_open()
        conn = self._connection(topic)
        if isinstance(timestamp_ns, bool) or not isinstance(timestamp_ns, (int, np.integer)) or timestamp_ns < 0:
            raise BagError(f"{self.path}: timestamp_ns must be an int >= 0, got {timestamp_ns!r}")
        try:
            writer.write(conn, int(timestamp_ns), data)
        except OSError as err:
            self._abort()
            raise BagError(f"{self.path}: write failed ({err.strerror or err}); bag aborted, "
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
            raise BagError(f"{self.path}: flush failed ({err.strerror or err}); bag aborted") from err
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
            raise BagError(f"{self.path}: closing the bag failed ({err}); recover with recover_bag") from err

    def _abort(self) -> None:
        writer, self._writer = self._writer, None
        if writer is not None:
            writer.abort()

    def _require_open(self) -> Writer:
        if self._writer is None:
            raise BagError(f"{self.path}: bag writer is not open (use it as a context manager)")
        return self._writer


# --- reading ------------------------------------------------------------------------------------


def _open_reader(path: Path) -> Reader:
    """A rosbags Reader of a bag directory or of a bare .mcap file, its files checked first
    (`check_bag_files`)."""
    if path.suffix == ".mcap" and not path.is_dir():
        check_mcap(path, BagError)
        try:
            reader = Reader(path)
            reader.open()
        except (ReaderError, OSError, KeyError, ValueError, struct.error) as err:
            raise BagError(f"{path}: unreadable MCAP file: {err}") from err
        return reader
    if not path.is_dir():
        raise BagError(f"{path}: neither a bag directory nor a .mcap file")
    if not (path / "metadata.yaml").exists():
        raise BagError(f"{path}: no metadata.yaml (writer not closed? try recover_bag({str(path)!r}))")
    check_bag_files(path)
    try:
        reader = Reader(path)
        reader.open()
    except (ReaderError, OSError, KeyError, ValueError) as err:
        raise BagError(f"{path}: unreadable bag: {err}") from err
    return reader


def check_bag_files(path: Path) -> None:
    """BagError unless the bag folder's metadata.yaml is a regular file of at most `MAX_METADATA_BYTES`
    without YAML aliases and every storage file it names is a regular file (an MCAP one within its
    declared sizes, `mcap_limits`): what rosbags then reads cannot block or exhaust memory."""
    metadata = load_yaml(path / "metadata.yaml", MAX_METADATA_BYTES, "bag's metadata.yaml", BagError)
    info = metadata.get("rosbag2_bagfile_information") if isinstance(metadata, dict) else None
    if not isinstance(info, dict) or not isinstance(info.get("relative_file_paths"), list):
        return  # rosbags says what is missing
    for name in info["relative_file_paths"]:
        storage = path / PurePath(str(name)).name  # where rosbags looks for it
        if not storage.exists():
            continue  # rosbags names the missing files
        if info.get("storage_identifier") == "mcap":
            check_mcap(storage, BagError)
        else:
            regular_file_size(storage, None, "bag storage file", BagError)


def read_bag(path: str | os.PathLike[str], topics: Iterable[str] | None = None, *,
             decode: bool = True, undecodable: dict[str, int] | None = None) -> Iterator[BagMessage]:
    """Messages of a bag in time order; `topics` restricts, `decode` adds the message objects.

    A message that does not decode raises BagError naming it, unless a dict `undecodable` is
    given: then such messages (a hostile publisher recorded raw, a few corrupt bytes) are skipped
    and counted there per topic, and the rest of the bag is read (`decode=False` decodes them
    only for this check).
    """
    path = Path(path)
    wanted = None if topics is None else set(topics)
    reader = _open_reader(path)
    try:
        conns = [c for c in reader.connections if wanted is None or c.topic in wanted]
        if not conns:
            return  # (rosbags reads every topic when given no connection)
        for conn, timestamp, raw in reader.messages(connections=conns):
            msg = None
            if (decode or undecodable is not None) and conn.msgtype in TYPESTORE.types:
                try:
                    msg = TYPESTORE.deserialize_cdr(raw, conn.msgtype)
                except Exception as err:  # rosbags raises plain exceptions on malformed CDR
                    if undecodable is None:
                        raise BagError(f"{path}: cannot decode a {conn.msgtype} on {conn.topic} at {timestamp} "
                                       f"ns: {err}") from err
                    undecodable[conn.topic] = undecodable.get(conn.topic, 0) + 1
                    continue
            yield BagMessage(conn.topic, conn.msgtype, int(timestamp), bytes(raw), msg if decode else None)
    except ReaderError as err:
        raise BagError(f"{path}: {err}") from err
    finally:
        reader.close()


def check_counts(info: BagInfo, read: Mapping[str, int]) -> None:
    """BagError if the messages read per topic (decoded or not) differ from what metadata.yaml
    claims: a metadata.yaml that lies (edited, or copied from another bag) would make every count
    derived from it wrong."""
    claimed = {t: n for t, (_, n) in info.topics.items() if n or read.get(t)}
    actual = {t: n for t, n in read.items() if n}
    if claimed != actual:
        diff = ", ".join(f"{t}: metadata {claimed.get(t, 0)}, file {actual.get(t, 0)}"
                         for t in sorted(set(claimed) | set(actual)) if claimed.get(t, 0) != actual.get(t, 0))
        raise BagError(f"{info.path}: metadata.yaml does not match the messages in the file ({diff}); "
                       "move metadata.yaml away and run recover_bag to rebuild it")


def bag_info(path: str | os.PathLike[str]) -> BagInfo:
    """Topics, counts and time span of a bag (from its metadata)."""
    path = Path(path)
    reader = _open_reader(path)
    try:
        topics: dict[str, tuple[str, int]] = {}
        qos: dict[str, list[Qos]] = {}
        for conn in reader.connections:
            old = topics.get(conn.topic, (conn.msgtype, 0))
            topics[conn.topic] = (conn.msgtype, old[1] + conn.msgcount)
            qos.setdefault(conn.topic, []).extend(getattr(conn.ext, "offered_qos_profiles", []))
        count = reader.message_count
        files = [path] if path.is_file() else list(path.iterdir())
        return BagInfo(path, "mcap" if any(p.suffix == ".mcap" for p in files) else "sqlite3", count,
                       reader.start_time if count else 0, reader.end_time - 1 if count else 0, topics, qos)
    finally:
        reader.close()


# --- recovery -----------------------------------------------------------------------------------


class _Salvage(NamedTuple):
    channels: dict[int, tuple[str, str]]  # channel id -> (topic, msgtype)
    messages: list[tuple[int, int, bytes]]  # (channel id, log_time, data)
    complete: bool  # the file had its footer
    qos: dict[str, str]  # topic -> offered_qos_profiles (YAML) of its channel


def _salvage_mcap(mcap_path: Path) -> _Salvage:
    """Schemas, channels and messages of every complete chunk, read with the `mcap` library."""
    from mcap.exceptions import McapError
    from mcap.records import Channel, Chunk, Footer, Message, Schema
    from mcap.stream_reader import StreamReader, breakup_chunk

    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, str]] = {}
    messages: list[tuple[int, int, bytes]] = []
    complete = False
    qos: dict[str, str] = {}

    def take(record: Any) -> None:
        if isinstance(record, Schema):
            schemas[record.id] = record.name
        elif isinstance(record, Channel):
            channels[record.id] = (record.topic, schemas.get(record.schema_id, ""))
            if record.metadata.get("offered_qos_profiles"):
                qos[record.topic] = record.metadata["offered_qos_profiles"]
        elif isinstance(record, Message) and record.channel_id in channels:
            messages.append((record.channel_id, record.log_time, bytes(record.data)))

    with open_to_read(mcap_path, None, "MCAP file", BagError) as stream:
        try:
            for record in StreamReader(stream, emit_chunks=True, record_size_limit=MAX_CHUNK_BYTES).records:
                if isinstance(record, Chunk):
                    if record.uncompressed_size > MAX_CHUNK_BYTES or \
                            (not record.compression and len(record.data) != record.uncompressed_size):
                        break  # a chunk cut off by the crash (or a forged size, never allocated)
                    for inner in breakup_chunk(record):
                        take(inner)
                elif isinstance(record, Footer):
                    complete = True
                else:
                    take(record)
        except (McapError, struct.error, ValueError):
            pass  # the file ends inside a record (or a compressed chunk is cut): keep what was read
    return _Salvage(channels, messages, complete, qos)


def _mcap_complete(mcap_path: Path) -> bool:
    """The file ends with the MCAP magic (its writer closed it), without reading it."""
    try:
        with open_to_read(mcap_path, None, "MCAP file", BagError) as f:
            f.seek(0, os.SEEK_END)
            if f.tell() < 2 * len(_MCAP_MAGIC):
                return False
            f.seek(-len(_MCAP_MAGIC), os.SEEK_END)
            return f.read() == _MCAP_MAGIC
    except (OSError, BagError):
        return False


def recover_bag(path: str | os.PathLike[str]) -> BagInfo:
    """Make a bag whose writer never closed readable again, in place; returns its info.

    Reads the MCAP file sequentially, keeps the messages of every complete chunk, and rewrites a
    complete MCAP file plus metadata.yaml. The damaged file is kept as `<name>.mcap.damaged`.
    A bag with metadata.yaml and a complete MCAP file (it ends with the MCAP magic) is left
    untouched; with a truncated MCAP file its metadata.yaml is kept as `metadata.yaml.damaged` and
    rewritten from what was recovered. Any failure (a full disk...) is a BagError: the new bag is
    written next to the old one first, so the damaged bag stays as it was.
    """
    path = Path(path)
    if not path.is_dir():
        raise BagError(f"{path}: not a bag directory")
    files = sorted(path.glob("*.mcap"))
    metadata = path / "metadata.yaml"
    if metadata.is_file() and (len(files) != 1 or _mcap_complete(files[0])):
        return bag_info(path)
    if len(files) != 1:
        raise BagError(f"{path}: expected one .mcap file to recover, found {len(files)}")
    damaged = files[0]
    salvage = _read_salvage(damaged)
    staging_root = path.parent / f".{path.name}.recovering"
    staging = _write_staging(path, staging_root, salvage)
    _swap_in(path, staging, damaged, metadata)
    shutil.rmtree(staging_root, ignore_errors=True)
    return bag_info(path)


def _os_reason(err: BaseException) -> str:
    """The OS's words for an error (for BagError wrapping an OSError, its cause's)."""
    cause = err if isinstance(err, OSError) else err.__cause__
    return (cause.strerror or str(cause)) if isinstance(cause, OSError) else str(err)


def _read_salvage(damaged: Path) -> _Salvage:
    """What `_salvage_mcap` finds in a damaged file; BagError when nothing is recoverable."""
    try:
        with open_to_read(damaged, None, "MCAP file", BagError) as f:
            if f.read(8) != _MCAP_MAGIC:
                raise BagError(f"{damaged}: no MCAP header; nothing recoverable (the writer never flushed)")
        salvage = _salvage_mcap(damaged)
    except OSError as err:
        raise BagError(f"{damaged}: cannot read it ({_os_reason(err)})") from err
    if not salvage.channels:
        raise BagError(f"{damaged}: no complete chunk on disk; nothing recoverable (the writer never flushed)")
    unknown = {t for _, t in salvage.channels.values() if t not in TYPESTORE.types}
    if unknown:
        raise BagError(f"{damaged}: cannot recover message types unknown to the Jazzy store: {sorted(unknown)}")
    return salvage


def _write_staging(path: Path, staging_root: Path, salvage: _Salvage) -> Path:
    """The recovered bag, written as `<staging_root>/<name>`; on failure nothing is left behind."""
    staging = staging_root / path.name
    topics = {topic: msgtype for topic, msgtype in salvage.channels.values()}
    cid_topic = {cid: topic for cid, (topic, _) in salvage.channels.items()}
    try:
        offered = {topic: parse_qos(text) for topic, text in salvage.qos.items()}
    except Exception:  # unreadable QoS text: the messages matter more than their QoS
        offered = {}
    try:
        if staging_root.exists():
            shutil.rmtree(staging_root)
        staging_root.mkdir()
        with BagWriter(staging, topics, offered_qos=lambda topic: offered.get(topic, [])) as writer:
            for cid, log_time, data in sorted(salvage.messages, key=lambda m: m[1]):
                writer.write_raw(cid_topic[cid], log_time, data)
    except (OSError, BagError) as err:
        shutil.rmtree(staging_root, ignore_errors=True)
        raise BagError(f"{path}: cannot write the recovered bag next to it ({_os_reason(err)}); "
                       "the bag is unchanged") from err
    return staging


def _swap_in(path: Path, staging: Path, damaged: Path, metadata: Path) -> None:
    """Keep the damaged files under new names and move the recovered ones in; undone on failure."""
    moves = [(damaged, damaged.with_name(damaged.name + ".damaged"))]
    if metadata.is_file():  # it describes the file before the damage: keep it for inspection
        moves.append((metadata, path / "metadata.yaml.damaged"))
    moves += [(item, path / item.name) for item in sorted(staging.iterdir())]
    done: list[tuple[Path, Path]] = []
    try:
        for source, target in moves:
            source.rename(target)
            done.append((source, target))
    except OSError as err:
        undone = True
        for source, target in reversed(done):
            try:
                target.rename(source)
            except OSError:
                undone = False
        state = "the bag is unchanged" if undone else "the bag is half moved"
        raise BagError(f"{path}: cannot move the recovered bag into place ({_os_reason(err)}); {state}, the "
                       f"recovered copy is kept in {staging}") from err


# --- replay: what the bag player does to a recording, without ROS ---------------------------------


def parse_remaps(entries: list[str]) -> dict[str, str]:
    """['a:=b', ...] -> {'/a': '/b'}; ParameterError naming a malformed entry."""
    remaps = {}
    for entry in entries:
        src, sep, dst = entry.partition(":=")
        if not sep or not src.strip() or not dst.strip():
            raise ParameterError(f"remap entry {entry!r} must look like 'from:=to'")
        remaps["/" + src.strip().lstrip("/")] = "/" + dst.strip().lstrip("/")
    return remaps


def shift_stamp(raw: bytes, msgtype: str, offset_s: float) -> bytes:
    """The CDR bytes of a message whose stamps are moved by `offset_s` (other types unchanged):
    JointState and DiagnosticArray headers (clamped at 0), the stamp in data[0] of a labelled array.

    Re-encoded with rosbags (exact sizes, so that a recorder can store the result again), not with
    rclpy's serializer, which may append padding that rosbags rejects.
    """
    if msgtype not in (JOINT_STATE, FLOAT64_MULTIARRAY, DIAGNOSTIC_ARRAY):
        return raw
    msg = deserialize(raw, msgtype)
    if msgtype == FLOAT64_MULTIARRAY:
        if msg.layout.data_offset >= 1 and len(msg.data) >= 1:
            data = np.array(msg.data, dtype=np.float64)
            data[0] += offset_s
            msg.data = data
    else:
        msg.header.stamp = _stamp(max(0.0, stamp_seconds(msg.header.stamp) + offset_s))
    return serialize(msg, msgtype)
