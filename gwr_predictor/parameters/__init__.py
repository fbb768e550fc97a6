"""One parameter declared once (`spec.ParamSpec`): the learner's and the robot's dataclasses check their
fields with it, the nodes declare it as a described ROS parameter, the docs tables are made from it.
"""

from gwr_predictor._exports import lazy_exports

_EXPORTS = {
    "ParamSpec": "spec",
    "ParameterError": "spec",
    "check_fields": "spec",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
