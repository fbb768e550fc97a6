"""Candidate defaults for motion that repeats with variation, composed from the package's parts.

Each is registered as `cand_<name>` (`research/registry.py`) so the experiments score it
like any other method. They differ from the default in what the linear read-out sees and in how fast
the gate trusts the model; the network (the local-linear P-GWR) is the default's, unchanged:
- `cand_long`: the default with its global read-out fitted on `global_frames` = 12 frames (RLS-AR and
  the direct linear model use 12; the default's read-out 2), decoupled from the 4 frames the neurons
  match on, behind the default gate;
- `cand_long_fast`: the same behind a gate that needs less evidence (a weaker prior, a lower bound
  at one standard error instead of two);
- `cand_experts`: the neurons' model (with the long read-out), the direct linear model and RLS-AR as
  experts, weighted per horizon step by each one's recent squared error (`research.blend`), behind the
  default gate with a ~20-frame memory (decay 0.95), a weaker prior and a one-standard-error bound.
- `cand_gated_experts`: the same three experts, each behind its own gate (the experts' gate settings),
  so a bad stretch of one expert falls back to hold-last instead of leaking into the blend; blended
  per step by recent squared error and behind the faster gate;
- `cand_sharp_experts`: the same with weights 1 / MSE^16, close to the single best gated expert per
  step, so the trained network keeps nearly all the weight where it is the best.

`ChooseExperts` also chooses one expert per step (with hysteresis, hold-last as an expert), blends only
the experts better than hold, or scales the network's error by its winning neuron's track record:
measured in `tuning.py`, none of these won.

`tuning.py` says on which streams their settings were chosen.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from gwr_predictor.default_predictor.gate import inner_model
from gwr_predictor.default_predictor.params import LocalLinearParams
from gwr_predictor.default_predictor.predictor import LocalLinearPredictor
from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.learning.protocol import Predictor
from gwr_predictor.learning.rls import RecursiveLeastSquares, window_features
from gwr_predictor.predictors.baselines import HoldLast, RLSAutoregressive, RLSParams
from gwr_predictor.predictors.direct_linear import DirectLinear, DirectLinearParams
from research.blend import BlendedPredictor, BlendParams
from research.predictors import gated, local_linear_params
from research.registry import RESEARCH, hierarchy_params

#: frames the candidates' global read-out spans (RLS-AR's and the direct linear model's order)
GLOBAL_FRAMES = 12
#: prior variance of the long read-out's weights (the direct linear model's tuned delta)
GLOBAL_DELTA = 1.0
#: the gate that opens faster: (prior, confidence) against the default's (0.01, 2.0)
FAST_GATE = {"prior": 0.001, "confidence": 1.0}
#: the experts' gate, chosen on the tuning set: a ~20-frame long memory instead of ~100 as well
EXPERTS_GATE = {"decay": 0.95, **FAST_GATE}
#: `cand_sharp_experts`' weights go as 1 / MSE^SHARP_POWER: nearly the best expert, never a hard switch
SHARP_POWER = 16.0


class CandidateError(GwrPredictorError, ValueError):
    """A candidate's setting out of range; the message says which."""


class LongReadoutPredictor(LocalLinearPredictor):
    """The default's model with a global read-out over the last `global_frames` frames, whatever the
    neurons' `order`: the read-out's features are `window_features` of its own newest-first window,
    padded with the oldest frame until it is full (as the direct linear model pads its first frames).
    Research only: no checkpoints."""

    def __init__(self, params: LocalLinearParams | None = None, seed: int | None = 0,
                 global_frames: int = GLOBAL_FRAMES, global_delta: float = GLOBAL_DELTA) -> None:
        if global_frames < 1 or not global_delta > 0:
            raise CandidateError(f"global_frames must be >= 1 and global_delta > 0, got {global_frames}, "
                                 f"{global_delta}")
        self.global_frames = global_frames
        self.global_delta = global_delta
        p = params or LocalLinearParams()
        super().__init__(p if p.global_order else p.replace(global_order=1), seed)

    def _init_global(self) -> None:
        super()._init_global()
        p = self.params
        self.linear = RecursiveLeastSquares(self.global_frames * p.n_joints + 1, p.horizon * p.n_joints,
                                            delta=self.global_delta)

    def _clear_sequence(self) -> None:
        super()._clear_sequence()
        self._long = np.zeros((self.global_frames, self.params.n_joints))
        self._long_fill = 0

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        frame = self._as_frame(x)
        if frame is not None:  # a missing frame clears the window in the parent's `_clear_sequence`
            if self._long_fill == 0:
                self._long[...] = frame
            else:
                self._long[1:] = self._long[:-1]
                self._long[0] = frame
            self._long_fill = min(self._long_fill + 1, self.global_frames)
        return super().step(x, learn)

    def _global_features(self, reg: np.ndarray) -> np.ndarray:
        """The global read-out sees the last `global_frames` frames, not the neurons' shorter regressor."""
        return window_features(self._long, self.global_frames)

    def state(self) -> Any:
        raise CandidateError("a research candidate cannot be saved")


