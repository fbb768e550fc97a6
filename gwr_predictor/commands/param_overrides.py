"""`--param KEY=VALUE` options of the command line, typed the way a YAML value would be."""

from __future__ import annotations

from gwr_predictor.parameters.spec import ParameterError


def parse_overrides(items: list[str]) -> dict[str, object]:
    """'key=value' strings -> {key: int | float | bool | str}."""
    out: dict[str, object] = {}
    for item in items:
        k, sep, v = item.partition("=")
        if not sep or not k:
            raise ParameterError(f"--param needs KEY=VALUE, got {item!r}")
        value: object
        if v.lower() in ("true", "false"):
            value = v.lower() == "true"
        else:
            try:
                value = int(v)
            except ValueError:
                try:
                    value = float(v)
                except ValueError:
                    value = v
        out[k.strip()] = value
    return out
