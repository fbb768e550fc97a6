"""Trust the experts where the movement is recognised: the paper's premise, that a network which has
seen a movement anticipates it when it comes again, used to decide how far to trust them.

Each expert's gate trusts it by its record, and a record needs scored frames: on the second
performance of a movement the gates are still shut by the first, when every expert was new to it and
wrong, although the experts have learned it since. The snippet memory knows, frame by frame, whether
it has seen the present motion before (`TrajectoryMemory.familiarity`). `RecognitionSwitch` returns
the experts' weighted prediction without their gates where the memory's nearest stored key lies within
`radius` x the motion scale, and with them elsewhere: a new movement, a jump, motion that does not
repeat. The default's last gate still guards whichever is chosen.

Both weightings run on every frame, each scoring its own predictions (no peeking), so each has a
record when it is chosen: `ungated` weighs the members' own predictions (`View`s of them), `experts` the
gated ones. The ungated weighting forgets faster (`decay`): its record starts with the members' errors
on movements that were new to them, which say little about them once the movement has been seen.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from gwr_predictor.default_predictor.experts import Experts
from gwr_predictor.default_predictor.gate import GatedPredictor
from gwr_predictor.default_predictor.params import DefaultPredictorError
from gwr_predictor.learning.checkpoint import CheckpointError
from gwr_predictor.learning.persistence import Checkpointed, Persist, params_from_json
from gwr_predictor.parameter_spec import ParamSpec, check_fields

#: The member whose memory judges recognition.
MEMORY = "memory"

RECOGNITION_SPECS = {spec.name: spec for spec in (
    ParamSpec("radius", 3.0, "the motion is recognised when the memory's nearest stored key is within this x the "
              "motion scale per coordinate (0: never; the gated experts always)", 0.0, 1e3),
    ParamSpec("decay", 0.98, "forgetting of the ungated weighting's running squared errors per scored frame", 0.0, 1.0,
              lo_open=True, hi_open=True),
)}


@dataclass(frozen=True)
class RecognitionParams:
    """Settings of `RecognitionSwitch` (see `RECOGNITION_SPECS`)."""

    radius: float = RECOGNITION_SPECS["radius"].default
    decay: float = RECOGNITION_SPECS["decay"].default

    def __post_init__(self) -> None:
        check_fields(self, RECOGNITION_SPECS.values(), DefaultPredictorError)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class NoParams:
    """`View` has no settings."""

    def to_dict(self) -> dict[str, Any]:
        return {}


class View(Checkpointed):
    """A prediction computed elsewhere this step (a gated member's own, before its gate): a model with no
    state of its own, stepped and reset by its owner."""

    kind: ClassVar[str] = "View"
    PARAMS = NoParams
    PERSIST = Persist()

    def __init__(self, source: Callable[[], np.ndarray | None] | None, params: NoParams | None = None) -> None:
        self.source = source
        self.params = params or NoParams()

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        return None if self.source is None else self.source()

    def reset_sequence(self) -> None:
        """Nothing: its owner resets what it views."""

    @classmethod
    def _fresh(cls, header: Mapping[str, Any]) -> View:
        return cls(None)  # a `RecognitionSwitch` builds its views linked; this one is restored into them


class RecognitionSwitch(Checkpointed):
    """The gated `experts`, or the same members ungated where the memory recognises the motion."""

    kind: ClassVar[str] = "RecognitionSwitch"
    PARAMS = RecognitionParams
    PERSIST = Persist(values=("recognised",), members={"experts": "experts", "ungated": "ungated"})

    def __init__(self, experts: Experts, params: RecognitionParams | None = None) -> None:
        for name, member in experts.members.items():
            if not isinstance(member, GatedPredictor):
                raise DefaultPredictorError(f"member {name!r} of the experts is not gated")
        if not hasattr(getattr(experts.members.get(MEMORY), "model", None), "familiarity"):
            raise DefaultPredictorError(f"the experts have no {MEMORY!r} member to recognise motion by")
        self.experts = experts
        self.params = params or RecognitionParams()
        self.ungated = Experts({n: View(m.ungated) for n, m in experts.members.items()},
                               dataclasses.replace(experts.params, decay=self.params.decay))
        self.recognised = 0  # frames on which the ungated prediction was returned

    def reset_sequence(self) -> None:
        self.experts.reset_sequence()
        self.ungated.reset_sequence()

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        gated = self.experts.step(x, learn)
        ungated = self.ungated.step(x, learn)
        if gated is None or ungated is None or not self.recognises():
            return gated
        self.recognised += 1
        return ungated

    def recognises(self) -> bool:
        """Whether the memory knew the motion at the last step."""
        familiarity = self.experts.members[MEMORY].model.familiarity
        return familiarity is not None and familiarity <= self.params.radius

    # --- introspection: the gated experts speak for the learner -------------------------------------
    @property
    def frames_seen(self) -> int:
        return self.experts.frames_seen

    def reset_errors(self) -> None:
        self.experts.reset_errors()

    @property
    def neuron_counts(self) -> tuple[int, ...] | None:
        return self.experts.neuron_counts

    def errors(self) -> dict[str, Any]:
        """The experts' errors and weights, and on how many frames the motion was recognised."""
        return {**self.experts.errors(), "recognised_frames": self.recognised}

    # --- persistence ----------------------------------------------------------------------------------
    @classmethod
    def _fresh(cls, header: Mapping[str, Any]) -> RecognitionSwitch:
        experts = header.get("experts")
        if not isinstance(experts, dict):
            raise CheckpointError("a recognition switch's checkpoint must hold its experts")
        # the views are linked to these gates, which restore their state in place
        return cls(Experts._fresh(experts), params_from_json(RecognitionParams, header["params"]))
