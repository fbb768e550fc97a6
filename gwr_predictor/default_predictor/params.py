"""The default predictor's settings, declared once (ParamSpecs: the dataclass, the node and the YAML)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, ClassVar

from gwr_predictor.default_predictor.errors import DefaultPredictorError
from gwr_predictor.learning.params import DEFAULT_HORIZON, MAX_HORIZON, GWRParams
from gwr_predictor.parameters.spec import ParamSpec, check_fields

#: The default network's bound (neurons): each holds a local linear model of 48 x 48 values (18 kB), so
#: 1,000 of them are 18 MB of memory and of checkpoint. Chosen by measurement (research/tuning.md: cost
#: at the bound, and no loss on the tuning set, whose streams stay far below it).
NETWORK_MAX_NEURONS = 1000


def default_gwr() -> GWRParams:
    """The GWR step of the default's network: the paper's, with edges removed at age 100, bounded."""
    return GWRParams(max_edge_age=100, max_neurons=NETWORK_MAX_NEURONS)


LOCAL_LINEAR_SPECS = {spec.name: spec for spec in (
    ParamSpec("order", 4, "frames in the regressor", 1, 32),
    ParamSpec("horizon", DEFAULT_HORIZON, "frames predicted", 1, MAX_HORIZON),
    ParamSpec("n_joints", 8, "joints per frame", 1),
    ParamSpec("insertion_scale", 1.5, "insertion distance in units of the motion scale", 0.0, 1e3,
              lo_open=True, hi_open=True),
    ParamSpec("noise_floor", 0.01, "lower bound of the motion scale (rad)", 0.0, 10.0, lo_open=True, hi_open=True),
    ParamSpec("motion_decay", 0.999, "forgetting of the motion estimate per frame", 0.0, 1.0,
              lo_open=True, hi_open=True),
    ParamSpec("rate", 0.2, "NLMS rate of the local models", 0.0, 1.5),
    ParamSpec("readout_k", 3, "neurons blended in the read-out", 1, 64),
    ParamSpec("neighbour_rate", 0.05, "NLMS rate of the BMU's neighbours", 0.0, 1.5),
    ParamSpec("global_order", 2, "frames the global linear read-out's features span (0: local read-outs only)", 0, 32),
    ParamSpec("global_delta", 100.0, "prior variance of the global read-out's weights (RLS P(0) = delta I)", 0.0,
              lo_open=True),
    ParamSpec("mix_decay", 0.995, "forgetting of the read-outs' mixing statistics per learned pair", 0.0, 1.0,
              lo_open=True),
    ParamSpec("mix_ridge", 0.01, "rad^2 per joint added to the mixing equations (pulls towards hold-last)", 0.0,
              lo_open=True),
    ParamSpec("consolidate_after", 200, "visits after which a neuron's rates fall as 1/visits (0 = never)",
              0, 10**9),
    ParamSpec("recruit_surprise", 6.0, "squared read-out error, in units of a consolidated BMU's running mean, "
              "beyond which a pair surprises it (0 = never recruit)", 0.0, 1e6),
    ParamSpec("recruit_after", 2, "surprising pairs in a row after which a consolidated BMU recruits a neuron",
              1, 1000),
)}
@dataclass(frozen=True)
class LocalLinearParams:
    """Settings of `LocalLinearPredictor` (chosen by `gwr-predictor experiment tune`, see docs).

    `order`: frames in the regressor (newest first). `horizon`: frames predicted. `insertion_scale`:
    insert when the per-frame RMS distance to the BMU exceeds this x the running RMS frame-to-frame
    motion. `noise_floor` (rad): lower bound of that motion scale (tracker jitter). `motion_decay`:
    forgetting factor of the motion estimate per frame. `rate`: NLMS rate mu of the local models
    (0 = plain VQTAM read-out, the ablation). `global_order`: frames the global linear read-out's
    features span (0: none, the local read-outs alone); `global_delta`: the prior variance of its
    weights (large: a weak prior, so it follows the data within a few dozen pairs; the mix below and
    the gate keep an immature fit from doing harm); `mix_decay`, `mix_ridge`: forgetting and ridge of
    the per-step least-squares mix of the local and global read-outs. `consolidate_after`: visits (as BMU) after which a
    neuron's rates fall as consolidate_after / visits (0 = constant rates): without it each
    new movement rewrote the outputs of the neurons it shares with earlier ones (`experiment
    incremental`). 200 is about the memory of Eq. 9's output step at the firing counter's floor,
    1 / (eps_b (1 - 1/kappa)) = 210 visits: a neuron consolidates once it has had that many, and
    from then on its position and output weight are about the running means of its visits.
    `recruit_surprise`: a pair surprises a consolidated BMU when its read-out's squared error exceeds
    this x the neuron's running mean (0 = never recruit; only consolidated neurons recruit, so none
    without `consolidate_after`). `recruit_after`: at that many surprising pairs in a row, the BMU
    leaves the pair to a new neuron placed at it; the surprising pairs before it move nothing and do
    not count in its error. So a new movement through the poses of an old one gets neurons of its own
    instead of being averaged into the old one's (`experiment incremental`), while one odd pair (a
    tracking glitch, one person's quirk) is only ignored.
    `gwr`: the GWR step's parameters (its a_T only fixes the constant -ln a_T the scaled distance is
    compared with).
    """

    SPECS: ClassVar[dict[str, ParamSpec]] = LOCAL_LINEAR_SPECS
    order: int = LOCAL_LINEAR_SPECS["order"].default
    horizon: int = LOCAL_LINEAR_SPECS["horizon"].default
    n_joints: int = LOCAL_LINEAR_SPECS["n_joints"].default
    insertion_scale: float = LOCAL_LINEAR_SPECS["insertion_scale"].default
    noise_floor: float = LOCAL_LINEAR_SPECS["noise_floor"].default
    motion_decay: float = LOCAL_LINEAR_SPECS["motion_decay"].default
    rate: float = LOCAL_LINEAR_SPECS["rate"].default
    readout_k: int = LOCAL_LINEAR_SPECS["readout_k"].default
    neighbour_rate: float = LOCAL_LINEAR_SPECS["neighbour_rate"].default
    global_order: int = LOCAL_LINEAR_SPECS["global_order"].default
    global_delta: float = LOCAL_LINEAR_SPECS["global_delta"].default
    mix_decay: float = LOCAL_LINEAR_SPECS["mix_decay"].default
    mix_ridge: float = LOCAL_LINEAR_SPECS["mix_ridge"].default
    consolidate_after: int = LOCAL_LINEAR_SPECS["consolidate_after"].default
    recruit_surprise: float = LOCAL_LINEAR_SPECS["recruit_surprise"].default
    recruit_after: int = LOCAL_LINEAR_SPECS["recruit_after"].default
    #: The GWR step's activation threshold is no setting of the network: it inserts by `insertion_scale` x
    #: the data's own motion scale, which cancels any a_T (see `predictor.py`).
    gwr: GWRParams = field(default_factory=default_gwr,
                           metadata={"about": "GWR step", "hidden": ("activation_threshold",)})

    def __post_init__(self) -> None:
        check_fields(self, LOCAL_LINEAR_SPECS.values(), DefaultPredictorError)
        if not isinstance(self.gwr, GWRParams):
            raise DefaultPredictorError(f"LocalLinearParams.gwr must be GWRParams, got {type(self.gwr).__name__}")
        if self.global_order > self.order:
            raise DefaultPredictorError(f"LocalLinearParams.global_order {self.global_order} exceeds the "
                                        f"regressor's {self.order} frames")

    def replace(self, **changes: Any) -> LocalLinearParams:
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> LocalLinearParams:
        d = dict(d)
        return cls(**{**d, "gwr": GWRParams(**d["gwr"])}) if "gwr" in d else cls(**d)


