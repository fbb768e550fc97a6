"""Writing experiment outputs: one JSON file, one markdown report and PNG figures per experiment.

Every experiment returns an `ExperimentOutput`; `write_output` turns it into
`<out>/results.json` (machine-readable, NaN as null) and `<out>/results.md` (the human summary that
research/experiments.md quotes). Figures are saved by the experiment through `save_figure` so that
they stay small (PNG, modest dpi) and matplotlib never keeps figures open.
"""

from __future__ import annotations

import io
import json
import math
import platform
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.evaluation.errors import EvaluationError
from gwr_predictor.files import json_safe, user_files


@dataclass
class ExperimentOutput:
    """What an experiment produced: results for JSON, markdown body, figure file names."""

    name: str
    title: str
    config: dict[str, Any]
    results: dict[str, Any]
    markdown: list[str] = field(default_factory=list)
    figures: list[str] = field(default_factory=list)
    elapsed_s: float = 0.0


def to_jsonable(obj: Any) -> Any:
    """`json_safe.to_jsonable`, raising EvaluationError for an object with no JSON form."""
    try:
        return json_safe.to_jsonable(obj)
    except TypeError as exc:
        raise EvaluationError(str(exc)) from None


def write_json(path: Path, obj: Any) -> Path:
    text = json.dumps(to_jsonable(obj), indent=1)
    if len(text) > 100_000:  # long traces: compact, to keep results small enough to commit
        text = json.dumps(to_jsonable(obj), separators=(",", ":"))
    return user_files.write_output(path, text + "\n", "results file", EvaluationError)


def fmt(value: Any, digits: int = 3) -> str:
    """A table cell: numbers with `digits` significant decimals, None/NaN as a dash."""
    if value is None:
        return "–"
    if isinstance(value, (float, np.floating)):
        return "–" if not math.isfinite(float(value)) else f"{float(value):.{digits}f}"
    return str(value)


def markdown_table(headers: Sequence[str], rows: Sequence[Sequence[Any]], digits: int = 3) -> str:
    """A GitHub markdown table; numeric cells formatted by `fmt`."""
    lines = ["| " + " | ".join(headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
    for row in rows:
        if len(row) != len(headers):
            raise EvaluationError(f"table row has {len(row)} cells for {len(headers)} headers")
        lines.append("| " + " | ".join(fmt(c, digits) for c in row) + " |")
    return "\n".join(lines)


def save_figure(fig: Any, out: Path, name: str, dpi: int = 80) -> str:
    """Save a matplotlib figure as `<out>/<name>.png` (a 64-colour palette PNG, a few times smaller
    than full colour and plenty for line plots), close it, return the file name."""
    import matplotlib.pyplot as plt
    from PIL import Image

    path = Path(out) / f"{name}.png"
    buf = io.BytesIO()
    try:
        with user_files.replacing(path, "figure", EvaluationError) as tmp:
            fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
            with Image.open(buf) as img:
                img.convert("RGB").quantize(colors=64).save(tmp, format="PNG", optimize=True)
    finally:
        plt.close(fig)
    return path.name


def figure(rows: int = 1, cols: int = 1, size: tuple[float, float] = (7.0, 4.0)) -> tuple[Any, Any]:
    """A new figure and axes (matplotlib imported lazily, Agg-safe)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt.subplots(rows, cols, figsize=size, squeeze=False)


def write_output(out: Path, output: ExperimentOutput, seed: int, quick: bool,
                 command: str | None = None) -> tuple[Path, Path]:
    """Write results.json and results.md for `output`; returns both paths. `command` is the
    command line that reproduces it (default: rebuilt from name, quick, seed and overrides)."""
    out = Path(out)
    if command is None:
        params = "".join(f" --param {k}={v}" for k, v in output.config.get("overrides", ()))
        command = f"gwr-predictor experiment {output.name}{' --quick' if quick else ''} --seed {seed}{params}"
    meta = {"experiment": output.name, "title": output.title, "command": command, "seed": seed, "quick": quick,
            "elapsed_s": round(output.elapsed_s, 1), "created": time.strftime("%Y-%m-%d %H:%M:%S"),
            "python": platform.python_version(), "numpy": np.__version__}
    json_path = write_json(out / "results.json", {**meta, "config": output.config, "results": output.results,
                                                  "figures": output.figures})
    md = [f"# {output.title}", "", f"`{command}` ({output.elapsed_s:.0f} s).", "", *output.markdown, ""]
    md += [f"![{f}]({f})" for f in output.figures]
    md_path = user_files.write_output(out / "results.md", "\n".join(md).rstrip() + "\n", "results file",
                                      EvaluationError)
    return json_path, md_path
