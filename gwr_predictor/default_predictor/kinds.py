"""The models that a gate's or the experts' checkpoint can hold inside it, by their `kind`: a saved
wrapper names the kind of each model it wraps, and loading rebuilds that class from its parameters."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from gwr_predictor.learning.checkpoint import CheckpointError
from gwr_predictor.learning.persistence import Checkpointed


def restorable() -> dict[str, type[Checkpointed]]:
    """Every class a wrapper's checkpoint can rebuild, by kind (imports deferred: they import the wrappers)."""
    from gwr_predictor.default_predictor.experts import Experts
    from gwr_predictor.default_predictor.gate import GatedPredictor
    from gwr_predictor.default_predictor.memory import TrajectoryMemory
    from gwr_predictor.default_predictor.predictor import LocalLinearPredictor
    from gwr_predictor.default_predictor.recognition import RecognitionSwitch, View
    from gwr_predictor.learning.hierarchy import FlatPredictor, Hierarchy
    from gwr_predictor.predictors.baselines import RLSAutoregressive
    from gwr_predictor.predictors.direct_linear import DirectLinear

    return {c.kind: c for c in (LocalLinearPredictor, Hierarchy, FlatPredictor, TrajectoryMemory, RLSAutoregressive,
                                DirectLinear, GatedPredictor, Experts, RecognitionSwitch, View)}


def kind_to_save(model: Any, what: str) -> str:
    """`model`'s kind if it can be saved inside a wrapper; CheckpointError naming `what` otherwise."""
    kinds = restorable()
    kind = getattr(model, "kind", None)
    if kind not in kinds or not isinstance(model, Checkpointed):
        raise CheckpointError(f"{what} ({type(model).__name__}) cannot be saved; supported: {', '.join(kinds)}")
    return str(kind)


def fresh_of_kind(kind: Any, header: Mapping[str, Any]) -> Checkpointed:
    """A fresh model of the saved `kind` and parameters (`header`), before its state is restored."""
    kinds = restorable()
    if not isinstance(kind, str) or kind not in kinds:
        raise CheckpointError(f"a wrapped model of kind {kind!r}; this build restores {', '.join(kinds)}")
    return kinds[kind]._fresh(header)
