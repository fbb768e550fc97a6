"""What the experiments share: parameters with overrides, model factories, data, orders.

Every model is built here, so that all experiments compare the same methods under the same names:
"hierarchy" (GWR1 -> GWR2 -> P-GWR), "pgwr_flat" (the P-GWR alone on raw frames, the ablation),
the baselines of `gwr_predictor.predictors.baselines`, and the per-step inverse-MSE blends of a GWR predictor with
RLS-AR (`gwr_predictor.predictors.blend`): "blend_hierarchy_rls", "blend_flat_rls".
"""

from __future__ import annotations

import copy
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from gwr_predictor.evaluation.online import Predictor
from gwr_predictor.learning.params import HierarchyParams
from gwr_predictor.predictors.baselines import make_baselines

HIERARCHY = "hierarchy"
FLAT = "pgwr_flat"
BASELINES = ("hold", "const_velocity", "rls_ar")
BLEND = "blend_hierarchy_rls"
BLEND_FLAT = "blend_flat_rls"
BLENDS = {BLEND: "hierarchy+rls", BLEND_FLAT: "flat+rls"}  # method name -> ensemble.make_blend kind
LLM = "llm_gwr"
GATED = "gated_llm_gwr"
#: The predictor the gwr_hierarchy node, demo.sh and pretrain run by default.
DEFAULT = GATED
ALL_METHODS = (*BASELINES, FLAT, HIERARCHY, BLEND, BLEND_FLAT, LLM, GATED)
#: Ablation variants of the default (experiment ablation): the gate around the paper's hierarchy, and
#: the gate around the P-GWR with displacement targets but without local models (rate 0).
GATED_HIERARCHY = "gated_hierarchy"
GATED_VQTAM = "gated_vqtam"
ABLATIONS = (GATED_HIERARCHY, GATED_VQTAM)
LABELS = {"hold": "hold last", "const_velocity": "constant velocity", "rls_ar": "RLS-AR",
          FLAT: "P-GWR alone", HIERARCHY: "GWR hierarchy", BLEND: "blend hierarchy + RLS-AR",
          BLEND_FLAT: "blend P-GWR alone + RLS-AR", LLM: "local-linear P-GWR (ungated)",
          GATED: "gated local-linear P-GWR (default)", GATED_HIERARCHY: "gate around the GWR hierarchy",
          GATED_VQTAM: "gated P-GWR, displacements, no local models"}


def make_params(overrides: Iterable[tuple[str, object]] = (), **changes: Any) -> HierarchyParams:
    """Defaults, then flat `overrides` (from the command line), then `changes` the experiment needs."""
    params = HierarchyParams.from_flat(dict(overrides))
    return params.replace(**changes) if changes else params


def make_model(name: str, params: HierarchyParams, seed: int) -> Predictor:
    """A fresh predictor called `name` (one of ALL_METHODS) for `params`."""
    if name == HIERARCHY:
        from gwr_predictor.learning.hierarchy import Hierarchy

        return Hierarchy(params, seed=seed)
    if name == FLAT:
        from gwr_predictor.learning.hierarchy import FlatPredictor

        return FlatPredictor(params, seed=seed)
    if name in BLENDS:
        from gwr_predictor.predictors.blend import make_blend

        return make_blend(BLENDS[name], params, seed=seed)
    if name in (LLM, GATED, GATED_VQTAM):
        from gwr_predictor.learning.local_linear import LocalLinearParams, LocalLinearPredictor
        from gwr_predictor.predictors.gate import make_gated_llm

        lp = LocalLinearParams(horizon=params.horizon, n_joints=params.n_joints)
        if name == GATED_VQTAM:
            lp = lp.replace(rate=0.0, neighbour_rate=0.0, readout_k=1)
        return LocalLinearPredictor(lp, seed=seed) if name == LLM else make_gated_llm(params=lp, seed=seed)
    if name == GATED_HIERARCHY:
        from gwr_predictor.learning.hierarchy import Hierarchy
        from gwr_predictor.predictors.gate import GatedPredictor, GateParams

        return GatedPredictor(Hierarchy(params, seed=seed), GateParams(horizon=params.horizon,
                                                                       joints=params.n_joints))
    baselines = make_baselines(params.horizon, params.span)
    if name not in baselines:
        raise KeyError(f"unknown method {name!r}; choose from {', '.join(ALL_METHODS + ABLATIONS)}")
    return baselines[name]  # type: ignore[return-value]


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
    from gwr_predictor.data.datasets import demo_angle_sequences

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
