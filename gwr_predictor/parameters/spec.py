"""One parameter declared once: type, default, allowed values, description, and whether it may change live.

The learning dataclasses validate their fields with these specs, the nodes turn them into ROS
ParameterDescriptors (`gwr_predictor.nodes.ros_parameters`), and both produce the same error message,
which names the parameter and what is allowed. No ROS here.

A spec exposes `lo` / `hi` (with `lo_open` / `hi_open`) so that a descriptor can carry a
FloatingPointRange / IntegerRange, and `live` (False: read once at start, read-only) so that a node can
accept `set_parameters` for the parameters that may change while it runs.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from gwr_predictor.errors import GwrPredictorError

KINDS = ("bool", "integer", "double", "string", "string list", "double list")


class ParameterError(GwrPredictorError, ValueError):
    """A parameter value that cannot be used; the message names the parameter and the allowed values."""


def kind_of(default: Any) -> str:
    """The parameter type a default implies (bool before int: a bool is an int in Python)."""
    if isinstance(default, bool):
        return "bool"
    if isinstance(default, int):
        return "integer"
    if isinstance(default, float):
        return "double"
    if isinstance(default, str):
        return "string"
    if isinstance(default, (list, tuple)):
        if all(isinstance(v, str) for v in default):
            return "string list"
        if all(isinstance(v, float) and not isinstance(v, bool) for v in default):
            return "double list"
    raise TypeError(f"unsupported parameter default {default!r}")


def _num(v: float) -> str:
    return repr(v) if isinstance(v, float) else str(v)


@dataclass(frozen=True)
class ParamSpec:
    """One parameter. `default` fixes the type (see `kind`); `lo`/`hi` bound numbers (open ends with
    `lo_open`/`hi_open`); `choices` lists the allowed strings; `none_value` is the flat value that stands
    for None (ROS parameters have no None, e.g. max_neurons 0 = unlimited); `live` marks a parameter that
    may be changed while a node runs (all others are read-only)."""

    name: str
    default: Any
    description: str
    lo: float | None = None
    hi: float | None = None
    choices: tuple[str, ...] | None = None
    lo_open: bool = False
    hi_open: bool = False
    none_value: int | None = None
    live: bool = False

    def __post_init__(self) -> None:
        kind_of(self.default)  # an unsupported default fails where it is declared

    @property
    def kind(self) -> str:
        return kind_of(self.default)

    @property
    def read_only(self) -> bool:
        return not self.live

    # the names node code and tests used before (`minimum` / `maximum`)
    @property
    def minimum(self) -> float | None:
        return self.lo

    @property
    def maximum(self) -> float | None:
        return self.hi

    def allowed(self) -> str:
        """Human-readable allowed values, used in descriptions and error messages."""
        if self.choices:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        lo, hi = self.lo, self.hi
        if lo is not None and hi is not None:
            text = f"{'(' if self.lo_open else '['}{_num(lo)}, {_num(hi)}{')' if self.hi_open else ']'}"
        elif lo is not None:
            text = f"{'>' if self.lo_open else '>='} {_num(lo)}"
        elif hi is not None:
            text = f"{'<' if self.hi_open else '<='} {_num(hi)}"
        else:
            return "any " + self.kind
        if self.none_value is not None:
            text += f" or {self.none_value} (none)"
        return text

    def in_range(self, v: float) -> bool:
        if self.lo is not None and (v < self.lo or (self.lo_open and v == self.lo)):
            return False
        return not (self.hi is not None and (v > self.hi or (self.hi_open and v == self.hi)))

    def check(self, value: Any, owner: str = "") -> Any:
        """`value` converted to the spec's type (ints to floats for doubles, lists for list kinds), or
        ParameterError naming the parameter (prefixed `owner.` for a dataclass field)."""
        label = f"{owner}.{self.name}" if owner else f"parameter '{self.name}'"
        kind = self.kind
        if kind == "double":
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ParameterError(f"{label} must be a number in {self.allowed()}, got {value!r}")
            value = float(value)
            if not math.isfinite(value):
                raise ParameterError(f"{label} must be finite, allowed {self.allowed()}, got {value}")
        elif kind == "integer":
            if isinstance(value, bool) or not isinstance(value, int):
                raise ParameterError(f"{label} must be an integer in {self.allowed()}, got {value!r}")
        elif kind == "bool":
            if not isinstance(value, bool):
                raise ParameterError(f"{label} must be true or false, got {value!r}")
        elif kind == "string":
            if not isinstance(value, str):
                raise ParameterError(f"{label} must be a string ({self.allowed()}), got {value!r}")
        if kind in ("double", "integer") and not (self.none_value is not None and value == self.none_value):
            if not self.in_range(value):
                raise ParameterError(f"{label} must be in {self.allowed()}, got {value!r}" if owner else
                                     f"{label} = {value} is outside the allowed range {self.allowed()}")
        if self.choices and value not in self.choices:
            raise ParameterError(f"{label} must be {self.allowed()}, got {value!r}" if owner else
                                 f"{label} = {value!r} is not allowed: must be {self.allowed()}")
        if kind in ("string list", "double list"):
            value = list(value) if value is not None else list(self.default)
        return value


def check_fields(instance: Any, specs: Iterable[ParamSpec], error: type[Exception] = ParameterError) -> None:
    """Check the fields of a settings dataclass against their specs, in its `__post_init__`.

    `error` lets a module raise its own class (derived from ValueError, as ParameterError is) with the
    spec's message, so that callers catching that class keep working."""
    owner = type(instance).__name__
    for spec in specs:
        try:
            spec.check(getattr(instance, spec.name), owner)
        except ParameterError as exc:
            if error is ParameterError:
                raise
            raise error(str(exc)) from None


def markdown_table(specs: Iterable[ParamSpec]) -> str:
    """The docs' parameter table of `specs` (docs/parameters.md shows these, and a test keeps them equal)."""
    rows = ["| parameter | default | allowed | what |", "|---|---|---|---|"]
    for s in specs:
        default = json.dumps(s.default)
        what = " ".join(s.description.split()).replace("|", "\\|")
        rows.append(f"| `{s.name}` | `{default}` | {s.allowed()} | {what} |")
    return "\n".join(rows)
