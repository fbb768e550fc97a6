"""Size limits checked before a file is read into memory, so that what cannot be a recording (a
400 MB CSV, a 17 MB `.npz` that inflates to 4 GB) is refused with a message instead of taking the
machine's memory.

The limits are far above what the pipeline writes. Arithmetic, not a measurement: 15 joints x 3
float64 at 30 fps are 39 MB per hour of `.npz` positions (a CSV row of 45 values of about 10
characters: about 50 MB per hour).
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

#: A skeleton recording as `.npz` (members inflated): over 6 hours at 30 fps.
MAX_RECORDING_BYTES = 256 << 20
#: A recording as CSV text: over 2 hours. Issue 15 saw a 400 MB CSV take 5.5 GB (about 14 times its
#: size) while parsing.
MAX_CSV_BYTES = 128 << 20
#: A model checkpoint (npz members inflated).
MAX_CHECKPOINT_BYTES = 2 << 30


def _human(n: int) -> str:
    return f"{n / (1 << 20):.0f} MB" if n >= 1 << 20 else f"{n} bytes"


def check_file_size(path: str | os.PathLike[str], limit: int, what: str,
                    error: type[Exception] = ValueError) -> int:
    """The size of `path` in bytes; `error` naming the file if it is larger than `limit`."""
    size = Path(path).stat().st_size
    if size > limit:
        raise error(f"{path}: {_human(size)} is too large for a {what} (limit {_human(limit)}); refused before reading")
    return size


def check_npz_members(path: str | os.PathLike[str], limit: int, what: str,
                      error: type[Exception] = ValueError) -> int:
    """The inflated size of every member of the `.npz` at `path`, read from the zip's directory
    (nothing is decompressed); `error` if it exceeds `limit`. Unreadable zips are left to the reader."""
    try:
        with zipfile.ZipFile(path) as zf:
            total = sum(info.file_size for info in zf.infolist())
    except (zipfile.BadZipFile, OSError, ValueError):
        return 0
    if total > limit:
        raise error(f"{path}: its arrays inflate to {_human(total)}, too large for a {what} "
                    f"(limit {_human(limit)}); refused before reading")
    return total
