"""The research predictors, registered beside the product's: the paper's P-GWR alone on raw frames,
the per-step blends with RLS-AR, the default's ungated model and the ablations of the default.

Each is a name in research's own registry (`research/registry.py`, beside the product's), so the
experiments and the tables use them like the product's; the product's registry, and so the learner node,
knows none of them.
"""

from __future__ import annotations

import os
from typing import Any

from gwr_predictor.default_predictor import LocalLinearParams, LocalLinearPredictor
from gwr_predictor.default_predictor.gate import GatedPredictor, GateParams
from gwr_predictor.learning.hierarchy import FlatPredictor, Hierarchy
from gwr_predictor.learning.protocol import Predictor
from gwr_predictor.predictors.direct_linear import DirectLinear, DirectLinearParams
from research.blend import load_blend, make_blend
from research.registry import RESEARCH, Factory, Loader, gate_loader, hierarchy_params
from research.safety import ungated


def local_linear_params(params: Any, **changes: Any) -> Any:
    """The default's own settings (`LocalLinearParams()`) with `changes`; only horizon and joints come from `params`."""

    hp = hierarchy_params(params)
    return LocalLinearParams(horizon=hp.horizon, n_joints=hp.n_joints).replace(**changes)


def gated(model: Any, params: Any, **changes: Any) -> Predictor:
    """`model` behind the default's confidence gate (with `changes` to the gate's settings)."""

    hp = hierarchy_params(params)
    return GatedPredictor(model, GateParams(horizon=hp.horizon, joints=hp.n_joints, **changes))


def _flat(params: Any, seed: int) -> Predictor:
    return FlatPredictor(hierarchy_params(params), seed=seed)


def _blend(name: str) -> tuple[Factory, Loader]:
    def make(params: Any, seed: int) -> Predictor:
        return make_blend(name, hierarchy_params(params), seed=seed)

    def load(path: str | os.PathLike[str]) -> Predictor:
        return load_blend(name, path)

    return make, load


def _llm(params: Any, seed: int) -> Predictor:
    return LocalLinearPredictor(local_linear_params(params), seed=seed)


def _load_llm(path: str | os.PathLike[str]) -> Predictor:
    return LocalLinearPredictor.load(path)


def _gated_vqtam(params: Any, seed: int) -> Predictor:
    lp = local_linear_params(params, rate=0.0, neighbour_rate=0.0, readout_k=1, global_order=0)
    return gated(LocalLinearPredictor(lp, seed=seed), params)


def _gated_llm_local(params: Any, seed: int) -> Predictor:
    return gated(LocalLinearPredictor(local_linear_params(params, global_order=0), seed=seed), params)


def _gated_linear(params: Any, seed: int) -> Predictor:
    lp = local_linear_params(params)  # the default's own global read-out, alone
    return gated(DirectLinear(DirectLinearParams(order=lp.global_order, horizon=lp.horizon, joints=lp.n_joints)),
                 params)


def _gated_hierarchy(params: Any, seed: int) -> Predictor:
    return gated(Hierarchy(hierarchy_params(params), seed=seed), params)


def _experts_ungated(params: Any, seed: int) -> Predictor:
    """The default's experts and weighting without any gate: what the gates add is the difference."""

    return ungated(hierarchy_params(params), seed)


def register_all() -> None:
    """Register every research predictor once (importing `research` does)."""
    if "pgwr_flat" in RESEARCH.names():
        return
    RESEARCH.register("pgwr_flat", _flat, "P-GWR alone")
    for name, label in (("blend_hierarchy_rls", "blend hierarchy + RLS-AR"),
                        ("blend_flat_rls", "blend P-GWR alone + RLS-AR")):
        make, load = _blend(name)
        RESEARCH.register(name, make, label, load)
    RESEARCH.register("llm_gwr", _llm, "local-linear P-GWR (ungated)", _load_llm)
    RESEARCH.register("experts_ungated", _experts_ungated, "GWR experts (ungated)")
    RESEARCH.register("gated_hierarchy", _gated_hierarchy, "gate around the GWR hierarchy", gate_loader("Hierarchy"))
    RESEARCH.register("gated_vqtam", _gated_vqtam, "gated P-GWR, displacements, no local models")
    RESEARCH.register("gated_llm_local", _gated_llm_local, "gated local-linear P-GWR, local read-outs only")
    RESEARCH.register("gated_linear", _gated_linear, "gated global linear read-out alone")


register_all()
