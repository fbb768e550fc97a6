"""The learning subpackage's one error class."""

from __future__ import annotations

import os
from typing import Any

from gwr_predictor.errors import GwrPredictorError


class LearningError(GwrPredictorError, ValueError):
    """What a learner refuses: a frame, size or state that does not fit a network, or a checkpoint that
    cannot be written or read (truncated, not a checkpoint, another format version, missing or
    inconsistent arrays, locked by another process). The message names the file or value and what is
    wrong.

    Attributes, for callers that must tell cases apart:

    - `source`: the checkpoint (a file, or the name of a state) the error is about; None for a value
      handed to a learner. A model's `from_state` passes errors that name a checkpoint through and
      rewraps the others into one that names its own.
    - `found`, `expected`: the model kinds when a readable checkpoint holds another kind than asked
      (`kind_mismatch`): the file is sound, the request is wrong, so a learner must not move it aside.
    - `locked`: another process holds the checkpoint's lock.
    """

    def __init__(self, message: str, *, source: str | os.PathLike[str] | None = None, found: Any = None,
                 expected: str | None = None, locked: bool = False) -> None:
        super().__init__(message)
        self.source, self.found, self.expected, self.locked = source, found, expected, locked

    @property
    def kind_mismatch(self) -> bool:
        """A readable checkpoint of another model kind (or blend) than the one asked for."""
        return self.expected is not None
