"""The predictors' settings as flat, named parameters, each declared once by the ParamSpec its
dataclass validates with.

- the gated network (`gated_llm_gwr`): the network's own settings, its GWR step's (`gwr.*`) and its
  gate's (`gate.*`);
- the default (`gwr_experts`): the network's settings under `network.` (`EXPERT_NETWORK` where its
  defaults differ from the gated network's), the snippet memory's under `memory.`, the long snippet
  memory's under `long_memory.` (`LONG_MEMORY` where its defaults differ from the snippet memory's;
  `long_memory.enabled` false leaves it out), the weighting's under `experts.`, where the memory's
  recognition lifts the gates under `recognition.`, the gate in front of each expert under
  `expert_gate.`, the last gates, one on each weighting, under `gate.` and the interval stated with every
  prediction (`spread.py`) under `spread.`. The two linear experts
  run with the tuned settings of the `rls_ar` and `linear` baselines.

The learner node declares exactly these (under `<predictor>.`) when it runs one; the horizon and the
joints are the node's, not the predictor's. The GWR step's activation threshold is not among them:
the network inserts by `insertion_scale` x the data's own motion scale, which cancels any a_T (see
`predictor.py`), so a parameter for it would have no effect.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from gwr_predictor.default_predictor.experts import EXPERTS_SPECS, ExpertsParams
from gwr_predictor.default_predictor.gate import GATE_SPECS, GateParams
from gwr_predictor.default_predictor.memory import MEMORY_SPECS, MemoryParams
from gwr_predictor.default_predictor.params import (
    LOCAL_LINEAR_SPECS,
    DefaultPredictorError,
    LocalLinearParams,
    default_gwr,
)
from gwr_predictor.default_predictor.recognition import RECOGNITION_SPECS, RecognitionParams
from gwr_predictor.default_predictor.spread import SPREAD_SPECS, SpreadParams
from gwr_predictor.learning.params import GWR_SPECS
from gwr_predictor.parameters.spec import ParamSpec

#: Set by the node (or `make_default`'s arguments), not by the predictor's settings.
FROM_THE_DATA = ("horizon", "n_joints", "joints")
#: The gate in front of each expert: it opens on little evidence, with a memory of ~20 scored frames at
#: first, so an expert that has just become good is heard within a performance, lengthening to ~200 over
#: the first 400, so a settled expert is not shrunk by chance runs of error (chosen on the tuning set,
#: docs/experiments.md).
EXPERT_GATE = {"decay": 0.995, "warmup": 400, "warmup_decay": 0.95, "prior": 0.001, "confidence": 1.0}
#: The last gates, one on each weighting (`recognition.py`): the gated network's, opening on less evidence
#: (prior 0.001, a bound of half a standard error), with a memory of ~33 scored frames and a short memory
#: that judges each step by its own record. They keep the default within 1 % of holding the pose on real
#: clips where the experts alone were up to 4 % above, and on a take learned after others, where the
#: memory recognises the motion but the experts ungated are worse than holding at the longer steps
#: (chosen on the tuning set, `docs/tuning.md` rounds 5 and 6).
OUTER_GATE = {"decay": 0.97, "fast_step": 0, "prior": 0.001, "confidence": 0.5}
#: Where the default's network expert differs from the gated network's settings (`LocalLinearParams()`,
#: chosen by `experiment tune` for the gated network): chosen on the default's own tuning set
#: (`docs/tuning.md`: rate and recruit_surprise in round 4, equal where motion repeats and 14 % lower
#: MSE on the demonstrator check; a 6-frame regressor in round 8, a better cold start and demonstrator check).
EXPERT_NETWORK = {"rate": 0.1, "recruit_surprise": 9.0, "order": 6}
#: Where the second snippet memory differs from the first: its key holds the pose's changes over up to 16
#: frames (1.6 s at 10 fps, against 0.8 s), weighs them less against the pose and fits its neighbours
#: only nearer the motion it knows. Two memories that recognise a movement by different spans of its past
#: are right on different frames, and the experts' weighting hears whichever is right now (round 12 of
#: `docs/tuning.md`: lower pooled error on the repetition streams and a better cold start).
LONG_MEMORY = {"longest_lag": 16, "velocity_weight": 0.15, "fit_radius": 2.0}
#: Whether the default runs the long snippet memory (false: the four experts of round 11 and before).
LONG_MEMORY_ENABLED = ParamSpec("long_memory.enabled", True, "long snippet memory: among the experts (false: the "
                                "other four without it)")
#: The GWR step's settings the default's network uses (not the activation threshold: see above).
GWR_USED = ("firing_threshold", "eps_b", "eps_n", "rho_b", "rho_n", "kappa", "max_edge_age", "max_neurons")


def network_specs() -> tuple[ParamSpec, ...]:
    """The local-linear network's settings, flat: its own names and `gwr.<name>`."""
    own = [s for name, s in LOCAL_LINEAR_SPECS.items() if name not in FROM_THE_DATA]
    gwr = default_gwr()
    steps = [dataclasses.replace(GWR_SPECS[name], name=f"gwr.{name}", default=_flat(getattr(gwr, name)),
                                 description=f"GWR step: {GWR_SPECS[name].description}") for name in GWR_USED]
    return (*own, *steps)


