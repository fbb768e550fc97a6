"""One-file, versioned, atomically written model checkpoints (npz + JSON header).

Layout: an uncompressed .npz whose member `__header__` holds UTF-8 JSON with `magic`, `kind`
(the model class), `format_version` and whatever plain values the model adds; every other member
is a named array. Writing goes to a temporary file in the destination folder, is fsynced and then
renamed over the target, so a crash leaves either the old or the new file, never half of one.
Anything wrong on reading (missing, truncated, not a checkpoint, another kind or version, missing
arrays) raises `CheckpointError` naming the file and the problem.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
import zipfile
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.data.file_limits import MAX_CHECKPOINT_BYTES, check_file_size, check_npz_members
from gwr_predictor.errors import GwrPredictorError

MAGIC = "gwr_predictor.checkpoint"
#: 2: HierarchyParams gained `target` and `readout_k`, and the frame buffer `xbuf` keeps one frame
#: more (the base of delta targets). Version 1 files are refused: their parameters lack the new keys.
#: Within 2, a model's layers are stored in the network's own format (`GWR.state`: arrays
#: `<layer>.weights/counters/edges`, the other values in the header's `layers`); files without
#: `layers` take those values from the parameters, as they were written.
FORMAT_VERSION = 2
HEADER_KEY = "__header__"


class CheckpointError(GwrPredictorError):
    """A checkpoint that cannot be written or read; the message names the file and the cause."""


class KindMismatchError(CheckpointError):
    """A readable checkpoint of another model kind (e.g. a Hierarchy where a BlendedPredictor was asked)."""

    def __init__(self, message: str, found: Any, expected: str) -> None:
        super().__init__(message)
        self.found, self.expected = found, expected


def write_checkpoint(path: str | os.PathLike[str], kind: str, header: Mapping[str, Any],
                     arrays: Mapping[str, np.ndarray]) -> None:
    """Atomically write `arrays` and the JSON-able `header` as a checkpoint of `kind`."""
    path = Path(path)
    meta = {"magic": MAGIC, "kind": kind, "format_version": FORMAT_VERSION, **header}
    if HEADER_KEY in arrays:
        raise CheckpointError(f"{path}: array name {HEADER_KEY!r} is reserved")
    try:
        blob = json.dumps(meta, allow_nan=True).encode()
    except (TypeError, ValueError) as exc:
        raise CheckpointError(f"{path}: header is not JSON-serialisable: {exc}") from exc
    members = {HEADER_KEY: np.frombuffer(blob, dtype=np.uint8), **arrays}
    folder = path.parent if str(path.parent) else Path(".")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    except OSError as exc:
        raise CheckpointError(f"{path}: cannot create a temporary file in {folder}: {exc}") from exc
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **members)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise CheckpointError(f"{path}: writing failed: {exc}") from exc
        raise
    _fsync_dir(folder)


def _fsync_dir(folder: Path) -> None:
    """Make the rename itself durable (best effort: not every platform can open a folder)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


_ZIP_LOCAL = b"PK\x03\x04"
_FIRST_MEMBER = (HEADER_KEY + ".npy").encode()


def looks_like_checkpoint(path: str | os.PathLike[str]) -> bool:
    """True if `path` is a file that begins like a checkpoint (a zip whose first member is the header).

    Truncated or corrupt checkpoints still begin this way; anything else (a folder, a user's
    file) is not ours, so it is neither moved aside nor overwritten.
    """
    path = Path(path)
    if not path.is_file():
        return False
    try:
        with open(path, "rb") as f:
            head = f.read(30 + len(_FIRST_MEMBER))
    except OSError:
        return False
    return head[:4] == _ZIP_LOCAL and head[30:] == _FIRST_MEMBER


