"""The default predictor's settings as flat, named parameters: its own, its network's GWR step
(`gwr.*`) and its gate's (`gate.*`), each declared once by the ParamSpec its dataclass validates with.

The learner node declares exactly these (under `gated_llm_gwr.`) when it runs the default; the
horizon and the joints are the node's, not the predictor's. The GWR step's activation threshold is
not among them: the default inserts by `insertion_scale` x the data's own motion scale, which cancels
any a_T (see `predictor.py`), so a parameter for it would have no effect.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from gwr_predictor.default_predictor.gate import GATE_SPECS, GateParams
from gwr_predictor.default_predictor.params import (
    LOCAL_LINEAR_SPECS,
    DefaultPredictorError,
    LocalLinearParams,
    default_gwr,
)
from gwr_predictor.learning.params import GWR_SPECS
from gwr_predictor.parameter_spec import ParamSpec

#: Set by the node (or `make_default`'s arguments), not by the predictor's settings.
FROM_THE_DATA = ("horizon", "n_joints", "joints")
#: The GWR step's settings the default's network uses (not the activation threshold: see above).
GWR_USED = ("firing_threshold", "eps_b", "eps_n", "rho_b", "rho_n", "kappa", "max_edge_age", "max_neurons")


def parameter_specs() -> tuple[ParamSpec, ...]:
    """Every setting of the default, flat: its own names, `gwr.<name>` and `gate.<name>`."""
    own = [s for name, s in LOCAL_LINEAR_SPECS.items() if name not in FROM_THE_DATA]
    gwr = default_gwr()
    steps = [dataclasses.replace(GWR_SPECS[name], name=f"gwr.{name}", default=_flat(getattr(gwr, name)),
                                 description=f"GWR step: {GWR_SPECS[name].description}") for name in GWR_USED]
    gate = [dataclasses.replace(s, name=f"gate.{name}", description=f"gate: {s.description}")
            for name, s in GATE_SPECS.items() if name not in FROM_THE_DATA]
    return (*own, *steps, *gate)


def _flat(value: Any) -> Any:
    return 0 if value is None else value  # max_neurons: None (unlimited) is 0 as a parameter


def from_settings(settings: Mapping[str, Any], horizon: int, joints: int) -> tuple[LocalLinearParams, GateParams]:
    """The model's and the gate's parameters for flat `settings` (any subset of `parameter_specs()`;
    missing ones keep their defaults). Unknown names or bad values raise DefaultPredictorError naming them."""
    specs = {s.name: s for s in parameter_specs()}
    unknown = sorted(set(settings) - set(specs))
    if unknown:
        raise DefaultPredictorError(f"unknown settings of the default predictor {unknown}; known: {', '.join(specs)}")
    own: dict[str, Any] = {}
    gwr: dict[str, Any] = {}
    gate: dict[str, Any] = {}
    for name, value in settings.items():
        specs[name].check(value)
        group, _, key = name.partition(".")
        if not key:
            own[name] = value
        elif group == "gwr":
            gwr[key] = None if key == "max_neurons" and value == 0 else value
        else:
            gate[key] = value
    model = LocalLinearParams(horizon=horizon, n_joints=joints, gwr=default_gwr().replace(**gwr), **own)
    return model, GateParams(horizon=horizon, joints=joints, **gate)

