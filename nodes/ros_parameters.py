"""`ParamSpec`s as described ROS parameters: `declare_parameters` declares them on a node with their
allowed values in the descriptor (and a range `ros2 param describe` and rqt show), read-only unless
`live`; a bad value is a `ParameterError` naming the parameter and what is allowed.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter

from gwr_predictor.parameters.spec import ParameterError, ParamSpec

_ARRAY_TYPES = {"string list": Parameter.Type.STRING_ARRAY, "double list": Parameter.Type.DOUBLE_ARRAY}


#: Why a parameter is read-only, shown by `ros2 param describe` next to its allowed values.
READ_ONLY_REASON = "read-only: read once at start (it shapes the node's model, topics or timers); restart to change"
LIVE_NOTE = "can be changed while the node runs (set_parameters), with the same check"
_INT64_MAX = 2**63 - 1


def value_range(spec: ParamSpec) -> dict[str, list]:
    """The spec's bounds as a descriptor's FloatingPointRange / IntegerRange, so that `ros2 param
    describe` and rqt show them. ROS ranges are closed and two-sided: a missing bound becomes
    +-inf (doubles) or the int64 limit, an open end is shown closed (the spec's check still refuses
    it), and a `none_value` outside the bounds (e.g. 0 = unlimited) widens the range to include it."""
    if spec.kind not in ("double", "integer") or (spec.lo is None and spec.hi is None):
        return {}
    if spec.kind == "double":
        lo = -math.inf if spec.lo is None else float(spec.lo)
        hi = math.inf if spec.hi is None else float(spec.hi)
        return {"floating_point_range": [FloatingPointRange(from_value=lo, to_value=hi, step=0.0)]}
    lo = -_INT64_MAX - 1 if spec.lo is None else math.ceil(spec.lo)
    hi = _INT64_MAX if spec.hi is None else math.floor(spec.hi)
    if spec.none_value is not None:
        lo, hi = min(lo, spec.none_value), max(hi, spec.none_value)
    return {"integer_range": [IntegerRange(from_value=int(lo), to_value=int(hi), step=1)]}


def descriptor(spec: ParamSpec, value_type: int = 0) -> ParameterDescriptor:
    """The ROS descriptor of a spec: described, the allowed values in `additional_constraints` (with
    why it is read-only, or that it can change live) and as a range, read-only unless `live`.

    Doubles are dynamically typed so that `-p rate_hz:=30` (an integer) is accepted and converted;
    the range then applies to doubles, and `ParamSpec.check` checks every value either way.
    """
    note = LIVE_NOTE if spec.live else READ_ONLY_REASON
    return ParameterDescriptor(description=spec.description, read_only=spec.read_only, type=value_type,
                               dynamic_typing=spec.kind == "double",
                               additional_constraints=f"allowed: {spec.allowed()}; {note}", **value_range(spec))


def declare_parameters(node: Node, specs: Iterable[ParamSpec]) -> dict[str, Any]:
    """Declare every spec and return {name: validated value}; a bad value raises ParameterError.

    Numbers are declared first without range or read-only flag, so that a bad start value gets the
    spec's own message (naming the value and the allowed range), then given their full descriptor."""
    values: dict[str, Any] = {}
    for spec in specs:
        kind = spec.kind
        default = spec.default
        if kind in _ARRAY_TYPES:  # an empty list has no type of its own
            default = list(spec.default) if spec.default else _ARRAY_TYPES[kind]
        ranged = bool(value_range(spec))
        first = (ParameterDescriptor(description=spec.description, dynamic_typing=kind == "double") if ranged
                 else descriptor(spec))
        try:
            value = node.declare_parameter(spec.name, default, first).value
        except InvalidParameterTypeException as exc:
            raise ParameterError(f"parameter '{spec.name}' must be of type {kind} ({spec.allowed()}): {exc}") from None
        except InvalidParameterValueException as exc:
            raise ParameterError(f"parameter '{spec.name}' ({spec.allowed()}): {exc}") from None
        values[spec.name] = spec.check(value)
        if ranged:
            node.set_descriptor(spec.name, descriptor(spec, node.describe_parameter(spec.name).type))
    return values
