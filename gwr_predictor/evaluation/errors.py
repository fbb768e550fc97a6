"""The evaluation subpackage's one error class."""

from __future__ import annotations

from gwr_predictor.errors import GwrPredictorError


class EvaluationError(GwrPredictorError, ValueError, RuntimeError):
    """What the evaluation cannot do: sequences, horizons or predictor outputs the online loop cannot
    use, arrays whose shapes or contents cannot be scored, an experiment output that cannot be written.
    The message names the culprit (the file, for an output). It is also a ValueError and a RuntimeError,
    what a caller that does not know the package's classes would catch.
    """
