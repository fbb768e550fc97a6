"""The one predictor registry: every online predictor of the package under one name.

The same names are used everywhere a user picks a predictor: the learner node's `predictor`
parameter, `gwr-predictor pretrain --predictor`, `gwr-predictor evaluate --methods` and the
experiments' method lists, and the reports' rows. A name maps to a factory `(params, seed) -> fresh
predictor` (the `Predictor` protocol), a label for tables and, for the predictors that can be saved,
a checkpoint loader; those are the `learner_names()` the node and `pretrain` accept.

Built in: the baselines `hold`, `const_velocity`, `rls_ar`, `linear` (direct multi-step linear
model), the paper's `hierarchy` (GWR1 -> GWR2 -> P-GWR), `gated_llm_gwr` (the local-linear P-GWR
behind a confidence gate) and the default `gwr_experts` (that network, two snippet memories and the
two linear models, each behind a gate, weighted per step by their recent errors, behind a last gate).
`register` adds one: the research part of the repository (research/, not installed) registers its
ablations and blends this way.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.learning.protocol import Predictor
from gwr_predictor.parameters.spec import ParamSpec
from gwr_predictor.predictors.errors import PredictorError

#: (settings, seed) -> a fresh predictor; settings are None (the defaults), a flat mapping of the
#: predictor's own parameters (`Entry.settings()`, plus `horizon` and `n_joints`) or, for the
#: experiments, a `HierarchyParams` (from which a predictor takes what it uses).
Factory = Callable[[Any, int], Predictor]
#: checkpoint path -> the saved predictor (a CheckpointError with `kind_mismatch` if the file holds another).
Loader = Callable[[str | os.PathLike[str]], Predictor]


#: () -> the predictor's own parameters, flat (imports deferred like the factories').
Settings = Callable[[], tuple[ParamSpec, ...]]
#: Parameters that are the node's or the data's, not a predictor's own.
DATA_PARAMETERS = ("horizon", "n_joints")


@dataclass(frozen=True)
class Entry:
    """One registered predictor: its factory, its label in tables, if it can be saved its loader, and
    its own parameters (what the learner node declares when it runs it)."""

    name: str
    factory: Factory
    label: str
    loader: Loader | None = None
    settings: Settings = tuple


_REGISTRY: dict[str, Entry] = {}


def register(name: str, factory: Factory, label: str | None = None, loader: Loader | None = None,
             settings: Settings = tuple) -> None:
    """Make `name` available to the node, pretrain, evaluate and the experiments; names are unique."""
    if not name.isidentifier():
        raise GwrPredictorError(f"predictor name {name!r} must be an identifier (letters, digits, '_')")
    if name in _REGISTRY:
        raise GwrPredictorError(f"predictor {name!r} is already registered")
    _REGISTRY[name] = Entry(name, factory, label or name, loader, settings)


def entry(name: str) -> Entry:
    try:
        return _REGISTRY[name]
    except KeyError:
        raise PredictorError(f"unknown predictor {name!r}; choose from {', '.join(_REGISTRY)}") from None


def names() -> tuple[str, ...]:
    """Every registered name, in registration order (baselines first)."""
    return tuple(_REGISTRY)


predictor_names = names  # the name exported at the package's top level


#: What the arm_predictor node, pretrain and demo.sh run unless told otherwise (`-p predictor:=...`):
#: the gated experts (registered below); `evaluate` and `experiment real` always score it and name it
#: (`default_method`).
DEFAULT_PREDICTOR = "gwr_experts"


def default_name() -> str:
    """The learner node's default predictor (one of `learner_names()`)."""
    return DEFAULT_PREDICTOR


def learner_names() -> tuple[str, ...]:
    """The product's predictors that can be saved and loaded: what the learner node and `pretrain` accept."""
    return tuple(n for n in PRODUCT if _REGISTRY[n].loader is not None)


def label(name: str) -> str:
    return entry(name).label


def make_predictor(name: str, params: Any = None, seed: int = 0) -> Predictor:
    """A fresh predictor `name`: `params` None (defaults), a flat mapping of its settings (with `horizon`
    and `n_joints`), or a `HierarchyParams` (the experiments' shared settings)."""
    return entry(name).factory(params, seed)


def settings_from_parameters(name: str, flat: Mapping[str, Any], joints: int = 8) -> dict[str, Any]:
    """The settings of predictor `name` among the learner node's flat parameters (its own as
    '<name>.<setting>', the node's `horizon`), as `make_predictor` takes them."""
    prefix = f"{name}."
    settings = {key[len(prefix):]: value for key, value in flat.items() if key.startswith(prefix)}
    settings.update(horizon=flat.get("horizon", 6), n_joints=joints)
    return settings


def hierarchy_params(params: Any) -> Any:
    """`HierarchyParams` for a factory's `params` (None, a flat mapping or one already)."""
    from gwr_predictor.learning.params import HierarchyParams

    if params is None:
        return HierarchyParams()
    return HierarchyParams.from_flat(params) if isinstance(params, Mapping) else params


def load_predictor(name: str, path: str | os.PathLike[str]) -> Predictor:
    """The predictor `name` saved at `path`; a CheckpointError with `kind_mismatch` if the file holds another
    kind or blend."""
    e = entry(name)
    if e.loader is None:
        raise PredictorError(f"predictor {name!r} cannot be loaded from a checkpoint; "
                                    f"choose from {', '.join(learner_names())}")
    return e.loader(path)


