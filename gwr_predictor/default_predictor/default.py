"""The default predictor (`gwr_experts`), read top-down: its settings tree, then the composition it builds.

Five experts, each behind its own confidence gate, weighted per horizon step by their recent errors:
the local-linear P-GWR, two snippet memories, and the `rls_ar` and `linear` models. Where the memory
recognises the motion, the same experts are weighted without their gates; a last gate guards each
weighting. `DefaultParams` holds every setting once, with the values chosen on the tuning set
(research/tuning.md names it): the ROS parameters, the YAML and the docs tables are made from it
(`gwr_predictor.parameters.tree`), and a checkpoint stores it beside the state.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar

import numpy as np

from gwr_predictor.default_predictor.errors import DefaultPredictorError
from gwr_predictor.default_predictor.experts import Experts, ExpertsParams
from gwr_predictor.default_predictor.gate import GatedPredictor, GateParams
from gwr_predictor.default_predictor.memory import MemoryParams, TrajectoryMemory
from gwr_predictor.default_predictor.params import LOCAL_LINEAR_SPECS, LocalLinearParams
from gwr_predictor.default_predictor.predictor import LocalLinearPredictor
from gwr_predictor.default_predictor.recognition import RecognitionParams, RecognitionSwitch
from gwr_predictor.default_predictor.spread import SpreadParams
from gwr_predictor.learning.checkpoint import read_checkpoint
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.parameters import tree
from gwr_predictor.parameters.spec import ParamSpec, check_fields
from gwr_predictor.predictors.baselines import RLSAutoregressive, RLSParams
from gwr_predictor.predictors.direct_linear import DirectLinear, DirectLinearParams

#: The data's shape, at the top of each tree: every member takes it from there.
SHAPE_SPECS = {"horizon": LOCAL_LINEAR_SPECS["horizon"], "n_joints": LOCAL_LINEAR_SPECS["n_joints"]}
_P = TypeVar("_P", bound="CompositionParams")
_LONG_MEMORY_ENABLED = ParamSpec("enabled", True, "among the experts (false: the other four without it)")


@dataclass(frozen=True)
class LongMemoryParams(MemoryParams):
    """The second snippet memory: its key holds the pose's changes over up to 16 frames (1.6 s at 10 fps,
    against the first's 0.8 s), weighs them less against the pose and fits its neighbours only nearer the
    motion it knows. Two memories that recognise a movement by different spans of its past are right on
    different frames, and the weighting hears whichever is right now (lower pooled error on the tuning
    set's repetition streams and a better cold start). `enabled` false leaves it out."""

    SPECS: ClassVar[dict[str, ParamSpec]] = {**MemoryParams.SPECS, "enabled": _LONG_MEMORY_ENABLED}
    longest_lag: int = 16
    velocity_weight: float = 0.15
    fit_radius: float = 2.0
    enabled: bool = True

    def __post_init__(self) -> None:
        super().__post_init__()
        check_fields(self, (_LONG_MEMORY_ENABLED,), DefaultPredictorError)

    def memory(self) -> MemoryParams:
        """The memory's own settings (without `enabled`)."""
        return MemoryParams(**{f.name: getattr(self, f.name) for f in dataclasses.fields(MemoryParams)})


def _about(words: str) -> dict[str, str]:
    """A member field's metadata: the words its parameters' descriptions start with."""
    return {"about": words}


@dataclass(frozen=True)
class CompositionParams:
    """A composition's settings tree: the data's shape at the top, which every member takes from there,
    and the members' settings below (in a subclass), by the tree's one naming rule."""

    SPECS: ClassVar[dict[str, ParamSpec]] = SHAPE_SPECS
    horizon: int = SHAPE_SPECS["horizon"].default
    n_joints: int = SHAPE_SPECS["n_joints"].default

    def __post_init__(self) -> None:
        check_fields(self, SHAPE_SPECS.values(), DefaultPredictorError)
        shape = {"horizon": self.horizon, "n_joints": self.n_joints, "joints": self.n_joints}
        for f in dataclasses.fields(self):
            member = getattr(self, f.name)
            if dataclasses.is_dataclass(member) and not isinstance(member, type):
                names = {g.name for g in dataclasses.fields(member)}
                changes = {k: v for k, v in shape.items() if k in names and getattr(member, k) != v}
                if changes:  # a member never has a shape of its own
                    object.__setattr__(self, f.name, dataclasses.replace(member, **changes))

    @classmethod
    def from_flat(cls: type[_P], flat: Mapping[str, Any]) -> _P:
        return tree.replace(cls(), flat, DefaultPredictorError)

    def to_flat(self) -> dict[str, Any]:
        return tree.flatten(self)


@dataclass(frozen=True)
class DefaultParams(CompositionParams):
    """Every setting of the default; flat, dotted names (`network.gwr.eps_b`) by `gwr_predictor.parameters.tree`.

    Where a member's values differ from its class's defaults, they were chosen for the default on its own
    tuning set: the network learns at half the rate, recruits on more surprise and regresses on 6 frames
    (equal where motion repeats, 14 % lower error on the demonstrator check, a better cold start). Each
    expert's gate opens on little evidence with a memory of ~20 scored frames at first, so an expert that
    has just become good is heard within a performance, lengthening to ~200 over the first 400, so a
    settled expert is not shrunk by chance runs of error. The last gates open on less evidence (a bound of
    half a standard error) with a memory of ~33 scored frames and judge each step by its own record: they
    keep the default within 1 % of holding the pose where the experts alone were up to 4 % above it."""

    network: LocalLinearParams = field(
        default_factory=lambda: LocalLinearParams(order=6, rate=0.1, recruit_surprise=9.0),
        metadata=_about("network"))
    memory: MemoryParams = field(default_factory=MemoryParams, metadata=_about("snippet memory"))
    long_memory: LongMemoryParams = field(default_factory=LongMemoryParams, metadata=_about("long snippet memory"))
    linear: DirectLinearParams = field(default_factory=DirectLinearParams, metadata=_about("linear model"))
    rls_ar: RLSParams = field(default_factory=RLSParams, metadata=_about("RLS-AR"))
    experts: ExpertsParams = field(default_factory=ExpertsParams, metadata=_about("weighting"))
    recognition: RecognitionParams = field(default_factory=RecognitionParams, metadata=_about("recognition"))
    expert_gate: GateParams = field(
        default_factory=lambda: GateParams(decay=0.995, warmup=400, warmup_decay=0.95, prior=0.001, confidence=1.0),
        metadata=_about("each expert's gate"))
    gate: GateParams = field(default_factory=lambda: GateParams(decay=0.97, fast_step=0, prior=0.001, confidence=0.5),
                             metadata=_about("the last gates"))
    spread: SpreadParams = field(default_factory=SpreadParams, metadata=_about("the interval of every prediction"))


@dataclass(frozen=True)
class GatedNetworkParams(CompositionParams):
    """The local-linear P-GWR with its global read-out behind one gate (`gated_llm_gwr`), as the
    `experiment tune` chose them for the network alone."""

    network: LocalLinearParams = field(default_factory=LocalLinearParams, metadata=_about("network"))
    gate: GateParams = field(default_factory=GateParams, metadata=_about("gate"))


class DefaultPredictor(RecognitionSwitch):
    """The default, built from `DefaultParams`: the five experts (four with `long_memory.enabled` false),
    each behind its gate, weighted per step, or ungated where the motion is recognised, each weighting
    behind its last gate. A checkpoint holds the settings tree and the state: loading builds the tree's
    composition, then restores what it learned."""

    kind = "DefaultPredictor"

    def __init__(self, params: DefaultParams | None = None, seed: int = 0) -> None:
        p = params or DefaultParams()
        experts: dict[str, Any] = {
            "network": LocalLinearPredictor(p.network, seed=seed),
            "linear": DirectLinear(p.linear),
            "rls_ar": RLSAutoregressive(p.rls_ar, p.horizon, p.n_joints),
            "memory": TrajectoryMemory(p.memory)}
        if p.long_memory.enabled:
            experts["long_memory"] = TrajectoryMemory(p.long_memory.memory())
        gated = {name: GatedPredictor(model, p.expert_gate, hold_when_silent=False) for name, model in experts.items()}
        super().__init__(Experts(gated, p.experts), p.recognition, p.gate, p.spread)
        self.settings = p

    def _capture(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        header, arrays = super()._capture()
        header["settings"] = self.settings.to_flat()
        return header, arrays

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> DefaultPredictor:
        """The default saved at `path`. One saved before its checkpoint held the settings tree (kind
        'RecognitionSwitch') is refused as unreadable, not as another predictor's, so that the node sets
        it aside and starts afresh instead of asking for another `predictor`."""
        header, arrays = read_checkpoint(path, (cls.kind, RecognitionSwitch.kind))
        if header["kind"] != cls.kind:
            raise LearningError(f"{path}: a default saved by an earlier build, without its settings tree; this build "
                                "does not read it (pretrain again, or let the node learn anew)", source=path)
        return cls.from_state(header, arrays, path)

    @classmethod
    def _fresh(cls, header: Mapping[str, Any]) -> DefaultPredictor:
        saved = header.get("settings")
        if not isinstance(saved, dict):
            raise LearningError("the default's checkpoint must hold its settings")
        missing = sorted(set(DefaultParams().to_flat()) - set(saved))
        if missing:
            raise LearningError(f"the default's checkpoint lacks the settings {missing}")
        return cls(DefaultParams.from_flat(saved))


def make_default(horizon: int = 6, joints: int = 8, seed: int = 0,
                 settings: Mapping[str, Any] | None = None) -> DefaultPredictor:
    """The default predictor, fresh. `settings`: flat, dotted parameters of `DefaultParams` (e.g.
    `network.order`, `memory.k`, `expert_gate.decay`); the others keep their defaults."""
    return DefaultPredictor(DefaultParams.from_flat({"horizon": horizon, "n_joints": joints, **(settings or {})}), seed)


def make_gated_network(horizon: int = 6, joints: int = 8, seed: int = 0,
                       settings: Mapping[str, Any] | None = None) -> GatedPredictor:
    """The local-linear P-GWR with its global read-out behind one gate (`gated_llm_gwr`). `settings`: flat,
    dotted parameters of `GatedNetworkParams` (e.g. `network.order`, `network.gwr.eps_b`, `gate.decay`)."""
    p = GatedNetworkParams.from_flat({"horizon": horizon, "n_joints": joints, **(settings or {})})
    return GatedPredictor(LocalLinearPredictor(p.network, seed=seed), p.gate)
