"""What `report`, `latency` and `render` read and where they write: the RUN argument they share."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_run_arguments(parser: argparse.ArgumentParser) -> None:
    """RUN (a run folder holding bag/, a bag directory or a bare .mcap file) and --namespace."""
    parser.add_argument("run", type=Path, help="run folder holding bag/ (or a bag directory, or a .mcap file)")
    parser.add_argument("--namespace", default=None, metavar="NS",
                        help="the pipeline to read when the bag holds several (run_pipeline.sh --namespace NS); "
                             "default: the bag's only one")


def bag_and_folder(run: Path) -> tuple[Path, Path]:
    """(the bag, the folder results go to by default): RUN/bag and RUN for a run folder; a bare bag directory
    and that directory itself (its results stay with it, never in a parent shared with other bags); a
    bare .mcap file and its folder."""
    if (run / "bag").is_dir():
        return run / "bag", run
    return run, run if run.is_dir() else run.parent
