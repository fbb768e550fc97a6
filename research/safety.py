"""Round 4 of the default's tuning (`research/tuning.md`): cheaper ways than a gate per expert to keep the
experts from doing worse than holding the pose. Prototypes measured on the tuning set; none is the default.

- `rebuilt`: the default with its member gates, a hold-last member and its last gate each optional;
- `AgreeingExperts`: the weighted prediction shrunk towards the newest pose by how much the members
  disagree (a Wiener factor |d|^2 / (|d|^2 + c var) per step: trust where the experts agree);
- `two_gates`: every member behind two gates, a short and a long memory, the experts weighting all.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from gwr_predictor.default_predictor import Experts, GatedPredictor, GateParams, RecognitionSwitch, View, make_default
from gwr_predictor.learning.pending import PendingPredictions
from gwr_predictor.predictors.baselines import HoldLast, observation

#: Each round's default in today's terms: what it set, then every later round's change undone.
#: Round 11's default: four experts, one snippet memory (round 12 added the long snippet memory).
R11 = {"long_memory.enabled": False}
#: Round 10's default: the snippet memory averaged its 3 nearest snippets everywhere (round 11: where the
#: motion is familiar, 32 fitted by locally weighted ridge regression).
R10 = {"memory.fit_k": 0, **R11}
#: Round 9's default: the ungated weighting's record over every prediction alike, forgetting at 0.98, its
#: weights at the experts' power (round 10: predictions outside a recognised movement weigh 0.1, forgetting
#: at 0.995, power 3).
R9 = {"recognition.outside_weight": 1.0, "recognition.decay": 0.98, "recognition.power": 0.0, **R10}
#: Round 8's default: also no trust lent to the ungated weighting's longer steps at a movement's onset
#: (round 9: 0.75 of step 1's).
R8 = {"recognition.onset_trust": 0.0, **R9}
#: Round 7's default: also the network's regressor over 4 frames (round 8: 6).
R7 = {"network.order": 4, **R8}
#: Round 6's default: also the memory's key over the changes of 1, 2 and 4 frames (round 7 added 8).
R6 = {"memory.longest_lag": 4, **R7}
#: Round 5's default: also one last gate over whichever weighting is returned, its bound one standard
#: error (the `D:` names of round 5 were measured with these).
R5 = {"recognition.separate_gates": False, "gate.confidence": 1.0, **R6}
#: Rounds 3 and 4 came before round 5: no recognition switch, the last gate's ~100-frame memory capped
#: by its 1-step record, its bound one standard error.
BEFORE_ROUND5 = {"recognition.radius": 0.0, "gate.decay": 0.99, "gate.fast_step": 1, "gate.confidence": 1.0, **R6}
#: The network's settings `experiment tune` chose for the gated network, which every round-4 variant
#: used (the default's own network keeps rate 0.1 and recruit_surprise 9: `DefaultParams().network`).
TUNED_NETWORK = {"network.rate": 0.2, "network.recruit_surprise": 6.0, **BEFORE_ROUND5}
#: Round 3's member gates (the default before round 4): a fixed ~20-frame memory.
R3 = {"expert_gate.decay": 0.95, "expert_gate.warmup": 0, **TUNED_NETWORK}


def default(params: Any, seed: int, settings: Mapping[str, Any] | None = None) -> RecognitionSwitch:
    return make_default(params.horizon, params.n_joints, seed, dict(settings or {}))


def experts_of(made: RecognitionSwitch) -> Experts:
    """The default's weighting of its gated members (behind its recognition switch)."""
    return made.experts


def rebuilt(params: Any, seed: int, settings: Mapping[str, Any] | None = None,
            member_gates: bool | tuple[str, ...] = True, hold: bool = False, last_gate: bool = True,
            own_gate: tuple[str, ...] = ()) -> Any:
    """The default's gated experts (with `settings`, without the recognition switch) with their member gates
    (all, none or those named), a hold-last member and its last gate each optional; the members in
    `own_gate` behind the library's `GateParams()`."""
    made = default(params, seed, settings)
    experts = Experts(_members(made, params, member_gates, hold, own_gate), experts_of(made).params)
    return GatedPredictor(experts, made.gate.params) if last_gate else experts


def ungated(params: Any, seed: int, settings: Mapping[str, Any] | None = None) -> Any:
    """The default's own ungated model: its experts (with `settings`) weighted without any gate."""
    return rebuilt(params, seed, settings, member_gates=False, last_gate=False)


