"""The default predictor: a growing network of local linear experts behind a confidence gate.

What a robot runs unless told otherwise (`make_default`; registry name `gated_llm_gwr`). Read it in
this order:

- `params.py`: every setting, declared once;
- `network.py`: the Predictive GWR whose neurons carry local linear models, consolidate with
  experience and recruit new neurons for movements they have not seen (beyond the paper);
- `predictor.py`: the online loop, one frame at a time, with a global linear read-out mixed per
  horizon step with the neurons' read-out, and its checkpoints;
- `gate.py`: the confidence gate that falls back to holding the pose wherever the model has not
  recently beaten holding it.

The paper's own method (GWR1 -> GWR2 -> P-GWR) is `gwr_predictor.learning.hierarchy`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from gwr_predictor._exports import lazy_exports

if TYPE_CHECKING:
    from gwr_predictor.default_predictor.gate import GatedPredictor

_EXPORTS = {
    "LocalLinearParams": "params",
    "LocalLinearError": "params",
    "LocalLinearPGWR": "network",
    "LocalLinearPredictor": "predictor",
    "GatedPredictor": "gate",
    "GateParams": "gate",
    "GateError": "gate",
    "inner_model": "gate",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = ["make_default", *sorted(_EXPORTS)]


def make_default(horizon: int = 6, joints: int = 8, seed: int = 0) -> GatedPredictor:
    """The default predictor, fresh: the local-linear P-GWR with its global read-out, behind the gate."""
    from gwr_predictor.default_predictor.gate import GatedPredictor, GateParams
    from gwr_predictor.default_predictor.params import LocalLinearParams
    from gwr_predictor.default_predictor.predictor import LocalLinearPredictor

    model = LocalLinearPredictor(LocalLinearParams(horizon=horizon, n_joints=joints), seed=seed)
    return GatedPredictor(model, GateParams(horizon=horizon, joints=joints))
