"""`gwr-predictor render RUN_DIR_OR_BAG`: a video of a recorded run (see gwr_predictor.pipeline.video).

The person as a stick figure, the compensated and the uncompensated Nao side by side and
time-aligned, the person's arm pose as a faint ghost over each robot, and captions with the time,
each robot's compensator mode, its current lag and tracking error. Real time at 30 fps by default
(GIF: 15 fps); MP4 when the encoder (imageio-ffmpeg) is installed, GIF otherwise.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tqdm import tqdm

from gwr_predictor.commands.run_folder import add_run_arguments, bag_and_folder
from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.pipeline.video import read_video_run, render_video
from gwr_predictor.pipeline.video_files import default_suffix


def configure(parser: argparse.ArgumentParser) -> None:
    add_run_arguments(parser)
    parser.add_argument("-o", "--out", type=Path, default=None,
                        help="video file, .mp4 or .gif (default: video.mp4 in the run folder; .gif without an encoder)")
    parser.add_argument("--seconds", default=None, metavar="A:B",
                        help="span from the run's start (s); negative: from its end (--seconds=-20: = last 20 s)")
    parser.add_argument("--fps", type=float, default=None, help="frames per second of run time (default 30; GIF 15)")
    parser.add_argument("--scale", type=float, default=1.0, help="size factor: 1.0 = 320x240 px per panel")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    bag, folder = bag_and_folder(args.run)
    out = args.out or folder / f"video{default_suffix()}"
    fps = args.fps if args.fps is not None else (15.0 if out.suffix.lower() == ".gif" else 30.0)
    bar = tqdm(unit="frame", desc=f"rendering {out.name}", file=sys.stderr, disable=args.no_progress,
               mininterval=0.5, leave=False)
    try:
        data = read_video_run(bag, args.namespace)
        for warning in data.warnings:
            bar.write(f"warning: {warning}", file=sys.stderr)
        stats = render_video(data, out, span=args.seconds, fps=fps, scale=args.scale,
                             progress=lambda n: bar.update(n - bar.n),
                             progress_total=lambda n: setattr(bar, "total", n))
    except GwrPredictorError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    finally:
        bar.close()
    print(f"written: {stats.path} ({stats.frames} frames, {stats.width}x{stats.height} at {stats.fps:g} fps, "
          f"run time {stats.start_s:.1f}-{stats.end_s:.1f} s, {stats.bytes / 1e6:.2f} MB, "
          f"rendered in {stats.seconds_taken:.1f} s)")
    return 0
