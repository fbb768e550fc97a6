"""The parameter reference a user reads, rendered from the specs: the docs' tables and the params
file's sections. `scripts/parameter_reference.py --write` puts them in docs/parameters.md and
config/arm_predictor.yaml; the tests keep both equal to what this renders."""

from __future__ import annotations

import json
from collections.abc import Iterable

from gwr_predictor.parameters.spec import ParamSpec, markdown_table

__all__ = ["markdown_table", "yaml_section"]

#: The column YAML comments start at.
COMMENT_COLUMN = 36


def _scalar(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value) if value == "" or not value.replace("_", "").isalnum() else value
    if isinstance(value, float):
        mantissa, e, exponent = repr(value).partition("e")
        return f"{mantissa if '.' in mantissa else mantissa + '.0'}{e}{exponent}"  # YAML 1.1 reads 1e-06 as text
    return json.dumps(value)


def yaml_section(name: str, specs: Iterable[ParamSpec], indent: int = 4) -> list[str]:
    """`name:` and, nested by their dotted names below it, every spec's default with its description as
    a comment (a nested spec's description starts with its group's words and ': ', which go on the
    group's line)."""
    lines = [" " * indent + f"{name}:"]
    opened: list[str] = []
    for spec in specs:
        *groups, leaf = spec.name.split(".")
        words, _, about = spec.description.partition(": ") if groups else ("", "", spec.description)
        depth = 0
        while depth < min(len(groups), len(opened)) and groups[depth] == opened[depth]:
            depth += 1
        opened = opened[:depth]
        for group in groups[depth:]:
            opened.append(group)
            text = " " * (indent + 2 * len(opened)) + f"{group}:"
            lines.append(f"{text.ljust(COMMENT_COLUMN - 1)} # {words}" if group == groups[-1] and words != group
                         else text)
        text = " " * (indent + 2 * (len(opened) + 1)) + f"{leaf}: {_scalar(spec.default)}"
        lines.append(f"{text.ljust(COMMENT_COLUMN - 1)} # {' '.join(about.split())}")
    return lines
