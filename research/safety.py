"""Round 4 of the default's tuning (`research/tuning.py`): cheaper ways than a gate per expert to keep the
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

from gwr_predictor.default_predictor import Experts, GatedPredictor, GateParams, make_default
from gwr_predictor.predictors.baselines import HoldLast, observation

#: The network's settings `experiment tune` chose for the gated network, which every round-4 variant
#: used (the default's own network keeps rate 0.1 and recruit_surprise 9: `settings.EXPERT_NETWORK`).
TUNED_NETWORK = {"network.rate": 0.2, "network.recruit_surprise": 6.0}
#: Round 3's member gates (the default before round 4): a fixed ~20-frame memory.
R3 = {"expert_gate.decay": 0.95, "expert_gate.warmup": 0, **TUNED_NETWORK}


def default(params: Any, seed: int, settings: Mapping[str, Any] | None = None) -> GatedPredictor:
    return make_default(params.horizon, params.n_joints, seed, dict(settings or {}))


def rebuilt(params: Any, seed: int, settings: Mapping[str, Any] | None = None,
            member_gates: bool | tuple[str, ...] = True, hold: bool = False, last_gate: bool = True,
            own_gate: tuple[str, ...] = ()) -> Any:
    """The default (with `settings`) with its member gates (all, none or those named), a hold-last member
    and its last gate each optional; the members in `own_gate` behind the library's `GateParams()`."""
    made = default(params, seed, settings)
    experts = Experts(_members(made, params, member_gates, hold, own_gate), made.model.params)
    return GatedPredictor(experts, made.params) if last_gate else experts


def _members(made: GatedPredictor, params: Any, member_gates: bool | tuple[str, ...] = True, hold: bool = False,
             own_gate: tuple[str, ...] = ()) -> dict[str, Any]:
    """`made`'s experts, each behind its gate or not, with a hold-last member and other gates (see `rebuilt`)."""
    gated = made.model.names if member_gates is True else member_gates or ()
    members = {n: m if n in gated else m.model for n, m in made.model.members.items()}
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
    model = AgreeingExperts(_members(made, params, member_gates), made.model.params, c, weighted)
    if not last_gate:
        return model
    return GatedPredictor(model, made.params if last_gate is True else dataclasses.replace(made.params, **last_gate))


class Echo:
    """A gated member's last raw prediction again, so a second gate can judge the same model."""

    def __init__(self, gate: GatedPredictor) -> None:
        self.gate = gate

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        diff = self.gate._out_diff
        return None if diff is None or self.gate._last is None else self.gate._last + diff

    def reset_sequence(self) -> None:
        """The gate it echoes resets the model."""


def two_gates(params: Any, seed: int, slow: Mapping[str, Any], settings: Mapping[str, Any] | None = None) -> Any:
    """Every member behind its gate and, as a second member, behind a `slow` one; the experts weight all."""
    made = default(params, seed, settings)
    members = dict(made.model.members)
    gate = GateParams(horizon=params.horizon, joints=params.n_joints, **slow)
    for n in list(members):
        members[f"{n}_slow"] = GatedPredictor(Echo(members[n]), gate, hold_when_silent=False)
    return GatedPredictor(Experts(members, made.model.params), made.params)
