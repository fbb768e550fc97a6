"""How a node stops: the exit codes of its process and the error that stops it."""

from __future__ import annotations

from gwr_predictor.errors import GwrPredictorError

EXIT_OK = 0
EXIT_FATAL = 1
EXIT_BAD_PARAMETER = 2


class NodeFatalError(GwrPredictorError):
    """A condition that stops the node (unwritable path, full disk, unreadable file); the message says which."""
