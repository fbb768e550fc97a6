"""The one predictor registry: every online predictor of the product under one name, above both the
paper's model and the default.

The same names are used everywhere a user picks a predictor: the learner node's `predictor`
parameter, `gwr-predictor pretrain --predictor`, `gwr-predictor evaluate --methods` and the
experiments' method lists, and the reports' rows. A name maps to a factory `(params, seed) -> fresh
predictor` (the `Predictor` protocol), a label for tables and, for the predictors that can be saved,
a checkpoint loader and their own parameters; those are the `learner_names()` the node and `pretrain`
accept.

Built in: the baselines `hold`, `const_velocity`, `rls_ar`, `linear` (direct multi-step linear
model), the paper's `hierarchy` (GWR1 -> GWR2 -> P-GWR), `gated_llm_gwr` (the local-linear P-GWR
behind a confidence gate) and the default `gwr_experts` (`default_predictor/default.py`). A `Registry`
made with `parent=PRODUCT` adds names of its own beside these without changing the product's: the
research part of the repository (research/, not installed) keeps its ablations and blends so.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from gwr_predictor.default_predictor import (
    DefaultParams,
    DefaultPredictor,
    GatedNetworkParams,
    GatedPredictor,
    SpreadParams,
    WithSpread,
    make_default,
    make_gated_network,
)
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.hierarchy import Hierarchy
from gwr_predictor.learning.params import HierarchyParams
from gwr_predictor.learning.protocol import Predictor
from gwr_predictor.parameters import tree
from gwr_predictor.parameters.spec import ParamSpec
from gwr_predictor.predictors.baselines import make_baselines
from gwr_predictor.predictors.direct_linear import DirectLinear, DirectLinearParams
from gwr_predictor.predictors.errors import PredictorError

#: (settings, seed) -> a fresh predictor; settings are None (the defaults), a flat mapping of the
#: predictor's own parameters (`Entry.settings()`, plus `horizon` and `n_joints`) or, for the
#: experiments, a `HierarchyParams` (from which a predictor takes what it uses).
Factory = Callable[[Any, int], Predictor]
#: checkpoint path -> the saved predictor (a LearningError with `kind_mismatch` if the file holds another).
Loader = Callable[[str | os.PathLike[str]], Predictor]
#: Parameters that are the node's or the data's, not a predictor's own.
DATA_PARAMETERS = tree.FROM_THE_DATA
#: What the arm_predictor node, pretrain and demo.sh run unless told otherwise (`-p predictor:=...`);
#: `evaluate` and `experiment real` always score it and name it.
DEFAULT_PREDICTOR = "gwr_experts"


@dataclass(frozen=True)
class Entry:
    """One registered predictor: its factory, its label in tables, if it can be saved its loader, and
    the class of its settings tree, whose parameters the learner node declares when it runs it."""

    name: str
    factory: Factory
    label: str
    loader: Loader | None = None
    params: type | None = None

    def settings(self) -> tuple[ParamSpec, ...]:
        """The predictor's own parameters, flat: its settings tree's, without the data's shape (the node's)."""
        if self.params is None:
            return ()
        return tuple(s for s in tree.parameter_specs(self.params()) if s.name not in DATA_PARAMETERS)


class Registry:
    """Predictors by name; one made with a `parent` knows the parent's names too (its own first), and
    registering in it leaves the parent as it was."""

    def __init__(self, parent: Registry | None = None) -> None:
        self.parent = parent
        self._own: dict[str, Entry] = {}

    def register(self, name: str, factory: Factory, label: str | None = None, loader: Loader | None = None,
                 params: type | None = None) -> None:
        """Make `name` available to whatever picks predictors from this registry; names are unique."""
        if not name.isidentifier():
            raise PredictorError(f"predictor name {name!r} must be an identifier (letters, digits, '_')")
        if name in self.names():
            raise PredictorError(f"predictor {name!r} is already registered")
        self._own[name] = Entry(name, factory, label or name, loader, params)

    def unregister(self, name: str) -> None:
        """Forget `name`, one this registry registered itself (a plugin's, a test's)."""
        if self._own.pop(name, None) is None:
            raise PredictorError(f"predictor {name!r} was not registered here")

    def names(self) -> tuple[str, ...]:
        """Every name, the parent's first, in registration order (baselines first)."""
        return (self.parent.names() if self.parent else ()) + tuple(self._own)

    def entry(self, name: str) -> Entry:
        if name in self._own:
            return self._own[name]
        if self.parent is not None and name in self.parent.names():
            return self.parent.entry(name)
        raise PredictorError(f"unknown predictor {name!r}; choose from {', '.join(self.names())}")

    def label(self, name: str) -> str:
        return self.entry(name).label

    def make_predictor(self, name: str, params: Any = None, seed: int = 0) -> Predictor:
        """A fresh predictor `name`: `params` None (defaults), a flat mapping of its settings (with `horizon`
        and `n_joints`), or a `HierarchyParams` (the experiments' shared settings)."""
        return self.entry(name).factory(params, seed)

    def learner_names(self) -> tuple[str, ...]:
        """The predictors that can be saved and loaded."""
        return tuple(n for n in self.names() if self.entry(n).loader is not None)

    def load_predictor(self, name: str, path: str | os.PathLike[str]) -> Predictor:
        """The predictor `name` saved at `path`; a LearningError with `kind_mismatch` if the file holds
        another kind or blend."""
        e = self.entry(name)
        if e.loader is None:
            raise PredictorError(f"predictor {name!r} cannot be loaded from a checkpoint; "
                                 f"choose from {', '.join(self.learner_names())}")
        return e.loader(path)


