"""Hyper-parameters of the GWR layers and of the hierarchy, as frozen validated dataclasses.

Parameters are set once and never mutated by learning (learned state lives in the networks).
`HierarchyParams.to_flat()` / `from_flat()` give the dotted flat form ROS parameters and
checkpoint headers use ("gwr1.activation_threshold", "horizon", ...); `hierarchy_parameter_specs()`
lists every flat key with its default, range and description for `declare_parameter`.
Values follow Table I of the paper unless stated.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

from gwr_predictor.files.limits import MAX_NETWORK_NEURONS
from gwr_predictor.parameters import tree
from gwr_predictor.parameters.spec import ParameterError, ParamSpec, check_fields

#: Edge ages are stored as int16, so the age limit stays well inside its range.
MAX_EDGE_AGE_LIMIT = 30000
MODES = ("recursive", "vector")
#: What the P-GWR's output weights learn: the future frames themselves (the paper) or their
#: displacement from the newest observed frame, added back to that frame when predicting.
TARGETS = ("absolute", "delta")
LAYERS = ("gwr1", "gwr2", "pgwr")

#: Default radians -> model-units factor (see docs/learning.md, "Input scaling").
DEFAULT_INPUT_SCALE = 0.1


GWR_SPECS: dict[str, ParamSpec] = {s.name: s for s in (
    ParamSpec("activation_threshold", 0.98, "a_T: insert a neuron when exp(-||x - w_b||) falls below it (Eq. 2)",
              0.0, 1.0, lo_open=True, hi_open=True),
    ParamSpec("firing_threshold", 0.1,
              "f_T: insert only when the BMU's firing counter is below it (enough training)", 0.0, 1.0, lo_open=True),
    ParamSpec("eps_b", 0.1, "learning rate of the best-matching unit (Eq. 4)", 0.0, 1.0, lo_open=True),
    ParamSpec("eps_n", 0.01, "learning rate of the BMU's topological neighbours (Eq. 4)", 0.0, 1.0),
    ParamSpec("rho_b", 0.3, "firing-counter decay of the BMU (Eq. 3)", 0.0, 1.0, lo_open=True),
    ParamSpec("rho_n", 0.1, "firing-counter decay of the BMU's neighbours (Eq. 3)", 0.0, 1.0),
    ParamSpec("kappa", 1.05, "firing-counter curve constant (Eq. 3); the counter tends to 1 - 1/kappa", 1.0, 10.0),
    ParamSpec("max_edge_age", 100, "edges older than this are removed, then neurons left without edges",
              1, MAX_EDGE_AGE_LIMIT),
    ParamSpec("max_neurons", 0, "neurons at most: beyond, a new neuron replaces the one best-matching longest ago (0 = "
              "unlimited)", 2, MAX_NETWORK_NEURONS, none_value=0),
)}

@dataclass(frozen=True)
class GWRParams:
    """One GWR layer (Sec. III-B, Table I). `max_neurons=None` means no size limit."""

    SPECS: ClassVar[dict[str, ParamSpec]] = GWR_SPECS
    activation_threshold: float = 0.98
    firing_threshold: float = 0.1
    eps_b: float = 0.1
    eps_n: float = 0.01
    rho_b: float = 0.3
    rho_n: float = 0.1
    kappa: float = 1.05
    max_edge_age: int = 100
    max_neurons: int | None = None

    def __post_init__(self) -> None:
        owner = type(self).__name__
        for name, spec in GWR_SPECS.items():
            value = getattr(self, name)
            if name == "max_neurons" and value is None:
                continue
            if name == "max_neurons" and value == spec.none_value:  # the flat form's 0 is None here
                raise ParameterError(f"{owner}.max_neurons must be None (unlimited) or in [{spec.lo}, {spec.hi}], "
                                     f"got {value!r}")
            spec.check(value, owner)
        # The counter converges to 1 - 1/kappa; above f_T no neuron would ever be inserted.
        floor = 1.0 - 1.0 / self.kappa
        if floor >= self.firing_threshold:
            raise ParameterError(
                f"{owner}.kappa={self.kappa:g} makes the firing counter settle at {floor:.4f} >= "
                f"firing_threshold={self.firing_threshold:g}: no neuron could ever be inserted; "
                f"kappa must be < {1.0 / (1.0 - self.firing_threshold):.4f}")

    def replace(self, **changes: Any) -> GWRParams:
        """A validated copy with some fields changed."""
        return dataclasses.replace(self, **changes)


#: Frames predicted by default: 6 at 10 fps, 600 ms, the paper's horizon.
DEFAULT_HORIZON = 6
#: The longest horizon any predictor accepts; prediction messages with more rows are refused on arrival.
MAX_HORIZON = 100

HIERARCHY_SPECS: dict[str, ParamSpec] = {s.name: s for s in (
    ParamSpec("n_joints", 8, "angles per frame (8 Nao arm joints)", 1, 256),
    ParamSpec("tau1", 3, "window of GWR1 BMUs concatenated into the GWR2 input (Eq. 5)", 1, 32),
    ParamSpec("tau2", 3, "window of GWR2 BMUs concatenated into the P-GWR regressor (Eq. 5)", 1, 32),
    ParamSpec("horizon", DEFAULT_HORIZON, "frames predicted ahead (6 at 10 fps = 600 ms)", 1, MAX_HORIZON),
    ParamSpec("input_scale", DEFAULT_INPUT_SCALE,
              "model units per radian; -ln(a_T)/input_scale is the insertion distance in radians",
              0.0, 1000.0, lo_open=True),
    ParamSpec("readout_k", 1, "P-GWR read-out: blend the outputs of the k nearest neurons by inverse distance "
              "(1 = the paper's BMU)", 1, 16),
    ParamSpec("mode", "recursive", "multi-step prediction: 'recursive' (feed predictions back) or 'vector' "
              "(x_out spans t+1..t+h)", choices=MODES),
    ParamSpec("target", "absolute", "P-GWR output: 'absolute' future frames (the paper) or 'delta', their offset "
              "from the newest frame", choices=TARGETS),
    ParamSpec("normalise_distance", True, "divide each layer's distance by sqrt(frames in its input) (RMS per frame)"),
)}


#: The bound of each of the hierarchy's layers: a robot runs for hours, and an unbounded layer grows for
#: as long (the paper's, `HierarchyParams.paper()`, have none). Above every size the experiments reach
#: (1,634 / 2,144 / 1,083 neurons after the demonstrator's five training epochs).
HIERARCHY_MAX_NEURONS = 5000


def _default_gwr(max_edge_age: int, bounded: bool = True) -> GWRParams:
    return GWRParams(max_edge_age=max_edge_age, max_neurons=HIERARCHY_MAX_NEURONS if bounded else None)


@dataclass(frozen=True)
class HierarchyParams:
    """The whole model: layer sizes of the windows, horizon, prediction mode, scaling, layers."""

    SPECS: ClassVar[dict[str, ParamSpec]] = HIERARCHY_SPECS
    n_joints: int = 8
    tau1: int = 3
    tau2: int = 3
    horizon: int = DEFAULT_HORIZON
    mode: str = "recursive"
    input_scale: float = DEFAULT_INPUT_SCALE
    normalise_distance: bool = True
    readout_k: int = 1
    target: str = "absolute"
    gwr1: GWRParams = field(default_factory=lambda: _default_gwr(100))
    gwr2: GWRParams = field(default_factory=lambda: _default_gwr(200))
    pgwr: GWRParams = field(default_factory=lambda: _default_gwr(300))

    def __post_init__(self) -> None:
        owner = type(self).__name__
        check_fields(self, HIERARCHY_SPECS.values())
        for layer in LAYERS:
            if not isinstance(getattr(self, layer), GWRParams):
                raise ParameterError(f"{owner}.{layer} must be a GWRParams, got {type(getattr(self, layer)).__name__}")

    # --- derived sizes -----------------------------------------------------------------------
    @property
    def gwr2_dim(self) -> int:
        return self.n_joints * self.tau1

    @property
    def regressor_dim(self) -> int:
        """P-GWR input size: tau2 GWR2 weights of tau1 frames each (72 with the defaults)."""
        return self.n_joints * self.tau1 * self.tau2

    @property
    def output_dim(self) -> int:
        """P-GWR output size: one frame (recursive) or `horizon` frames (vector)."""
        return self.n_joints * (self.horizon if self.mode == "vector" else 1)

    @property
    def span(self) -> int:
        """Frames one regressor covers: tau1 + tau2 - 1 (5 with the defaults)."""
        return self.tau1 + self.tau2 - 1

    def replace(self, **changes: Any) -> HierarchyParams:
        """A validated copy with some fields changed (layers as GWRParams)."""
        return dataclasses.replace(self, **changes)

    @classmethod
    def paper(cls, **changes: Any) -> HierarchyParams:
        """The paper's learner exactly (Sec. III, Table I): recursive roll-out, the BMU's output
        weights are the predicted frame itself, plus this package's input scaling (see
        docs/learning.md). `changes` override fields, as in `replace`."""
        base = cls(mode="recursive", readout_k=1, target="absolute", input_scale=DEFAULT_INPUT_SCALE,
                   normalise_distance=True, gwr1=_default_gwr(100, bounded=False),
                   gwr2=_default_gwr(200, bounded=False), pgwr=_default_gwr(300, bounded=False))
        return base.replace(**changes) if changes else base

    # --- flat form ---------------------------------------------------------------------------
    def to_flat(self) -> dict[str, Any]:
        """Dotted flat dict (`gwr_predictor.parameters.tree`); `max_neurons=None` is written as 0."""
        return tree.flatten(self)

    @classmethod
    def from_flat(cls, flat: Mapping[str, object]) -> HierarchyParams:
        """Inverse of `to_flat`; missing keys keep their defaults. Unknown keys or bad values raise
        ParameterError naming the key."""
        return tree.replace(cls(), flat)


def hierarchy_parameter_specs() -> list[ParamSpec]:
    """Every flat parameter of `HierarchyParams` (dotted names for the layers) with default, range and
    description: the specs the dataclasses validate with, with each layer's own defaults."""
    return list(tree.parameter_specs(HierarchyParams()))
