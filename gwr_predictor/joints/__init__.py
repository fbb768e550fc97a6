"""The joints every part names: the 8 arm angles the learner, the robot and the messages exchange.

Below every other subpackage (the learner draws its first neurons inside the arm's limits, the
robot and the pipeline name the same joints), so that none of them imports another for a name.
"""

from gwr_predictor._exports import lazy_exports

_EXPORTS = {
    "ARM_JOINTS": "arm",
    "ARM_JOINT_LIMITS": "arm",
    "SIDES": "arm",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