def hierarchy_params(params: Any) -> HierarchyParams:
    """`HierarchyParams` for a factory's `params` (None, a flat mapping or one already)."""
    if params is None:
        return HierarchyParams()
    return HierarchyParams.from_flat(params) if isinstance(params, Mapping) else params


def settings_from_parameters(name: str, flat: Mapping[str, Any], joints: int = 8) -> dict[str, Any]:
    """The settings of predictor `name` among the learner node's flat parameters (its own as
    '<name>.<setting>', the node's `horizon`), as `make_predictor` takes them."""
    prefix = f"{name}."
    settings = {key[len(prefix):]: value for key, value in flat.items() if key.startswith(prefix)}
    settings.update(horizon=flat.get("horizon", 6), n_joints=joints)
    return settings


# --- the built-in predictors -----------------------------------------------------------------------
#: The baselines that state an interval with every prediction: the default's spread of their own residuals
#: (`default_predictor.spread.WithSpread`), so that the reports compare widths at equal coverage.
SPREADING_BASELINES = ("hold", "rls_ar")


def _baseline(name: str) -> Factory:
    def make(params: Any, seed: int) -> Predictor:
        hp = hierarchy_params(params)
        model = make_baselines(hp.horizon, hp.span)[name]
        if name not in SPREADING_BASELINES:
            return model  # type: ignore[return-value]
        return WithSpread(model, SpreadParams(horizon=hp.horizon, joints=hp.n_joints, groups=1))

    return make


def _linear(params: Any, seed: int) -> Predictor:
    hp = hierarchy_params(params)
    return DirectLinear(DirectLinearParams(horizon=hp.horizon, joints=hp.n_joints))


def _hierarchy(params: Any, seed: int) -> Predictor:
    return Hierarchy(hierarchy_params(params), seed=seed)


def _made_by(build: Callable[..., Predictor]) -> Factory:
    """A factory calling `build(horizon, joints, seed, settings)`."""
    def make(params: Any, seed: int) -> Predictor:
        if params is None:
            return build(seed=seed)
        if isinstance(params, Mapping):
            own = {k: v for k, v in params.items() if k not in DATA_PARAMETERS}
            return build(params.get("horizon", 6), params.get("n_joints", 8), seed, own)
        return build(params.horizon, params.n_joints, seed)  # HierarchyParams

    return make


def gate_loader(wraps: str) -> Loader:
    """A loader of gated checkpoints that refuses a gate around another kind of model."""
    def load(path: str | os.PathLike[str]) -> Predictor:
        gate = GatedPredictor.load(path)
        if gate.model.kind != wraps:
            raise LearningError(f"{path}: holds a gate around a {gate.model.kind!r}, expected a {wraps!r}",
                                source=path, found=gate.model.kind, expected=wraps)
        return gate

    return load


PRODUCT = Registry()
PRODUCT.register("hold", _baseline("hold"), "hold last")
PRODUCT.register("const_velocity", _baseline("const_velocity"), "constant velocity")
PRODUCT.register("rls_ar", _baseline("rls_ar"), "RLS-AR")
PRODUCT.register("linear", _linear, "direct linear (RLS)")
PRODUCT.register("hierarchy", _hierarchy, "GWR hierarchy", Hierarchy.load, HierarchyParams)
PRODUCT.register("gated_llm_gwr", _made_by(make_gated_network), "gated local-linear P-GWR",
                 gate_loader("LocalLinearPredictor"), GatedNetworkParams)
PRODUCT.register(DEFAULT_PREDICTOR, _made_by(make_default), "GWR experts (default)", DefaultPredictor.load,
                 DefaultParams)

# The product registry's operations under the names the package exports.
entry = PRODUCT.entry
register = PRODUCT.register
names = predictor_names = PRODUCT.names
label = PRODUCT.label
make_predictor = PRODUCT.make_predictor
load_predictor = PRODUCT.load_predictor
learner_names = PRODUCT.learner_names


def default_name() -> str:
    """The learner node's default predictor (one of `learner_names()`)."""
    return DEFAULT_PREDICTOR
