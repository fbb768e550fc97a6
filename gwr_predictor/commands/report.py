"""`gwr-predictor report RUN_DIR`: summarise a recorded pipeline run (see gwr_predictor.pipeline.run_report).

Prints the prediction error at the horizon, how far each simulated robot lags the person (with and
without compensation), neurons per layer and message counts; writes report.json and report.png
(person, prediction and robots over the last seconds) into the run folder (`run_folder.bag_and_folder`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gwr_predictor.commands.run_folder import add_run_arguments, bag_and_folder
from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.files.user_files import write_output
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.run_report import compute_report, plot_run, read_run


def configure(parser: argparse.ArgumentParser) -> None:
    add_run_arguments(parser)
    parser.add_argument("--out", type=Path, default=None, help="where report.json/png go (default: the run folder)")
    parser.add_argument("--plot-seconds", type=float, default=12.0, help="time span of the plot (default 12 s)")
    parser.add_argument("--max-lag", type=float, default=1.5, help="largest lag searched (s, default 1.5)")


def run(args: argparse.Namespace) -> int:
    bag, folder = bag_and_folder(args.run)
    out = args.out or folder
    try:
        data = read_run(bag, args.namespace)
        for warning in data.warnings:
            print(f"warning: {warning}", file=sys.stderr)
        report = compute_report(data, max_lag_s=args.max_lag)
        json_path = write_output(out / "report.json", report.to_json() + "\n", "report", PipelineError)
        png_path = plot_run(data, out / "report.png", seconds=args.plot_seconds)
    except GwrPredictorError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    for line in report.summary_lines():
        print(line)
    print(f"written: {json_path} and {png_path}")
    return 0
