"""Opening the files and paths a user names (arguments, node parameters, params files, bags,
checkpoints): one set of rules, so that no command or node checks a path its own way.

Reading: only regular files are read. A FIFO, a device, a socket or a folder is refused at once: files
are opened with O_NONBLOCK, so opening a FIFO never waits for a writer, and checked on the open
descriptor (fstat) before a byte is read; the size limit is checked there too, and a file that grows
while it is read is cut at the limit and refused. O_NOFOLLOW where a link must not be followed.
YAML files are read through these rules and parsed by `yaml_safe`.
Writing: the chosen path must not be a symlink, FIFO, device or folder; the new file is written as a
temporary file beside it and renamed over it (a crash leaves the old file or the new one, a link at
the path is never followed); a folder that cannot be created or written to is a one-line error before
any work. Lock files: never through a symlink or a hard link, which would truncate another file.

Every function takes the error class to raise (the caller's own, so messages stay in its family) and
`what` the file is for the message, which names the path and the rule it breaks.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

PathLike = str | os.PathLike[str]

_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"), (stat.S_ISLNK, "a symlink"))


def human_size(n: int) -> str:
    return f"{n / (1 << 20):.0f} MB" if n >= 1 << 20 else f"{n} bytes"


def kind_of(mode: int) -> str:
    """'a FIFO (named pipe)', 'a folder', ... for a file mode that is not a regular file's."""
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def reason(exc: OSError) -> str:
    """The OS's words for `exc`, with a symlink loop said plainly."""
    if exc.errno == errno.ELOOP:
        return "a symlink loop, or a symlink where none is followed"
    return exc.strerror or str(exc)


def _require_regular(path: PathLike, st: os.stat_result, what: str, error: type[Exception]) -> None:
    if not stat.S_ISREG(st.st_mode):
        raise error(f"{path}: is {kind_of(st.st_mode)}, not a regular file; refused as a {what}")


def _require_size(path: PathLike, size: int, limit: int | None, what: str, error: type[Exception]) -> None:
    if limit is not None and size > limit:
        raise error(f"{path}: {human_size(size)} is too large for a {what} (limit {human_size(limit)}); "
                    "refused before reading")


def regular_file_size(path: PathLike, limit: int | None, what: str, error: type[Exception]) -> int:
    """The size of the regular file at `path` (links followed; nothing is opened), for files another
    library opens by name; `error` if it is missing, not a regular file or larger than `limit`."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise error(f"{path}: no such {what} (no such file or directory)") from None
    except OSError as exc:
        raise error(f"{path}: cannot use it as a {what}: {reason(exc)}") from None
    _require_regular(path, st, what, error)
    _require_size(path, st.st_size, limit, what, error)
    return st.st_size


def open_to_read(path: PathLike, limit: int | None, what: str, error: type[Exception], *,
                 follow_symlinks: bool = True) -> IO[bytes]:
    """The regular file at `path` opened for binary reading, its size within `limit`; `error` naming
    it otherwise. Never blocks on a FIFO; `follow_symlinks=False` refuses a symlink at `path`."""
    flags = os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC | (0 if follow_symlinks else os.O_NOFOLLOW)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise error(f"{path}: no such {what} (no such file or directory)") from None
    except OSError as exc:
        raise error(f"{path}: cannot open it as a {what}: {reason(exc)}") from None
    try:
        st = os.fstat(fd)
        _require_regular(path, st, what, error)
        _require_size(path, st.st_size, limit, what, error)
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_bytes(path: PathLike, limit: int | None, what: str, error: type[Exception]) -> bytes:
    """The bytes of the regular file at `path`, at most `limit` of them (see `open_to_read`)."""
    with open_to_read(path, limit, what, error) as fh:
        try:
            data = fh.read(-1 if limit is None else limit + 1)
        except OSError as exc:
            raise error(f"{path}: cannot read the {what}: {reason(exc)}") from None
    _require_size(path, len(data), limit, what, error)  # it grew while being read
    return data


def read_text(path: PathLike, limit: int | None, what: str, error: type[Exception]) -> str:
    """`read_bytes` decoded as UTF-8; `error` naming the file if it is not text."""
    try:
        return read_bytes(path, limit, what, error).decode()
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not UTF-8 text ({what}): {exc.reason} at byte {exc.start}") from None


# --- symlinks ------------------------------------------------------------------------------------


def final_target(path: PathLike, what: str, error: type[Exception]) -> Path:
    """The file a symlink at `path` finally points to (dangling or not); `path` itself if it is no
    symlink. `error` for a symlink loop, which no read or write could ever get through."""
    path = Path(path)
    if not path.is_symlink():
        return path
    try:
        return Path(os.path.realpath(path, strict=True))
    except FileNotFoundError:  # dangling: the target is created by the first write
        return Path(os.path.realpath(path))
    except OSError as exc:
        raise error(f"{path}: cannot be used as a {what}: {reason(exc)}") from None


# --- writing -------------------------------------------------------------------------------------


def check_folder(folder: PathLike, what: str, error: type[Exception]) -> Path:
    """`folder`, created if missing, after a test file was created and removed in it; `error` naming it
    and the OS's reason otherwise (read-only, a file in the way, /proc...)."""
    folder = Path(folder) if str(folder) else Path(".")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".write-test.", suffix=".tmp", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise error(f"{folder}: cannot write the {what} there: {reason(exc)}") from None
    return folder


