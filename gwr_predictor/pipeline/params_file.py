"""Start-up checks of a node's ROS arguments: params files and parameter names (one mechanism).

rcl refuses a missing or malformed `--params-file` with a traceback-sized RCLError, and silently
ignores keys that name no declared parameter, in a file or in `-p name:=value` alike. These
functions, called by every node before and after it declares its parameters, turn the first into
an error that names the file and the line, and the second into a warning per unknown key with the
closest declared names.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from gwr_predictor.files.yaml_safe import load_yaml
from gwr_predictor.pipeline.errors import PipelineError

#: A params file is settings, never data: larger than this is not one.
MAX_PARAMS_FILE_BYTES = 1 << 20


def params_files(argv: Sequence[str]) -> list[Path]:
    """The `--params-file` paths among the ROS arguments of `argv` (inside `--ros-args ... --`)."""
    files: list[Path] = []
    in_ros = False
    it = iter(argv)
    for arg in it:
        if arg == "--ros-args":
            in_ros = True
        elif arg == "--":
            in_ros = False
        elif in_ros and arg == "--params-file":
            value = next(it, None)
            if value is None:
                raise PipelineError("--params-file needs a file name")
            files.append(Path(value))
    return files


def load_params_file(path: Path) -> dict[str, dict[str, Any]]:
    """{node name pattern: {parameter: value}} of a ROS 2 params file, or PipelineError (the file
    read and parsed by `files.yaml_safe.load_yaml`: a regular file, size-limited, without YAML aliases)."""
    doc = load_yaml(path, MAX_PARAMS_FILE_BYTES, "params file", PipelineError)
    if not isinstance(doc, dict) or not doc:
        raise PipelineError(f"params file {path}: expected '<node name>: {{ros__parameters: {{...}}}}' "
                            f"sections, got {type(doc).__name__}")
    sections: dict[str, dict[str, Any]] = {}
    for node, body in doc.items():
        if not isinstance(body, dict) or not isinstance(body.get("ros__parameters"), dict):
            raise PipelineError(f"params file {path}: section {node!r} must hold a 'ros__parameters' mapping")
        sections[str(node)] = flatten(body["ros__parameters"])
    return sections


def flatten(tree: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested YAML parameters -> {'gwr1.eps_b': value} as rcl names them."""
    out: dict[str, Any] = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flatten(value, name + "."))
        else:
            out[name] = value
    return out


def check_params_files(argv: Sequence[str]) -> list[Path]:
    """Load every params file of `argv` (PipelineError on the first bad one); the files found."""
    files = params_files(argv)
    for path in files:
        load_params_file(path)
    return files


def names_node(section: str, node: str) -> bool:
    """Whether a params-file section key names a node called `node` (`node`, `/node`, `/**/node`,
    `/ns/node`); wildcards for every node (`/**`) do not count."""
    return section == node or section.endswith("/" + node)


def sections_for_other_name(argv: Sequence[str], node: str, other: str) -> list[Path]:
    """The params files of `argv` with a section for a node named `other` and none for `node`: rcl applies
    none of that section to `node` and says nothing, e.g. a `gwr_hierarchy:` section read by the learner
    under its new name."""
    found = []
    for path in params_files(argv):
        keys = load_params_file(path)
        if any(names_node(k, other) for k in keys) and not any(names_node(k, node) for k in keys):
            found.append(path)
    return found


def unknown_parameters(given: Iterable[str], declared: Iterable[str]) -> list[str]:
    """One warning per given name that is no declared parameter, with the closest declared names."""
    known = sorted(set(declared))
    warnings = []
    for name in sorted(set(given) - set(known)):
        if name.startswith("qos_overrides."):  # declared by rclpy when the publisher is created
            continue
        close = difflib.get_close_matches(name, known, n=3, cutoff=0.6)
        hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
        warnings.append(f"parameter {name!r} is not a parameter of this node and is ignored{hint}")
    return warnings
