"""One-file, versioned, atomically written model checkpoints (npz + JSON header).

Layout: an uncompressed .npz whose member `__header__` holds UTF-8 JSON with `magic`, `kind`
(the model class), `format_version` and whatever plain values the model adds; every other member
is a named array (which header keys and arrays a model writes: `persistence.py`). Writing goes to a
temporary file in the destination folder, is fsynced and then renamed over the target, so a crash
leaves either the old or the new file, never half of one.
Anything wrong on reading (missing, truncated, not a checkpoint, another kind or version, missing
arrays, and whatever else a hostile or damaged file makes the zip, npy or JSON readers raise) raises
`LearningError` naming the file and the problem: every array's declared size is checked against the
bytes the member holds, and the header's size and nesting are bounded, before anything is allocated.
A checkpoint path that is a symlink is written through (the target is replaced, the link stays).
`CheckpointLock` keeps one writer per checkpoint file.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import re
import tempfile
import time
import zipfile
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.files.limits import MAX_CHECKPOINT_BYTES, MAX_NETWORK_NEURONS, check_zip_directory, npy_header
from gwr_predictor.files.user_files import (
    check_folder,
    final_target,
    fsync_folder,
    new_file_mode,
    open_lock_file,
    open_to_read,
    regular_file_size,
)
from gwr_predictor.learning.errors import LearningError

MAGIC = "gwr_predictor.checkpoint"
#: The one format this build reads and writes; older files are refused with a clear message (their
#: history: CHANGELOG.md). 4: the layout `persistence.py` makes from each class's declaration; 5: bounded
#: learners, whose networks carry when each neuron last matched and whose memories which snippets are still.
FORMAT_VERSION = 5
HEADER_KEY = "__header__"
#: The JSON header holds parameters and small per-layer values (a few kB); arrays are members.
MAX_HEADER_BYTES = 4 << 20
#: Real headers nest about 4 deep; deeper ones are refused before parsing.
MAX_HEADER_DEPTH = 32


class CheckpointLock:
    """One writer per checkpoint file: an advisory `flock` on `.<name>.lock` beside the file (a
    symlink's target), held until `release` or the process ends. The OS drops it when its holder
    dies, so a SIGKILLed learner never blocks its restart. The lock file stays (removing it would
    race with the next locker) and names its holder's pid for the message of the one refused."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self._fd: int | None = None
        real = Path(os.path.realpath(path))  # every name of one file gets one lock
        self.lock_path = real.with_name(f".{real.name}.lock")
        fd = open_lock_file(self.lock_path, f"lock file of checkpoint {path}", LearningError)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = _lock_holder(fd)
            os.close(fd)
            if isinstance(exc, BlockingIOError):
                raise LearningError(
                    f"checkpoint {path} is in use by process {holder} (lock {self.lock_path}): two learners on one "
                    "checkpoint overwrite each other's learning; stop the other one or give this one another "
                    "path", source=path, locked=True) from None
            raise LearningError(f"{path}: cannot lock {self.lock_path}: {exc}", source=path) from exc
        self._fd = fd
        with contextlib.suppress(OSError):  # the pid only makes the refusal's message clearer (disk full: none)
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode())

    def release(self) -> None:
        """Unlock (closing the descriptor drops the flock); safe to call twice."""
        fd, self._fd = self._fd, None
        if fd is not None:
            os.close(fd)

    __del__ = release


def _lock_holder(fd: int) -> str:
    """The pid the lock file names ('another process' while its holder has not written it yet)."""
    with contextlib.suppress(OSError):
        text = os.pread(fd, 32, 0).decode(errors="replace").strip()
        if text.isdigit():
            return text
    return "another process"


