"""Reading rosbag2 bags with `rosbags`: their messages in time order (`read_bag`) and what they hold
(`bag_info`: topics, counts, time span, offered QoS), the bag's files checked first so that what
rosbags then reads cannot block or exhaust memory.

Reading accepts a bag directory or a bare `.mcap` file (e.g. one copied out of a bag).
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path, PurePath
from typing import Any, NamedTuple

from rosbags.interfaces import Qos
from rosbags.rosbag2 import Reader
from rosbags.rosbag2.errors import ReaderError

from gwr_predictor.files.user_files import regular_file_size
from gwr_predictor.files.yaml_safe import load_yaml
from gwr_predictor.pipeline.bag_messages import TYPESTORE
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.mcap_limits import check_mcap

#: A bag's metadata.yaml: about 1 kB per topic (with its QoS profiles) and 150 bytes per split file.
MAX_METADATA_BYTES = 1 << 20


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


def _open_reader(path: Path) -> Reader:
    """A rosbags Reader of a bag directory or of a bare .mcap file, its files checked first
    (`check_bag_files`)."""
    if path.suffix == ".mcap" and not path.is_dir():
        check_mcap(path, PipelineError)
        try:
            reader = Reader(path)
            reader.open()
        except (ReaderError, OSError, KeyError, ValueError, struct.error) as err:
            raise PipelineError(f"{path}: unreadable MCAP file: {err}") from err
        return reader
    if not path.is_dir():
        raise PipelineError(f"{path}: neither a bag directory nor a .mcap file")
    if not (path / "metadata.yaml").exists():
        raise PipelineError(f"{path}: no metadata.yaml (writer not closed? try recover_bag({str(path)!r}))")
    check_bag_files(path)
    try:
        reader = Reader(path)
        reader.open()
    except (ReaderError, OSError, KeyError, ValueError) as err:
        raise PipelineError(f"{path}: unreadable bag: {err}") from err
    return reader


def check_bag_files(path: Path) -> None:
    """PipelineError unless the bag folder's metadata.yaml is a regular file of at most `MAX_METADATA_BYTES`
    without YAML aliases and every storage file it names is a regular file (an MCAP one within its
    declared sizes, `mcap_limits`): what rosbags then reads cannot block or exhaust memory."""
    metadata = load_yaml(path / "metadata.yaml", MAX_METADATA_BYTES, "bag's metadata.yaml", PipelineError)
    info = metadata.get("rosbag2_bagfile_information") if isinstance(metadata, dict) else None
    if not isinstance(info, dict) or not isinstance(info.get("relative_file_paths"), list):
        return  # rosbags says what is missing
    for name in info["relative_file_paths"]:
        storage = path / PurePath(str(name)).name  # where rosbags looks for it
        if not storage.exists():
            continue  # rosbags names the missing files
        if info.get("storage_identifier") == "mcap":
            check_mcap(storage, PipelineError)
        else:
            regular_file_size(storage, None, "bag storage file", PipelineError)


def read_bag(path: str | os.PathLike[str], topics: Iterable[str] | None = None, *,
             decode: bool = True, undecodable: dict[str, int] | None = None) -> Iterator[BagMessage]:
    """Messages of a bag in time order; `topics` restricts, `decode` adds the message objects.

    A message that does not decode raises PipelineError naming it, unless a dict `undecodable` is
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
                        raise PipelineError(f"{path}: cannot decode a {conn.msgtype} on {conn.topic} at {timestamp} "
                                            f"ns: {err}") from err
                    undecodable[conn.topic] = undecodable.get(conn.topic, 0) + 1
                    continue
            yield BagMessage(conn.topic, conn.msgtype, int(timestamp), bytes(raw), msg if decode else None)
    except ReaderError as err:
        raise PipelineError(f"{path}: {err}") from err
    finally:
        reader.close()


def check_counts(info: BagInfo, read: Mapping[str, int]) -> None:
    """PipelineError if the messages read per topic (decoded or not) differ from what metadata.yaml
    claims: a metadata.yaml that lies (edited, or copied from another bag) would make every count
    derived from it wrong."""
    claimed = {t: n for t, (_, n) in info.topics.items() if n or read.get(t)}
    actual = {t: n for t, n in read.items() if n}
    if claimed != actual:
        diff = ", ".join(f"{t}: metadata {claimed.get(t, 0)}, file {actual.get(t, 0)}"
                         for t in sorted(set(claimed) | set(actual)) if claimed.get(t, 0) != actual.get(t, 0))
        raise PipelineError(f"{info.path}: metadata.yaml does not match the messages in the file ({diff}); "
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
