"""Size limits checked before a file is read into memory, so that what cannot be a recording (a
400 MB CSV, a 17 MB `.npz` that inflates to 4 GB, a 4 KB BVH that declares a day between frames, a
`.pt` tensor whose strides repeat one value four billion times) is refused with a one-line message
naming the file and the limit instead of taking the machine's memory.

One policy for every importer (skeleton `.npz`/CSV, BVH, ASF/AMC, `.npy`/`.npz` positions, `.pt`):
sizes are read from what the file declares (its size on disk, zip directory, npy headers, BVH/AMC
frame counts, tensor shapes) and checked against the limits below BEFORE anything of that size is
allocated. The limits are far above what the pipeline writes or the real recordings it reads need
(the largest, a holosoma climbing take, is 3,700 frames x 53 joints = 0.6 M values). Arithmetic,
not a measurement: 15 joints x 3 float64 at 30 fps are 39 MB per hour of `.npz` positions (a CSV row
of 45 values of about 10 characters: about 50 MB per hour).
"""

from __future__ import annotations

import os
import struct
import tokenize
import zipfile
import zlib
from collections.abc import Iterator
from typing import IO

import numpy as np

from gwr_predictor.files.user_files import human_size, regular_file_size

#: A binary recording (`.npz` members inflated, `.npy`, `.pt`): over 6 hours at 30 fps of 15 joints.
MAX_RECORDING_BYTES = 256 << 20
#: A recording as text (CSV, BVH, AMC): over 2 hours. A 400 MB CSV took 5.5 GB (about
#: 14 times its size) while parsing.
MAX_TEXT_BYTES = 128 << 20
MAX_CSV_BYTES = MAX_TEXT_BYTES
#: A skeleton-only text file (ASF): real ones are a few kB.
MAX_SKELETON_BYTES = 4 << 20
#: A model checkpoint (npz members inflated).
MAX_CHECKPOINT_BYTES = 2 << 30
#: Neurons of one network a checkpoint may declare (checked in the array headers, before reading), and the
#: largest `max_neurons` a layer may have: the product's layers are bounded far below it (the default's
#: network at 1,000, the paper's layers at 5,000), while the largest networks the experiments report, the
#: upper layers without normalisation, grow past 10,000. A checkpoint of a larger network is refused
#: naming this limit.
MAX_NETWORK_NEURONS = 20_000
#: Joints of one skeleton (BVH joints and End Sites, ASF bone starts and ends, array columns / 3).
#: Real skeletons with fingers and face have up to about 150.
MAX_JOINTS = 512
#: Nesting depth of a joint hierarchy; real ones (hips to a fingertip) are about 12 deep.
MAX_DEPTH = 64
#: Frames in a file and after resampling to the skeleton rate: over 9 hours at 30 fps.
MAX_FRAMES = 1_000_000
#: Numbers in one array a file declares (frames x channels, frames x joints x 3, a tensor's
#: elements): 256 MB as float64, the same as `MAX_RECORDING_BYTES`.
MAX_VALUES = 1 << 25
#: Members of one zip archive (`.npz`, `.pt`); ours have about ten.
MAX_ARCHIVE_MEMBERS = 1024
#: Working arrays of forward kinematics are computed this many (frame x joint) values at a time.
WORK_CHUNK_VALUES = 1 << 22


def check_file_size(path: str | os.PathLike[str], limit: int, what: str,
                    error: type[Exception] = ValueError) -> int:
    """The size of `path` in bytes; `error` naming the file if it is larger than `limit` or not a
    regular file (a FIFO would block its reader for ever, /dev/zero never end)."""
    return regular_file_size(path, limit, what, error)


def check_count(path: str | os.PathLike[str], count: int, limit: int, what: str, error: type[Exception]) -> int:
    """`count` (of frames, joints, values... that `path` declares) unless it exceeds `limit`."""
    if count > limit:
        raise error(f"{path}: {count:,} {what} exceed the limit of {limit:,} "
                    "(gwr_predictor.files.limits); refused before reading")
    return count


def check_shape(path: str | os.PathLike[str], frames: int, joints: int, error: type[Exception],
                values_per_joint: int = 3) -> None:
    """Frames, joints and frames x joints x `values_per_joint` within the limits."""
    check_count(path, frames, MAX_FRAMES, "frames", error)
    check_count(path, joints, MAX_JOINTS, "joints", error)
    check_count(path, frames * joints * values_per_joint, MAX_VALUES, "values (frames x joints x 3)", error)


def check_resampled(path: str | os.PathLike[str], duration_s: float, fps: float, error: type[Exception]) -> int:
    """Frames of a clip of `duration_s` seconds resampled to `fps`, unless over `MAX_FRAMES`."""
    frames = duration_s * fps + 1.0
    if not np.isfinite(frames) or frames > MAX_FRAMES:
        raise error(f"{path}: {duration_s:.6g} s at {fps:g} fps are {frames:,.0f} frames, over the limit of "
                    f"{MAX_FRAMES:,} (gwr_predictor.files.limits; a wrong frame time?); refused before resampling")
    return int(frames)


