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
    settings_from_parameters,
)

RESEARCH = Registry(parent=PRODUCT)
register = RESEARCH.register
entry = RESEARCH.entry
names = RESEARCH.names
label = RESEARCH.label
make_predictor = RESEARCH.make
load_predictor = RESEARCH.load
learner_names = RESEARCH.learner_names


def default_name() -> str:
    """The product's default predictor, which every experiment scores."""
    return DEFAULT_PREDICTOR


__all__ = ["DEFAULT_PREDICTOR", "RESEARCH", "Factory", "Loader", "default_name", "entry", "gate_loader",
           "hierarchy_params", "label", "learner_names", "load_predictor", "make_predictor", "names", "register",
           "settings_from_parameters"]
