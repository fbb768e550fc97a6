"""The package's one exception base.

Every error class of gwr_predictor (and of its nodes) derives from `GwrPredictorError`, so a caller
(the `gwr-predictor` command line, a node, a script) can catch everything the package raises on
purpose in one `except` and report it in one line, while bugs (TypeError, KeyError of our own code...)
still surface with a traceback. Classes also keep their historical built-in base (ValueError,
OSError, RuntimeError, KeyError) where callers catch that.
"""


class GwrPredictorError(Exception):
    """Base of every error gwr_predictor raises on purpose; the message names the file/field and what is wrong."""
