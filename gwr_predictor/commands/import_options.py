"""Command-line options shared by every command that reads recordings: units, up axis, frame rate,
joint map and the ASF skeleton of an AMC file (see `gwr_predictor.data.mocap`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from gwr_predictor.data.mocap_clip import UNITS, UP_AXES, ImportOptions


def add_import_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("mocap import (.bvh, .amc, .npy/.npz positions, .pt)")
    group.add_argument("--units", default="auto",
                       help=f"length unit of the file: auto (from the skeleton's size), {', '.join(UNITS)} "
                            "or metres per unit")
    group.add_argument("--up", default="auto", choices=UP_AXES, help="the file's up axis (auto: from the skeleton)")
    group.add_argument("--fps", type=float, default=0.0, help="frame rate of the file (default: what it says)")
    group.add_argument("--joint-map", type=Path, default=None,
                       help="JSON/YAML file {skeleton joint: file joint name or index} (default: a preset "
                            "detected from the names)")
    group.add_argument("--asf", type=Path, default=None, help="ASF skeleton for .amc files (default: beside it)")


def import_options(args: argparse.Namespace) -> ImportOptions:
    """`ImportOptions` from parsed arguments (raises DataError for a bad value)."""
    return ImportOptions(units=args.units, up=args.up, fps=args.fps, joint_map=args.joint_map, asf=args.asf)
