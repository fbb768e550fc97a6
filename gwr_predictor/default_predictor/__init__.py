"""The default predictor: a growing network of local linear experts behind a confidence gate.

What a robot runs unless told otherwise (`make_default`; registry name `gated_llm_gwr`). Read it in
this order:

- `params.py`: every setting, declared once; `settings.py`: the same as the node's flat parameters;
- `network.py`: the Predictive GWR whose neurons carry local linear models, consolidate with
  experience and recruit new neurons for movements they have not seen (beyond the paper);
- `predictor.py`: the online loop, one frame at a time, with a global linear read-out mixed per
  horizon step with the neurons' read-out, and its checkpoints;
- `gate.py`: the confidence gate that falls back to holding the pose wherever the model has not
  recently beaten holding it.

The paper's own method (GWR1 -> GWR2 -> P-GWR) is `gwr_predictor.learning.hierarchy`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from gwr_predictor._exports import lazy_exports

if TYPE_CHECKING:
    from gwr_predictor.default_predictor.gate import GatedPredictor

_EXPORTS = {
    "LocalLinearParams": "params",
    "DefaultPredictorError": "params",
    "LocalLinearError": "params",
    "LocalLinearPGWR": "network",
    "LocalLinearPredictor": "predictor",
    "GatedPredictor": "gate",
    "GateParams": "gate",
    "GateError": "gate",
    "inner_model": "gate",
    "parameter_specs": "settings",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = ["make_default", *sorted(_EXPORTS)]


def make_default(horizon: int = 6, joints: int = 8, seed: int = 0,
                 settings: Mapping[str, Any] | None = None) -> GatedPredictor:
    """The default predictor, fresh: the local-linear P-GWR with its global read-out, behind the gate.

    `settings`: flat parameters (`parameter_specs()`: e.g. `order`, `gwr.eps_b`, `gate.decay`); the
    others keep their defaults."""
    from gwr_predictor.default_predictor.gate import GatedPredictor
    from gwr_predictor.default_predictor.predictor import LocalLinearPredictor
    from gwr_predictor.default_predictor.settings import from_settings

    model_params, gate_params = from_settings(settings or {}, horizon, joints)
    return GatedPredictor(LocalLinearPredictor(model_params, seed=seed), gate_params)
