"""The research predictors' registry: the product's names and, beside them, the ablations and blends
that research/ registers (`research.predictors`). Registering here leaves the product's registry, and
so the learner node's choices, as they are."""

from __future__ import annotations

from gwr_predictor.registry import (
    DEFAULT_PREDICTOR,
    PRODUCT,
    Factory,
    Loader,
    Registry,
    gate_loader,
    hierarchy_params,
)

RESEARCH = Registry(parent=PRODUCT)

__all__ = ["DEFAULT_PREDICTOR", "RESEARCH", "Factory", "Loader", "gate_loader", "hierarchy_params"]
