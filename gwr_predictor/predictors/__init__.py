"""Online predictors beside the paper's hierarchy and the default: the baselines they must beat, and
the one registry of predictors by name.
"""

from gwr_predictor._exports import lazy_exports

_EXPORTS = {
    "HoldLast": "baselines",
    "ConstantVelocity": "baselines",
    "RLSAutoregressive": "baselines",
    "RLSParams": "baselines",
    "make_baselines": "baselines",
    "make_predictor": "registry",
    "load_predictor": "registry",
    "register": "registry",
    "learner_names": "registry",
    "PredictorError": "errors",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
