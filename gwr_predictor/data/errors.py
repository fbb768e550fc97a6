"""The data subpackage's one error class."""

from __future__ import annotations

from gwr_predictor.errors import GwrPredictorError


class DataError(GwrPredictorError, ValueError):
    """Data the package cannot use: a skeleton, mocap, angle or torch file, positions or joint names
    that angle extraction or smoothing cannot take, a demonstrator or fault setting out of range, body
    tracking or REP-155 joint states that cannot be a body. The message names the file, field, joint or
    line and what is wrong.

    `reason`: the rule a streamed message broke, for rejection counters (`layout`, `missing_joints`,
    `non_finite`); empty where no counter reads it.
    """

    def __init__(self, message: str, reason: str = "") -> None:
        super().__init__(message)
        self.reason = reason