def write_checkpoint(path: str | os.PathLike[str], kind: str, header: Mapping[str, Any],
                     arrays: Mapping[str, np.ndarray]) -> None:
    """Atomically write `arrays` and the JSON-able `header` as a checkpoint of `kind`.

    The new file takes the mode of the one it replaces (umask default for a new one); a symlink at
    `path` is written through: the temporary file goes beside its target, which it replaces."""
    path = Path(path)
    meta = {"magic": MAGIC, "kind": kind, "format_version": FORMAT_VERSION, **header}
    if HEADER_KEY in arrays:
        raise LearningError(f"{path}: array name {HEADER_KEY!r} is reserved", source=path)
    try:
        blob = json.dumps(meta, allow_nan=True).encode()
    except (TypeError, ValueError) as exc:
        raise LearningError(f"{path}: header is not JSON-serialisable: {exc}", source=path) from exc
    members: dict[str, Any] = {HEADER_KEY: np.frombuffer(blob, dtype=np.uint8), **arrays}
    dest = destination(path)
    folder = dest.parent
    try:
        mode = new_file_mode(dest)
        fd, tmp = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".tmp", dir=folder)
    except OSError as exc:
        raise LearningError(f"{path}: cannot create a temporary file in {folder}: {exc}", source=path) from exc
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **members)
            os.fchmod(f.fileno(), mode)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, dest)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise LearningError(f"{path}: writing failed: {exc}", source=path) from exc
        raise
    fsync_folder(folder)


def destination(path: str | os.PathLike[str]) -> Path:
    """The file a checkpoint path stands for: a symlink's final target (dangling or not), so that a
    save updates the target instead of replacing the link; else the path itself. LearningError for
    a symlink loop (every save would fail)."""
    return final_target(path, "checkpoint", LearningError)


_ZIP_LOCAL = b"PK\x03\x04"
_FIRST_MEMBER = (HEADER_KEY + ".npy").encode()


def looks_like_checkpoint(path: str | os.PathLike[str]) -> bool:
    """True if `path` is a file that begins like a checkpoint (a zip whose first member is the header).

    Truncated or corrupt checkpoints still begin this way; anything else (a folder, a user's
    file) is not ours, so it is neither moved aside nor overwritten.
    """
    try:
        with open_to_read(path, None, "checkpoint", LearningError) as f:
            head = f.read(30 + len(_FIRST_MEMBER))
    except (OSError, LearningError):
        return False
    return head[:4] == _ZIP_LOCAL and head[30:] == _FIRST_MEMBER


def stale_temp_files(path: str | os.PathLike[str]) -> list[Path]:
    """Temporary files of interrupted saves of `path` (`.<name>.*.tmp` next to it, or next to a
    symlink's target, where saves write)."""
    dest = destination(path)
    folder = dest.parent if str(dest.parent) else Path(".")
    return sorted(folder.glob(f".{glob_escape(dest.name)}.*.tmp"))


def glob_escape(name: str) -> str:
    return "".join(f"[{c}]" if c in "*?[" else c for c in name)


def check_checkpoint_place(path: str | os.PathLike[str]) -> None:
    """LearningError naming the path when it is a folder or a file that is not a checkpoint (never
    moved or overwritten), or when its folder (a symlink's target's) cannot be created or written to."""
    path = Path(path)
    if path.is_dir():
        raise LearningError(f"{path} is an existing folder, not a checkpoint file: give a file path "
                            "such as <folder>/model.npz", source=path)
    if path.exists() and not looks_like_checkpoint(path):
        raise LearningError(f"{path} exists and is not a gwr_predictor checkpoint: refusing to move or overwrite it",
                            source=path)
    try:
        check_folder(destination(path).parent, f"checkpoint {path}", LearningError)
    except LearningError as exc:
        raise LearningError(str(exc), source=path) from None


def remove_stale_temp_files(path: str | os.PathLike[str]) -> list[Path]:
    """Remove the temporary files of interrupted saves of `path`; returns those removed. Only safe
    while holding the path's `CheckpointLock` (another writer's save in progress looks the same)."""
    removed = []
    for stale in stale_temp_files(path):
        with contextlib.suppress(OSError):
            stale.unlink()
            removed.append(stale)
    return removed


