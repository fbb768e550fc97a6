"""What the experiments share: parameters with overrides, model factories, data, orders.

Every model is built from the one predictor registry (`research/registry.py`: the product's and research's names), so
that all experiments, `evaluate`, `pretrain` and the learner node use the same names: "hierarchy"
(GWR1 -> GWR2 -> P-GWR), "pgwr_flat" (the P-GWR alone on raw frames, the ablation), the baselines
"hold", "const_velocity", "rls_ar", and the per-step inverse-MSE blends of a GWR predictor with
RLS-AR: "blend_hierarchy_rls", "blend_flat_rls"; the default predictor "gated_llm_gwr" (the
local-linear P-GWR behind the confidence gate), "llm_gwr" without the gate, and the ablation variants.
"""

from __future__ import annotations

import copy
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from gwr_predictor.data.datasets import demo_angle_sequences
from gwr_predictor.learning.params import HierarchyParams
from gwr_predictor.learning.protocol import Predictor
from research.registry import DEFAULT_PREDICTOR, RESEARCH

HIERARCHY = "hierarchy"
FLAT = "pgwr_flat"
BASELINES = ("hold", "const_velocity", "rls_ar", "linear")
LINEAR = "linear"
BLEND = "blend_hierarchy_rls"
BLEND_FLAT = "blend_flat_rls"
LLM = "llm_gwr"
GATED = "gated_llm_gwr"
EXPERTS_UNGATED = "experts_ungated"
#: The predictor the arm_predictor node, demo.sh, pretrain and evaluate's `default_method` run by default.
DEFAULT = DEFAULT_PREDICTOR
#: Ablation variants of the default (experiment ablation, not in `compare`): the gate around the
#: paper's hierarchy, and the gate around the P-GWR with displacement targets but no local models ...
GATED_HIERARCHY = "gated_hierarchy"
GATED_VQTAM = "gated_vqtam"
#: ... and the default's two read-outs alone: the local models only, the global linear read-out only.
GATED_LOCAL = "gated_llm_local"
GATED_LINEAR = "gated_linear"
ABLATIONS = (GATED_HIERARCHY, GATED_VQTAM, GATED_LOCAL, GATED_LINEAR)


def all_methods() -> tuple[str, ...]:
    """Every predictor the experiments and `evaluate` can run: the registry's names."""
    return RESEARCH.names()


def label(name: str) -> str:
    """The predictor's row label in tables and plots."""
    return RESEARCH.label(name)


def make_params(overrides: Iterable[tuple[str, object]] = (), **changes: Any) -> HierarchyParams:
    """Defaults, then flat `overrides` (from the command line), then `changes` the experiment needs."""
    params = HierarchyParams.from_flat(dict(overrides))
    return params.replace(**changes) if changes else params


def make_model(name: str, params: HierarchyParams, seed: int) -> Predictor:
    """A fresh predictor called `name` (a registry name) for `params`."""
    return RESEARCH.make_predictor(name, params, seed)


def make_models(names: Sequence[str], params: HierarchyParams, seed: int) -> dict[str, Predictor]:
    return {name: make_model(name, params, seed) for name in names}


def clone(models: Mapping[str, Predictor]) -> dict[str, Predictor]:
    """Independent copies, so that one evaluation condition cannot change another's model."""
    return {name: copy.deepcopy(m) for name, m in models.items()}


def neuron_counts(model: Any) -> list[int] | None:
    counts = getattr(model, "neuron_counts", None)
    return None if counts is None else [int(c) for c in counts]


def demo_data(patterns: Sequence[str] | None, subjects: int, repetitions: int, seed: int) -> tuple[Any, ...]:
    """The demonstrator's angle sequences (10 fps), pattern-major."""

    return tuple(demo_angle_sequences(patterns=patterns, subjects=subjects, repetitions=repetitions, seed=seed))


def by_pattern(sequences: Sequence[Any]) -> dict[str, list[Any]]:
    out: dict[str, list[Any]] = {}
    for s in sequences:
        out.setdefault(s.pattern, []).append(s)
    return out


def shuffled(items: Sequence[Any], rng: np.random.Generator) -> list[Any]:
    return [items[i] for i in rng.permutation(len(items))]


def frames_in(sequences: Sequence[Any]) -> int:
    return int(sum(np.asarray(getattr(s, "angles", s)).shape[0] for s in sequences))


def worst_ratio_to_hold(stats: Mapping[str, Mapping[str, Any]], method: str) -> float | None:
    """max over horizon steps of MAE(method) / MAE(hold) in one condition's {method: stats dict}:
    the figure of the "never worse than holding still" band (None without hold or scores)."""
    if "hold" not in stats or method not in stats:
        return None
    pairs = [(m, h) for m, h in zip(stats[method]["mae"], stats["hold"]["mae"], strict=True)
             if m is not None and h]
    return max(m / h for m, h in pairs) if pairs else None
