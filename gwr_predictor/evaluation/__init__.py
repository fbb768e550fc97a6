"""Measuring prediction quality: the one online evaluation loop, metrics, and the experiments' outputs.

What it cannot evaluate, score or write is an `EvaluationError` (`errors.py`).
"""

from gwr_predictor._exports import lazy_exports

_EXPORTS = {
    "Predictor": "online",
    "OnlineResult": "online",
    "EvaluationError": "errors",
    "compare_online": "online",
    "evaluate_online": "online",
    "train_online": "online",
    "run_sequence": "online",
    "run_with_intervals": "online",
    "HorizonStats": "metrics",
    "horizon_stats": "metrics",
    "IntervalStats": "metrics",
    "interval_stats": "metrics",
    "future_windows": "metrics",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
