"""A confidence gate: shrink a model's prediction towards the newest pose by how well it has done.

The robot executes the prediction, so a prediction worse than "the person stays where they are"
makes the robot worse than no compensation. `GatedPredictor` wraps any online predictor m and
returns, per horizon step k (pooled over joints by default, or per joint),

    p_k = x(t) + alpha_k (m_k - x(t))

where alpha_k shrinks the model's step towards hold-last. From the predictions already scored
against their observed targets y, decayed per scored frame, the gate keeps S_xy = sum (y - x(t))
(m_k - x(t)), S_xx = sum (m_k - x(t))^2, S_yy = sum (y - x(t))^2 and the number of scores n. The
least-squares shrinkage a = S_xy / (S_xx + prior) is 0 (hold-last) until the model has shown
anything and 1 where it is reliably right. Two rules make it safe on motion that does not repeat:

- a lower confidence bound: shrinking by alpha saves 2 alpha S_xy - alpha^2 S_xx of squared error
  against hold-last, which stays >= 0 up to alpha = 2 a; alpha is capped at 2 (a - z se(a)), with
  se(a)^2 = RSS / ((n - 1)(S_xx + prior)), so a step that beat hold-last by chance over a few
  frames is not trusted (`confidence` = z), while a reliably good model keeps alpha = a;
- two memories: the same cap from a short memory (`fast_decay`, `fast_confidence`), so a model that
  was right on earlier motion but fails on this one is shrunk within a few frames instead of the
  ~100 the long memory needs. The short memory judges every step by the model's 1-step predictions
  (`fast_step` = 1): they are scored one frame after they are made, so they tell whether the model
  follows the motion now, while a k-step error arrives k frames late, after the motion that caused
  it may be over (a memory of those shrinks the good predictions of the next movement).

A model that is new changes fast, and its record from a few seconds ago says little about it now:
with `warmup`, the long memory starts short (`warmup_decay`) and lengthens to `decay` over the first
`warmup` scored frames.

Measured (`gwr-predictor experiment real`, `experiment gate`): without these two rules the default
is up to 1.10x hold-last on a clip of real motion learned from scratch and 1.23x on a climbing take
learned after the others; with them at most 1.02x on every clip, at a small cost where the model
is reliably good. `confidence=0, fast_decay=0` is the plain least-squares gate. The gate only counts
observed errors (no peeking): a prediction made at frame t for step k is scored when frame t + k is
observed, and dropped if that frame is missing or the sequence is reset first. The statistics keep
adapting when `step` is called with learn=False (they are running statistics, not a model).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from gwr_predictor.default_predictor.errors import DefaultPredictorError
from gwr_predictor.learning.pending import PendingPredictions, every, some
from gwr_predictor.learning.persistence import Checkpointed, Persist, fresh_of_kind, kind_to_save, params_from_json
from gwr_predictor.parameters.spec import ParamSpec, check_fields
from gwr_predictor.pipeline.conventions import DEFAULT_HORIZON
from gwr_predictor.predictors.baselines import N_JOINTS, observation

GATE_SPECS = {spec.name: spec for spec in (
    ParamSpec("decay", 0.99, "forgetting per scored frame of the long memory", 0.0, 1.0, lo_open=True),
    ParamSpec("warmup", 0, "scored frames over which the long memory's forgetting goes from warmup_decay to decay "
              "(0: decay from the start)", 0, 10**9),
    ParamSpec("warmup_decay", 0.95, "forgetting of the long memory at its first scored frame (with warmup)", 0.0, 1.0,
              lo_open=True),
    ParamSpec("prior", 0.01, "rad^2 per joint added to S_xx", 0.0, lo_open=True),
    ParamSpec("confidence", 2.0, "z of the lower confidence bound on alpha (0: the estimate itself)", 0.0, 10.0),
    ParamSpec("fast_decay", 0.9, "forgetting of the short memory (0: no short memory)", 0.0, 1.0, hi_open=True),
    ParamSpec("fast_confidence", 0.0, "z of the short memory's bound (0: its least-squares estimate)", 0.0, 10.0),
    ParamSpec("fast_step", 1, "step whose record the short memory caps every step with (0: each its own)", 0),
    ParamSpec("per_joint", False, "one alpha per (step, joint) instead of per step"),
    ParamSpec("horizon", DEFAULT_HORIZON, "steps gated", 1),
    ParamSpec("joints", N_JOINTS, "joints per frame", 1),
)}
_XY, _XX, _YY, _N = range(4)  # the running sums, per memory


@dataclass(frozen=True)
class GateParams:
    """`decay`: forgetting per scored frame (0.99 ~ the last 100 frames). `warmup`: over its first
    `warmup` scored frames the long memory's forgetting goes linearly from `warmup_decay` to `decay`, so
    it is short while the model is new and changing fast and long once both are settled. `prior` (rad^2 per joint):
    added to S_xx, so alpha stays near 0 until the model's steps have some weight of evidence.
    `confidence`: how many standard errors alpha is lowered by. `fast_decay`/`fast_confidence`: the
    short memory whose bound also caps alpha (0.9 ~ the last 10 frames). `fast_step`: the horizon step
    whose record the short memory's cap is taken from for every step (1: the freshest evidence; 0:
    each step its own, the gate before `fast_step` existed). `per_joint`: one alpha per
    (step, joint) instead of per step (more to estimate: less safe on short clips)."""

    SPECS: ClassVar[dict[str, ParamSpec]] = GATE_SPECS
    decay: float = GATE_SPECS["decay"].default
    warmup: int = GATE_SPECS["warmup"].default
    warmup_decay: float = GATE_SPECS["warmup_decay"].default
    prior: float = GATE_SPECS["prior"].default
    confidence: float = GATE_SPECS["confidence"].default
    fast_decay: float = GATE_SPECS["fast_decay"].default
    fast_confidence: float = GATE_SPECS["fast_confidence"].default
    fast_step: int = GATE_SPECS["fast_step"].default
    per_joint: bool = GATE_SPECS["per_joint"].default
    horizon: int = GATE_SPECS["horizon"].default
    joints: int = GATE_SPECS["joints"].default

    def __post_init__(self) -> None:
        check_fields(self, GATE_SPECS.values(), DefaultPredictorError)
        if self.fast_step > self.horizon:
            raise DefaultPredictorError(f"GateParams.fast_step {self.fast_step} exceeds the horizon {self.horizon}")

    @property
    def memories(self) -> tuple[tuple[float, float], ...]:
        """(decay, z) of each memory whose bound caps alpha."""
        long = ((self.decay, self.confidence),)
        return long + ((self.fast_decay, self.fast_confidence),) if self.fast_decay > 0 else long


class GatedPredictor(Checkpointed):
    """`model`'s predictions shrunk towards hold-last per horizon step (see the module docstring)."""

    kind: ClassVar[str] = "GatedPredictor"

    def __init__(self, model: Any, params: GateParams | None = None, hold_when_silent: bool = True) -> None:
        """`hold_when_silent`: where the model predicts nothing (a window refilling after a gap), the
        newest pose; False: None, for a member of `Experts`, which weighs and scores only predictions."""
        if not (callable(getattr(model, "step", None)) and callable(getattr(model, "reset_sequence", None))):
            raise DefaultPredictorError(f"{type(model).__name__} does not implement step/reset_sequence")
        self.model = model
        self.hold_when_silent = hold_when_silent
        self.params = p = params or GateParams()
        horizon = getattr(getattr(model, "params", None), "horizon", p.horizon)
        if horizon < p.horizon:
            raise DefaultPredictorError(f"the gate's horizon {p.horizon} exceeds the model's {horizon}")
        # per memory: [S_xy, S_xx, S_yy, n], each (horizon, joints) (pooled: equal across joints)
        self._stats: np.ndarray = np.zeros((len(p.memories), 4, p.horizon, p.joints))
        # scratch of `_score` (row _N stays 1); pooled, one column, which the sums take in every joint's
        self._new = np.ones((4, p.horizon, p.joints if p.per_joint else 1))
        self._shape = (p.horizon, p.joints)  # of a prediction gated
        self._filed = np.empty((2, p.horizon, p.joints))  # scratch of `step`: newest pose, model's step
        self._decays = np.array([d for d, _ in p.memories])[:, None, None, None]  # per memory, over `_stats`
        self._z = np.array([z for _, z in p.memories])[:, None, None]
        self._z2 = 2.0 * self._z  # `alpha`'s doubled bound
        self._prior = p.prior if p.per_joint else p.prior * p.joints  # added to S_xx
        # the memories whose bound needs computing: up to the last one with z > 0 (0: none)
        self._bounded = int(np.flatnonzero(self._z.ravel() > 0).max()) + 1 if self._z.any() else 0
        self._scored = np.zeros(p.horizon, dtype=np.int64)
        # per prediction: [newest pose at prediction time, model step k - that pose], filed by target step
        self._pending = PendingPredictions(p.horizon, p.joints, lead=(2,))
        self._t = 0  # steps seen, observed or not: the clock of the pending predictions
        #: per step k, a share of step 1's alpha that step k's is raised to (None: each step its own), set
        #: by an owner that knows step k's record cannot yet hold the present motion (`RecognitionSwitch`)
        self.borrow: np.ndarray | None = None
        self._clear_sequence()

    def _clear_sequence(self) -> None:
        self._pending.drop()
        self._last: np.ndarray | None = None
        self._out_diff: np.ndarray | None = None

    def reset_sequence(self) -> None:
        """Sequence boundary: drop pending predictions and the last pose (not the statistics)."""
        self.model.reset_sequence()
        self._clear_sequence()

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        self.advance(observation(x, self.params.joints), learn)
        return self._gated(self._out_diff)

    def advance(self, obs: np.ndarray | None, learn: bool = True) -> None:
        """`step` on an observation already checked (`observation`), without making the gated prediction:
        for an owner that checks the frame once for all its parts and may not return this gate's output
        (`predict` makes it)."""
        due, valid = self._pending.take(self._t)
        if obs is not None:
            self._score(obs, due, valid)
            self._last = obs.copy()
        out = self.model.step(obs, learn=learn)
        diff = None
        if out is not None and self._last is not None:
            diff = self._checked(out) - self._last
            if not math.isfinite(diff.sum()):
                diff = None
        if diff is not None:  # a prediction implies a newest pose
            filed = self._filed
            filed[0] = self._last
            filed[1] = diff
            self._pending.file(self._t, filed)
        self._t += 1
        self._out_diff = diff

    def _checked(self, out: Any) -> np.ndarray:
        """The model's prediction, its first `horizon` steps (DefaultPredictorError if its shape is wrong)."""
        if type(out) is np.ndarray and out.shape == self._shape and out.dtype == np.float64:
            return out  # the usual prediction, as it is (in a fraction of the checks' time)
        p = self.params
        out = np.asarray(out, dtype=float)
        if out.ndim != 2 or out.shape[0] < p.horizon or out.shape[1] != p.joints:
            raise DefaultPredictorError(f"{type(self.model).__name__} returned shape {out.shape}; need at least "
                                        f"({p.horizon}, {p.joints})")
        return out[:p.horizon]

    def predict(self) -> np.ndarray | None:
        """The last `step`'s gated prediction, with the current alphas; no state change."""
        return self._gated(self._out_diff)

    def ungated(self) -> np.ndarray | None:
        """The model's own prediction at the last `step`, before the gate shrinks it (None if it made none)."""
        return None if self._out_diff is None or self._last is None else self._last + self._out_diff

    def _gated(self, diff: np.ndarray | None) -> np.ndarray | None:
        if self._last is None:
            return None
        if diff is None:
            return np.repeat(self._last[None, :], self.params.horizon, axis=0) if self.hold_when_silent else None
        out = self.alpha()
        out *= diff
        out += self._last
        return out

    def _score(self, obs: np.ndarray, due: np.ndarray, valid: np.ndarray) -> None:
        """Score the pending predictions that target this observed frame (row k made k + 1 steps ago)."""
        ok = valid[0]
        if not some(ok):
            return
        p = self.params
        if p.warmup:
            self._decays[0] = forgetting_after(p, self._scored[0])
        _products(obs - due[0], due[1], p.per_joint, self._new)  # y - newest pose at prediction time, model's step
        _accumulate(self._stats, self._decays, self._scored, self._new, ok)

    def alpha(self) -> np.ndarray:
        """(horizon, joints) shrinkage factors in [0, 1] (0 = hold-last, 1 = the model as it is); a new array.

        min(a, 2 lcb_long, 2 lcb_short): the long memory's least-squares estimate, capped by each
        memory at the largest shrinkage that still saves squared error against hold-last at the lower
        bound (2 alpha S_xy - alpha^2 S_xx >= 0 for alpha <= 2 a)."""
        out = shrinkage(self._stats, self._prior, self._z2, self._bounded, self.params.fast_step)
        if self.borrow is not None:
            np.maximum(out, np.minimum(self.borrow[:, None] * out[0], 1.0), out=out)
        return out

    # --- introspection ------------------------------------------------------------------------------
    @property
    def horizon(self) -> int:
        """Frames predicted (the gate gates as many steps as its model predicts)."""
        return self.params.horizon

    @property
    def neuron_counts(self) -> tuple[int, ...] | None:
        counts = getattr(self.model, "neuron_counts", None)
        return None if counts is None else tuple(counts)

    def errors(self) -> dict[str, Any]:
        a = self.alpha()
        out: dict[str, Any] = {"gate_alpha_mean": a.mean(axis=1).tolist(), "gate_scored": self._scored.tolist()}
        if callable(getattr(self.model, "errors", None)):
            out["model"] = self.model.errors()
        return out

    # --- persistence --------------------------------------------------------------------------------
    PARAMS = GateParams
    PERSIST = Persist(arrays=("_stats", "_scored"), values=("_t", "hold_when_silent"), optional=("_last", "_out_diff"),
                      members={"model": "model", "_pending": ""})

    @classmethod
    def _fresh(cls, header: Mapping[str, Any]) -> GatedPredictor:
        return cls(fresh_of_kind(header["model_kind"], header["model"]), params_from_json(GateParams, header["params"]))

    def _save_extra(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """The model's kind (which class to rebuild); only models that can be restored are saved."""
        return {"model_kind": kind_to_save(self.model, "the gated model")}, {}


class GateBank:
    """The gates of several members of one weighting (`Experts`), alike in their parameters, stepped as
    one: each gate's running sums, pending predictions and counts are rows of arrays the bank holds and
    the gate views, so each stays a whole `GatedPredictor` (its alpha, errors, checkpoint) while a frame
    costs one set of numpy calls for all of them instead of one per gate (the same numbers: every
    operation is the gate's own, done row by row).

    For gates that are not silent-holding (`hold_when_silent` false), lend nothing (`borrow`) and step in
    step (one clock); `GateBank.takes` says whether a set of members qualifies."""

    def __init__(self, gates: Sequence[GatedPredictor]) -> None:
        self.gates = list(gates)
        first = self.gates[0]
        self.params = first.params
        self.stats = np.stack([g._stats for g in self.gates], axis=1)  # (memory, gate, 4, horizon, joints)
        self.decays = np.stack([g._decays for g in self.gates], axis=1)
        self.scored = np.stack([g._scored for g in self.gates])  # (gate, horizon)
        self.pending = np.stack([g._pending.pending for g in self.gates])  # (gate, 2, horizon, horizon, joints)
        self.valid = np.stack([g._pending.valid for g in self.gates])
        for i, g in enumerate(self.gates):  # each gate's state is now a view of its row
            g._stats, g._decays, g._scored = self.stats[:, i], self.decays[:, i], self.scored[i]
            g._pending.pending, g._pending.valid = self.pending[i], self.valid[i]
        self._new = np.ones((len(self.gates), *first._new.shape))
        self._z2 = first._z2[:, None]
        self._slots, self._k = first._pending._slots, first._pending._k
        # whether every gate's long memory forgets at its end value `_end_decay` (its warmup over)
        self._settled = False
        self._end_decay = forgetting_after(self.params, self.params.warmup)
        # the last bank step's model steps, predicting gates and newest pose (None: not stepped as a bank)
        self._ungated: tuple[np.ndarray, np.ndarray, np.ndarray | None] | None = None

    @staticmethod
    def takes(members: Sequence[Any]) -> bool:
        """Whether `members` can be stepped as one bank."""
        first = members[0]
        return all(type(m) is GatedPredictor and m.params == first.params and not m.hold_when_silent
                   and m._t == first._t for m in members)

    def step(self, obs: np.ndarray | None, learn: bool) -> tuple[np.ndarray, np.ndarray]:
        """Every gate's `step` on the checked observation: (gate, horizon, joints) predictions and which
        gates predict (the rows of the others are undefined)."""
        gates, p = self.gates, self.params
        t = gates[0]._t
        if any(g.borrow is not None or g._t != t for g in gates):  # not a bank this step
            self._ungated = None
            outs = [g.step(obs, learn) for g in gates]
            ok = np.array([o is not None for o in outs])
            return np.array([o if o is not None else np.zeros((p.horizon, p.joints)) for o in outs]), ok
        s = t % p.horizon
        valid = self.valid[:, 0, s, :].copy()  # (gate, horizon): row k made k + 1 steps ago
        self.valid[:, :, s, :] = False
        if obs is not None:
            self._score(obs, self.pending[:, :, s], valid)  # due: (gate, 2, horizon, joints)
            last = obs.copy()
            for g in gates:
                g._last = last
        outs = [g.model.step(obs, learn=learn) for g in gates]
        predicted = [o is not None and g._last is not None for o, g in zip(outs, gates, strict=True)]
        diff = np.zeros((len(gates), p.horizon, p.joints))
        for i, o in enumerate(outs):
            if predicted[i]:
                diff[i] = gates[i]._checked(o)
        diff -= gates[0]._last if gates[0]._last is not None else 0.0
        ok = np.isfinite(diff.reshape(len(gates), -1).sum(axis=1))
        if not all(predicted):
            ok &= predicted
        for g, d, k in zip(gates, diff, ok.tolist(), strict=True):
            g._out_diff = d if k else None
            g._t = t + 1
        if every(ok):  # file every prediction (a prediction implies a newest pose)
            slots = self._slots[s]
            self.pending[:, 0, slots, self._k, :] = gates[0]._last
            self.pending[:, 1, slots, self._k, :] = diff
            self.valid[:, :, slots, self._k] = True
        else:
            for i in ok.nonzero()[0].tolist():
                filed = gates[i]._filed
                filed[0] = gates[i]._last
                filed[1] = diff[i]
                gates[i]._pending.file(t, filed)
        self._ungated = diff, ok, gates[0]._last
        out = shrinkage(self.stats, gates[0]._prior, self._z2, gates[0]._bounded, p.fast_step)
        out *= diff
        out += gates[0]._last if gates[0]._last is not None else 0.0
        return out, ok

    def ungated(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Right after `step`: every gate's `ungated` prediction, (gate, horizon, joints), and which gates
        made one (the rows of the others are undefined), in one call; None if the gates were stepped one
        by one."""
        if self._ungated is None:
            return None
        diff, ok, last = self._ungated
        return (diff if last is None else last + diff), ok

    def _score(self, obs: np.ndarray, due: np.ndarray, valid: np.ndarray) -> None:
        """Every gate's `_score`: the products of the predictions due now, into each gate's sums."""
        p = self.params
        if every(valid):  # the common case: every gate has a scored prediction at every step
            if p.warmup and not self._settled:
                self._lengthen(slice(None))
            _products(obs - due[:, 0], due[:, 1], p.per_joint, self._new)
            _accumulate(self.stats, self.decays, self.scored, self._new, valid)
            return
        any_ok = np.asarray(valid.any(axis=1))
        if not some(any_ok):
            return
        rows = any_ok.nonzero()[0]
        if p.warmup and not self._settled:
            self._lengthen(rows)
        new = self._new
        _products(obs - due[:, 0], due[:, 1], p.per_joint, new)
        for i in rows.tolist():  # as each gate's `_score` does, on its views
            g = self.gates[i]
            _accumulate(g._stats, g._decays, g._scored, new[i], valid[i])

    def _lengthen(self, rows: np.ndarray | slice) -> None:
        """The long memory's forgetting of the gates `rows` that score now, as `GatedPredictor._score` sets
        it over the warmup; once every gate's is at its end value, which it keeps, this is no longer called."""
        p = self.params
        self.decays[0, rows, 0, 0, 0] = forgetting_after(p, self.scored[rows, 0])
        self._settled = every(self.scored[:, 0] >= p.warmup) and every(self.decays[0] == self._end_decay)


def forgetting_after(p: GateParams, scored: int | np.ndarray) -> float | np.ndarray:
    """The long memory's forgetting after `scored` scored frames (of one gate, or of several): from
    `warmup_decay` to `decay` over the first `warmup`, then `decay`'s value as this sum rounds it."""
    return p.warmup_decay + (p.decay - p.warmup_decay) * np.minimum(1.0, scored / p.warmup)


def _products(resid: np.ndarray, diff: np.ndarray, per_joint: bool, new: np.ndarray) -> None:
    """The products a scored prediction adds to a gate's sums, into `new` (..., 4, horizon, joints): of the
    residual against the newest pose then and the model's step, per joint or pooled over the joints (one
    sum of products per step, in `new`'s one column, added to every joint's); for one gate or several (`...`)."""
    if per_joint:
        np.multiply(resid, diff, out=new[..., _XY, :, :])
        np.multiply(diff, diff, out=new[..., _XX, :, :])
        np.multiply(resid, resid, out=new[..., _YY, :, :])
    else:
        np.vecdot(resid, diff, out=new[..., _XY, :, 0])
        np.vecdot(diff, diff, out=new[..., _XX, :, 0])
        np.vecdot(resid, resid, out=new[..., _YY, :, 0])


def _accumulate(stats: np.ndarray, decays: np.ndarray, scored: np.ndarray, new: np.ndarray, ok: np.ndarray) -> None:
    """Forget and add `new` into running sums `stats` (memory, [gate,] 4, horizon, joints), in place, on the
    steps `ok` (horizon,) holds, counting them in `scored`; every step at once in the common case."""
    if every(ok):
        stats *= decays
        stats += new
        scored += 1
        return
    rows = ok.nonzero()[0]
    stats[:, :, rows] = decays * stats[:, :, rows] + new[:, rows]
    scored[rows] += 1


def shrinkage(s: np.ndarray, prior: float, z2: np.ndarray, bounded: int, fast_step: int) -> np.ndarray:
    """`GatedPredictor.alpha` from the running sums `s` (memory, ..., 4, horizon, joints) of one gate or of
    several alike (the leading `...`), with z2 (memory, 1, ...) the doubled bounds of the first `bounded`
    memories; a new array (..., horizon, joints)."""
    sxy = s[:, ..., _XY, :, :]
    sxx = s[:, ..., _XX, :, :] + prior
    a = sxy / sxx
    cap = a * 2.0  # 2 (a - z se(a)), the doubling exact: 2 a - (2 z) se
    b = bounded
    if b:  # z se(a), se(a)^2 = RSS / ((n - 1) S_xx), RSS = S_yy - 2 a S_xy + a^2 S_xx (in place, few calls)
        sxy_b, a_b = sxy[:b], a[:b]
        se = a_b * s[:b, ..., _XX, :, :]
        se -= sxy_b
        se -= sxy_b
        se *= a_b
        se += s[:b, ..., _YY, :, :]
        np.maximum(se, 0.0, out=se)
        dof = np.maximum(s[:b, ..., _N, :, :], 2.0)
        dof -= 1.0
        dof *= sxx[:b]
        se /= dof
        np.sqrt(se, out=se)
        se *= z2[:b]
        cap[:b] -= se
    if len(cap) == 2:  # the short memory caps every step by one step's record (`fast_step`) or each its own
        out = np.minimum(cap[0], cap[1, ..., fast_step - 1, None, :] if fast_step else cap[1])
    else:
        out = cap.min(axis=0)
    np.minimum(out, a[0], out=out)
    np.minimum(out, 1.0, out=out)
    np.maximum(out, 0.0, out=out)
    return out


def inner_model(model: Any) -> Any:
    """The learner behind a gate, or the model itself: what has neurons, errors and `frames_seen`."""
    return model.model if isinstance(model, GatedPredictor) else model
