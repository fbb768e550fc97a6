"""Checkpoints written off the learner's path: a learner that saves on its own thread stops learning
and predicting for as long as the disk takes (a full model is tens of MB, an fsync can take a second).

The learner takes a snapshot of the model between two frames (`Checkpointed.state()` copies every
array, milliseconds), hands it to `CheckpointSaver`, and goes on; one writer thread writes it with
`write_checkpoint` (atomic: a crash leaves the old file or the new one). A snapshot taken while an
earlier one is still being written replaces the one waiting, if any: only the newest is worth writing.
Results (written, failed, how long) are collected by the learner's own thread with `results()`.
"""

from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gwr_predictor.learning.checkpoint import write_checkpoint
from gwr_predictor.learning.errors import LearningError


@dataclass(frozen=True)
class SaveResult:
    """One finished write: the error (None: written), its size and how long the write took."""

    error: LearningError | None
    bytes: int
    write_s: float


@dataclass(frozen=True)
class _Snapshot:
    kind: str
    header: dict[str, Any]
    arrays: dict[str, Any]


class CheckpointSaver:
    """Writes snapshots of a model to `path` on a thread of its own (see the module docstring)."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self._lock = threading.Condition()
        self._waiting: _Snapshot | None = None
        self._writing = False
        self._closed = False
        self._results: list[SaveResult] = []
        self.superseded = 0  # snapshots replaced by a newer one before they were written
        self._thread = threading.Thread(target=self._run, name=f"checkpoint writer {self.path.name}", daemon=True)
        self._thread.start()

    def submit(self, model: Any) -> float:
        """Snapshot `model` (its kind and `state()`) for writing; returns the seconds the snapshot took,
        the only part of a save on the caller's thread."""
        start = time.perf_counter()
        header, arrays = model.state()
        snapshot = _Snapshot(str(model.kind), header, arrays)
        taken = time.perf_counter() - start
        with self._lock:
            if self._closed:
                raise LearningError(f"{self.path}: the checkpoint writer is closed", source=self.path)
            if self._waiting is not None:
                self.superseded += 1
            self._waiting = snapshot
            self._lock.notify_all()
        return taken

    def busy(self) -> bool:
        """Whether a snapshot is waiting or being written."""
        with self._lock:
            return self._waiting is not None or self._writing

    def wait(self, timeout: float | None = None) -> bool:
        """Block until every submitted snapshot is written (or failed); False on timeout."""
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._lock:
            while self._waiting is not None or self._writing:
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    return False
                self._lock.wait(remaining)
        return True

    def results(self) -> list[SaveResult]:
        """The writes finished since the last call, oldest first."""
        with self._lock:
            done, self._results = self._results, []
        return done

    def close(self, timeout: float | None = None) -> bool:
        """Write what is waiting, then stop the writer; False if it did not finish within `timeout`."""
        finished = self.wait(timeout)
        with self._lock:
            self._closed = True
            self._lock.notify_all()
        self._thread.join(timeout if finished else 0)
        return finished

    def _run(self) -> None:
        while True:
            with self._lock:
                while self._waiting is None and not self._closed:
                    self._lock.wait()
                if self._waiting is None:  # closed, nothing left
                    return
                snapshot, self._waiting = self._waiting, None
                self._writing = True
            result = self._write(snapshot)
            with self._lock:
                self._results.append(result)
                self._writing = False
                self._lock.notify_all()

    def _write(self, snapshot: _Snapshot) -> SaveResult:
        start = time.perf_counter()
        try:
            write_checkpoint(self.path, snapshot.kind, snapshot.header, snapshot.arrays)
        except LearningError as exc:
            return SaveResult(exc, 0, time.perf_counter() - start)
        except Exception as exc:  # whatever the disk, the zip writer or a bug raises: reported, the thread lives on
            return SaveResult(LearningError(f"{self.path}: writing failed: {type(exc).__name__}: {exc}",
                                            source=self.path), 0, time.perf_counter() - start)
        elapsed = time.perf_counter() - start
        try:
            size = self.path.stat().st_size
        except OSError:
            size = 0
        return SaveResult(None, size, elapsed)