def stale_temp_files(path: str | os.PathLike[str]) -> list[Path]:
    """Temporary files of interrupted saves of `path` (`.<name>.*.tmp` next to it)."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    return sorted(folder.glob(f".{glob_escape(path.name)}.*.tmp"))


def glob_escape(name: str) -> str:
    return "".join(f"[{c}]" if c in "*?[" else c for c in name)


def prepare_checkpoint_place(path: str | os.PathLike[str]) -> list[Path]:
    """Check, before anything is learned, that a checkpoint can be kept at `path`; returns the stale
    temporary files of interrupted saves that it removed.

    Raises CheckpointError naming the path when it is a folder or a file that is not a checkpoint
    (never moved or overwritten), or when its folder cannot be created or written to.
    """
    path = Path(path)
    if path.is_dir():
        raise CheckpointError(f"{path} is an existing folder, not a checkpoint file: give a file path "
                              "such as <folder>/model.npz")
    if path.exists() and not looks_like_checkpoint(path):
        raise CheckpointError(f"{path} exists and is not a gwr_predictor checkpoint: refusing to move or overwrite it")
    folder = path.parent if str(path.parent) else Path(".")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise CheckpointError(f"{path}: the checkpoint cannot be written in {folder}: {exc}") from exc
    removed = []
    for stale in stale_temp_files(path):
        with contextlib.suppress(OSError):
            stale.unlink()
            removed.append(stale)
    return removed


def read_checkpoint(path: str | os.PathLike[str], kind: str,
                    required: Iterable[str] = ()) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """(header, arrays) of a checkpoint of `kind`; every name in `required` must be present."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"{path}: no such checkpoint file")
    check_file_size(path, MAX_CHECKPOINT_BYTES, "checkpoint", CheckpointError)
    check_npz_members(path, MAX_CHECKPOINT_BYTES, "checkpoint", CheckpointError)
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {name: npz[name] for name in npz.files}
    except (zipfile.BadZipFile, ValueError, EOFError, OSError, KeyError) as exc:
        raise CheckpointError(f"{path}: not a readable checkpoint (truncated or corrupt?): {exc}") from exc
    blob = arrays.pop(HEADER_KEY, None)
    if blob is None or blob.dtype != np.uint8 or blob.ndim != 1:
        raise CheckpointError(f"{path}: no {HEADER_KEY!r} member: not a gwr_predictor checkpoint")
    try:
        header = json.loads(blob.tobytes().decode())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CheckpointError(f"{path}: header is not valid JSON: {exc}") from exc
    if not isinstance(header, dict) or header.get("magic") != MAGIC:
        raise CheckpointError(f"{path}: wrong magic {header.get('magic') if isinstance(header, dict) else None!r}, "
                              f"expected {MAGIC!r}: not a gwr_predictor checkpoint")
    version = header.get("format_version")
    if version != FORMAT_VERSION:
        hint = (" (written by an older build, before the P-GWR target/read-out options: retrain or "
                "re-run `gwr-predictor pretrain`)") if isinstance(version, int) and version < FORMAT_VERSION else ""
        raise CheckpointError(f"{path}: format_version {version!r} is not supported (this build reads "
                              f"{FORMAT_VERSION}){hint}")
    if header.get("kind") != kind:
        found = header.get("kind")
        raise KindMismatchError(f"{path}: holds a {found!r}, expected a {kind!r}", found, kind)
    require_arrays(required, arrays, path)
    return header, arrays


def require_arrays(required: Iterable[str], arrays: Mapping[str, Any], source: str | os.PathLike[str]) -> None:
    """CheckpointError naming `source` and what is missing unless every `required` array is there."""
    missing = sorted(set(required) - arrays.keys())
    if missing:
        raise CheckpointError(f"{source}: missing arrays {missing}")


def set_aside(path: str | Path, when: str | None = None) -> Path:
    """The corrupt-checkpoint policy: an unreadable checkpoint is moved to `<name>.corrupt-<time>`
    (never deleted, never overwritten) so a fresh model can start; returns where it went. OSError
    if it cannot be moved: then the caller must not start, or it would overwrite the file."""
    import time

    path = Path(path)
    aside = path.with_name(f"{path.name}.corrupt-{when or time.strftime('%Y%m%d-%H%M%S')}")
    os.replace(path, aside)
    return aside
