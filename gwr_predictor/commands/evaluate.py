"""`gwr-predictor evaluate FILE...`: online evaluation of recordings, the learners against the baselines.

Files are skeleton recordings (NPZ/CSV, 30 fps: median of 3 -> 10 fps -> angles), mocap
recordings (.bvh, .amc, .npy/.npz joint positions, .pt: mapped and resampled to the same 30 fps
stream, see `data.mocap`) or angle CSVs (10 fps). All methods learn online on the recordings in
the given order (optionally several passes) and are scored on the same frames; the table goes to
stdout and its numbers again as one JSON object on the last line (keys horizon, mae_rad, frames,
neurons, default_method: the key of the learner node's default predictor, always evaluated). The
methods that state an interval with every prediction (the default, `hold`, `rls_ar`) get a second
table, the share of true angles inside it and its mean width per step: in the JSON line
`interval_nominal` (the stated share), `interval_coverage[method]` and `interval_width_rad[method]`.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor import registry
from gwr_predictor.commands.errors import CommandError
from gwr_predictor.commands.import_options import add_import_options, import_options
from gwr_predictor.commands.param_overrides import parse_overrides
from gwr_predictor.data.angle_files import load_angles_csv
from gwr_predictor.data.errors import DataError
from gwr_predictor.data.extraction import extract_angles
from gwr_predictor.data.mocap import load_any_skeleton
from gwr_predictor.data.mocap_clip import ImportOptions
from gwr_predictor.evaluation.online import EvaluationError, compare_online
from gwr_predictor.evaluation.output import markdown_table, to_jsonable
from gwr_predictor.learning.params import HierarchyParams
from gwr_predictor.learning.protocol import Learner, Predictor
from gwr_predictor.robot.nao import ARM_JOINTS

DEFAULT_METHODS = ("hold", "const_velocity", "rls_ar", "hierarchy")


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("files", nargs="+", type=Path,
                        help="recordings: skeleton (.npz/.csv), angle (.csv) or mocap (.bvh, .amc, .npy/.npz "
                             "joint positions, .pt) files")
    parser.add_argument("--passes", type=int, default=1, help="times the recordings are presented (default 1)")
    parser.add_argument("--horizon", type=int, default=None,
                        help="frames every model predicts ahead and is scored at (default 6: 600 ms at 10 fps)")
    parser.add_argument("--methods", default=",".join(DEFAULT_METHODS),
                        help=f"comma-separated subset of {','.join(registry.names())}")
    parser.add_argument("--checkpoint", type=Path, default=None,
                        help="start the method 'hierarchy' (the paper's model) from this checkpoint of one; the "
                             "other methods start fresh")
    parser.add_argument("--param", action="append", default=[], metavar="KEY=VALUE",
                        help="a setting of the method 'hierarchy' (the paper's model), flat as in its params-file "
                             "section (e.g. gwr1.eps_b=0.1); horizon and n_joints reach every method (repeatable)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-progress", action="store_true")
    add_import_options(parser)


def default_method() -> str:
    """The predictor the arm_predictor node runs by default (its key in evaluate's `mae_rad`)."""
    return registry.default_name()


def load_recording(path: Path, options: ImportOptions | None = None) -> np.ndarray:
    """Angles (T, 8) at 10 fps in ARM_JOINTS order from an angle CSV, a skeleton or a mocap file."""
    angle_error = None
    if path.suffix.lower() == ".csv":
        try:
            _, angles, names = load_angles_csv(path)
        except DataError as exc:
            angle_error = exc
        else:
            missing = [n for n in ARM_JOINTS if n not in names]
            if missing:
                raise CommandError(f"{path}: angle file lacks the arm joints {missing}")
            return angles[:, [names.index(n) for n in ARM_JOINTS]]
    try:
        seq = load_any_skeleton(path, options)
    except DataError as exc:
        raise CommandError(f"{path}: not an angle CSV ({angle_error}) nor a skeleton file ({exc})"
                           if angle_error else str(exc)) from exc
    return extract_angles(seq.positions, seq.timestamps, seq.joint_names).angles


def run(args: argparse.Namespace) -> int:
    try:
        methods = tuple(m.strip() for m in args.methods.split(",") if m.strip())
        if unknown := [m for m in methods if m not in registry.names()]:
            raise CommandError(f"unknown methods {unknown}; choose from {', '.join(registry.names())}")
        if args.passes < 1:
            raise CommandError(f"--passes must be >= 1, got {args.passes}")
        if default_method() not in methods:
            methods = (*methods, default_method())
        options = import_options(args)
        recordings = [load_recording(p, options) for p in args.files]
        overrides = parse_overrides(args.param)
        if args.horizon is not None:  # the models predict as far as they are scored
            if overrides.setdefault("horizon", args.horizon) != args.horizon:
                raise CommandError(f"--horizon {args.horizon} and --param horizon={overrides['horizon']} disagree")
        params = HierarchyParams.from_flat(overrides)
        models = {m: (registry.load_predictor(m, args.checkpoint) if m == "hierarchy" and args.checkpoint
                      else registry.make_predictor(m, params, args.seed)) for m in methods}
        horizon = params.horizon
        results = compare_online(models, recordings, horizon=horizon, passes=args.passes,
                                 progress=not args.no_progress, desc="evaluate")
    except (ValueError, OSError) as exc:  # CommandError, EvaluationError, LearningError, bad params
        kind = "evaluation" if isinstance(exc, EvaluationError) else "input"
        print(f"error ({kind}): {exc}", file=sys.stderr)
        return 2
    steps = sorted({1, *range(2, horizon + 1, max(1, horizon // 6)), horizon})
    rows = [[registry.label(m), *[r.stats.mae[k - 1] for k in steps], r.coverage] for m, r in results.items()]
    first = next(iter(results.values()))
    print(f"{len(recordings)} recording(s), {first.frames} frames fed ({args.passes} pass(es)), "
          f"{first.scored_frames} scored on the same frames by every method. MAE (rad) per horizon step:")
    print(markdown_table(["method", *[f"h={k}" for k in steps], "coverage"], rows))
    spreads = {m: r for m, r in results.items() if r.interval is not None}
    nominals = {m: r.interval_nominal for m, r in spreads.items()}
    # one stated share (every method's, by default), else per method
    nominal: Any = next(iter(nominals.values())) if len(set(nominals.values())) == 1 else nominals or None
    if spreads:
        print(f"Stated central interval ({_percent(nominal) if isinstance(nominal, float) else 'shares differ'}): "
              "share of the true angles inside it / mean width (rad) per horizon step, on the same frames:")
        print(markdown_table(["method", *[f"h={k}" for k in steps]], [
            [registry.label(m), *[f"{_percent(r.interval.coverage[k - 1])} / {r.interval.width[k - 1]:.3f}"
                                  for k in steps]] for m, r in spreads.items() if r.interval is not None]))
    summary = {"horizon": horizon, "mae_rad": {m: r.stats.mae for m, r in results.items()},
               "mse_rad2": {m: r.stats.mse for m, r in results.items()},
               "default_method": default_method(),
               "frames": first.frames, "scored_frames": first.scored_frames, "passes": args.passes,
               "neurons": _neurons(models), "interval_nominal": nominal,
               "interval_coverage": {m: r.interval.coverage for m, r in spreads.items() if r.interval is not None},
               "interval_width_rad": {m: r.interval.width for m, r in spreads.items() if r.interval is not None}}
    print(json.dumps(to_jsonable(summary)))
    return 0


def _percent(share: float | None) -> str:
    return "–" if share is None or not np.isfinite(share) else f"{100 * share:.1f} %"


def _neurons(models: Mapping[str, Predictor]) -> dict[str, list[int]]:
    """Neurons per layer of the methods that grow a network (the others have none to report)."""
    return {m: [int(c) for c in model.neuron_counts] for m, model in models.items()
            if isinstance(model, Learner) and model.neuron_counts}
