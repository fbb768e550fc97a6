"""The confidence gate's settings: how safe against holding still, and at what cost where the model is good.

The gate (`default_predictor.gate`) only reads the wrapped model's outputs and never changes the model, so
the default's local-linear P-GWR is run once per condition with its outputs recorded, and every gate
variant replays exactly those outputs frame by frame (the same frames, the same model, no peeking):
a grid of gates costs little more than one run. Conditions:
* real people (`real.load_clips`): every clip one pass from scratch, and each climbing take held out
  after the other takes were learned (the two protocols of `experiment real`);
* the demonstrator: each pattern one pass from scratch, and the held-out repetitions and person
  after `epochs` passes over the training split (still learning while scored), and `experiment
  delay`'s person (the held-out subject doing every pattern once, back to back, open loop).
The figures: the worst MAE ratio to hold-last over the horizons on any clip / take / pattern (the
"never worse than holding still" band), and the 600 ms MAE and MSE ratios where motion repeats.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.default_predictor.gate import GatedPredictor, GateParams
from gwr_predictor.evaluation.metrics import HorizonStats
from gwr_predictor.evaluation.online import compare_online, train_online
from gwr_predictor.evaluation.output import ExperimentOutput, markdown_table
from gwr_predictor.predictors.baselines import HoldLast
from research.experiments import common, real
from research.experiments.delay import person_sequence
from research.experiments.splits import make_splits
from research.registry import RESEARCH

NAME = "gate"

#: name -> GateParams changes; "default" is `GateParams()`, "plain" the least-squares gate before the bound.
VARIANTS: dict[str, dict[str, Any]] = {
    "plain, per joint (the first gate)": {"confidence": 0.0, "fast_decay": 0.0, "per_joint": True},
    "plain, pooled": {"confidence": 0.0, "fast_decay": 0.0},
    "bound z=2 only": {"fast_decay": 0.0},
    "short memory only": {"confidence": 0.0},
    "short memory per step, 0.8, z=0.5": {"fast_decay": 0.8, "fast_step": 0, "fast_confidence": 0.5},
    "short memory per step, 0.9": {"fast_step": 0},
    "short memory z=0.5": {"fast_confidence": 0.5},
    "default (bound z=2 + short memory of step 1, 0.9, z=0)": {},
    "default, bound z=1": {"confidence": 1.0},
    "default, bound z=3": {"confidence": 3.0},
    "default, short memory 0.95": {"fast_decay": 0.95},
    "default, short memory 0.85": {"fast_decay": 0.85},
    "default, short memory z=1": {"fast_confidence": 1.0},
    "default, short memory of step 2": {"fast_step": 2},
    "default, per joint": {"per_joint": True},
    "ungated model": None,
}


@dataclass(frozen=True)
class Config:
    clips: tuple[str, ...] | None = None  # real clips (None = all; () = none, e.g. offline)
    patterns: tuple[str, ...] | None = None
    subjects: int = 3
    repetitions: int = 10
    heldout_repetitions: int = 2
    epochs: int = 5
    variants: tuple[str, ...] = tuple(VARIANTS)


DEFAULT = "default (bound z=2 + short memory of step 1, 0.9, z=0)"
QUICK = Config(clips=(), patterns=("wave_one", "raise_front_both"), subjects=2, repetitions=3,
               heldout_repetitions=1, epochs=1,
               variants=("plain, per joint (the first gate)", DEFAULT, "ungated model"))
FULL = Config()


class _Recorder:
    """Passes a model through and keeps every output (None where none), with a mark at each reset."""

    def __init__(self, model: Any) -> None:
        self.model, self.params, self.outputs = model, model.params, []

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        out = self.model.step(x, learn=learn)
        self.outputs.append(None if out is None else np.array(out, dtype=float))
        return out

    def reset_sequence(self) -> None:
        self.model.reset_sequence()
        self.outputs.append("reset")


class _Replay:
    """Gives back a recording, call by call; a call out of turn is an error, not a silent mismatch."""

    def __init__(self, outputs: list[Any], params: Any) -> None:
        self.outputs, self.params, self._i = outputs, params, 0

    def _next(self, reset: bool) -> Any:
        out = self.outputs[self._i]
        self._i += 1
        if (isinstance(out, str)) != reset:
            raise RuntimeError(f"replay out of step at call {self._i}")
        return out

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        return self._next(False)

    def reset_sequence(self) -> None:
        self._next(True)


def _conditions(config: Config, seed: int) -> dict[str, tuple[list[Any], list[Any]]]:
    """name -> (sequences learned first, sequences scored)."""

    out: dict[str, tuple[list[Any], list[Any]]] = {}
    if config.clips != ():
        clips = real.load_clips(real.Config(clips=config.clips))
        for c in clips:
            out[f"real, one pass/{c['name']}"] = ([], [c["angles"]])
        for held, others in real.left_out_takes(clips):
            out[f"real, left out/{held['name']}"] = (others, [held["angles"]])
    data = common.demo_data(config.patterns, config.subjects, config.repetitions, seed)
    for pattern, seqs in common.by_pattern(data).items():
        out[f"demonstrator, from scratch/{pattern}"] = ([], list(seqs))
    splits = make_splits(data, 1, config.heldout_repetitions)
    rng = np.random.default_rng(seed)
    train = [s for _ in range(config.epochs) for s in common.shuffled(splits.train, rng)]
    out["demonstrator, trained/new repetitions"] = (train, list(splits.heldout_repetitions))
    out["demonstrator, trained/new person"] = (train, list(splits.heldout_subjects))
    out["demonstrator, trained/closed-loop person"] = (train, [person_sequence(splits.heldout_subjects)])
    return out


def _score(model: Any, learned: list[Any], scored: list[Any], horizon: int) -> tuple[HorizonStats, HorizonStats]:
    if learned:
        train_online(model, learned, progress=False)
    res = compare_online({"hold": HoldLast(), "m": model}, scored, horizon=horizon, progress=False)
    return res["hold"].stats, res["m"].stats


def run(config: Config, out: Path, seed: int = 0, progress: bool = True) -> ExperimentOutput:
    from tqdm import tqdm


    params = common.make_params()
    conds = _conditions(config, seed)
    ratios: dict[str, dict[str, dict[str, Any]]] = {v: {} for v in config.variants}
    with tqdm(total=len(conds) * (1 + len(config.variants)), desc=NAME, disable=not progress, leave=False) as bar:
        for name, (learned, scored) in conds.items():
            recorder = _Recorder(RESEARCH.make_predictor(common.GATED, params, seed).model)
            _score(recorder, learned, scored, params.horizon)
            bar.update()
            for v in config.variants:
                replay = _Replay(recorder.outputs, recorder.params)
                changes = VARIANTS[v]
                model = replay if changes is None else GatedPredictor(replay, GateParams(
                    horizon=params.horizon, joints=params.n_joints, **changes))
                hold, m = _score(model, learned, scored, params.horizon)
                ratios[v][name] = {"mae": (np.array(m.mae) / np.array(hold.mae)).tolist(),
                                   "mse": (np.array(m.mse) / np.array(hold.mse)).tolist()}
                bar.update()
    summary = {v: _summary(r) for v, r in ratios.items()}
    results = {"conditions": list(conds), "ratio_to_hold": ratios, "summary": summary}
    return ExperimentOutput(NAME, "The confidence gate: safety against holding still vs gain", asdict(config),
                            results, _markdown(summary), [])


def _summary(r: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """Worst MAE ratio over the horizons per group of conditions; 600 ms ratios of the trained ones."""
    out: dict[str, Any] = {}
    for name, v in r.items():
        group, _ = name.split("/")
        worst = max(v["mae"])
        if worst > out.get(f"worst: {group}", (-np.inf, ""))[0]:
            out[f"worst: {group}"] = (worst, name.split("/")[1])
    for name, v in r.items():
        if name.startswith("demonstrator, trained/"):
            out[f"600 ms: {name.split('/')[1]}"] = (v["mae"][-1], v["mse"][-1])
    return out


def _markdown(summary: dict[str, dict[str, Any]]) -> list[str]:
    keys = list(next(iter(summary.values())))
    headers = ["gate", *[k.replace("worst: ", "worst ") + (" (MAE / MSE)" if k.startswith("600") else "")
                         for k in keys]]

    def cell(k: str, v: Any) -> str:
        return f"{v[0]:.3f} / {v[1]:.3f}" if k.startswith("600") else f"{v[0]:.3f} ({v[1]})"

    return ["Ratios to hold-last's error on the same frames (below 1: better than holding the last pose). "
            "'worst': the largest MAE ratio over horizons 1..6 on any clip, take or pattern of the group "
            "(the band the default must stay under: 1.02); '600 ms': MAE and MSE ratios at 600 ms on the "
            "demonstrator's held-out splits after training (learning online while scored).", "",
            markdown_table(headers, [[v, *[cell(k, s[k]) for k in keys]] for v, s in summary.items()])]