def _members(made: RecognitionSwitch, params: Any, member_gates: bool | tuple[str, ...] = True, hold: bool = False,
             own_gate: tuple[str, ...] = ()) -> dict[str, Any]:
    """`made`'s experts, each behind its gate or not, with a hold-last member and other gates (see `rebuilt`)."""
    gated = experts_of(made).names if member_gates is True else member_gates or ()
    members = {n: m if n in gated else m.model for n, m in experts_of(made).members.items()}
    for n in own_gate:
        members[n] = GatedPredictor(members[n].model, GateParams(horizon=params.horizon, joints=params.n_joints),
                                    hold_when_silent=False)
    if hold:
        members["hold"] = HoldLast(params.horizon, params.n_joints)
    return members


class AgreeingExperts(Experts):
    """`Experts` whose weighted prediction is shrunk towards the newest pose where the members disagree."""

    def __init__(self, members: Mapping[str, Any], params: Any, c: float, weighted: bool = True) -> None:
        super().__init__(members, params)
        self.c, self.weighted = c, weighted
        self._now: np.ndarray | None = None

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        self._now = observation(x, self.params.n_joints)
        return super().step(x, learn)

    def _combine(self, preds: np.ndarray) -> np.ndarray | None:
        avail = np.isfinite(preds).all(axis=2)
        if not avail.any():
            return None
        w = self.weights(avail) if self.weighted else avail / np.maximum(avail.sum(axis=0, keepdims=True), 1)
        p = np.where(avail[:, :, None], preds, 0.0)
        mean = np.einsum("mh,mhj->hj", w, p)
        if self._now is None:
            return mean
        var = np.einsum("mh,mhj->h", w, (p - mean) ** 2)
        d = mean - self._now
        d2 = np.einsum("hj,hj->h", d, d)
        return self._now + (d2 / np.maximum(d2 + self.c * var, 1e-12))[:, None] * d


def agreeing(params: Any, seed: int, c: float, settings: Mapping[str, Any] | None = None,
             member_gates: bool = False, last_gate: bool | dict[str, Any] = False, weighted: bool = True) -> Any:
    made = default(params, seed, settings)
    model = AgreeingExperts(_members(made, params, member_gates), experts_of(made).params, c, weighted)
    if not last_gate:
        return model
    gate = made.gate.params
    return GatedPredictor(model, gate if last_gate is True else dataclasses.replace(gate, **last_gate))


def two_gates(params: Any, seed: int, slow: Mapping[str, Any], settings: Mapping[str, Any] | None = None) -> Any:
    """Every member behind its gate and, as a second member, behind a `slow` one; the experts weight all."""
    made = default(params, seed, settings)
    members = dict(experts_of(made).members)
    gate = GateParams(horizon=params.horizon, joints=params.n_joints, **slow)
    for n in list(members):
        members[f"{n}_slow"] = GatedPredictor(View(members[n].ungated), gate, hold_when_silent=False)
    return GatedPredictor(Experts(members, experts_of(made).params), made.gate.params)


class BlendedSwitch(RecognitionSwitch):
    """Where the memory recognises the motion, the gated and the ungated weighted predictions weighted per
    step by 1 / MSE^power over the recognised frames only (decay per scored frame); elsewhere the gated."""

    def __init__(self, experts: Experts, params: Any, decay: float, power: float) -> None:
        super().__init__(experts, params)
        h, j = experts.params.horizon, experts.params.n_joints
        self.decay, self.power = decay, power
        self.sse = np.zeros((2, h))
        self.weight = np.zeros((2, h))
        self._pending = PendingPredictions(h, j, (2,))
        self._t = 0

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        obs = observation(x, self.experts.params.n_joints)
        due, valid = self._pending.take(self._t)
        if obs is not None and valid.any():
            err = np.mean((due - obs) ** 2, axis=2)
            ok = valid & np.isfinite(err)
            d = np.where(ok, self.decay, 1.0)
            self.sse = self.sse * d + np.where(ok, err, 0.0)
            self.weight = self.weight * d + ok
        gated = self.experts.step(x, learn)
        ungated = self.ungated.step(x, learn)
        t = self._t
        self._t += 1
        if gated is None or ungated is None or not self.recognises():
            return gated
        both = np.stack([gated, ungated])
        self._pending.file(t, both)
        self.recognised += 1
        known = (self.weight > 0).all(axis=0)  # per step: both scored (else equal weights)
        mse = np.maximum(np.where(known, self.sse / np.where(known, self.weight, 1.0), 1.0), 1e-6)
        w = (mse.min(axis=0, keepdims=True) / mse) ** self.power
        w /= w.sum(axis=0, keepdims=True)
        return np.einsum("mh,mhj->hj", w, both)

    def reset_sequence(self) -> None:
        super().reset_sequence()
        self._pending.drop()


def blended(params: Any, seed: int, decay: float, power: float = 4.0,
            settings: Mapping[str, Any] | None = None) -> GatedPredictor:
    made = default(params, seed, settings)
    return GatedPredictor(BlendedSwitch(made.experts, made.params, decay, power), made.gate.params)

