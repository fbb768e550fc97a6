#!/usr/bin/env python3
"""Render the parameter reference from the specs: the tables of docs/parameters.md and the predictor
sections of config/arm_predictor.yaml. The predictors' specs come from their settings dataclasses
(`gwr_predictor.parameters.tree`), so a changed default, range or name is changed there once and this
carries it here. `--write` rewrites the two files; without it, exits 1 naming what is out of date
(test/test_docs_parameters.py runs the same check).

    python scripts/parameter_reference.py [--write]
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gwr_predictor.parameters.reference import markdown_table, yaml_section  # noqa: E402
from gwr_predictor.registry import DEFAULT_PREDICTOR, entry, learner_names  # noqa: E402

DOC = ROOT / "docs" / "parameters.md"
YAML = ROOT / "config" / "arm_predictor.yaml"
NODES = ("skeleton_source", "angle_extractor", "arm_predictor", "delay_compensator", "nao_sim", "bag_recorder",
         "bag_player", "hri_bodies")
#: The line after which config/arm_predictor.yaml is rendered.
YAML_MARKER = ("    # --- each predictor's own settings (rendered by scripts/parameter_reference.py; "
               "edit the dataclasses)")


def predictors() -> tuple[str, ...]:
    """The learner's predictors, the default first."""
    return (DEFAULT_PREDICTOR, *(n for n in learner_names() if n != DEFAULT_PREDICTOR))


def tables() -> dict[str, str]:
    """{docs heading: table}."""
    from gwr_predictor.nodes.arm_predictor import predictor_specs
    from gwr_predictor.nodes.pipeline_node import COMMON_PARAMS

    out = {"every node": markdown_table(COMMON_PARAMS)}
    for node in NODES:
        out[node] = markdown_table(importlib.import_module(f"gwr_predictor.nodes.{node}").PARAMS)
    for name in predictors():
        out[f"arm_predictor: predictor {name}"] = markdown_table(predictor_specs(name))
    return out


def rendered_doc(text: str) -> str:
    for heading, table in tables().items():
        pattern = re.compile(rf"^(## {re.escape(heading)}\n\n)((?:\|.*\n)+)", re.MULTILINE)
        if not pattern.search(text):
            raise SystemExit(f"{DOC}: no '## {heading}' heading followed by a table")
        text = pattern.sub(lambda m, t=table: m.group(1) + t + "\n", text, count=1)
    return text


def rendered_yaml(text: str) -> str:
    head, marker, _ = text.partition(YAML_MARKER + "\n")
    if not marker:
        raise SystemExit(f"{YAML}: no line '{YAML_MARKER.strip()}'")
    lines: list[str] = []
    for name in predictors():
        label = entry(name).label
        lines += ["", f"    # --- predictor: {name} ({label})", *yaml_section(name, entry(name).settings())]
    return head + marker + "\n".join(lines[1:]) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="rewrite the files (default: check them)")
    args = parser.parse_args()
    stale = []
    for path, render in ((DOC, rendered_doc), (YAML, rendered_yaml)):
        text = path.read_text(encoding="utf-8")
        new = render(text)
        if new != text:
            stale.append(path)
            if args.write:
                path.write_text(new, encoding="utf-8")
    if stale and not args.write:
        print("out of date (run scripts/parameter_reference.py --write): " + ", ".join(map(str, stale)))
        return 1
    for path in stale:
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
