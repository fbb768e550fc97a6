"""The predictors' one error class."""

from __future__ import annotations

from gwr_predictor.errors import GwrPredictorError


class PredictorError(GwrPredictorError, ValueError):
    """The predictors' one error: a name that is not registered (the message lists the registered
    ones), a setting out of its range, an input or a saved state that does not fit."""
