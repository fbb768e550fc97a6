"""Online predictors beside the paper's hierarchy and the default: the baselines they must beat (hold
the last pose, constant velocity, RLS-AR) and the direct multi-step linear model."""

from gwr_predictor._exports import lazy_exports

_EXPORTS = {
    "HoldLast": "baselines",
    "ConstantVelocity": "baselines",
    "RLSAutoregressive": "baselines",
    "RLSParams": "baselines",
    "make_baselines": "baselines",
    "DirectLinear": "direct_linear",
    "DirectLinearParams": "direct_linear",
    "PredictorError": "errors",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