def read_checkpoint(path: str | os.PathLike[str], kind: str | tuple[str, ...],
                    required: Iterable[str] = ()) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """(header, arrays) of a checkpoint of `kind` (or of any of several: the header says which); every
    name in `required` must be present."""
    path = Path(path)
    try:
        regular_file_size(path, MAX_CHECKPOINT_BYTES, "checkpoint", LearningError)
        check_zip_directory(path, MAX_CHECKPOINT_BYTES, "checkpoint", LearningError)
    except LearningError as exc:
        exc.source = path
        raise
    arrays = _read_arrays(path)
    header = _parse_header(arrays.pop(HEADER_KEY, None), path)
    if not isinstance(header, dict) or header.get("magic") != MAGIC:
        raise LearningError(f"{path}: wrong magic {header.get('magic') if isinstance(header, dict) else None!r}, "
                            f"expected {MAGIC!r}: not a gwr_predictor checkpoint", source=path)
    version = header.get("format_version")
    if version != FORMAT_VERSION:
        hint = (" (written by an older build: retrain, or re-run `gwr-predictor pretrain`; CHANGELOG.md says "
                "what changed)") if isinstance(version, int) and version < FORMAT_VERSION else ""
        raise LearningError(f"{path}: format_version {version!r} is not supported (this build reads "
                            f"{FORMAT_VERSION}){hint}", source=path)
    kinds = (kind,) if isinstance(kind, str) else kind
    if header.get("kind") not in kinds:
        found = header.get("kind")
        raise LearningError(f"{path}: holds a {found!r}, expected a {' or '.join(map(repr, kinds))}", source=path,
                            found=found, expected=kinds[0])
    require_arrays(required, arrays, path)
    return header, arrays


def _read_arrays(path: Path) -> dict[str, np.ndarray]:
    """Every member as an array, each one's declared size checked first. Whatever a damaged or forged
    zip, deflate stream or npy header makes the readers raise (zlib.error, MemoryError, ...) is a
    LearningError: an unreadable checkpoint must be set aside, never crash its reader."""
    try:
        with zipfile.ZipFile(path) as zf:
            shapes = {info.filename.removesuffix(".npy"): _check_member(zf, info, path) for info in zf.infolist()}
        check_network_sizes(path, shapes)
        with np.load(path, allow_pickle=False) as npz:
            return {name: npz[name] for name in npz.files}
    except LearningError:
        raise
    except Exception as exc:
        raise LearningError(f"{path}: not a readable checkpoint (truncated or corrupt?): "
                            f"{type(exc).__name__}: {exc}", source=path) from exc


def _check_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, path: Path) -> tuple[int, ...]:
    """The shape of a member, which must be an npy array whose declared shape x item size is exactly the
    data it holds (so numpy never allocates more than the member's size, which `check_zip_directory`
    bounded)."""
    if not info.filename.endswith(".npy"):
        raise LearningError(f"{path}: member {info.filename!r} is not an array: not a gwr_predictor checkpoint",
                            source=path)
    with zf.open(info) as f:
        try:
            shape, dtype, header_len = npy_header(f, LearningError)
        except LearningError as exc:
            raise LearningError(f"{path}: member {info.filename!r}: {exc}", source=path) from None
    declared = int(np.prod(shape, dtype=object)) * dtype.itemsize
    stored = info.file_size - header_len
    if dtype.hasobject or declared != stored:
        raise LearningError(f"{path}: member {info.filename!r} declares shape {shape} of {dtype} "
                            f"({declared:,} bytes) but holds {stored:,} bytes: corrupt or forged", source=path)
    return shape


