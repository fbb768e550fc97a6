"""Impact of the activation threshold (Sec. VI-B3, Fig. 6): P-GWR neurons versus prediction MSE.

A hierarchy is trained on the training split; then GWR1 and GWR2 are frozen and, for every a_T,
the P-GWR is replaced by a fresh one with that threshold and re-learned incrementally (patterns
one after another). Its size and its MSE, frozen, on the training data and on held-out
repetitions and subjects, give the neurons-vs-MSE curve.
"""

from __future__ import annotations

import copy
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.evaluation.online import compare_online, train_online
from gwr_predictor.evaluation.output import ExperimentOutput, figure, markdown_table, save_figure
from research.experiments import common
from research.experiments.splits import make_splits

NAME = "threshold"


@dataclass(frozen=True)
class Config:
    thresholds: tuple[float, ...] = (0.5, 0.55, 0.6, 0.65, 0.7, 0.75, 0.8, 0.85, 0.9, 0.95, 0.99)
    patterns: tuple[str, ...] | None = None
    subjects: int = 3
    repetitions: int = 10
    heldout_subjects: int = 1
    heldout_repetitions: int = 2
    pretrain_epochs: int = 3
    epochs_per_pattern: int = 3
    overrides: tuple[tuple[str, object], ...] = ()


QUICK = Config(thresholds=(0.5, 0.9, 0.99), patterns=("wave_one", "raise_front_one"), subjects=2, repetitions=2,
               heldout_repetitions=1, pretrain_epochs=1, epochs_per_pattern=1)
FULL = Config()


def measure(config: Config, seed: int, progress: bool) -> dict[str, Any]:
    params = common.make_params(config.overrides)
    data = common.demo_data(config.patterns, config.subjects, config.repetitions, seed)
    splits = make_splits(data, config.heldout_subjects, config.heldout_repetitions)
    base = common.make_model(common.HIERARCHY, params, seed)
    rng = np.random.default_rng(seed)
    for epoch in range(config.pretrain_epochs):
        train_online(base, common.shuffled(splits.train, rng), progress=progress,
                     desc=f"{NAME} pretrain {epoch + 1}/{config.pretrain_epochs}")
    base.freeze_layers(("gwr1", "gwr2"))
    groups = common.by_pattern(splits.train)
    points = []
    for a_t in config.thresholds:
        model = copy.deepcopy(base)
        model.reset_layer("pgwr", params.pgwr.replace(activation_threshold=a_t))
        for pattern in groups:
            for _ in range(config.epochs_per_pattern):
                train_online(model, common.shuffled(groups[pattern], rng), progress=progress,
                             desc=f"{NAME} a_T={a_t} {pattern}")
        point: dict[str, Any] = {"a_t": a_t, "neurons": list(model.neuron_counts)}
        for split_name, seqs in splits.items():
            if seqs:
                res = compare_online({"h": model}, seqs, learn=False, horizon=params.horizon, progress=False)["h"]
                point[split_name] = {"mse": res.stats.mse[-1], "mae": res.stats.mae[-1]}
        points.append(point)
    return {"params": params.to_flat(), "lower_layers": list(base.neuron_counts[:2]), "points": points}


def run(config: Config, out: Path, seed: int = 0, progress: bool = True) -> ExperimentOutput:
    r = measure(config, seed, progress)
    splits = [k for k in ("train", "heldout_repetitions", "heldout_subjects") if k in r["points"][0]]
    rows = [[f"{p['a_t']:g}", p["neurons"][2], *[p[s]["mse"] for s in splits]] for p in r["points"]]
    md = [f"GWR1/GWR2 frozen with {r['lower_layers']} neurons; P-GWR re-learned ({config.epochs_per_pattern} "
          f"epochs per pattern, patterns one after another) for each a_T. MSE (rad²) at the "
          f"{r['params']['horizon']}-frame horizon, frozen.", "",
          markdown_table(["a_T", "P-GWR neurons", *[f"MSE {s.replace('_', ' ')}" for s in splits]], rows, digits=4)]
    return ExperimentOutput(NAME, "Impact of the activation threshold", asdict(config), r, md,
                            [_plot(r, splits, Path(out))])


def _plot(r: dict[str, Any], splits: list[str], out: Path) -> str:
    fig, axes = figure(size=(6.0, 4.0))
    ax = axes[0][0]
    n = [p["neurons"][2] for p in r["points"]]
    for s in splits:
        ax.plot(n, [p[s]["mse"] for p in r["points"]], marker="o", ms=4, label=s.replace("_", " "))
    for p in r["points"]:
        ax.annotate(f"{p['a_t']:g}", (p["neurons"][2], p["train"]["mse"]), fontsize=7, xytext=(3, 3),
                    textcoords="offset points")
    ax.set_xscale("symlog")
    ax.set_xlabel("P-GWR neurons")
    ax.set_ylabel("MSE at the horizon (rad²)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return save_figure(fig, out, "threshold_neurons_vs_mse")
