"""How far off a prediction may be: a stated central interval around every predicted angle, learned online.

A robot that moves on a prediction should know when the prediction is a guess. `Spread` sits beside a
predictor's output: per horizon step k and joint j it states the interval

    p_k,j ± q_g,k,j s_k,j(t)

that should hold the true angle on a share `nominal` (80 %) of the predictions. Neither part is assumed:

- the scale s is what is known at t about how wrong the prediction may be: its own recent errors at
  (k, j), E_k,j (the running mean square of the residuals scored lately, forgetting `error_decay` per
  scored frame), and how fast the joint moves now, v_j (rad per frame, smoothed by `speed_decay`),

      s_k,j = sqrt(floor² + error_weight E_k,j + motion_weight (k v_j)²),

  so the interval widens when the predictor has lately been wrong or the arm moves fast, and narrows
  where it has been right;
- the multiplier q is tracked online so that the stated share of the residuals falls inside: every
  scored residual r = |y - p| moves log q by `rate` (1{r > q s} - (1 - nominal)), per step, joint and
  group (quantile tracking, the O(1) form of adaptive conformal inference, Gibbs & Candès 2021: whatever
  the sequence, the long-run share of misses goes to 1 - nominal, at a pace set by `rate`).

`groups` > 1 gives each group its own multipliers: an owner that knows which predictions are guesses says
so (the default: whether its memory recognises the motion, where its experts are trusted without their
gates), so the interval can be narrow on a movement the predictor knows and wide on a new one, and the
share holds within each group.

Residuals are scored only against frames observed later (no peeking); a prediction whose target is lost
is never scored. The spread never changes a prediction: it reads it, once, when it is made.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from gwr_predictor.default_predictor.errors import DefaultPredictorError
from gwr_predictor.learning.params import DEFAULT_HORIZON, MAX_HORIZON
from gwr_predictor.learning.pending import PendingPredictions, every, some
from gwr_predictor.learning.persistence import Checkpointed, Persist, fresh_of_kind, kind_to_save, params_from_json
from gwr_predictor.parameters.spec import ParamSpec, check_fields
from gwr_predictor.predictors.baselines import observation

SPREAD_SPECS = {spec.name: spec for spec in (
    ParamSpec("nominal", 0.8, "share of the true angles the stated central interval should hold", 0.0, 1.0,
              lo_open=True, hi_open=True),
    ParamSpec("rate", 0.05, "step of the quantile tracker per scored prediction, in log units (0: the multiplier "
              "stays at `initial`)", 0.0, 2.0),
    ParamSpec("initial", 1.3, "the multiplier of the scale before anything was scored", 0.0, 1e3, lo_open=True),
    ParamSpec("error_weight", 1.0, "weight of the recent squared errors in the scale", 0.0, 1e6),
    ParamSpec("error_decay", 0.97, "forgetting of the recent squared errors per scored frame", 0.0, 1.0,
              lo_open=True, hi_open=True),
    ParamSpec("error_prior", 0.01, "rad^2: the recent squared error before anything was scored (weighs one score)",
              0.0, 100.0),
    ParamSpec("motion_weight", 0.02, "weight of the squared displacement at the present speed (k v)^2 in the scale",
              0.0, 1e6),
    ParamSpec("speed_decay", 0.5, "smoothing of each joint's speed per observed frame", 0.0, 1.0, hi_open=True),
    ParamSpec("floor", 0.005, "rad: the smallest scale", 0.0, 10.0, lo_open=True),
    ParamSpec("groups", 2, "sets of multipliers an owner can choose between per prediction (the default: motion "
              "new, motion recognised)", 1, 16),
    ParamSpec("horizon", DEFAULT_HORIZON, "steps predicted", 1, MAX_HORIZON),
    ParamSpec("joints", 8, "joints per frame", 1),
)}
#: What the learner node and `make_default` take under `spread.` (the horizon and the joints are the data's).
FLAT_SPREAD_SPECS = tuple(s for name, s in SPREAD_SPECS.items() if name not in ("horizon", "joints"))


@dataclass(frozen=True)
class SpreadParams:
    """Settings of `Spread` (see `SPREAD_SPECS` and the module docstring)."""

    SPECS: ClassVar[dict[str, ParamSpec]] = SPREAD_SPECS
    nominal: float = SPREAD_SPECS["nominal"].default
    rate: float = SPREAD_SPECS["rate"].default
    initial: float = SPREAD_SPECS["initial"].default
    error_weight: float = SPREAD_SPECS["error_weight"].default
    error_decay: float = SPREAD_SPECS["error_decay"].default
    error_prior: float = SPREAD_SPECS["error_prior"].default
    motion_weight: float = SPREAD_SPECS["motion_weight"].default
    speed_decay: float = SPREAD_SPECS["speed_decay"].default
    floor: float = SPREAD_SPECS["floor"].default
    groups: int = SPREAD_SPECS["groups"].default
    horizon: int = SPREAD_SPECS["horizon"].default
    joints: int = SPREAD_SPECS["joints"].default

    def __post_init__(self) -> None:
        check_fields(self, SPREAD_SPECS.values(), DefaultPredictorError)

    def replace(self, **changes: Any) -> SpreadParams:
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


_PRED, _HALF, _GROUP = range(3)  # the rows filed per prediction


class Spread(Checkpointed):
    """The central interval of every prediction it is shown (see the module docstring)."""

    kind: ClassVar[str] = "Spread"
    PARAMS = SpreadParams
    PERSIST = Persist(arrays=("log_q", "err_sum", "err_weight", "speed", "scored", "_bounds"),
                      values=("_t", "_has_bounds"), optional=("_last",), members={"_pending": "pending"},
                      nan_ok=("_bounds",))  # NaN: a step the last prediction had nothing for

    def __init__(self, params: SpreadParams | None = None) -> None:
        self.params = p = params or SpreadParams()
        shape = (p.horizon, p.joints)
        self.log_q = np.full((p.groups, *shape), math.log(p.initial))  # the multipliers, per group, step, joint
        self.err_sum = np.zeros(shape)  # decayed sums of squared residuals
        self.err_weight = np.zeros(shape)  # and of their counts
        self.speed = np.zeros(p.joints)  # smoothed |x(t) - x(t - 1)| per joint (rad per frame)
        self.scored = np.zeros((p.groups, p.horizon), dtype=np.int64)  # residuals scored per group and step
        self._bounds = np.zeros((2, *shape))  # the last prediction's [lower, upper]
        self._has_bounds = False
        self._last: np.ndarray | None = None  # the newest observed pose
        # per prediction: [the prediction, the half-width stated, its group (in every column)]
        self._pending = PendingPredictions(p.horizon, p.joints, lead=(3,))
        self._filed = np.empty((3, *shape))  # scratch of `step`
        self._t = 0
        miss = 1.0 - p.nominal  # the share of misses the tracker aims at
        # a miss moves log q up by rate (1 - share of misses), a hit down by rate x that share
        self._up, self._down = (1.0 - miss) * p.rate, (0.0 - miss) * p.rate
        self._q = np.exp(self.log_q)  # the multipliers themselves, refreshed when log q moves
        self._group_ids = np.arange(p.groups, dtype=float)[:, None]
        self._motion = (p.motion_weight * np.arange(1, p.horizon + 1, dtype=float) ** 2)[:, None]  # w k^2

    @property
    def nominal(self) -> float:
        """The share of true angles the stated interval should hold."""
        return self.params.nominal

    def reset_sequence(self) -> None:
        """Sequence boundary: pending predictions, the last pose and the last interval go (what was learned stays)."""
        self._pending.drop()
        self._last = None
        self._has_bounds = False

    def step(self, x: np.ndarray | None, prediction: np.ndarray | None, group: int = 0) -> None:
        """Score what targets this frame `x` (None: lost), then state the interval of `prediction` ((horizon,
        joints) made at this frame; None: none), counted in `group`."""
        self.advance(observation(x, self.params.joints), prediction, group)

    def advance(self, obs: np.ndarray | None, prediction: np.ndarray | None, group: int = 0) -> None:
        """`step` on an observation already checked (`observation`), for an owner that checks it once."""
        p = self.params
        due, valid = self._pending.take(self._t)
        self._t += 1
        if obs is not None:
            if some(valid[_PRED]):
                self._score(obs, due, valid[_PRED])
            if self._last is not None and p.motion_weight:
                self.speed *= p.speed_decay
                self.speed += (1.0 - p.speed_decay) * np.abs(obs - self._last)
            self._last = obs.copy()
        self._has_bounds = prediction is not None
        if prediction is None:
            return
        if not 0 <= group < p.groups:
            raise DefaultPredictorError(f"spread group {group} outside 0..{p.groups - 1}")
        filed = self._filed
        half = filed[_HALF]  # the scale s, then q s
        np.add(self.err_sum, p.error_prior, out=half)
        half /= self.err_weight + 1.0
        if p.error_weight != 1.0:
            half *= p.error_weight
        if p.motion_weight:
            half += self._motion * self.speed ** 2
        half += p.floor ** 2
        np.sqrt(half, out=half)
        half *= self._q[group]
        filed[_PRED] = prediction[:p.horizon]
        filed[_GROUP] = group
        finite = math.isfinite(filed[_PRED].sum())  # a row of NaN: a step the predictor has nothing for
        self._pending.file(self._t - 1, filed, True if finite else np.isfinite(filed[_PRED]).all(axis=1))
        np.subtract(filed[_PRED], half, out=self._bounds[0])
        np.add(filed[_PRED], half, out=self._bounds[1])

    def _score(self, obs: np.ndarray, due: np.ndarray, valid: np.ndarray) -> None:
        """Residuals of the predictions that target `obs` (row k made k + 1 frames ago): the quantile tracker
        of each one's group, and the recent errors."""
        p = self.params
        resid = np.abs(obs - due[_PRED])  # (horizon, joints)
        step = np.where(resid > due[_HALF], self._up, self._down)
        resid *= resid
        member = self._group_ids == due[_GROUP, :, 0]  # (groups, horizon): which group each row was stated in
        if every(valid):  # the common case
            self.err_sum *= p.error_decay
            self.err_weight *= p.error_decay
        else:  # a prediction a gap left unscored: no step, no error, no forgetting
            member &= valid
            resid *= valid[:, None]
            decay = np.where(valid, p.error_decay, 1.0)[:, None]
            self.err_sum *= decay
            self.err_weight *= decay
        self.log_q += member[:, :, None] * step
        np.exp(self.log_q, out=self._q)
        self.err_sum += resid
        self.err_weight += valid[:, None]
        self.scored += member

    def _load_extra(self, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> None:
        np.exp(self.log_q, out=self._q)

    def interval(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(lower, upper), each (horizon, joints) rad, of the last prediction shown; None if it was none. Copies."""
        return (self._bounds[0].copy(), self._bounds[1].copy()) if self._has_bounds else None

    def multipliers(self) -> np.ndarray:
        """(groups, horizon) the multiplier q of the scale, mean over joints, per group and step."""
        return self._q.mean(axis=2)

    def errors(self) -> dict[str, Any]:
        """The stated share, the multipliers per group and step and the residuals scored."""
        return {"interval_nominal": self.params.nominal, "interval_multiplier": self.multipliers().tolist(),
                "interval_scored": self.scored.tolist()}


class WithSpread(Checkpointed):
    """Any online predictor's predictions unchanged, each with a `Spread` of its own residuals (group 0): the
    baselines' intervals, learned the same way as the default's, so that widths compare at equal coverage.
    Saved with its model when the model can be (`learning.persistence.kind_to_save`)."""

    kind: ClassVar[str] = "WithSpread"
    PARAMS = SpreadParams
    PERSIST = Persist(members={"model": "model", "spread": "spread"})

    def __init__(self, model: Any, params: SpreadParams | None = None) -> None:
        if not (callable(getattr(model, "step", None)) and callable(getattr(model, "reset_sequence", None))):
            raise DefaultPredictorError(f"{type(model).__name__} does not implement step/reset_sequence")
        self.model = model
        horizon = int(getattr(model, "horizon", DEFAULT_HORIZON))
        joints = int(getattr(model, "joints", SPREAD_SPECS["joints"].default))
        self.spread = Spread(params or SpreadParams(horizon=horizon, joints=joints, groups=1))
        self.params = self.spread.params

    @property
    def horizon(self) -> int:
        return self.spread.params.horizon

    @property
    def interval_nominal(self) -> float:
        return self.spread.nominal

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        out = self.model.step(x, learn=learn)
        self.spread.step(x, None if out is None else np.asarray(out, dtype=float))
        return out

    def reset_sequence(self) -> None:
        self.model.reset_sequence()
        self.spread.reset_sequence()

    def interval(self) -> tuple[np.ndarray, np.ndarray] | None:
        return self.spread.interval()

    def _save_extra(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        return {"model_kind": kind_to_save(self.model, "the model with a spread")}, {}

    @classmethod
    def _fresh(cls, header: Mapping[str, Any]) -> WithSpread:
        return cls(fresh_of_kind(header["model_kind"], header["model"]), params_from_json(SpreadParams,
                                                                                          header["params"]))
