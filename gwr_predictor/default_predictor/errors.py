"""The default predictor's one error class."""

from __future__ import annotations

from gwr_predictor.errors import GwrPredictorError


class DefaultPredictorError(GwrPredictorError, ValueError):
    """The default predictor's one error: invalid parameters (of the network, the read-outs or the gate),
    state that does not fit them, or a wrapped model's output of the wrong shape."""
