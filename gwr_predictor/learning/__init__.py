"""The paper's learner (Sec. III-B..D), readable top-down: params -> gwr -> predictive_gwr -> hierarchy.

`scaling` maps radians to the units the layers measure distances in; `checkpoint` is the one
versioned file format every learner saves to; `protocol` is what every predictor of the package
follows (`Predictor`), `pending` how its predictions wait for the frame they target. What a learner
refuses (an input, a checkpoint) is a `LearningError` (`errors.py`).
"""

from gwr_predictor._exports import lazy_exports

_EXPORTS = {
    "ParamSpec": "params",
    "GWRParams": "params",
    "HierarchyParams": "params",
    "GWR": "gwr",
    "LearningError": "errors",
    "PredictiveGWR": "predictive_gwr",
    "Hierarchy": "hierarchy",
    "FlatPredictor": "hierarchy",
    "ErrorTracker": "online_loop",
    "PendingPredictions": "pending",
    "Predictor": "protocol",
    "Learner": "protocol",
    "Spreading": "protocol",
    "InputScaling": "scaling",
    "read_checkpoint": "checkpoint",
    "write_checkpoint": "checkpoint",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