def long_model(params: Any, seed: int, global_frames: int = GLOBAL_FRAMES, global_delta: float = GLOBAL_DELTA,
               **changes: Any) -> LongReadoutPredictor:
    """The long-read-out model for the experiments' `params` (only horizon and joints are taken)."""

    return LongReadoutPredictor(local_linear_params(params, **changes), seed, global_frames, global_delta)


def gate(model: Any, params: Any, **changes: Any) -> Predictor:
    """`model` behind the default's gate with `changes` to its settings."""

    return gated(model, params, **changes)


def _sharp_blend(members: Mapping[str, Any], params: Any, power: float) -> Any:
    """A `research.blend.BlendedPredictor` whose weights go as 1 / MSE^power (1: the blend's own)."""

    class SharpBlend(BlendedPredictor):
        def running_mse(self) -> np.ndarray:
            return super().running_mse() ** power

    return SharpBlend(members, params)


def experts(params: Any, seed: int, decay: float = 0.99, members: tuple[str, ...] = ("llm", "linear", "rls"),
            model: Mapping[str, Any] | None = None, power: float = 1.0) -> Predictor:
    """The neurons' model, the direct linear model and RLS-AR, blended per step by recent squared error
    (weights 1 / MSE^power)."""

    hp = hierarchy_params(params)
    make = {"llm": lambda: long_model(params, seed, **(model or {})),
            "linear": lambda: DirectLinear(DirectLinearParams(horizon=hp.horizon, joints=hp.n_joints)),
            "rls": lambda: RLSAutoregressive(RLSParams(), hp.horizon, hp.n_joints)}
    return _sharp_blend({m: make[m]() for m in members}, BlendParams(decay=decay, horizon=hp.horizon), power)


class ChooseExperts(BlendedPredictor):
    """Per horizon step, the one member with the lowest running squared error, kept until another is
    better by the fraction `hysteresis` (so the output does not flicker between near-equal experts).
    With a hold-last member an expert is switched off wherever holding still has done better.
    `blend_below`: instead of choosing, the 1 / MSE blend of the members at least as good as the
    member named `blend_below` (itself included). `track`: the member whose MSE is scaled by its
    network's winning neuron's own read-out error against the network's mean, so a neuron with a good
    track record keeps the network in charge. `favour`: member name -> factor on its MSE."""

    def __init__(self, members: Mapping[str, Any], params: Any, hysteresis: float = 0.1,
                 blend_below: str | None = None, track: str | None = None,
                 favour: Mapping[str, float] | None = None, average: bool = False, power: float = 1.0) -> None:
        if not 0.0 <= hysteresis < 1.0:
            raise CandidateError(f"hysteresis must be in [0, 1), got {hysteresis}")
        for name in (blend_below, track, *(favour or {})):
            if name is not None and name not in members:
                raise CandidateError(f"{name!r} is not a member ({', '.join(members)})")
        self.hysteresis = hysteresis
        self.blend_below = blend_below
        self.track = track
        self.favour = dict(favour or {})
        self.average, self.power = average, power
        super().__init__(members, params)
        self._choice = np.full(self.horizon, -1)

    def effective_mse(self) -> np.ndarray:
        """(members, horizon) running MSE with the track record and the favours applied."""
        mse = self.running_mse()
        for name, factor in self.favour.items():
            mse[self.names.index(name)] *= factor
        if self.track is not None:
            mse[self.names.index(self.track)] *= self._track_factor(self.members[self.track])
        return mse

    @staticmethod
    def _track_factor(model: Any) -> float:
        """Winning neuron's read-out MSE / the visit-weighted mean over neurons, within [1/4, 4]."""

        model = inner_model(model)
        reg = getattr(model, "_last_reg", None)
        net = model.pgwr
        known = np.isfinite(net.readout_mse)
        if reg is None or not known.any():
            return 1.0
        own = net.readout_mse[net.match_unchecked(reg)]
        if not np.isfinite(own):
            return 1.0
        visits = net._visits[:net.n_neurons][known]
        mean = float(np.average(net.readout_mse[known], weights=np.maximum(visits, 1e-9)))
        return float(np.clip(own / max(mean, 1e-12), 0.25, 4.0))

    def _blend(self, preds: np.ndarray) -> np.ndarray | None:
        avail = np.isfinite(preds).all(axis=2)
        if not avail.any():
            return None
        mse = np.where(avail, self.effective_mse(), np.nan)
        if self.average:
            return self._weighted(preds, avail, mse)
        if self.blend_below is not None:
            ref = mse[self.names.index(self.blend_below)]
            keep = avail & ~(mse > ref[None, :])  # NaN reference or MSE: kept
            w = self.weight_matrix(keep)
            return np.einsum("mh,mhj->hj", w, np.where(keep[:, :, None], preds, 0.0))
        steps = np.arange(self.horizon)
        ranked = np.where(np.isfinite(mse), mse, np.inf)
        best = ranked.argmin(axis=0)
        none_scored = ~np.isfinite(ranked).any(axis=0)
        best[none_scored] = avail[:, none_scored].argmax(axis=0)  # the first member that predicts
        cur = self._choice
        cur_mse = np.where(cur >= 0, ranked[np.maximum(cur, 0), steps], np.inf)
        better = ranked[best, steps] < (1.0 - self.hysteresis) * cur_mse
        switch = (cur < 0) | ~avail[np.maximum(cur, 0), steps] | better
        self._choice = np.where(switch, best, cur)
        return preds[self._choice, steps]


    def _weighted(self, preds: np.ndarray, avail: np.ndarray, mse: np.ndarray) -> np.ndarray:
        """Weights 1 / MSE^power over the available members; an unscored one gets the scored ones' mean."""
        known = np.isfinite(mse)
        n_known = known.sum(axis=0)
        mean = np.where(known, mse, 0.0).sum(axis=0) / np.maximum(n_known, 1)
        mse = np.where(known, mse, np.where(n_known > 0, mean, 1.0)[None, :])
        inv = np.where(avail, np.maximum(mse, self.params.floor) ** -self.power, 0.0)
        w = inv / inv.sum(axis=0, keepdims=True)
        return np.einsum("mh,mhj->hj", w, np.where(avail[:, :, None], preds, 0.0))


