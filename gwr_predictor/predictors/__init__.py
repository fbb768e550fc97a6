"""Online predictors beside the paper's hierarchy: the baselines it must beat and the blend; the
offline k-NN reference of `experiment real`.
"""

from gwr_predictor._exports import lazy_exports

_EXPORTS = {
    "HoldLast": "baselines",
    "ConstantVelocity": "baselines",
    "RLSAutoregressive": "baselines",
    "RLSParams": "baselines",
    "make_baselines": "baselines",
    "BlendedPredictor": "blend",
    "BlendParams": "blend",
    "BlendError": "blend",
    "make_blend": "blend",
    "make_predictor": "registry",
    "load_predictor": "registry",
    "register": "registry",
    "learner_names": "registry",
    "UnknownPredictorError": "registry",
    "KnnPredictor": "knn",
    "KnnError": "knn",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
