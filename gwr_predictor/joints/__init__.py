"""The joints every part names: the 8 arm angles (`arm`) the learner, the robot and the messages
exchange, the 15-joint skeleton every source delivers (`skeleton`), and how many joint names an input
may carry (`names`).

Below every other subpackage (the learner draws its first neurons inside the arm's limits, the data's
sources make the skeleton the pipeline's messages carry), so that none of them imports another for a name.
"""

from gwr_predictor._exports import lazy_exports

_EXPORTS = {
    "ARM_JOINTS": "arm",
    "ARM_JOINT_LIMITS": "arm",
    "SIDES": "arm",
    "SKELETON_JOINTS": "skeleton",
    "SKELETON_FPS": "skeleton",
    "ANGLE_FPS": "skeleton",
    "MAX_JOINTS": "names",
    "MAX_NAME_CHARS": "names",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
