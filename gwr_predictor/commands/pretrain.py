"""`gwr-predictor pretrain`: train a predictor offline on the demonstrator's training repetitions.

The live pipeline then starts from this checkpoint (arm_predictor's `checkpoint` parameter) and
keeps learning: pretraining only front-loads what the paper's online training would learn over
many demonstrations. The learning parameters and the `predictor` (the default gated local-linear
P-GWR or the paper's hierarchy) come from the node's YAML (`--params-file`)
unless `--predictor` is given, so the
checkpoint and the node agree. Each epoch presents every sequence once, in a shuffled order, with
a sequence reset between them; the summary line per epoch is neurons and C.P.E. per horizon step.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from gwr_predictor.data.datasets import demo_angle_sequences
from gwr_predictor.data.demonstrator import PATTERNS
from gwr_predictor.default_predictor.gate import inner_model
from gwr_predictor.learning.checkpoint import check_checkpoint_place
from gwr_predictor.learning.protocol import Learner
from gwr_predictor.pipeline.conventions import DEPRECATED_LEARNER_NODE, LEARNER_NODE
from gwr_predictor.pipeline.params_file import load_params_file
from gwr_predictor.registry import (
    DEFAULT_PREDICTOR,
    learner_names,
    make_predictor,
    settings_from_parameters,
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("-o", "--out", type=Path, required=True, help="checkpoint file to write (.npz)")
    parser.add_argument("--params-file", type=Path, default=None,
                        help="ROS params YAML of the arm_predictor node (e.g. config/arm_predictor.yaml): its "
                             "learning parameters and seed are used")
    parser.add_argument("--patterns", nargs="*", default=None, help=f"patterns (default all: {', '.join(PATTERNS)})")
    parser.add_argument("--subjects", type=int, default=3, help="simulated people (default 3)")
    parser.add_argument("--repetitions", type=int, default=3,
                        help="training repetitions 1..N per pattern and subject (default 3); the live demo "
                             "performs later repetitions")
    parser.add_argument("--epochs", type=int, default=5, help="passes over all sequences (default 5)")
    parser.add_argument("--max-seconds", type=float, default=120.0, help="stop after the epoch that exceeds this")
    parser.add_argument("--seed", type=int, default=None, help="model seed (default: the params file's, else 0)")
    parser.add_argument("--data-seed", type=int, default=0, help="demonstrator seed (default 0, as the live source)")
    parser.add_argument("--predictor", choices=learner_names(), default=None,
                        help=f"model to train (default: the params file's 'predictor', else {DEFAULT_PREDICTOR}); "
                             "must match "
                             "the node's 'predictor' parameter")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def node_parameters(path: Path, node: str = LEARNER_NODE) -> dict[str, Any]:
    """The flat (dotted) ros__parameters of `node` in a ROS params YAML (keys '/**', 'node', '/node',
    '/**/node'), the file checked as the nodes check theirs (`params_file.load_params_file`). For the
    learner, a section of its old name (`gwr_hierarchy`) is read too, before its own, for one release."""
    sections = load_params_file(path)
    names = (DEPRECATED_LEARNER_NODE, node) if node == LEARNER_NODE else (node,)
    flat: dict[str, Any] = dict(sections.get("/**", {}))
    for name in names:
        keys = [key for key in (name, "/" + name, "/**/" + name) if key in sections]
        if keys and name == DEPRECATED_LEARNER_NODE:
            print(f"warning: {path}: section {keys[0]!r} has the learner's old name, read for one more release: "
                  f"name it '{LEARNER_NODE}'", file=sys.stderr)
        for key in keys:
            flat.update(sections[key])
    return flat


def run(args: argparse.Namespace) -> int:
    try:
        check_checkpoint_place(args.out)  # before the training, which takes minutes
        flat = node_parameters(args.params_file) if args.params_file else {}
        seed = args.seed if args.seed is not None else int(flat.get("seed", 0))
        seqs = demo_angle_sequences(args.patterns or None, args.subjects, args.repetitions, args.data_seed)
    except ValueError as exc:  # the place (LearningError), the params file (PipelineError), the data (DataError)
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.epochs < 1:
        print("error: --epochs must be >= 1", file=sys.stderr)
        return 2
    predictor = args.predictor or str(flat.get("predictor", DEFAULT_PREDICTOR))
    if predictor not in learner_names():
        print(f"error: predictor {predictor!r} is not one of {', '.join(learner_names())}", file=sys.stderr)
        return 2
    try:
        model = make_predictor(predictor, settings_from_parameters(predictor, flat), seed=seed)
    except ValueError as exc:  # a setting the predictor refuses, named
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if not isinstance(model, Learner):  # learner_names() are the ones that can be saved
        print(f"error: a {predictor} cannot be saved to a checkpoint", file=sys.stderr)
        return 2
    learner = inner_model(model)  # neurons and C.P.E. of the GWR learner (behind the gate, if any)
    rng = np.random.default_rng(seed)
    frames = sum(len(s) for s in seqs)
    print(f"pretraining a {predictor} on {len(seqs)} sequences ({frames} frames at 10 fps) x {args.epochs} epochs",
          flush=True)
    start = time.monotonic()
    summary: list[dict[str, Any]] = []
    for epoch in range(1, args.epochs + 1):
        learner.reset_errors()
        _epoch(model, [seqs[i] for i in rng.permutation(len(seqs))], f"epoch {epoch}/{args.epochs}", args.quiet)
        err = learner.errors()
        summary.append({"epoch": epoch, "neurons": err["neurons"], "cpe": err["cpe"]})
        cpe = " ".join(f"{v:.4f}" for v in err["cpe"])
        print(f"epoch {epoch}: neurons {err['neurons']}, C.P.E. (MSE rad^2) per step {cpe}", flush=True)
        if time.monotonic() - start > args.max_seconds and epoch < args.epochs:
            print(f"time budget of {args.max_seconds:.0f} s used up after epoch {epoch}", flush=True)
            break
    model.reset_sequence()
    model.save(args.out)
    elapsed = time.monotonic() - start
    print(f"checkpoint written to {args.out} ({args.out.stat().st_size / 1e6:.1f} MB, {elapsed:.1f} s)")
    print(json.dumps({"checkpoint": str(args.out), "seconds": round(elapsed, 1), "epochs": summary}))
    return 0


def _epoch(model: Any, seqs: list[Any], label: str, quiet: bool) -> None:
    with tqdm(total=sum(len(s) for s in seqs), desc=label, unit="frame", disable=quiet, leave=False,
              mininterval=0.5) as bar:
        for seq in seqs:
            model.reset_sequence()
            for x in seq.angles:
                model.step(x)
            bar.update(len(seq))
