"""Hyper-parameters of the GWR layers and of the hierarchy, as frozen validated dataclasses.

Parameters are set once and never mutated by learning (learned state lives in the networks).
`HierarchyParams.to_flat()` / `from_flat()` give the dotted flat form ROS parameters and
checkpoint headers use ("gwr1.activation_threshold", "horizon", ...); `hierarchy_parameter_specs()`
lists every flat key with its default, range and description for `declare_parameter`.
Values follow Table I of the paper unless stated.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, NamedTuple

#: Edge ages are stored as int16, so the age limit stays well inside its range.
MAX_EDGE_AGE_LIMIT = 30000
MODES = ("recursive", "vector")
#: What the P-GWR's output weights learn: the future frames themselves (the paper) or their
#: displacement from the newest observed frame, added back to that frame when predicting.
TARGETS = ("absolute", "delta")
LAYERS = ("gwr1", "gwr2", "pgwr")

#: Default radians -> model-units factor (see docs/learning.md, "Input scaling").
DEFAULT_INPUT_SCALE = 0.1


class ParamSpec(NamedTuple):
    """One flat parameter: what `declare_parameter` needs plus the allowed range."""

    name: str
    default: float | int | str | bool
    description: str
    minimum: float | None = None
    maximum: float | None = None
    choices: tuple[str, ...] | None = None


class _Range(NamedTuple):
    kind: type
    low: float | None
    high: float | None
    low_open: bool = False
    high_open: bool = False

    def text(self) -> str:
        lo = "-inf" if self.low is None else f"{self.low:g}"
        hi = "inf" if self.high is None else f"{self.high:g}"
        return f"{'(' if self.low_open else '['}{lo}, {hi}{')' if self.high_open else ']'}"

    def contains(self, v: float) -> bool:
        if self.low is not None and (v < self.low or (self.low_open and v == self.low)):
            return False
        return not (self.high is not None and (v > self.high or (self.high_open and v == self.high)))


def _check(owner: str, name: str, value: Any, rng: _Range) -> None:
    """Type and range check of one field; the error names the field and the allowed range."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{owner}.{name} must be a number in {rng.text()}, got {value!r}")
    if rng.kind is int and not isinstance(value, int):
        raise ValueError(f"{owner}.{name} must be an integer in {rng.text()}, got {value!r}")
    if not math.isfinite(value) or not rng.contains(value):
        raise ValueError(f"{owner}.{name} must be in {rng.text()}, got {value!r}")


_GWR_RANGES: dict[str, _Range] = {
    "activation_threshold": _Range(float, 0.0, 1.0, True, True),
    "firing_threshold": _Range(float, 0.0, 1.0, True, False),
    "eps_b": _Range(float, 0.0, 1.0, True, False),
    "eps_n": _Range(float, 0.0, 1.0),
    "rho_b": _Range(float, 0.0, 1.0, True, False),
    "rho_n": _Range(float, 0.0, 1.0),
    "kappa": _Range(float, 1.0, 10.0),
    "max_edge_age": _Range(int, 1, MAX_EDGE_AGE_LIMIT),
    "max_neurons": _Range(int, 2, 10_000_000),
}

_GWR_DOC: dict[str, str] = {
    "activation_threshold": "a_T: insert a neuron when exp(-||x - w_b||) falls below it (Eq. 2)",
    "firing_threshold": "f_T: insert only when the BMU's firing counter is below it (enough training)",
    "eps_b": "learning rate of the best-matching unit (Eq. 4)",
    "eps_n": "learning rate of the BMU's topological neighbours (Eq. 4)",
    "rho_b": "firing-counter decay of the BMU (Eq. 3)",
    "rho_n": "firing-counter decay of the BMU's neighbours (Eq. 3)",
    "kappa": "firing-counter curve constant (Eq. 3); the counter tends to 1 - 1/kappa",
    "max_edge_age": "edges older than this are removed, then neurons left without edges",
    "max_neurons": "no insertion beyond this many neurons (0 = unlimited)",
}


@dataclass(frozen=True)
class GWRParams:
    """One GWR layer (Sec. III-B, Table I). `max_neurons=None` means no size limit."""

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
        for name, rng in _GWR_RANGES.items():
            value = getattr(self, name)
            if name == "max_neurons" and value is None:
                continue
            _check(owner, name, value, rng)
        # The counter converges to 1 - 1/kappa; above f_T no neuron would ever be inserted.
        floor = 1.0 - 1.0 / self.kappa
        if floor >= self.firing_threshold:
            raise ValueError(
                f"{owner}.kappa={self.kappa:g} makes the firing counter settle at {floor:.4f} >= "
                f"firing_threshold={self.firing_threshold:g}: no neuron could ever be inserted; "
                f"kappa must be < {1.0 / (1.0 - self.firing_threshold):.4f}")

    def replace(self, **changes: Any) -> GWRParams:
        """A validated copy with some fields changed."""
        return dataclasses.replace(self, **changes)


_HIER_RANGES: dict[str, _Range] = {
    "n_joints": _Range(int, 1, 256),
    "tau1": _Range(int, 1, 32),
    "tau2": _Range(int, 1, 32),
    "horizon": _Range(int, 1, 100),
    "input_scale": _Range(float, 0.0, 1000.0, True, False),
    "readout_k": _Range(int, 1, 16),
}

