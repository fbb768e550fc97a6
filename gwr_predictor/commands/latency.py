"""`gwr-predictor latency RUN_DIR`: latency percentiles per hop and message loss of a recorded run.

Reads the bag only (see gwr_predictor.pipeline.message_latency for the definitions): the recorder's receive time
against the frame's source stamp, and each node's final /diagnostics counters against the messages
recorded. Prints a table, writes latency.json into the run folder; exit code 1 if the bag is unreadable,
3 if `--max-lost` is exceeded (for benchmark scripts).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gwr_predictor.commands.run_folder import add_run_arguments, bag_and_folder
from gwr_predictor.files.user_files import write_output
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.message_latency import latency_report


def configure(parser: argparse.ArgumentParser) -> None:
    add_run_arguments(parser)
    parser.add_argument("--out", type=Path, default=None, help="where latency.json goes (default: the run folder)")
    parser.add_argument("--max-lost", type=int, default=None,
                        help="fail (exit code 3) if more messages than this were lost")


def run(args: argparse.Namespace) -> int:
    bag, folder = bag_and_folder(args.run)
    out = args.out or folder
    try:
        report = latency_report(bag, args.namespace)
        path = write_output(out / "latency.json", report.to_json() + "\n", "latency report", PipelineError)
    except PipelineError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    for line in report.summary_lines():
        print(line)
    print(f"written: {path}")
    if args.max_lost is not None and report.total_lost > args.max_lost:
        print(f"error: {report.total_lost} messages lost, more than --max-lost {args.max_lost}", file=sys.stderr)
        return 3
    return 0