def check_network_sizes(path: Path, shapes: Mapping[str, tuple[int, ...]]) -> None:
    """LearningError if a network (a `<name>weights` array beside `<name>edges`) declares more neurons
    than `MAX_NETWORK_NEURONS`, read from the npy headers before anything is allocated: a network's
    edges grow with the square of its neurons, so a few kB of zeros could ask for gigabytes.
    A layer's own, smaller `max_neurons` is checked when the network is built (`GWR.from_arrays`)."""
    for name in shapes:
        prefix = name.removesuffix("edges")
        if prefix != name and (not prefix or prefix.endswith(".")) and f"{prefix}weights" in shapes:
            neurons = (shapes[f"{prefix}weights"] or (0,))[0]
            if neurons > MAX_NETWORK_NEURONS:
                raise LearningError(f"{path}: network {prefix.rstrip('.') or 'gwr'!r} declares {neurons:,} neurons, "
                                    f"over the limit of {MAX_NETWORK_NEURONS:,} (gwr_predictor.files.limits); "
                                    "refused before reading", source=path)


_JSON_STRING = re.compile(r'"(?:[^"\\]|\\.)*+"')


def json_depth(text: str) -> int:
    """Deepest bracket nesting of JSON `text`, brackets inside strings not counted (linear time)."""
    codes = np.frombuffer(_JSON_STRING.sub('""', text).encode(), dtype=np.uint8)
    steps = np.isin(codes, (ord("["), ord("{"))).astype(np.int64) - np.isin(codes, (ord("]"), ord("}")))
    return int(np.cumsum(steps).max(initial=0))


def _parse_header(blob: np.ndarray | None, path: Path) -> Any:
    """The JSON header, its size and nesting bounded before parsing."""
    if blob is None or blob.dtype != np.uint8 or blob.ndim != 1:
        raise LearningError(f"{path}: no {HEADER_KEY!r} member: not a gwr_predictor checkpoint", source=path)
    if blob.size > MAX_HEADER_BYTES:
        raise LearningError(f"{path}: header of {blob.size:,} bytes, over the limit of {MAX_HEADER_BYTES:,}",
                            source=path)
    try:
        text = blob.tobytes().decode()
    except UnicodeDecodeError as exc:
        raise LearningError(f"{path}: header is not valid JSON: {type(exc).__name__}: {exc}", source=path) from exc
    depth = json_depth(text)
    if depth > MAX_HEADER_DEPTH:
        raise LearningError(f"{path}: header nested {depth} deep (limit {MAX_HEADER_DEPTH}): corrupt or forged",
                            source=path)
    try:
        return json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise LearningError(f"{path}: header is not valid JSON: {type(exc).__name__}: {exc}", source=path) from exc


def raise_state_error(exc: Exception, source: str | os.PathLike[str], what: str,
                      error: type[GwrPredictorError] = LearningError) -> NoReturn:
    """Raise for `exc`, met while a model was rebuilt from the state at `source`: `exc` itself if it
    already names a checkpoint (a nested model's, a missing array), else `error` naming `source` and
    `what` did not fit (and carrying `source`, if it is a LearningError)."""
    if isinstance(exc, LearningError) and exc.source is not None:
        raise exc
    message = f"{source}: {what}: {type(exc).__name__}: {exc}"
    if issubclass(error, LearningError):
        raise error(message, source=source) from exc
    raise error(message) from exc


def require_arrays(required: Iterable[str], arrays: Mapping[str, Any], source: str | os.PathLike[str]) -> None:
    """LearningError naming `source` and what is missing unless every `required` array is there."""
    missing = sorted(set(required) - arrays.keys())
    if missing:
        raise LearningError(f"{source}: missing arrays {missing}", source=source)


def set_aside(path: str | Path, when: str | None = None) -> Path:
    """The corrupt-checkpoint policy: an unreadable checkpoint is moved to `<name>.corrupt-<time>`
    (never deleted, never overwritten) so a fresh model can start; returns where it went. OSError
    if it cannot be moved: then the caller must not start, or it would overwrite the file. Through a
    symlink it is the target that moves (beside itself): the link stays, and saves recreate the target."""
    path = destination(path)
    aside = path.with_name(f"{path.name}.corrupt-{when or time.strftime('%Y%m%d-%H%M%S')}")
    os.replace(path, aside)
    return aside