def members(params: Any, seed: int, names: tuple[str, ...] = ("llm", "linear", "rls", "hold"),
            member_gate: Mapping[str, float] | None = None, model: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The experts by name, each behind its own gate with `member_gate`'s settings if given (hold never)."""

    hp = hierarchy_params(params)
    make = {"llm": lambda: long_model(params, seed, **(model or {})),
            "linear": lambda: DirectLinear(DirectLinearParams(horizon=hp.horizon, joints=hp.n_joints)),
            "rls": lambda: RLSAutoregressive(RLSParams(), hp.horizon, hp.n_joints),
            "hold": lambda: HoldLast(hp.horizon, hp.n_joints)}
    out = {m: make[m]() for m in names}
    if member_gate is not None:
        out = {m: e if m == "hold" else gate(e, params, **member_gate) for m, e in out.items()}
    return out


def choose(params: Any, seed: int, decay: float = 0.99, names: tuple[str, ...] = ("llm", "linear", "rls", "hold"),
           member_gate: Mapping[str, float] | None = None, **kw: Any) -> ChooseExperts:
    """`ChooseExperts` over `members` (running-error decay `decay`)."""

    hp = hierarchy_params(params)
    return ChooseExperts(members(params, seed, names, member_gate), BlendParams(decay=decay, horizon=hp.horizon),
                         **kw)


def experts_gated(params: Any, seed: int, member_gate: Mapping[str, float], decay: float = 0.99) -> Predictor:
    """The 1 / MSE blend of the neurons' model, direct linear and RLS-AR, each behind its own gate."""

    hp = hierarchy_params(params)
    return BlendedPredictor(members(params, seed, ("llm", "linear", "rls"), member_gate),
                            BlendParams(decay=decay, horizon=hp.horizon))


def _cand_long(params: Any, seed: int) -> Predictor:
    return gate(long_model(params, seed), params)


def _cand_long_fast(params: Any, seed: int) -> Predictor:
    return gate(long_model(params, seed), params, **FAST_GATE)


def _cand_experts(params: Any, seed: int) -> Predictor:
    return gate(experts(params, seed), params, **EXPERTS_GATE)


def _cand_gated_experts(params: Any, seed: int) -> Predictor:
    return gate(experts_gated(params, seed, EXPERTS_GATE), params, **FAST_GATE)


def _cand_sharp_experts(params: Any, seed: int) -> Predictor:
    hp = hierarchy_params(params)
    experts = ChooseExperts(members(params, seed, ("llm", "linear", "rls"), EXPERTS_GATE),
                            BlendParams(horizon=hp.horizon), average=True, power=SHARP_POWER)
    return gate(experts, params, **FAST_GATE)


CANDIDATES = {
    "cand_long": (_cand_long, "candidate: default, 12-frame global read-out"),
    "cand_long_fast": (_cand_long_fast, "candidate: 12-frame read-out, faster gate"),
    "cand_experts": (_cand_experts, "candidate: gated experts by recent error"),
    "cand_gated_experts": (_cand_gated_experts, "candidate: experts each behind a gate, blended, gated"),
    "cand_sharp_experts": (_cand_sharp_experts, "candidate: gated experts, weights 1 / MSE^16, gated"),
}


def register_all() -> None:
    """Register every candidate once (importing this module does)."""
    for name, (factory, label) in CANDIDATES.items():
        if name not in RESEARCH.names():
            RESEARCH.register(name, factory, label)


register_all()