# --- the built-in predictors (imports deferred: choosing `hold` must not load the GWR code) -------
#: The baselines that state an interval with every prediction: the default's spread of their own residuals
#: (`default_predictor.spread.WithSpread`), so that the reports compare widths at equal coverage.
SPREADING_BASELINES = ("hold", "rls_ar")


def _baseline(name: str) -> Factory:
    def make(params: Any, seed: int) -> Predictor:
        from gwr_predictor.predictors.baselines import make_baselines

        hp = hierarchy_params(params)
        model = make_baselines(hp.horizon, hp.span)[name]
        if name not in SPREADING_BASELINES:
            return model  # type: ignore[return-value]
        from gwr_predictor.default_predictor.spread import SpreadParams, WithSpread

        return WithSpread(model, SpreadParams(horizon=hp.horizon, joints=hp.n_joints, groups=1))

    return make


def _hierarchy(params: Any, seed: int) -> Predictor:
    from gwr_predictor.learning.hierarchy import Hierarchy

    return Hierarchy(hierarchy_params(params), seed=seed)


def _hierarchy_settings() -> tuple[ParamSpec, ...]:
    from gwr_predictor.learning.params import hierarchy_parameter_specs

    return tuple(s for s in hierarchy_parameter_specs() if s.name not in DATA_PARAMETERS)


def _load_hierarchy(path: str | os.PathLike[str]) -> Predictor:
    from gwr_predictor.learning.hierarchy import Hierarchy

    return Hierarchy.load(path)


register("hold", _baseline("hold"), "hold last")
register("const_velocity", _baseline("const_velocity"), "constant velocity")
register("rls_ar", _baseline("rls_ar"), "RLS-AR")


def _linear(params: Any, seed: int) -> Predictor:
    from gwr_predictor.predictors.direct_linear import TUNED_LINEAR, DirectLinear

    hp = hierarchy_params(params)
    return DirectLinear(TUNED_LINEAR.replace(horizon=hp.horizon, joints=hp.n_joints))


register("linear", _linear, "direct linear (RLS)")
register("hierarchy", _hierarchy, "GWR hierarchy", _load_hierarchy, _hierarchy_settings)


# --- the default predictor and its network alone (beyond the paper) -------------------------------
def _made_by(maker: str) -> Factory:
    """A factory calling `gwr_predictor.default_predictor.<maker>(horizon, joints, seed, settings)`."""
    def make(params: Any, seed: int) -> Predictor:
        import gwr_predictor.default_predictor as default

        build = getattr(default, maker)
        if params is None:
            return build(seed=seed)
        if isinstance(params, Mapping):
            own = {k: v for k, v in params.items() if k not in DATA_PARAMETERS}
            return build(params.get("horizon", 6), params.get("n_joints", 8), seed, own)
        return build(params.horizon, params.n_joints, seed)  # HierarchyParams

    return make


def _settings_of(specs: str) -> Settings:
    def settings() -> tuple[ParamSpec, ...]:
        from gwr_predictor.default_predictor import settings as module

        return getattr(module, specs)()

    return settings


def gate_loader(wraps: str) -> Loader:
    """A loader of gated checkpoints that refuses a gate around another kind of model."""
    def load(path: str | os.PathLike[str]) -> Predictor:
        from gwr_predictor.default_predictor.gate import GatedPredictor
        from gwr_predictor.learning.checkpoint import CheckpointError

        gate = GatedPredictor.load(path)
        if gate.model.kind != wraps:
            raise CheckpointError(f"{path}: holds a gate around a {gate.model.kind!r}, expected a {wraps!r}",
                                  source=path, found=gate.model.kind, expected=wraps)
        return gate

    return load


def _load_default(path: str | os.PathLike[str]) -> Predictor:
    """The default saved at `path`; one saved with its last gate around the experts (before round 6 of
    the tuning) is upgraded, everything it learned kept (`RecognitionSwitch.upgraded`)."""
    from gwr_predictor.default_predictor.gate import GatedPredictor
    from gwr_predictor.default_predictor.recognition import RecognitionSwitch
    from gwr_predictor.learning.checkpoint import CheckpointError, read_checkpoint

    header, arrays = read_checkpoint(path, (RecognitionSwitch.kind, GatedPredictor.kind))
    if header["kind"] == RecognitionSwitch.kind:
        return RecognitionSwitch.from_state(header, arrays, path)
    if header.get("model_kind") not in (RecognitionSwitch.kind, "Experts"):
        raise CheckpointError(f"{path}: holds a gate around a {header.get('model_kind')!r}, expected the default's "
                              "experts", source=path, found=header.get("model_kind"), expected=RecognitionSwitch.kind)
    try:
        return RecognitionSwitch.upgraded(header, arrays)
    except (KeyError, ValueError, TypeError, IndexError) as exc:
        RecognitionSwitch._inconsistent(path, exc)


register("gated_llm_gwr", _made_by("make_gated_network"), "gated local-linear P-GWR",
         gate_loader("LocalLinearPredictor"), _settings_of("parameter_specs"))
register(DEFAULT_PREDICTOR, _made_by("make_default"), "GWR experts (default)",
         _load_default, _settings_of("experts_parameter_specs"))

#: The product's predictors: the ones registered above, whatever registers itself later (research/).
PRODUCT: tuple[str, ...] = tuple(_REGISTRY)
