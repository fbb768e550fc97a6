"""Sizes an MCAP file declares, checked against the file before a reader allocates them.

The readers (rosbags' MCAP storage, the `mcap` library) read a record, a chunk or a chunk index's
chunk by the length the file states, so 8 changed bytes can make them ask for a terabyte.
`check_mcap` walks the records' length prefixes (seeks and a few bytes per record, never a record's
body) and refuses, naming the file, the record and the offset, any record that reaches past the end
of the file, any chunk whose parts do not fit inside its record or whose uncompressed size is over
`MAX_CHUNK_BYTES`, and any chunk index that points outside the file. A file that was cut off (no
end magic) is left to the reader, which refuses it or recovers what is there; only its first record
is checked, which rosbags reads before it looks for the end.
"""

from __future__ import annotations

import os
import struct
from typing import IO

from gwr_predictor.files.user_files import PathLike, open_to_read

MAGIC = b"\x89MCAP0\r\n"
#: A chunk's uncompressed size: rosbag2 writes chunks of 768 kB, rosbags about 1 MB.
MAX_CHUNK_BYTES = 256 << 20

_OP_FOOTER, _OP_CHUNK, _OP_CHUNK_INDEX = 0x02, 0x06, 0x08
_PREFIX = struct.Struct("<BQ")  # opcode, record length


def check_mcap(path: PathLike, error: type[Exception]) -> int:
    """The size of the regular MCAP file at `path`; `error` if a length it declares cannot be right."""
    with open_to_read(path, None, "MCAP file", error) as fh:
        size = os.fstat(fh.fileno()).st_size
        if fh.read(len(MAGIC)) != MAGIC:
            return size  # not an MCAP file: the reader says so
        complete = size >= 2 * len(MAGIC) and _pread(fh, size - len(MAGIC), len(MAGIC)) == MAGIC
        end = size - len(MAGIC) if complete else size
        at = len(MAGIC)
        while at + _PREFIX.size <= end:
            op, length = _PREFIX.unpack(_pread(fh, at, _PREFIX.size))
            body = at + _PREFIX.size
            if length > end - body:
                if not complete and at > len(MAGIC):
                    break  # cut off by a crash
                raise error(f"{path}: MCAP record 0x{op:02x} at byte {at:,} declares {length:,} bytes, past the end "
                            f"of the {size:,}-byte file: corrupt or forged; refused before reading")
            if op == _OP_CHUNK:
                _check_chunk(fh, body, length, f"{path}: MCAP chunk at byte {at:,}", error)
            elif op == _OP_CHUNK_INDEX:
                _check_chunk_index(fh, body, length, size, f"{path}: MCAP chunk index at byte {at:,}", error)
            elif op == _OP_FOOTER:
                break
            if not complete and at == len(MAGIC):
                break  # the first record is all rosbags reads of a file without its end
            at = body + length
    return size


def _pread(fh: IO[bytes], offset: int, n: int) -> bytes:
    return os.pread(fh.fileno(), n, offset)


def _fields(fh: IO[bytes], offset: int, end: int, fmt: str, where: str, error: type[Exception]) -> tuple[int, ...]:
    size = struct.calcsize(fmt)
    if offset + size > end:
        raise error(f"{where}: its fields run past the end of the record: corrupt or forged")
    return struct.unpack(fmt, _pread(fh, offset, size))


def _check_chunk(fh: IO[bytes], body: int, length: int, where: str, error: type[Exception]) -> None:
    """Chunk: start, end, uncompressed size, crc, compression (string), records (u64-prefixed bytes)."""
    end = body + length
    _, _, uncompressed, _, name_len = _fields(fh, body, end, "<QQQII", where, error)
    at = body + 32 + name_len
    (stored,) = _fields(fh, at, end, "<Q", where, error)
    if stored > end - at - 8:
        raise error(f"{where}: declares {stored:,} bytes of records in a record of {length:,}: corrupt or forged; "
                    "refused before reading")
    _check_uncompressed(uncompressed, where, error)


def _check_chunk_index(fh: IO[bytes], body: int, length: int, size: int, where: str,
                       error: type[Exception]) -> None:
    """Chunk index: times, the chunk's offset and length, message index offsets (u32-prefixed map),
    their length, compression (string), compressed and uncompressed size."""
    end = body + length
    _, _, start, chunk_length, map_len = _fields(fh, body, end, "<QQQQI", where, error)
    at = body + 36 + map_len
    (index_length, name_len) = _fields(fh, at, end, "<QI", where, error)
    compressed, uncompressed = _fields(fh, at + 12 + name_len, end, "<QQ", where, error)
    if start + chunk_length > size or compressed > chunk_length or start + chunk_length + index_length > size:
        raise error(f"{where}: points to a chunk of {chunk_length:,} bytes ({compressed:,} compressed) at byte "
                    f"{start:,}, outside the {size:,}-byte file: corrupt or forged; refused before reading")
    _check_uncompressed(uncompressed, where, error)


def _check_uncompressed(uncompressed: int, where: str, error: type[Exception]) -> None:
    if uncompressed > MAX_CHUNK_BYTES:
        raise error(f"{where}: declares {uncompressed:,} uncompressed bytes, over the limit of "
                    f"{MAX_CHUNK_BYTES:,} (gwr_predictor.pipeline.mcap_limits); refused before reading")