_HIER_DOC: dict[str, str] = {
    "n_joints": "angles per frame (8 Nao arm joints)",
    "tau1": "window of GWR1 BMUs concatenated into the GWR2 input (Eq. 5)",
    "tau2": "window of GWR2 BMUs concatenated into the P-GWR regressor (Eq. 5)",
    "horizon": "frames predicted ahead (6 at 10 fps = 600 ms)",
    "mode": "multi-step prediction: 'recursive' (feed predictions back) or 'vector' (x_out spans t+1..t+h)",
    "input_scale": "model units per radian; -ln(a_T)/input_scale is the insertion distance in radians",
    "normalise_distance": "divide each layer's distance by sqrt(frames in its input) (RMS per frame)",
    "readout_k": "P-GWR read-out: blend the outputs of the k nearest neurons by inverse distance (1 = the paper's BMU)",
    "target": "P-GWR output: 'absolute' future frames (the paper) or 'delta', their offset from the newest frame",
}


_HIER_CHOICES: dict[str, tuple[str, ...]] = {"mode": MODES, "target": TARGETS}


def _default_gwr(max_edge_age: int) -> GWRParams:
    return GWRParams(max_edge_age=max_edge_age)


@dataclass(frozen=True)
class HierarchyParams:
    """The whole model: layer sizes of the windows, horizon, prediction mode, scaling, layers."""

    n_joints: int = 8
    tau1: int = 3
    tau2: int = 3
    horizon: int = 6
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
        for name, rng in _HIER_RANGES.items():
            _check(owner, name, getattr(self, name), rng)
        if self.mode not in MODES:
            raise ValueError(f"{owner}.mode must be one of {MODES}, got {self.mode!r}")
        if self.target not in TARGETS:
            raise ValueError(f"{owner}.target must be one of {TARGETS}, got {self.target!r}")
        if not isinstance(self.normalise_distance, bool):
            raise ValueError(f"{owner}.normalise_distance must be true or false, got {self.normalise_distance!r}")
        for layer in LAYERS:
            if not isinstance(getattr(self, layer), GWRParams):
                raise ValueError(f"{owner}.{layer} must be a GWRParams, got {type(getattr(self, layer)).__name__}")

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
                   normalise_distance=True)
        return base.replace(**changes) if changes else base

    # --- flat form ---------------------------------------------------------------------------
    def to_flat(self) -> dict[str, float | int | str | bool]:
        """Dotted flat dict; `max_neurons=None` is written as 0 (ROS parameters have no None)."""
        flat: dict[str, float | int | str | bool] = {}
        for name in (*_HIER_RANGES, *_HIER_CHOICES, "normalise_distance"):
            flat[name] = getattr(self, name)
        for layer in LAYERS:
            gp = getattr(self, layer)
            for name in _GWR_RANGES:
                value = getattr(gp, name)
                flat[f"{layer}.{name}"] = 0 if value is None else value
        return flat

    @classmethod
    def from_flat(cls, flat: Mapping[str, object]) -> HierarchyParams:
        """Inverse of `to_flat`; missing keys keep their defaults. Unknown keys or bad values raise
        ValueError naming the key."""
        top: dict[str, Any] = {}
        layers: dict[str, dict[str, Any]] = {layer: {} for layer in LAYERS}
        defaults = cls()
        for key, value in flat.items():
            if not isinstance(key, str):
                raise ValueError(f"parameter names must be strings, got {key!r}")
            layer, _, name = key.partition(".")
            if name:
                if layer not in layers or name not in _GWR_RANGES:
                    raise ValueError(f"unknown parameter {key!r}")
                layers[layer][name] = _coerce(key, value, _GWR_RANGES[name].kind, name == "max_neurons")
            elif key in _HIER_RANGES:
                top[key] = _coerce(key, value, _HIER_RANGES[key].kind, False)
            elif key in _HIER_CHOICES:
                if not isinstance(value, str) or value not in _HIER_CHOICES[key]:
                    raise ValueError(f"parameter {key!r} must be one of {_HIER_CHOICES[key]}, got {value!r}")
                top[key] = value
            elif key == "normalise_distance":
                if not isinstance(value, bool):
                    raise ValueError(f"parameter 'normalise_distance' must be true or false, got {value!r}")
                top[key] = value
            else:
                raise ValueError(f"unknown parameter {key!r}")
        for layer, changes in layers.items():
            if changes:
                try:
                    top[layer] = getattr(defaults, layer).replace(**changes)
                except ValueError as exc:
                    raise ValueError(f"parameter {layer}.*: {exc}") from None
        return cls(**top)


def _coerce(key: str, value: object, kind: type, zero_is_none: bool) -> Any:
    """ROS and YAML hand over ints for floats and floats for ints; accept the lossless cases."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        if zero_is_none and value is None:
            return None
        raise ValueError(f"parameter {key!r} must be a number, got {value!r}")
    if kind is int:
        if isinstance(value, float):
            if not value.is_integer():
                raise ValueError(f"parameter {key!r} must be an integer, got {value!r}")
            value = int(value)
        if zero_is_none and value == 0:
            return None
        return value
    return float(value)


def hierarchy_parameter_specs() -> list[ParamSpec]:
    """Every flat parameter of `HierarchyParams` with default, description and range."""
    defaults = HierarchyParams().to_flat()
    specs: list[ParamSpec] = []
    for name, rng in _HIER_RANGES.items():
        specs.append(ParamSpec(name, defaults[name], _HIER_DOC[name], rng.low, rng.high))
    for name, choices in _HIER_CHOICES.items():
        specs.append(ParamSpec(name, defaults[name], _HIER_DOC[name], choices=choices))
    specs.append(ParamSpec("normalise_distance", defaults["normalise_distance"], _HIER_DOC["normalise_distance"]))
    for layer in LAYERS:
        for name, rng in _GWR_RANGES.items():
            low = 0 if name == "max_neurons" else rng.low
            specs.append(ParamSpec(f"{layer}.{name}", defaults[f"{layer}.{name}"], f"{layer}: {_GWR_DOC[name]}",
                                   low, rng.high))
    return specs
