"""Trust the experts where the movement is recognised: the paper's premise, that a network which has
seen a movement anticipates it when it comes again, used to decide how far to trust them.

Each expert's gate trusts it by its record, and a record needs scored frames: on the second
performance of a movement the gates are still shut by the first, when every expert was new to it and
wrong, although the experts have learned it since. The snippet memory knows, frame by frame, whether
it has seen the present motion before (`TrajectoryMemory.familiarity`). `RecognitionSwitch` returns
the experts' weighted prediction without their gates where the memory's nearest stored key lies within
`radius` x the motion scale, and with them elsewhere: a new movement, a jump, motion that does not
repeat.

Both weightings run on every frame, each scoring its own predictions (no peeking), so each has a
record when it is chosen: `ungated` weighs the members' own predictions (`View`s of them), `experts` the
gated ones. The ungated weighting's record is kept on the movements the memory recognises: a
prediction made outside one (a new movement, where every member is new to it, or a pause) counts
`outside_weight` as much, so the record says how each member anticipates what it knows, and can be
long (`decay`), while a person met a minute ago still gets a weighting from the first performance;
on that record the ungated weighting hears its members more evenly than the gated one (`power` 3
against the experts' 4; chosen on the tuning set, research/tuning.md; `outside_weight` 1 weighs every
prediction alike, `power` 0 weighs the members as the gated weighting does).

Each weighting has its own last gate, which judges it on the frames it is returned on: the gated one
where the motion is new, the ungated one where it is recognised. One gate over both judged each by the
other's record: on the second performance of a movement, the ungated weighting was held back by the
first performance's record of the gated one, which had mostly held the pose (`separate_gates` false:
that single gate).

A k-step prediction is scored k frames after it is made, so at the onset of a recognised movement the
ungated weighting's gate judges step k by what came before: often a pause in the start pose, where
the weighting predicted the movement to begin and it did not. With `onset_trust`, outside a
recognised movement (the pose has travelled `onset_travel` x the motion scale over the memory's
longest lag) and over its first k frames, step k is trusted at least `onset_trust` x step 1, whose
scores arrive a frame after they are made; from then on each step by its own record (chosen on the
tuning set, research/tuning.md; 0 lends nothing).
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from gwr_predictor.default_predictor.errors import DefaultPredictorError
from gwr_predictor.default_predictor.experts import Experts, ExpertsPair
from gwr_predictor.default_predictor.gate import GatedPredictor, GateParams
from gwr_predictor.default_predictor.spread import Spread, SpreadParams
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.persistence import Checkpointed, Persist, params_from_json
from gwr_predictor.parameters.spec import ParamSpec, check_fields
from gwr_predictor.predictors.baselines import observation

#: The member whose memory judges recognition.
MEMORY = "memory"

RECOGNITION_SPECS = {spec.name: spec for spec in (
    ParamSpec("radius", 3.0, "the motion is recognised when the memory's nearest stored key is within this x the "
              "motion scale per coordinate (0: never; the gated experts always)", 0.0, 1e3),
    ParamSpec("decay", 0.995, "forgetting of the ungated weighting's running squared errors per scored frame", 0.0,
              1.0, lo_open=True, hi_open=True),
    ParamSpec("power", 3.0, "the ungated weighting's weights go as 1 / MSE^power (0: the experts' power)", 0.0,
              64.0),
    ParamSpec("outside_weight", 0.1, "weight in the ungated weighting's record of a prediction made outside a "
              "recognised movement (1: every prediction alike)", 0.0, 1.0),
    ParamSpec("onset_trust", 0.75, "outside a recognised movement and over its first k frames, the ungated "
              "weighting's step k is trusted at least this x its step 1 (0: each step by its own record)", 0.0, 1.0),
    ParamSpec("onset_travel", 1.0, "a recognised frame belongs to a movement when the pose has travelled at least "
              "this x the motion scale over the memory's longest lag", 0.0, 1e3),
    ParamSpec("separate_gates", True, "each weighting behind its own last gate, judged on the frames it is returned "
              "on (false: one last gate over whichever is returned)"),
)}


@dataclass(frozen=True)
class RecognitionParams:
    """Settings of `RecognitionSwitch` (see `RECOGNITION_SPECS`)."""

    SPECS: ClassVar[dict[str, ParamSpec]] = RECOGNITION_SPECS
    radius: float = RECOGNITION_SPECS["radius"].default
    decay: float = RECOGNITION_SPECS["decay"].default
    power: float = RECOGNITION_SPECS["power"].default
    outside_weight: float = RECOGNITION_SPECS["outside_weight"].default
    onset_trust: float = RECOGNITION_SPECS["onset_trust"].default
    onset_travel: float = RECOGNITION_SPECS["onset_travel"].default
    separate_gates: bool = RECOGNITION_SPECS["separate_gates"].default

    def __post_init__(self) -> None:
        check_fields(self, RECOGNITION_SPECS.values(), DefaultPredictorError)
        if self.onset_trust and not self.separate_gates:
            raise DefaultPredictorError(f"recognition.onset_trust {self.onset_trust} lends to the ungated weighting's "
                                        "own last gate: with separate_gates false, set onset_trust 0")

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
    """The gated `experts`, or the same members ungated where the memory recognises the motion, each
    weighting behind its last gate (`gate`)."""

    kind: ClassVar[str] = "RecognitionSwitch"
    PARAMS = RecognitionParams
    PERSIST = Persist(values=("recognised",), members={"experts": "experts", "ungated": "ungated", "gate": "gate",
                                                       "ungated_gate": "ungated_gate", "spread": "spread"})

    def __init__(self, experts: Experts, params: RecognitionParams | None = None,
                 gate: GateParams | None = None, spread: SpreadParams | None = None) -> None:
        for name, member in experts.members.items():
            if not isinstance(member, GatedPredictor):
                raise DefaultPredictorError(f"member {name!r} of the experts is not gated")
        if not hasattr(getattr(experts.members.get(MEMORY), "model", None), "familiarity"):
            raise DefaultPredictorError(f"the experts have no {MEMORY!r} member to recognise motion by")
        self.experts = experts
        self.params = p = params or RecognitionParams()
        self.ungated = Experts({n: View(m.ungated) for n, m in experts.members.items()},
                               experts.params.replace(decay=p.decay, power=p.power or experts.params.power))
        #: both weightings stepped as one, where they are alike (None: each steps itself)
        self._pair = ExpertsPair(experts, self.ungated) if ExpertsPair.takes(experts, self.ungated) else None
        self.recognised = 0  # frames on which the ungated prediction was returned
        self.onset = 0  # frames of the present recognised movement (with `onset_trust`)
        self._outputs: tuple[np.ndarray | None, np.ndarray | None] = (None, None)  # this step's weightings
        self._recognises = False  # whether this step returns the ungated weighting
        gate = gate or GateParams(horizon=experts.params.horizon, joints=experts.params.n_joints)
        # the last gates view this step's weightings through bound methods, which deep copies follow
        if p.separate_gates:
            self.gate = GatedPredictor(View(self._gated_output), gate)
            self.ungated_gate: GatedPredictor | None = GatedPredictor(View(self._ungated_output), gate)
        else:
            self.gate = GatedPredictor(View(self._returned_output), gate)
            self.ungated_gate = None
        # per onset up to the horizon, the share of step 1's trust each step borrows (from then on: none)
        steps = np.arange(1, gate.horizon + 1)
        self._borrows = [(onset <= steps) * p.onset_trust for onset in range(gate.horizon + 1)]
        #: the interval of every prediction, beside it (its groups: the motion new, the motion recognised)
        self.spread = Spread(spread or SpreadParams(horizon=gate.horizon, joints=gate.joints))

    def __deepcopy__(self, memo: dict[int, Any]) -> RecognitionSwitch:
        """A copy whose pair of weightings is rebuilt over the copied ones (a deep copy of a view is no view)."""
        new = copy.copy(self)
        memo[id(self)] = new
        new.__dict__.update({k: copy.deepcopy(v, memo) for k, v in self.__dict__.items() if k != "_pair"})
        new._pair = None if self._pair is None else ExpertsPair(new.experts, new.ungated)
        return new

    def _gated_output(self) -> np.ndarray | None:
        return None if self._recognises else self._outputs[0]

    def _ungated_output(self) -> np.ndarray | None:
        return self._outputs[1] if self._recognises else None

    def _returned_output(self) -> np.ndarray | None:
        return self._outputs[1] if self._recognises else self._outputs[0]

    def reset_sequence(self) -> None:
        self.experts.reset_sequence()
        self.ungated.reset_sequence()
        self.onset = 0
        for gate in self.gates:
            gate.reset_sequence()
        self.spread.reset_sequence()

    @property
    def gates(self) -> tuple[GatedPredictor, ...]:
        """The last gates: the gated weighting's (or the only one), then the ungated weighting's."""
        return (self.gate,) if self.ungated_gate is None else (self.gate, self.ungated_gate)

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        obs = observation(x, self.experts.params.n_joints)  # checked once for every part
        if self._pair is not None:
            gated, ungated = self._pair.advance(obs, learn)
        else:
            gated = self.experts.advance(obs, learn)
            ungated = self.ungated.advance(obs, learn, self.experts.ungated())  # its views, in one call if it can
        self._outputs = (gated, ungated)
        self._recognises = gated is not None and ungated is not None and self.recognises()
        self.recognised += self._recognises
        p = self.params
        moving = self._recognises and self._travelled()
        if p.outside_weight < 1.0:
            self.ungated.weigh_last(1.0 if moving else p.outside_weight)
        if p.onset_trust and self.ungated_gate is not None:
            self._borrow(self.ungated_gate, moving)
        gates = self.gates
        for gate in gates:  # every gate scores what it is owed
            gate.advance(obs, learn)
        out = (gates[-1] if self._recognises else gates[0]).predict()  # only the returned gate's prediction
        self.spread.advance(obs, out, min(int(self._recognises), self.spread.params.groups - 1))
        return out

    @property
    def interval_nominal(self) -> float:
        """The share of true angles the interval of every prediction should hold."""
        return self.spread.nominal

    def interval(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(lower, upper) bounds, each (horizon, joints) rad, of the central interval of the last prediction."""
        return self.spread.interval()

    def _travelled(self) -> bool:
        """Whether the pose has moved `onset_travel` x the motion scale over the memory's longest lag."""
        travel = self.experts.members[MEMORY].model.travel
        return travel is not None and travel >= self.params.onset_travel

    def _borrow(self, gate: GatedPredictor, moving: bool) -> None:
        """Count the frames of the present recognised movement (`moving`: this frame is one); the steps
        none of whose predictions made in it has been scored yet (every step, outside a movement) borrow
        step 1's trust."""
        self.onset = self.onset + 1 if moving else 0
        gate.borrow = self._borrows[self.onset] if self.onset < len(self._borrows) else None

    def recognises(self) -> bool:
        """Whether the memory knew the motion at the last step."""
        familiarity = self.experts.members[MEMORY].model.familiarity
        return familiarity is not None and familiarity <= self.params.radius

    # --- introspection: the gated experts speak for the learner -------------------------------------
    @property
    def horizon(self) -> int:
        """Frames predicted."""
        return self.experts.params.horizon

    @property
    def frames_seen(self) -> int:
        return self.experts.frames_seen

    def reset_errors(self) -> None:
        self.experts.reset_errors()

    @property
    def neuron_counts(self) -> tuple[int, ...] | None:
        return self.experts.neuron_counts

    def errors(self) -> dict[str, Any]:
        """The experts' errors and weights, on how many frames the motion was recognised, and each last
        gate's mean shrinkage per step."""
        out = {**self.experts.errors(), "recognised_frames": self.recognised,
               "gate_alpha_mean": self.gate.alpha().mean(axis=1).tolist(), **self.spread.errors()}
        if self.ungated_gate is not None:
            out["ungated_gate_alpha_mean"] = self.ungated_gate.alpha().mean(axis=1).tolist()
        return out

    # --- persistence ----------------------------------------------------------------------------------
    def _save_extra(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        return {"onset": self.onset}, {}

    def _load_extra(self, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> None:
        self.onset = int(header["onset"])

    @classmethod
    def _fresh(cls, header: Mapping[str, Any]) -> RecognitionSwitch:
        experts, gate = header.get("experts"), header.get("gate")
        if not isinstance(experts, dict) or not isinstance(gate, dict):
            raise LearningError("a recognition switch's checkpoint must hold its experts and its last gate")
        # the views are linked to these gates and weightings, which restore their state in place
        return cls(Experts._fresh(experts), params_from_json(RecognitionParams, header["params"]),
                   params_from_json(GateParams, gate["params"]),
                   params_from_json(SpreadParams, header["spread"]["params"]))
