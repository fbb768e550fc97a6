"""`gwr-predictor experiment NAME`: run one of the paper's experiments and write its report."""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

from gwr_predictor.commands.param_overrides import parse_overrides
from gwr_predictor.evaluation.output import write_output
from research.experiments import EXPERIMENTS, load
from research.experiments.common import all_methods


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("name", choices=list(EXPERIMENTS), help="which experiment")
    parser.add_argument("--quick", action="store_true", help="CI sizes (each well under a minute)")
    parser.add_argument("--out", type=Path, default=None, help="output folder (default results/NAME)")
    parser.add_argument("--seed", type=int, default=0, help="seed of data, models and orders")
    parser.add_argument("--orders", type=int, default=None,
                        help="presentation orders / repeats to average over (experiments that have them)")
    parser.add_argument("--param", action="append", default=[], metavar="KEY=VALUE",
                        help="hierarchy parameter override in flat form, e.g. input_scale=0.2 or "
                             "pgwr.activation_threshold=0.95 (repeatable)")
    parser.add_argument("--method", default=None,
                        help="predictor to run (experiments with one method, e.g. incremental: gated_llm_gwr)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def run(args: argparse.Namespace) -> int:
    module = load(args.name)
    config = module.QUICK if args.quick else module.FULL
    try:
        overrides = parse_overrides(args.param)
        if overrides:
            config = dataclasses.replace(config, overrides=(*config.overrides, *overrides.items()))
        if args.orders is not None:
            if not hasattr(config, "orders"):
                print(f"experiment {args.name} has no --orders", file=sys.stderr)
                return 2
            config = dataclasses.replace(config, orders=args.orders)
        if args.method is not None:
            if not hasattr(config, "method") or args.method not in all_methods():
                print(f"experiment {args.name} has no --method {args.method!r} (methods: {', '.join(all_methods())})",
                      file=sys.stderr)
                return 2
            config = dataclasses.replace(config, method=args.method)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    out = args.out or Path("results") / args.name
    start = time.perf_counter()
    output = module.run(config, out, seed=args.seed, progress=not args.no_progress)
    output.elapsed_s = time.perf_counter() - start
    command = " ".join(["gwr-predictor", "experiment", args.name, *(["--quick"] if args.quick else []),
                        "--seed", str(args.seed), *(["--orders", str(args.orders)] if args.orders else []),
                        *(["--method", args.method] if args.method else []),
                        *[f"--param {p}" for p in args.param]])
    json_path, md_path = write_output(out, output, seed=args.seed, quick=args.quick, command=command)
    print(md_path.read_text())
    print(f"wrote {json_path}, {md_path} and {len(output.figures)} figure(s) to {out}", file=sys.stderr)
    return 0
