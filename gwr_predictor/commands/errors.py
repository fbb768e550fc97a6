"""The commands' one error class."""

from __future__ import annotations

from gwr_predictor.errors import GwrPredictorError


class CommandError(GwrPredictorError, ValueError):
    """What a command refuses before the library sees it: an option out of its range, options that
    disagree, a method name that is not registered, a file that is neither an angle CSV nor a skeleton
    or mocap recording. The message names the option or file and what is wrong."""
