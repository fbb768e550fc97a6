"""Nested settings dataclasses as flat, dotted parameters: one naming rule for the library, the node,
its YAML and the docs.

A settings dataclass declares its parameters in a class attribute `SPECS` ({field: ParamSpec}); a field
holding another settings dataclass is a branch, named by the field (`network.gwr.eps_b`). The default
of every flat parameter is the value the tree holds, so a composition that sets a member's tuned values
in its own dataclass states them once, and the node's declarations, the YAML and the docs tables follow.

Two field metadata keys shape a branch: `about` (the words that start its parameters' descriptions)
and `hidden` (its fields that are not parameters here, e.g. a GWR step's threshold that the network
overrides). The data's own shape (`horizon`, `n_joints`, `joints`) is a parameter only at the top of a
tree: a member takes it from there.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from gwr_predictor.parameters.spec import ParameterError, ParamSpec

#: The data's shape: set at the top of a tree, never a member's own parameter.
FROM_THE_DATA = ("horizon", "n_joints", "joints")


def _branches(params: Any) -> dict[str, dataclasses.Field[Any]]:
    return {f.name: f for f in dataclasses.fields(params) if dataclasses.is_dataclass(getattr(params, f.name))}


def _leaves(params: Any, top: bool, hidden: tuple[str, ...] = ()) -> dict[str, ParamSpec]:
    specs: Mapping[str, ParamSpec] = getattr(type(params), "SPECS", {})
    return {name: spec for name, spec in specs.items()
            if name not in hidden and (top or name not in FROM_THE_DATA)}


def parameter_specs(params: Any, prefix: str = "", about: str = "", hidden: tuple[str, ...] = ()
                    ) -> tuple[ParamSpec, ...]:
    """Every parameter of the tree `params`, flat and dotted, each defaulting to the value the tree holds."""
    out = []
    for name, spec in _leaves(params, not prefix, hidden).items():
        value = getattr(params, name)
        out.append(dataclasses.replace(
            spec, name=prefix + name, description=f"{about}: {spec.description}" if about else spec.description,
            default=spec.none_value if value is None and spec.none_value is not None else value))
    for name, f in _branches(params).items():
        words = f.metadata.get("about", name)
        out.extend(parameter_specs(getattr(params, name), f"{prefix}{name}.",
                                   f"{about} {words}" if about and words else words or about,
                                   tuple(f.metadata.get("hidden", ()))))
    return tuple(out)


def flatten(params: Any) -> dict[str, Any]:
    """{dotted name: value} of every parameter of the tree (None as its spec's `none_value`)."""
    return {s.name: s.default for s in parameter_specs(params)}


def replace(params: Any, flat: Mapping[str, Any], error: type[Exception] = ParameterError) -> Any:
    """The tree `params` with the dotted parameters `flat` changed; ints and floats are taken for each
    other where no value is lost (ROS and YAML hand over either). An unknown name or a bad value raises
    `error` naming it; each dataclass's own checks then run as it is rebuilt."""
    known = {s.name: s for s in parameter_specs(params)}
    unknown = sorted(k for k in flat if k not in known)
    if unknown:
        raise error(f"unknown parameters {unknown} of {type(params).__name__}; known: {', '.join(known)}")
    try:
        checked = {k: coerce(known[k], v) for k, v in flat.items()}
    except ParameterError as exc:
        raise error(str(exc)) from None
    return _rebuilt(params, checked, error)


def _rebuilt(params: Any, flat: Mapping[str, Any], error: type[Exception]) -> Any:
    own: dict[str, Any] = {}
    below: dict[str, dict[str, Any]] = {}
    for key, value in flat.items():
        head, _, rest = key.partition(".")
        if rest:
            below.setdefault(head, {})[rest] = value
        else:
            own[head] = value
    for name, changes in below.items():
        own[name] = _rebuilt(getattr(params, name), changes, error)
    try:
        return dataclasses.replace(params, **own) if own else params
    except ValueError as exc:  # each subpackage's error class is a ValueError too
        raise error(str(exc)) from None


def coerce(spec: ParamSpec, value: Any) -> Any:
    """`value` for `spec`: an int for a double and an integral float for an integer are taken; a spec's
    `none_value` (or None) stands for None; anything else goes through the spec's check."""
    if spec.none_value is not None and (value is None or (not isinstance(value, bool) and value == spec.none_value)):
        return None
    if spec.kind == "integer" and isinstance(value, float) and value.is_integer():
        value = int(value)
    return spec.check(value)