def check_output_path(path: PathLike, what: str, error: type[Exception]) -> Path:
    """`path` as a place to write a new file to: `error` if it is a symlink (never followed), a folder,
    FIFO or device, or if its folder cannot be created or written to; checked before any work."""
    path = Path(path)
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise error(f"{path}: cannot write the {what} there: {reason(exc)}") from None
    if st is not None and stat.S_ISLNK(st.st_mode):
        raise error(f"{path}: is a symlink; the {what} is not written through it (name the file itself)")
    if st is not None and not stat.S_ISREG(st.st_mode):
        raise error(f"{path}: is {kind_of(st.st_mode)}; refusing to replace it with the {what}")
    check_folder(path.parent, what, error)
    return path


def new_file_mode(replaced: PathLike) -> int:
    """Permission bits for a file that replaces `replaced`: its own, or the umask default if new."""
    try:
        return stat.S_IMODE(os.stat(replaced).st_mode)
    except OSError:
        return 0o666 & ~_umask()


def _umask() -> int:
    """The process umask, read without changing it where Linux shows it (os.umask can only swap)."""
    with contextlib.suppress(OSError, ValueError):
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def fsync_folder(folder: PathLike) -> None:
    """Make a rename in `folder` durable (best effort: not every platform can open a folder)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    with contextlib.suppress(OSError):
        os.fsync(fd)
    os.close(fd)


class PendingFile:
    """A new, empty temporary file beside `path` (same suffix, for writers that choose the format by
    it; `tmp`) for the caller to write, by name or stream; `commit` fsyncs it and renames it over
    `path` (so a symlink there is replaced, never followed), `discard` removes it. `checked`: `path`
    was already given to `check_output_path` (or is a checkpoint's target, checked by its own rule)."""

    def __init__(self, path: PathLike, what: str, error: type[Exception], *, checked: bool = False) -> None:
        self.path = Path(path) if checked else check_output_path(path, what, error)
        self.what, self.error = what, error
        self.folder = self.path.parent if str(self.path.parent) else Path(".")
        self.mode = new_file_mode(self.path)
        try:
            fd, name = tempfile.mkstemp(prefix=f".{self.path.stem}.", suffix=f".part{self.path.suffix}",
                                        dir=self.folder)
            os.close(fd)
        except OSError as exc:
            raise error(f"{self.path}: cannot create a temporary file in {self.folder} for the {what}: "
                        f"{reason(exc)}") from None
        self.tmp = Path(name)

    def commit(self) -> Path:
        """The written file in place at `path` (`error` naming it if that fails; nothing is left behind)."""
        try:
            with open(self.tmp, "rb+") as fh:
                os.fchmod(fh.fileno(), self.mode)
                os.fsync(fh.fileno())
            os.replace(self.tmp, self.path)
        except OSError as exc:
            self.discard()
            raise self.error(f"{self.path}: writing the {self.what} failed: {reason(exc)}") from exc
        fsync_folder(self.folder)
        return self.path

    def discard(self) -> None:
        with contextlib.suppress(OSError):
            self.tmp.unlink()


@contextlib.contextmanager
def replacing(path: PathLike, what: str, error: type[Exception], *, checked: bool = False) -> Iterator[Path]:
    """A `PendingFile`'s temporary path, committed when the block ends, discarded if it raises (an
    OSError while writing is then `error` naming `path`)."""
    pending = PendingFile(path, what, error, checked=checked)
    try:
        yield pending.tmp
    except BaseException as exc:
        pending.discard()
        if isinstance(exc, OSError):
            raise error(f"{pending.path}: writing the {what} failed: {reason(exc)}") from exc
        raise
    pending.commit()


@contextlib.contextmanager
def output_file(path: PathLike, what: str, error: type[Exception], text: bool = False) -> Iterator[IO[Any]]:
    """`replacing`, opened: a binary (or, with `text`, UTF-8 text) stream to write the new file to."""
    with replacing(path, what, error) as tmp, open(tmp, "w" if text else "wb", **_text_options(text)) as fh:
        yield fh


def _text_options(text: bool) -> dict[str, Any]:
    return {"encoding": "utf-8", "newline": ""} if text else {}


def write_output(path: PathLike, data: str | bytes, what: str, error: type[Exception]) -> Path:
    """Write `data` as the new file at `path` (see `replacing`); returns `path`."""
    with output_file(path, what, error, text=isinstance(data, str)) as fh:
        fh.write(data)
    return Path(path)


def open_lock_file(path: PathLike, what: str, error: type[Exception]) -> int:
    """A read-write descriptor of the lock file at `path` (created if missing): `error` if it is a
    symlink, a hard link to another name, or not a regular file; the caller then never truncates or
    writes anything but its own lock file."""
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC, 0o666)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise error(f"{path}: is a symlink; refused as the {what} (locking would overwrite the file it "
                        "points to)") from None
        raise error(f"{path}: cannot open the {what}: {reason(exc)}") from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode) or st.st_nlink != 1:
        os.close(fd)
        kind = "a hard link of another file" if stat.S_ISREG(st.st_mode) else kind_of(st.st_mode)
        raise error(f"{path}: is {kind}; refused as the {what} (locking would overwrite that file)")
    os.set_blocking(fd, True)
    return fd
