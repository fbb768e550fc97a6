"""YAML a user names (params files, a bag's metadata.yaml, joint-map files), parsed safely.

Aliases are refused (rcl refuses them in params files too) and the nesting is bounded, while the
parser's events stream past, so that an alias bomb of a few hundred bytes never expands. The file
itself is read by `user_files`' rules (a regular file, size-limited).
"""

from __future__ import annotations

from typing import Any

import yaml

from gwr_predictor.files.user_files import PathLike, read_text

#: Nesting of a YAML document (params files nest about 5 deep, a bag's metadata.yaml 6).
MAX_YAML_DEPTH = 64


def load_yaml(path: PathLike, limit: int, what: str, error: type[Exception]) -> Any:
    """The YAML document of the regular file at `path` (at most `limit` bytes), built only after every
    event was checked: no alias, nesting at most `MAX_YAML_DEPTH`. `error` naming the file, and the line
    for a syntax error, otherwise."""
    return parse_yaml(read_text(path, limit, what, error), str(path), what, error)


def parse_yaml(text: str, where: str, what: str, error: type[Exception]) -> Any:
    """`load_yaml` of text already read (`where` names it in messages)."""
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    depth = 0
    try:
        for event in yaml.parse(text, Loader=loader):
            if isinstance(event, yaml.AliasEvent):
                raise error(f"{where}: YAML alias '*{event.anchor}'{_line(event)}: aliases are not accepted in a "
                            f"{what} (a few of them can expand to gigabytes); write the values out")
            if isinstance(event, yaml.CollectionStartEvent):
                depth += 1
                if depth > MAX_YAML_DEPTH:
                    raise error(f"{where}: YAML nested more than {MAX_YAML_DEPTH} deep{_line(event)}; "
                                f"refused as a {what}")
            elif isinstance(event, yaml.CollectionEndEvent):
                depth -= 1
        return yaml.load(text, Loader=loader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        raise error(f"{where}: not valid YAML{at}: {getattr(exc, 'problem', None) or exc}") from None


def _line(event: Any) -> str:
    mark = getattr(event, "start_mark", None)
    return f" at line {mark.line + 1}" if mark is not None else ""
