"""Several online predictors side by side, weighted per horizon step by how well each did lately.

No one model is best everywhere. On a movement a person has just started to repeat, a global linear
model of the last frames extrapolates well after a few seconds; once the movement has come back a few
times, the growing networks that remember it (the local-linear P-GWR, the snippet memories) know where
it goes. `Experts` runs every member on every frame and returns, per horizon step k, the members'
predictions weighted by 1 / MSE_k^`power`, with MSE_k each member's running squared error at step k
(decayed by `decay` per scored frame). A large power puts nearly all the weight on the member that is
best at that step now, without a hard switch that flickers between near-equal members. A member not
scored yet at a step gets the scored members' mean MSE (all equal weights while none is scored).

An owner that knows some predictions say less about the members than others (`RecognitionSwitch`:
those made outside the movements it recognises) weighs them in the record with `weigh_last`.

Predictions are scored only against frames observed later (`PendingPredictions`: no peeking). A
member that predicts nothing at a frame (None: its window refilling after a gap or a new sequence) is
left out of that frame's weights and is not scored for it; where no member predicts, the newest pose
is held.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from gwr_predictor.default_predictor.errors import DefaultPredictorError
from gwr_predictor.default_predictor.gate import GateBank, inner_model
from gwr_predictor.default_predictor.memory import TrajectoryMemory
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.params import DEFAULT_HORIZON, MAX_HORIZON
from gwr_predictor.learning.pending import PendingPredictions, every, some
from gwr_predictor.learning.persistence import Checkpointed, Persist, fresh_of_kind, kind_to_save, params_from_json, sub
from gwr_predictor.parameters.spec import ParamSpec, check_fields
from gwr_predictor.predictors.baselines import observation

EXPERTS_SPECS = {spec.name: spec for spec in (
    ParamSpec("decay", 0.995, "forgetting of each member's running squared error per scored frame", 0.0, 1.0,
              lo_open=True, hi_open=True),
    ParamSpec("power", 4.0, "weights go as 1 / MSE^power (1: inverse MSE; large: nearly the best member)",
              0.0, 64.0, lo_open=True),
    ParamSpec("floor", 1e-6, "lower bound of the running MSE (rad^2) before it is inverted", 0.0, 1.0, lo_open=True),
    ParamSpec("horizon", DEFAULT_HORIZON, "steps predicted", 1, MAX_HORIZON),
    ParamSpec("n_joints", 8, "joints per frame", 1),
)}


@dataclass(frozen=True)
class ExpertsParams:
    """Settings of `Experts` (see `EXPERTS_SPECS`)."""

    SPECS: ClassVar[dict[str, ParamSpec]] = EXPERTS_SPECS
    decay: float = EXPERTS_SPECS["decay"].default
    power: float = EXPERTS_SPECS["power"].default
    floor: float = EXPERTS_SPECS["floor"].default
    horizon: int = EXPERTS_SPECS["horizon"].default
    n_joints: int = EXPERTS_SPECS["n_joints"].default

    def __post_init__(self) -> None:
        check_fields(self, EXPERTS_SPECS.values(), DefaultPredictorError)

    def replace(self, **changes: Any) -> ExpertsParams:
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


class Experts(Checkpointed):
    """Per-step weighted mean of `members`' predictions (see the module docstring)."""

    kind: ClassVar[str] = "Experts"
    PARAMS = ExpertsParams
    PERSIST = Persist(arrays=("sse", "weight", "scored", "_outputs"), values=("_t",), members={"_pending": ""},
                      nan_ok=("_outputs",))  # NaN: a member that predicted nothing

    def __init__(self, members: Mapping[str, Any], params: ExpertsParams | None = None) -> None:
        if not members:
            raise DefaultPredictorError("Experts needs at least one member")
        for name, m in members.items():
            if not (callable(getattr(m, "step", None)) and callable(getattr(m, "reset_sequence", None))):
                raise DefaultPredictorError(f"member {name!r} does not implement step/reset_sequence")
        self.members = dict(members)
        self.names = tuple(self.members)
        self.params = p = params or ExpertsParams()
        n = len(self.names)
        self.sse = np.zeros((n, p.horizon))  # decayed sums of squared errors (mean over joints)
        self.weight = np.zeros((n, p.horizon))  # decayed counts of scored predictions
        self.scored = np.zeros((n, p.horizon), dtype=np.int64)
        self._pending = PendingPredictions(p.horizon, p.n_joints, (n,))
        self._outputs = np.full((n, p.horizon, p.n_joints), np.nan)
        self._t = 0
        #: the weight in the record of the predictions made at each of the last `horizon` steps (by step
        #: % horizon; 1 unless an owner weighs them)
        self.record_weight = np.ones(p.horizon)
        # per t % horizon, where in `record_weight` the predictions scored at t were weighed (k steps before)
        self._made_at = [(t - np.arange(1, p.horizon + 1)) % p.horizon for t in range(p.horizon)]
        members_list = list(self.members.values())
        #: the members' gates stepped as one, where they are alike (None: each member steps itself)
        self._bank = GateBank(members_list) if GateBank.takes(members_list) else None

    def __deepcopy__(self, memo: dict[int, Any]) -> Experts:
        """A copy whose gate bank is rebuilt over the copied gates (a deep copy of a view is no view)."""
        new = copy.copy(self)
        memo[id(self)] = new
        new.__dict__.update({k: copy.deepcopy(v, memo) for k, v in self.__dict__.items() if k != "_bank"})
        new._bank = None if self._bank is None else GateBank(list(new.members.values()))
        return new

    def weigh_last(self, weight: float) -> None:
        """The weight of the last step's predictions in the running errors when they are scored (1: as
        every other; 0: scored, but adding nothing but forgetting)."""
        if not 0.0 <= weight <= 1.0:  # NaN too: it would poison every running error it reached
            raise DefaultPredictorError(f"a record weight must be in [0, 1], got {weight!r}")
        self.record_weight[(self._t - 1) % self.params.horizon] = weight

    def reset_sequence(self) -> None:
        """Sequence boundary: members reset, pending predictions dropped (the running errors stay)."""
        for m in self.members.values():
            m.reset_sequence()
        self._pending.drop()
        self._outputs.fill(np.nan)

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        return self.advance(observation(x, self.params.n_joints), learn)

    def advance(self, obs: np.ndarray | None, learn: bool = True,
                given: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray | None:
        """`step` on an observation already checked (`observation`). `given`: the members' predictions this
        step, (members, horizon, joints), and which members made one, computed by an owner for members that
        are views of them (not stepped then): the same weighting without a Python call per member."""
        due, valid = self._pending.take(self._t)
        if obs is not None:
            self._score(obs, due, valid)
        self._predict(obs, learn, given)
        return self._returned(obs, self._combine(self._outputs, self._file()))

    def _predict(self, obs: np.ndarray | None, learn: bool, given: tuple[np.ndarray, np.ndarray] | None) -> None:
        """The members' predictions this step into `_outputs` (NaN: a member that predicts nothing)."""
        if given is None and self._bank is not None:
            given = self._bank.step(obs, learn)
        if given is not None:
            predictions, predicting = given
            np.copyto(self._outputs, predictions)
            if not every(predicting):
                self._outputs[~predicting] = np.nan
        else:
            self._collect([m.step(obs, learn=learn) for m in self.members.values()])

    def _file(self) -> np.ndarray | bool:
        """File this step's predictions to be scored, and end the step: (members, horizon) which predict
        (True: all, the usual frame, told by one finite sum: it has no NaN or inf in it)."""
        avail = True if math.isfinite(self._outputs.sum()) else np.isfinite(self._outputs).all(axis=-1)
        self._pending.file(self._t, self._outputs, avail)
        self.record_weight[self._t % self.params.horizon] = 1.0  # until an owner weighs them
        self._t += 1
        return avail

    def _returned(self, obs: np.ndarray | None, out: np.ndarray | None) -> np.ndarray | None:
        """The weighted prediction, or where no member predicts yet (windows refilling) the newest pose."""
        if out is None and obs is not None:
            return np.repeat(obs[None, :], self.params.horizon, axis=0)
        return out

    def ungated(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Right after `step`: the members' own predictions before their gates, as `advance` takes them
        `given`, where the members were stepped as one bank of gates (else None)."""
        return None if self._bank is None else self._bank.ungated()

    def _score(self, obs: np.ndarray, due: np.ndarray, valid: np.ndarray) -> None:
        """Score the predictions `due` (members, horizon, joints) that target `obs` where `valid`."""
        self._add(((due - obs) ** 2).sum(axis=2) / self.params.n_joints, valid)

    def _add(self, err: np.ndarray, valid: np.ndarray) -> None:
        """The squared errors `err` (members, horizon; NaN: no prediction) of the `valid` predictions scored
        now into the running errors (`err` is overwritten)."""
        made = self.record_weight[self._made_at[self._t % self.params.horizon]]
        # the usual frame: every member scored at every step (the same sums, fewer calls; a finite sum of
        # squares has no NaN or inf in it)
        if every(valid) and math.isfinite(err.sum()):
            _forget_and_add(self.sse, self.weight, self.scored, err, made, self.params.decay)
            return
        scored = valid & np.isfinite(err)
        decay = np.where(scored, self.params.decay, 1.0)
        self.sse *= decay
        self.sse += np.where(scored, err * made, 0.0)
        self.weight *= decay
        self.weight += scored * made
        self.scored += scored

    def _collect(self, outputs: list[Any]) -> None:
        p, out = self.params, self._outputs
        out.fill(np.nan)
        for i, o in enumerate(outputs):
            if o is None:
                continue
            o = np.asarray(o, dtype=float)
            if o.ndim != 2 or o.shape[0] < p.horizon or o.shape[1] != p.n_joints:
                raise DefaultPredictorError(f"member {self.names[i]!r} returned shape {o.shape}; need at least "
                                            f"({p.horizon}, {p.n_joints})")
            out[i] = o[:p.horizon]

    def running_mse(self) -> np.ndarray:
        """(members, horizon) running MSE (rad^2, mean over joints); NaN where nothing was scored yet."""
        known = self.weight > 0
        return np.where(known, self.sse / np.where(known, self.weight, 1.0), np.nan)

    def weights(self, available: np.ndarray | None = None) -> np.ndarray:
        """(members, horizon) weights summing to 1 per step over the `available` members (default all)."""
        p = self.params
        if (available is None or every(available)) and every(self.weight):  # the usual frame, in fewer calls
            return _inverse_mse_weights(self.sse, self.weight, p.floor, p.power)
        avail = np.ones(self.sse.shape, dtype=bool) if available is None else available
        mse = np.where(avail, self.running_mse(), np.nan)
        known = np.isfinite(mse)
        n_known = known.sum(axis=0)
        mean = np.where(known, mse, 0.0).sum(axis=0) / np.maximum(n_known, 1)
        mse = np.where(known, mse, np.where(n_known > 0, mean, 1.0)[None, :])
        mse = np.maximum(mse, p.floor)
        best = np.where(avail, mse, np.inf).min(axis=0, keepdims=True)  # relative: no overflow at any power
        best[~np.isfinite(best)] = 1.0  # a step no member predicts gets no weight anyway
        inv = np.where(avail, (best / mse) ** p.power, 0.0)
        return inv / inv.sum(axis=0, keepdims=True)

    def _combine(self, preds: np.ndarray, avail: np.ndarray | bool) -> np.ndarray | None:
        """The weighted mean of `preds` (members, horizon, joints) over the `avail` (members, horizon)
        finite ones (True: all); None where no member predicts."""
        if not isinstance(avail, np.ndarray) or every(avail):  # True: every member predicts
            return np.einsum("mh,mhj->hj", self.weights(), preds)
        if not some(avail):
            return None
        w = self.weights(avail)
        return np.einsum("mh,mhj->hj", w, np.where(avail[:, :, None], preds, 0.0))

    # --- introspection: the first member that learns like the hierarchy speaks for the frames ---------
    @property
    def learner(self) -> Any:
        """The first member (behind its gate, if any) that counts frames and P.E./C.P.E.: the network."""
        for m in self.members.values():
            inner = getattr(m, "model", m)
            if hasattr(inner, "frames_seen"):
                return inner
        raise DefaultPredictorError(f"none of the members {', '.join(self.names)} counts frames")

    @property
    def frames_seen(self) -> int:
        return int(self.learner.frames_seen)

    def reset_errors(self) -> None:
        self.learner.reset_errors()

    @property
    def neuron_counts(self) -> tuple[int, ...] | None:
        counts = getattr(self.learner, "neuron_counts", None)
        return None if counts is None else tuple(counts)

    def errors(self) -> dict[str, Any]:
        """The learner's errors (counts, neurons, P.E./C.P.E.), per member its running MSE and its
        weight per step (`expert_mse`, `expert_weights`), and per snippet memory the snippets it holds and
        has replaced at capacity (`snippets`: a long session's memory filling up)."""
        mse, w = self.running_mse(), self.weights()
        out = {**self.learner.errors(), "expert_mse": {n: mse[i].tolist() for i, n in enumerate(self.names)},
               "expert_weights": {n: w[i].tolist() for i, n in enumerate(self.names)}}
        memories = {n: inner_model(m).errors() for n, m in self.members.items()
                    if isinstance(inner_model(m), TrajectoryMemory)}
        if memories:
            out["snippets"] = {n: {"stored": e["snippets"], "replaced": e["snippets_replaced"]}
                               for n, e in memories.items()}
        return out

    # --- persistence: the members by name and kind (the weighting's own state is declared above) -----
    def _load_record_weight(self, saved: Any) -> None:
        """The saved weights of the pending predictions."""
        try:
            weights = np.array(saved, dtype=float)
        except (TypeError, ValueError) as exc:
            raise LearningError(f"record_weight must be {self.params.horizon} numbers") from exc
        if weights.shape != self.record_weight.shape or not ((weights >= 0.0) & (weights <= 1.0)).all():
            raise LearningError(f"record_weight must be {self.params.horizon} numbers in [0, 1]")
        self.record_weight[...] = weights

    @classmethod
    def _fresh(cls, header: Mapping[str, Any]) -> Experts:
        kinds = header["member_kinds"]
        if not isinstance(kinds, dict) or not kinds:
            raise LearningError("member_kinds must name every member's kind")
        members = {name: fresh_of_kind(kind, header["members"][name]) for name, kind in kinds.items()}
        return cls(members, params_from_json(ExpertsParams, header["params"]))

    def _save_extra(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        header: dict[str, Any] = {"member_kinds": {}, "members": {}}
        arrays: dict[str, np.ndarray] = {}
        for name, member in self.members.items():
            header["member_kinds"][name] = kind_to_save(member, f"member {name!r}")
            header["members"][name], m_arrays = member._capture()
            arrays.update({f"member.{name}.{k}": v for k, v in m_arrays.items()})
        header["record_weight"] = self.record_weight.tolist()
        return header, arrays

    def _load_extra(self, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> None:
        self._load_record_weight(header["record_weight"])
        for name, member in self.members.items():
            saved = header["members"][name]
            self.members[name] = member._restored(saved, sub(arrays, f"member.{name}"), f"members.{name}.")



class ExpertsPair:
    """Two weightings of one set of members on one clock (`RecognitionSwitch`'s gated weighting and the
    ungated one over views of its members), stepped as one: each one's running errors, counts, record
    weights, pending predictions and outputs are rows of arrays the pair holds and the weighting views (as
    `GateBank` does for gates), so each stays a whole `Experts` (its weights, errors, checkpoint) while a
    frame scores, files and weighs both in one set of numpy calls instead of one each (the same numbers:
    every operation is the weighting's own, done row by row). `ExpertsPair.takes` says which pairs qualify."""

    def __init__(self, first: Experts, second: Experts) -> None:
        self.pair = (first, second)
        self.sse = np.stack([first.sse, second.sse])  # (weighting, member, horizon)
        self.weight = np.stack([first.weight, second.weight])
        self.scored = np.stack([first.scored, second.scored])
        self.record_weight = np.stack([first.record_weight, second.record_weight])  # (weighting, horizon)
        self.outputs = np.stack([first._outputs, second._outputs])  # (weighting, member, horizon, joints)
        self.pending = np.stack([first._pending.pending, second._pending.pending])
        self.valid = np.stack([first._pending.valid, second._pending.valid])
        for i, e in enumerate(self.pair):  # each weighting's state is now a view of its row
            e.sse, e.weight, e.scored = self.sse[i], self.weight[i], self.scored[i]
            e.record_weight = self.record_weight[i]
            e._outputs, e._pending.pending, e._pending.valid = self.outputs[i], self.pending[i], self.valid[i]
        self.params = p = first.params
        self._decay = np.array([first.params.decay, second.params.decay])[:, None, None]
        self._power = np.array([first.params.power, second.params.power])[:, None, None]
        self._made_at, self._slots, self._k = first._made_at, first._pending._slots, first._pending._k
        self._horizon, self._joints = p.horizon, p.n_joints

    @staticmethod
    def takes(first: Experts, second: Experts) -> bool:
        """Whether two weightings can be stepped as one: as many members, alike but for their forgetting
        and power, on one clock."""
        unlike = {"decay": 0.5, "power": 1.0}
        return (type(first) is Experts and type(second) is Experts and len(first.names) == len(second.names)
                and first.params.replace(**unlike) == second.params.replace(**unlike) and first._t == second._t)

    def advance(self, obs: np.ndarray | None, learn: bool) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Both weightings' `advance` on the checked observation, the second on the first's members'
        predictions before their gates (`Experts.ungated`): their weighted predictions."""
        first, second = self.pair
        t = first._t
        if second._t != t:  # not a pair this step
            out = first.advance(obs, learn)
            return out, second.advance(obs, learn, first.ungated())
        s = t % self._horizon
        valid = self.valid[:, :, s, :].copy()  # (weighting, member, horizon): row k made k + 1 steps ago
        self.valid[:, :, s, :] = False
        if obs is not None:
            self._score(obs, self.pending[:, :, s], valid, s)
        first._predict(obs, learn, None)
        second._predict(obs, learn, first.ungated())
        if not math.isfinite(self.outputs.sum()):  # a member predicts nothing: each on its own
            return first._returned(obs, first._combine(first._outputs, first._file())), \
                second._returned(obs, second._combine(second._outputs, second._file()))
        slots = self._slots[s]  # every prediction made: `Experts._file` of both
        self.pending[:, :, slots, self._k, :] = self.outputs
        self.valid[:, :, slots, self._k] = True
        self.record_weight[:, s] = 1.0
        first._t = second._t = t + 1
        w = self._weights()
        if w is None:
            return first._returned(obs, first._combine(first._outputs, True)), \
                second._returned(obs, second._combine(second._outputs, True))
        return np.einsum("mh,mhj->hj", w[0], self.outputs[0]), np.einsum("mh,mhj->hj", w[1], self.outputs[1])

    def _score(self, obs: np.ndarray, due: np.ndarray, valid: np.ndarray, s: int) -> None:
        """Both weightings' `_score` of the predictions `due` (weighting, member, horizon, joints)."""
        err = ((due - obs) ** 2).sum(axis=3) / self._joints  # (weighting, member, horizon)
        if not (every(valid) and math.isfinite(err.sum())):  # not every member scored at every step
            for e, e_err, e_valid in zip(self.pair, err, valid, strict=True):
                e._add(e_err, e_valid)
            return
        made = self.record_weight[:, None, self._made_at[s]]  # (weighting, 1, horizon)
        _forget_and_add(self.sse, self.weight, self.scored, err, made, self._decay)

    def _weights(self) -> np.ndarray | None:
        """Both weightings' `Experts.weights` where every member is known at every step (else None)."""
        if not every(self.weight):
            return None
        return _inverse_mse_weights(self.sse, self.weight, self.params.floor, self._power)


def _forget_and_add(sse: np.ndarray, weight: np.ndarray, scored: np.ndarray, err: np.ndarray, made: np.ndarray,
                    decay: float | np.ndarray) -> None:
    """The usual frame's scoring, in place, for one weighting or several (leading axes): every member scored
    at every step, its squared error `err` weighed by `made` (overwritten), after forgetting by `decay`."""
    err *= made
    sse *= decay
    sse += err
    weight *= decay
    weight += made
    scored += 1


def _inverse_mse_weights(sse: np.ndarray, weight: np.ndarray, floor: float, power: float | np.ndarray) -> np.ndarray:
    """The usual frame's weights, every member known at every step: 1 / MSE^power over the members (axis -2),
    relative to the best (no overflow at any power), summing to 1 per step; for one weighting or several."""
    mse = sse / weight
    np.maximum(mse, floor, out=mse)
    inv = mse.min(axis=-2, keepdims=True) / mse
    inv **= power
    return inv / inv.sum(axis=-2, keepdims=True)
