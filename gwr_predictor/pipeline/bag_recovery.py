"""Making a bag whose writer never closed (a crash, a killed recorder) readable again: `recover_bag`
keeps the messages of every complete MCAP chunk the writer flushed (`BagWriter.flush`) and rewrites
a complete bag beside the damaged files, which are kept.
"""

from __future__ import annotations

import os
import shutil
import struct
from pathlib import Path
from typing import Any, NamedTuple

from mcap.exceptions import McapError
from mcap.records import Channel, Chunk, Footer, Message, Schema
from mcap.stream_reader import StreamReader, breakup_chunk
from rosbags.rosbag2.metadata import parse_qos

from gwr_predictor.files.user_files import open_to_read
from gwr_predictor.pipeline.bag_messages import TYPESTORE
from gwr_predictor.pipeline.bag_reader import BagInfo, bag_info
from gwr_predictor.pipeline.bag_writer import BagWriter
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.mcap_limits import MAGIC as MCAP_MAGIC
from gwr_predictor.pipeline.mcap_limits import MAX_CHUNK_BYTES

_MCAP_MAGIC = MCAP_MAGIC


class _Salvage(NamedTuple):
    channels: dict[int, tuple[str, str]]  # channel id -> (topic, msgtype)
    messages: list[tuple[int, int, bytes]]  # (channel id, log_time, data)
    complete: bool  # the file had its footer
    qos: dict[str, str]  # topic -> offered_qos_profiles (YAML) of its channel


def _salvage_mcap(mcap_path: Path) -> _Salvage:
    """Schemas, channels and messages of every complete chunk, read with the `mcap` library."""
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

    with open_to_read(mcap_path, None, "MCAP file", PipelineError) as stream:
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
        with open_to_read(mcap_path, None, "MCAP file", PipelineError) as f:
            f.seek(0, os.SEEK_END)
            if f.tell() < 2 * len(_MCAP_MAGIC):
                return False
            f.seek(-len(_MCAP_MAGIC), os.SEEK_END)
            return f.read() == _MCAP_MAGIC
    except (OSError, PipelineError):
        return False


def recover_bag(path: str | os.PathLike[str]) -> BagInfo:
    """Make a bag whose writer never closed readable again, in place; returns its info.

    Reads the MCAP file sequentially, keeps the messages of every complete chunk, and rewrites a
    complete MCAP file plus metadata.yaml. The damaged file is kept as `<name>.mcap.damaged`.
    A bag with metadata.yaml and a complete MCAP file (it ends with the MCAP magic) is left
    untouched; with a truncated MCAP file its metadata.yaml is kept as `metadata.yaml.damaged` and
    rewritten from what was recovered. Any failure (a full disk...) is a PipelineError: the new bag is
    written next to the old one first, so the damaged bag stays as it was.
    """
    path = Path(path)
    if not path.is_dir():
        raise PipelineError(f"{path}: not a bag directory")
    files = sorted(path.glob("*.mcap"))
    metadata = path / "metadata.yaml"
    if metadata.is_file() and (len(files) != 1 or _mcap_complete(files[0])):
        return bag_info(path)
    if len(files) != 1:
        raise PipelineError(f"{path}: expected one .mcap file to recover, found {len(files)}")
    damaged = files[0]
    salvage = _read_salvage(damaged)
    staging_root = path.parent / f".{path.name}.recovering"
    staging = _write_staging(path, staging_root, salvage)
    _swap_in(path, staging, damaged, metadata)
    shutil.rmtree(staging_root, ignore_errors=True)
    return bag_info(path)


def _os_reason(err: BaseException) -> str:
    """The OS's words for an error (for PipelineError wrapping an OSError, its cause's)."""
    cause = err if isinstance(err, OSError) else err.__cause__
    return (cause.strerror or str(cause)) if isinstance(cause, OSError) else str(err)


def _read_salvage(damaged: Path) -> _Salvage:
    """What `_salvage_mcap` finds in a damaged file; PipelineError when nothing is recoverable."""
    try:
        with open_to_read(damaged, None, "MCAP file", PipelineError) as f:
            if f.read(8) != _MCAP_MAGIC:
                raise PipelineError(f"{damaged}: no MCAP header; nothing recoverable (the writer never flushed)")
        salvage = _salvage_mcap(damaged)
    except OSError as err:
        raise PipelineError(f"{damaged}: cannot read it ({_os_reason(err)})") from err
    if not salvage.channels:
        raise PipelineError(f"{damaged}: no complete chunk on disk; nothing recoverable (the writer never flushed)")
    unknown = {t for _, t in salvage.channels.values() if t not in TYPESTORE.types}
    if unknown:
        raise PipelineError(f"{damaged}: cannot recover message types unknown to the Jazzy store: {sorted(unknown)}")
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
    except (OSError, PipelineError) as err:
        shutil.rmtree(staging_root, ignore_errors=True)
        raise PipelineError(f"{path}: cannot write the recovered bag next to it ({_os_reason(err)}); "
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
        raise PipelineError(f"{path}: cannot move the recovered bag into place ({_os_reason(err)}); {state}, the "
                            f"recovered copy is kept in {staging}") from err
