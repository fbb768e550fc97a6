"""`gwr-predictor angles SKELETON_FILE`: the 8 Nao arm angles of a skeleton file, as CSV and/or PNG."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from gwr_predictor.commands.import_options import add_import_options, import_options
from gwr_predictor.data.angle_files import save_angles_csv, write_angles_csv
from gwr_predictor.data.angles import clip_fractions
from gwr_predictor.data.errors import DataError
from gwr_predictor.data.extraction import extract_angles
from gwr_predictor.data.mocap import load_any_skeleton
from gwr_predictor.pipeline.plotting import plot_angle_series
from gwr_predictor.robot.nao import ARM_JOINTS


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("skeleton", type=Path, help="skeleton file (.npz or .csv, see docs/data.md) or mocap file "
                                                      "(.bvh, .amc, .npy/.npz positions, .pt)")
    parser.add_argument("-o", "--output", type=Path, default=None,
                        help="angle CSV to write (default: print the CSV to stdout unless --plot is given)")
    parser.add_argument("--plot", type=Path, default=None, help="also draw the angles over time as this PNG")
    parser.add_argument("--no-smooth", action="store_true",
                        help="keep every frame instead of the median of every 3 (30 -> 10 fps)")
    parser.add_argument("--quiet", action="store_true", help="no summary on stderr")
    add_import_options(parser)


def run(args: argparse.Namespace) -> int:
    try:
        seq = load_any_skeleton(args.skeleton, import_options(args))
    except DataError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    t, angles, raw = extract_angles(seq.positions, seq.timestamps, seq.joint_names, smooth=not args.no_smooth)
    if args.output is not None:
        save_angles_csv(args.output, t, angles)
    elif args.plot is None:
        write_angles_csv(sys.stdout, t, angles)
    if args.plot is not None:
        plot_angle_series(args.plot, {seq.name: (t, angles)}, title=f"{args.skeleton.name}: Nao arm angles")
    if not args.quiet:
        missing = int(np.isnan(angles[:, 0]).sum())
        clipped = {k: v for k, v in clip_fractions(raw).items() if v > 0}
        clip_text = ", ".join(f"{k} {100 * v:.0f}%" for k, v in clipped.items()) or "none"
        print(f"{len(t)} frames ({missing} missing) of {len(ARM_JOINTS)} angles; clipped to the Nao limits: "
              f"{clip_text}", file=sys.stderr)
    return 0