def parameter_specs() -> tuple[ParamSpec, ...]:
    """Every setting of the gated network, flat: the network's and `gate.<name>`."""
    return (*network_specs(), *_prefixed("gate", GATE_SPECS, "gate"))


def experts_parameter_specs() -> tuple[ParamSpec, ...]:
    """Every setting of the default, flat (see the module docstring)."""
    network = {s.name: s for s in network_specs()}
    return (*_prefixed("network", network, "network", EXPERT_NETWORK),
            *_prefixed("memory", MEMORY_SPECS, "snippet memory"),
            LONG_MEMORY_ENABLED,
            *_prefixed("long_memory", MEMORY_SPECS, "long snippet memory", LONG_MEMORY),
            *_prefixed("experts", EXPERTS_SPECS, "weighting"),
            *_prefixed("recognition", RECOGNITION_SPECS, "recognition"),
            *_prefixed("expert_gate", GATE_SPECS, "each expert's gate", EXPERT_GATE),
            *_prefixed("gate", GATE_SPECS, "the last gates", OUTER_GATE),
            *_prefixed("spread", SPREAD_SPECS, "the interval of every prediction"))


def _prefixed(prefix: str, specs: Mapping[str, ParamSpec], what: str,
              defaults: Mapping[str, Any] | None = None) -> list[ParamSpec]:
    return [dataclasses.replace(s, name=f"{prefix}.{name}", description=f"{what}: {s.description}",
                                default=(defaults or {}).get(name, s.default))
            for name, s in specs.items() if name not in FROM_THE_DATA]


def _flat(value: Any) -> Any:
    return 0 if value is None else value  # max_neurons: None (unlimited) is 0 as a parameter


def _grouped(settings: Mapping[str, Any], specs: tuple[ParamSpec, ...], what: str) -> dict[str, dict[str, Any]]:
    """Flat `settings`, checked against `specs`, grouped by their first name part ('' for unprefixed)."""
    known = {s.name: s for s in specs}
    unknown = sorted(set(settings) - set(known))
    if unknown:
        raise DefaultPredictorError(f"unknown settings of {what} {unknown}; known: {', '.join(known)}")
    groups: dict[str, dict[str, Any]] = {}
    for name, value in settings.items():
        known[name].check(value)
        group, _, key = name.partition(".")
        if key:
            groups.setdefault(group, {})[key] = value
        else:
            groups.setdefault("", {})[name] = value
    return groups


def _network(groups: Mapping[str, Mapping[str, Any]], horizon: int, joints: int) -> LocalLinearParams:
    gwr = {k: None if k == "max_neurons" and v == 0 else v for k, v in groups.get("gwr", {}).items()}
    return LocalLinearParams(horizon=horizon, n_joints=joints, gwr=default_gwr().replace(**gwr), **groups.get("", {}))


def from_settings(settings: Mapping[str, Any], horizon: int, joints: int) -> tuple[LocalLinearParams, GateParams]:
    """The gated network's model and gate parameters for flat `settings` (any subset of `parameter_specs()`;
    missing ones keep their defaults). Unknown names or bad values raise DefaultPredictorError naming them."""
    groups = _grouped(settings, parameter_specs(), "the gated network")
    return _network(groups, horizon, joints), GateParams(horizon=horizon, joints=joints, **groups.get("gate", {}))


def from_experts_settings(settings: Mapping[str, Any], horizon: int, joints: int
                          ) -> tuple[LocalLinearParams, MemoryParams, MemoryParams | None, ExpertsParams,
                                     RecognitionParams, GateParams, GateParams, SpreadParams]:
    """The default's parts' parameters for flat `settings` (any subset of `experts_parameter_specs()`):
    network, memory, long memory (None: left out), weighting, recognition, each expert's gate, the last gates,
    the interval of every prediction."""
    groups = _grouped(settings, experts_parameter_specs(), "the default predictor")
    network = {**EXPERT_NETWORK, **groups.get("network", {})}
    long_memory = {**LONG_MEMORY, **groups.get("long_memory", {})}
    enabled = long_memory.pop("enabled", LONG_MEMORY_ENABLED.default)
    return (_network(_grouped(network, network_specs(), "the network"), horizon, joints),
            MemoryParams(horizon=horizon, n_joints=joints, **groups.get("memory", {})),
            MemoryParams(horizon=horizon, n_joints=joints, **long_memory) if enabled else None,
            ExpertsParams(horizon=horizon, n_joints=joints, **groups.get("experts", {})),
            RecognitionParams(**groups.get("recognition", {})),
            GateParams(horizon=horizon, joints=joints, **{**EXPERT_GATE, **groups.get("expert_gate", {})}),
            GateParams(horizon=horizon, joints=joints, **{**OUTER_GATE, **groups.get("gate", {})}),
            SpreadParams(horizon=horizon, joints=joints, **groups.get("spread", {})))

