"""The default predictor: growing networks that remember movements and linear models that
extrapolate them, each behind a confidence gate (lifted where the movement is recognised), heard per
horizon step by how well it did lately, behind a last gate.

What a robot runs unless told otherwise (`make_default`; registry name `gwr_experts`), composed in one
file, `default.py`: its settings tree `DefaultParams`, then `DefaultPredictor`, which builds it. Its
experts:

- the local-linear P-GWR (`network.py`, `predictor.py`): the Predictive GWR whose neurons carry local
  linear models, consolidate with experience and recruit new neurons for movements they have not
  seen, with a global linear read-out mixed in per horizon step;
- the snippet memory (`memory.py`): a bounded memory of short movement snippets, read out by the
  nearest ones at the present speed, so a movement seen once is anticipated when it comes again; and
  a second one, the long memory, whose snippets' keys span twice as much of the past;
- the `rls_ar` and `linear` models (`gwr_predictor.predictors`): linear models of the last frames,
  which are best while a person's movements are still new.

Each expert sits behind its own confidence gate (`gate.py`: it falls back to holding the pose where
the expert has not recently beaten holding it); `experts.py` weights them per horizon step by their
recent errors; where the memory recognises the motion, `recognition.py` returns the experts' weighting
without their gates; a last gate guards each weighting; `spread.py` states an interval with every
prediction. The network behind one gate alone is `make_gated_network` (registry name `gated_llm_gwr`).

The paper's own method (GWR1 -> GWR2 -> P-GWR) is `gwr_predictor.learning.hierarchy`.
"""

from gwr_predictor.default_predictor.default import (
    DefaultParams,
    DefaultPredictor,
    GatedNetworkParams,
    LongMemoryParams,
    make_default,
    make_gated_network,
)
from gwr_predictor.default_predictor.errors import DefaultPredictorError
from gwr_predictor.default_predictor.experts import Experts, ExpertsParams
from gwr_predictor.default_predictor.gate import GatedPredictor, GateParams, inner_model
from gwr_predictor.default_predictor.memory import MemoryParams, TrajectoryMemory
from gwr_predictor.default_predictor.network import LocalLinearPGWR
from gwr_predictor.default_predictor.params import LocalLinearParams
from gwr_predictor.default_predictor.predictor import LocalLinearPredictor
from gwr_predictor.default_predictor.recognition import RecognitionParams, RecognitionSwitch, View
from gwr_predictor.default_predictor.spread import Spread, SpreadParams, WithSpread

__all__ = [
    "DefaultParams",
    "DefaultPredictor",
    "DefaultPredictorError",
    "Experts",
    "ExpertsParams",
    "GateParams",
    "GatedNetworkParams",
    "GatedPredictor",
    "LocalLinearPGWR",
    "LocalLinearParams",
    "LocalLinearPredictor",
    "LongMemoryParams",
    "MemoryParams",
    "RecognitionParams",
    "RecognitionSwitch",
    "Spread",
    "SpreadParams",
    "TrajectoryMemory",
    "View",
    "WithSpread",
    "inner_model",
    "make_default",
    "make_gated_network",
]
