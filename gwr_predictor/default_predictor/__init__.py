"""The default predictor: growing networks that remember movements and linear models that
extrapolate them, each behind a confidence gate (lifted where the movement is recognised), heard per
horizon step by how well it did lately, behind a last gate.

What a robot runs unless told otherwise (`make_default`; registry name `gwr_experts`). Its experts:

- the local-linear P-GWR (`network.py`, `predictor.py`): the Predictive GWR whose neurons carry local
  linear models, consolidate with experience and recruit new neurons for movements they have not
  seen, with a global linear read-out mixed in per horizon step;
- the snippet memory (`memory.py`): a growing memory of short movement snippets, read out by the
  nearest ones at the present speed, so a movement seen once is anticipated when it comes again; and
  a second one, the long memory, whose snippets' keys span twice as much of the past;
- the `rls_ar` and `linear` baselines (`gwr_predictor.predictors`): linear models of the last frames,
  which are best while a person's movements are still new.

Each expert sits behind its own confidence gate (`gate.py`: it falls back to holding the pose where
the expert has not recently beaten holding it); `experts.py` weights them per horizon step by their
recent errors; where the memory recognises the motion, `recognition.py` returns the experts' weighting
without their gates; a last gate guards each weighting. `params.py` and `settings.py` declare every
setting once. The network behind one gate alone is `make_gated_network` (registry name `gated_llm_gwr`).

The paper's own method (GWR1 -> GWR2 -> P-GWR) is `gwr_predictor.learning.hierarchy`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from gwr_predictor._exports import lazy_exports

if TYPE_CHECKING:
    from gwr_predictor.default_predictor.gate import GatedPredictor
    from gwr_predictor.default_predictor.recognition import RecognitionSwitch

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
    "experts_parameter_specs": "settings",
    "Experts": "experts",
    "ExpertsParams": "experts",
    "TrajectoryMemory": "memory",
    "MemoryParams": "memory",
    "RecognitionSwitch": "recognition",
    "RecognitionParams": "recognition",
    "View": "recognition",
    "Spread": "spread",
    "SpreadParams": "spread",
    "WithSpread": "spread",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = ["make_default", "make_gated_network", *sorted(_EXPORTS)]


def make_default(horizon: int = 6, joints: int = 8, seed: int = 0,
                 settings: Mapping[str, Any] | None = None) -> RecognitionSwitch:
    """The default predictor, fresh: the five experts (four with `long_memory.enabled` false), each behind
    its gate, weighted per step, or ungated where the motion is recognised, each weighting behind its last
    gate.

    `settings`: flat parameters (`experts_parameter_specs()`: e.g. `network.order`, `memory.k`,
    `experts.power`, `expert_gate.decay`, `gate.confidence`); the others keep their defaults."""
    from gwr_predictor.default_predictor.experts import Experts
    from gwr_predictor.default_predictor.gate import GatedPredictor
    from gwr_predictor.default_predictor.memory import TrajectoryMemory
    from gwr_predictor.default_predictor.predictor import LocalLinearPredictor
    from gwr_predictor.default_predictor.recognition import RecognitionSwitch
    from gwr_predictor.default_predictor.settings import from_experts_settings
    from gwr_predictor.predictors.baselines import TUNED_RLS, RLSAutoregressive
    from gwr_predictor.predictors.direct_linear import TUNED_LINEAR, DirectLinear

    network, memory, long_memory, weighting, recognition, expert_gate, gate, spread = from_experts_settings(
        settings or {}, horizon, joints)
    experts = {"network": LocalLinearPredictor(network, seed=seed),
               "linear": DirectLinear(TUNED_LINEAR.replace(horizon=horizon, joints=joints)),
               "rls_ar": RLSAutoregressive(TUNED_RLS, horizon, joints),
               "memory": TrajectoryMemory(memory)}
    if long_memory is not None:
        experts["long_memory"] = TrajectoryMemory(long_memory)
    gated = {name: GatedPredictor(model, expert_gate, hold_when_silent=False) for name, model in experts.items()}
    return RecognitionSwitch(Experts(gated, weighting), recognition, gate, spread)


def make_gated_network(horizon: int = 6, joints: int = 8, seed: int = 0,
                       settings: Mapping[str, Any] | None = None) -> GatedPredictor:
    """The local-linear P-GWR with its global read-out behind one gate (`gated_llm_gwr`).

    `settings`: flat parameters (`parameter_specs()`: e.g. `order`, `gwr.eps_b`, `gate.decay`)."""
    from gwr_predictor.default_predictor.gate import GatedPredictor
    from gwr_predictor.default_predictor.predictor import LocalLinearPredictor
    from gwr_predictor.default_predictor.settings import from_settings

    model_params, gate_params = from_settings(settings or {}, horizon, joints)
    return GatedPredictor(LocalLinearPredictor(model_params, seed=seed), gate_params)
