"""The `gwr-predictor` command line: a thin dispatcher over library functions.

Each sub-command lives in its own module exposing `configure(parser)` and `run(args) -> int`,
imported only when chosen so that `gwr-predictor angles` does not pay for pybullet or matplotlib.
Any `GwrPredictorError` a command lets through (bad file, corrupt checkpoint, bad parameter) is
printed as one line on stderr with exit code 2; anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from gwr_predictor.errors import GwrPredictorError

#: The research part of the repository (experiments, bench, soak): not installed, run from a checkout.
RESEARCH = "research"
# name -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "demonstrate": ("gwr_predictor.commands.demonstrate", "write the demonstrator's skeleton sequences to files"),
    "angles": ("gwr_predictor.commands.angles", "extract the 8 Nao arm angles from a skeleton file"),
    "bench": ("research.bench", "benchmark learn+predict through the hierarchy (from a checkout)"),
    "soak": ("research.soak", "long offline run: memory and throughput over 1M frames (from a checkout)"),
    "experiment": ("research.experiment_command", "reproduce one of the paper's experiments (from a checkout)"),
    "evaluate": ("gwr_predictor.commands.evaluate", "online evaluation of recordings against baselines"),
    "pretrain": ("gwr_predictor.commands.pretrain", "train a hierarchy offline and save a checkpoint"),
    "report": ("gwr_predictor.commands.report", "summarise a recorded pipeline bag: errors, lag, plot"),
    "latency": ("gwr_predictor.commands.latency", "latency percentiles per hop and message loss of a recorded run"),
    "render": ("gwr_predictor.commands.render", "video of a recorded run: person, compensated and uncompensated Nao"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="gwr-predictor", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, (_, help_text) in COMMANDS.items():
        sub.add_parser(name, help=help_text, add_help=False)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help") or argv[0] not in COMMANDS:
        build_parser().parse_args(argv)  # prints usage / the error and exits
        return 2
    name, rest = argv[0], argv[1:]
    try:
        module = importlib.import_module(COMMANDS[name][0])
    except ModuleNotFoundError as exc:
        if (exc.name or "").partition(".")[0] != RESEARCH:
            raise
        print(f"gwr-predictor {name}: error: '{name}' is research code, which runs from a source checkout of "
              "gwr_predictor (its research/ folder is not installed): source scripts/env.sh in the checkout "
              "and run it there", file=sys.stderr)
        return 2
    parser = argparse.ArgumentParser(prog=f"gwr-predictor {name}", description=COMMANDS[name][1])
    module.configure(parser)
    args = parser.parse_args(rest)
    try:
        return int(module.run(args) or 0)
    except GwrPredictorError as exc:
        message = " ".join(str(exc).split())  # one line, even for multi-line messages
        print(f"gwr-predictor {name}: error: {message}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
