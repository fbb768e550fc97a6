"""`gwr-predictor demonstrate`: write the synthetic demonstrator's skeleton sequences, one file each."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tqdm import tqdm

from gwr_predictor.commands.errors import CommandError
from gwr_predictor.data.demonstrator import PATTERNS, default_subjects, demonstrate_one
from gwr_predictor.data.errors import DataError
from gwr_predictor.data.skeleton_files import save_skeleton


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, required=True, help="output folder (created if needed)")
    parser.add_argument("--patterns", nargs="+", choices=PATTERNS, default=list(PATTERNS), metavar="PATTERN",
                        help=f"patterns to generate (default all): {', '.join(PATTERNS)}")
    parser.add_argument("--subjects", type=int, default=3, help="number of simulated people (default 3)")
    parser.add_argument("--repetitions", type=int, default=10, help="repetitions per pattern and person")
    parser.add_argument("--seed", type=int, default=0, help="seed; the same seed gives the same files")
    parser.add_argument("--format", choices=("npz", "csv"), default="npz", help="file format (default npz)")
    parser.add_argument("--no-noise", action="store_true", help="leave out the tracker noise")
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")


def run(args: argparse.Namespace) -> int:
    try:
        subjects = default_subjects(args.subjects, seed=args.seed)
        if args.repetitions < 1:
            raise CommandError(f"--repetitions must be >= 1, got {args.repetitions}")
    except (CommandError, DataError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    jobs = [(p, s, r) for p in args.patterns for s in subjects for r in range(1, args.repetitions + 1)]
    frames = 0
    bar = tqdm(jobs, desc="demonstrate", unit="seq", file=sys.stderr, disable=args.quiet or not sys.stderr.isatty())
    for pattern, subject, rep in bar:
        seq = demonstrate_one(pattern, subject, rep, seed=args.seed, noise=not args.no_noise)
        save_skeleton(args.out / f"{seq.name}.{args.format}", seq)
        frames += len(seq.timestamps)
    if not args.quiet:
        print(f"wrote {len(jobs)} sequences ({frames} frames at 30 fps) to {args.out}", file=sys.stderr)
    return 0
