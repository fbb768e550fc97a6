"""The pipeline subpackage's one error class."""

from __future__ import annotations

from gwr_predictor.errors import GwrPredictorError


class PipelineError(GwrPredictorError, ValueError, RuntimeError):
    """What the ROS-free pipeline cannot do: a message whose layout breaks the conventions, a bag, params
    file or video that cannot be written or read, a run that cannot be summarised, plotted or rendered.
    The message names the bag, file, topic or field and what is wrong. It is also a ValueError and a
    RuntimeError, what a caller that does not know the package's classes would catch (a bag or video
    that cannot be written is a runtime failure, a bad layout a bad value).

    `reason`, for the rejection counters: `too_large` for a message over a declared bound
    (`conventions.MAX_*`), refused before anything is sized by it and counted as `<input>.too_large`
    rather than `<input>.layout`; `missing_joints` for a message without a joint the reader needs
    (`<input>.missing_joints`); empty otherwise.
    """

    def __init__(self, message: str, reason: str = "") -> None:
        super().__init__(message)
        self.reason = reason
