"""Test doubles shared by several test files."""

import errno


class FullDisk:
    """A file whose writes fail like a full disk; everything else goes to the real file."""

    def __init__(self, real) -> None:
        self.real = real

    def write(self, _data) -> int:
        raise OSError(errno.ENOSPC, "No space left on device")

    def __getattr__(self, name):
        return getattr(self.real, name)