def frame_chunks(frames: int, per_frame: int) -> Iterator[slice]:
    """Slices of at most `WORK_CHUNK_VALUES // per_frame` frames: working arrays stay small."""
    step = max(1, WORK_CHUNK_VALUES // max(1, per_frame))
    for start in range(0, frames, step):
        yield slice(start, min(frames, start + step))


def check_npz_members(path: str | os.PathLike[str], limit: int, what: str,
                      error: type[Exception] = ValueError) -> int:
    """The inflated size of every member of the `.npz` at `path`, read from the zip's directory
    (nothing is decompressed); `error` if it exceeds `limit`. Unreadable zips are left to the reader."""
    try:
        with zipfile.ZipFile(path) as zf:
            total = sum(info.file_size for info in zf.infolist())
    except (zipfile.BadZipFile, OSError, ValueError, EOFError, NotImplementedError, RuntimeError, struct.error):
        return 0
    if total > limit:
        raise error(f"{path}: its arrays inflate to {human_size(total)}, too large for a {what} "
                    f"(limit {human_size(limit)}); refused before reading")
    return total


#: A central-directory entry is 46 bytes plus its name and extra fields; real ones stay below this.
_MAX_DIRECTORY_ENTRY_BYTES = 512


def zip_entry_count(path: str | os.PathLike[str]) -> int | None:
    """Members a zip declares in its end record (read before `zipfile` builds its directory, which
    costs about 400 bytes per member); None if there is no end record (not a zip: the reader says why)."""
    with open(path, "rb") as fh:
        fh.seek(0, os.SEEK_END)
        size = fh.tell()
        fh.seek(max(0, size - (1 << 16) - 22))
        tail = fh.read()
    at = tail.rfind(b"PK\x05\x06")
    if at < 0 or len(tail) < at + 22:
        return None
    count, directory = struct.unpack_from("<HI", tail, at + 10)
    locator = at - 20
    if count == 0xFFFF and locator >= 0 and tail[locator:locator + 4] == b"PK\x06\x07":
        with open(path, "rb") as fh:  # zip64: the end record's count is in the zip64 record
            fh.seek(struct.unpack_from("<Q", tail, locator + 8)[0])
            record = fh.read(56)
        if len(record) == 56 and record[:4] == b"PK\x06\x06":
            count, directory = struct.unpack_from("<QQ", record, 32)
    # zipfile parses the directory's bytes, whatever count the record claims: a forged small count with a
    # large directory still costs a member per entry, so the directory's size bounds the count from below
    return max(count, directory // _MAX_DIRECTORY_ENTRY_BYTES)


def npy_header(fh: IO[bytes], error: type[Exception]) -> tuple[tuple[int, ...], np.dtype, int]:
    """Shape, dtype and header length of the `.npy` stream `fh` (only the header is read); `error`
    saying why if it is not one."""
    try:
        major, _minor = np.lib.format.read_magic(fh)
        reader = np.lib.format.read_array_header_1_0 if major == 1 else np.lib.format.read_array_header_2_0
        shape, _fortran, dtype = reader(fh)
        return tuple(int(s) for s in shape), dtype, fh.tell()
    except (ValueError, EOFError, SyntaxError, TypeError, KeyError, struct.error, tokenize.TokenError,
            UnicodeDecodeError, zlib.error, zipfile.BadZipFile) as exc:
        raise error(f"unreadable .npy header ({type(exc).__name__}: {str(exc)[:80]})") from None


def check_npy_declared(where: str, shape: tuple[int, ...], dtype: np.dtype, stored: int,
                       error: type[Exception]) -> None:
    """An npy header's shape against the limit and against the `stored` data bytes behind it."""
    values = int(np.prod(shape, dtype=object))
    check_count(where, values, MAX_VALUES, "values in one array", error)
    if not dtype.hasobject and values * dtype.itemsize > stored:
        raise error(f"{where}: declares {values:,} values of {dtype.itemsize} bytes but holds {stored:,} bytes "
                    "(truncated or forged header); refused before reading")


def check_npy_file(path: str | os.PathLike[str], error: type[Exception]) -> None:
    """A `.npy` file: its size and the array its header declares, before numpy allocates it."""
    size = check_file_size(path, MAX_RECORDING_BYTES, "numpy array", error)
    try:
        with open(path, "rb") as fh:
            shape, dtype, header = npy_header(fh, error)
    except (error, ValueError) as exc:
        raise error(f"{path}: not a numpy array file: {exc}") from None
    check_npy_declared(str(path), shape, dtype, size - header, error)


def check_zip_directory(path: str | os.PathLike[str], limit: int, what: str, error: type[Exception]) -> bool:
    """A zip's size, member count and inflated size, from its directory alone (nothing is inflated);
    False when it is no zip (the reader then says why)."""
    check_file_size(path, limit, what, error)
    count = zip_entry_count(path)
    if count is None:
        return False
    check_count(path, count, MAX_ARCHIVE_MEMBERS, "archive members", error)
    check_npz_members(path, limit, what, error)
    return True


def check_archive(path: str | os.PathLike[str], limit: int, what: str, error: type[Exception]) -> None:
    """A zip (`.npz`, `.pt`): its size, member count, inflated size and, for `.npy` members, the
    arrays their headers declare; all from directories and headers, before any member is inflated.
    Archives that cannot be read are left to the reader, which says why."""
    if not check_zip_directory(path, limit, what, error):
        return
    try:
        zf = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError, EOFError, ValueError, NotImplementedError, RuntimeError, struct.error):
        return
    with zf:
        for info in zf.infolist():
            if info.filename.endswith(".npy"):
                shape, dtype, header = _member_header(zf, info, f"{path} ({info.filename})", error)
                check_npy_declared(f"{path} ({info.filename})", shape, dtype, info.file_size - header, error)


def _member_header(zf: zipfile.ZipFile, info: zipfile.ZipInfo, where: str,
                   error: type[Exception]) -> tuple[tuple[int, ...], np.dtype, int]:
    try:
        with zf.open(info) as fh:
            return npy_header(fh, error)
    except (error, ValueError, OSError, NotImplementedError, RuntimeError, EOFError, zipfile.BadZipFile,
            zlib.error) as exc:
        raise error(f"{where}: unreadable archive member ({type(exc).__name__}: {str(exc)[:80]})") from None
