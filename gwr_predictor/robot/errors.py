"""The robot subpackage's one error class."""

from __future__ import annotations

from gwr_predictor.errors import GwrPredictorError


class RobotError(GwrPredictorError, ValueError, RuntimeError):
    """What the robot side cannot do: robot, delay or compensator parameters out of range, angles or
    commands of the wrong shape, a naoqi command that cannot be made, a PyBullet simulator that cannot
    start or is used wrongly, series the lag and tracking measures cannot compare. The message names
    the field or cause. It is also a ValueError and a RuntimeError, what a caller that does not know the
    package's classes would catch (a simulator that cannot start is a runtime failure, a bad parameter a
    bad value).
    """
