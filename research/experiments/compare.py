"""Baselines and ablation side by side, on the same frames, on trained and held-out data.

Every method (hold, constant velocity, RLS-AR, P-GWR alone, hierarchy, and the per-step inverse-MSE
blends of hierarchy or P-GWR alone with RLS-AR, `research.blend`) is trained online on the
training split for `epochs` passes in random order; the online error of every pass is the learning
curve. Then each trained model is copied and evaluated on the training split, held-out repetitions
and held-out subjects, once frozen and once still learning (the paper's continual setting).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.evaluation.online import compare_online
from gwr_predictor.evaluation.output import ExperimentOutput, figure, markdown_table, save_figure
from research.experiments import common
from research.experiments.splits import make_splits

NAME = "compare"
CONDITIONS = ("train", "heldout_repetitions", "heldout_subjects")
CONDITION_LABELS = {"train": "trained on", "heldout_repetitions": "held-out repetitions",
                    "heldout_subjects": "held-out subject"}


@dataclass(frozen=True)
class Config:
    patterns: tuple[str, ...] | None = None  # None = all 10
    subjects: int = 3
    repetitions: int = 10
    heldout_subjects: int = 1
    heldout_repetitions: int = 2
    epochs: int = 5
    methods: tuple[str, ...] = tuple(m for m in common.all_methods() if m not in common.ABLATIONS)
    overrides: tuple[tuple[str, object], ...] = ()


QUICK = Config(patterns=("wave_one", "raise_front_both"), subjects=2, repetitions=3, heldout_repetitions=1,
               epochs=1)
FULL = Config()


def train_and_evaluate(config: Config, seed: int, progress: bool) -> dict[str, Any]:
    """The measurements, without any writing: learning curve, per-condition per-horizon stats."""
    params = common.make_params(config.overrides)
    data = common.demo_data(config.patterns, config.subjects, config.repetitions, seed)
    splits = make_splits(data, config.heldout_subjects, config.heldout_repetitions)
    from_scratch = {}
    for pattern, seqs in common.by_pattern(data).items():  # a new user's first minutes: no training
        res = compare_online(common.make_models(config.methods, params, seed), seqs, horizon=params.horizon,
                             progress=progress, desc=f"{NAME} from scratch {pattern}")
        from_scratch[pattern] = {m: r.summary() for m, r in res.items()}
    models = common.make_models(config.methods, params, seed)
    rng = np.random.default_rng(seed)
    curve: dict[str, list[float]] = {m: [] for m in config.methods}
    growth: dict[str, list[list[int] | None]] = {m: [] for m in config.methods}
    for epoch in range(config.epochs):
        res = compare_online(models, common.shuffled(splits.train, rng), horizon=params.horizon,
                             progress=progress, desc=f"{NAME} epoch {epoch + 1}/{config.epochs}")
        for m, r in res.items():
            curve[m].append(float(r.stats.mae[-1]))
            growth[m].append(common.neuron_counts(models[m]))
    conditions: dict[str, Any] = {}
    for split_name, seqs in splits.items():
        if not seqs:
            continue
        for learn in (False, True):
            res = compare_online(common.clone(models), seqs, learn=learn, horizon=params.horizon,
                                 progress=progress, desc=f"{split_name} learn={learn}")
            conditions[f"{split_name}/{'online' if learn else 'frozen'}"] = {m: r.summary() for m, r in res.items()}
    return {"params": params.to_flat(), "splits": splits.sizes(), "frames_per_epoch": common.frames_in(splits.train),
            "learning_curve_mae_h": curve, "neurons_per_epoch": growth, "conditions": conditions,
            "from_scratch": from_scratch,
            "neurons": {m: common.neuron_counts(models[m]) for m in config.methods}}


def run(config: Config, out: Path, seed: int = 0, progress: bool = True) -> ExperimentOutput:
    r = train_and_evaluate(config, seed, progress)
    horizon = int(r["params"]["horizon"])
    methods = config.methods
    conds = [c for c in r["conditions"]]
    headers = ["method", *[f"{CONDITION_LABELS[c.split('/')[0]]} ({c.split('/')[1]})" for c in conds]]

    def table(metric: str) -> str:
        return markdown_table(headers, [[common.label(m), *[r["conditions"][c][m][metric][-1] for c in conds]]
                                        for m in methods], digits=3 if metric == "mae" else 4)

    best = {c: min(methods, key=lambda m, c=c: r["conditions"][c][m]["mae"][-1]) for c in conds}
    best_mse = {c: min(methods, key=lambda m, c=c: r["conditions"][c][m]["mse"][-1]) for c in conds}
    md = [f"MAE (rad) at the {horizon}-frame ({100 * horizon} ms) horizon, every method scored on the same "
          f"frames. Splits: {r['splits']}; {config.epochs} training epochs of {r['frames_per_epoch']} frames; "
          f"neurons: {r['neurons']}.", "", table("mae"), "",
          "Best MAE per column: " + ", ".join(f"{c}: {common.label(m)}" for c, m in best.items()) + ".", "",
          "MSE (rad²) at the same horizon, same frames (large errors weigh more):", "", table("mse"), "",
          "Best MSE per column: " + ", ".join(f"{c}: {common.label(m)}" for c, m in best_mse.items()) + ".",
          "", *_from_scratch_table(r, methods)]
    out = Path(out)
    figs = [_plot_horizons(r, methods, out), _plot_curve(r, methods, out)]
    return ExperimentOutput(NAME, "Hierarchy vs baselines and ablation", _config_dict(config), r, md, figs)


def _from_scratch_table(r: dict[str, Any], methods: tuple[str, ...]) -> list[str]:
    """Per pattern, one online pass from scratch: each method's worst MAE ratio to hold-last over the horizons."""
    per = r["from_scratch"]
    ratio = {m: [common.worst_ratio_to_hold(per[p], m) for p in per] for m in methods if m != "hold"}
    return ["One online pass from scratch over each pattern's recordings (fresh models, no training): worst MAE "
            "ratio to hold-last over the horizons (below 1: better than holding the last pose at every horizon):",
            "", markdown_table(["method", *per], [[common.label(m), *["–" if v is None else f"{v:.3f}" for v in vals]]
                                                  for m, vals in ratio.items()])]


def _config_dict(config: Config) -> dict[str, Any]:
    from dataclasses import asdict

    return asdict(config)


def _plot_horizons(r: dict[str, Any], methods: tuple[str, ...], out: Path) -> str:
    conds = [c for c in ("train/frozen", "heldout_repetitions/frozen", "heldout_subjects/online")
             if c in r["conditions"]]
    fig, axes = figure(2, len(conds), size=(4.2 * len(conds), 6.6))
    for row, metric in enumerate(("mae", "mse")):
        for ax, c in zip(axes[row], conds, strict=True):
            for m in methods:
                vals = r["conditions"][c][m][metric]
                ax.plot(np.arange(1, len(vals) + 1), vals, marker="o", ms=3, label=common.label(m))
            if row == 0:
                ax.set_title(c.replace("_", " "))
            else:
                ax.set_xlabel("horizon (frames of 100 ms)")
            ax.grid(alpha=0.3)
        axes[row][0].set_ylabel("MAE (rad)" if metric == "mae" else "MSE (rad²)")
    axes[0][-1].legend(fontsize=7)
    return save_figure(fig, out, "compare_mae_vs_horizon")


def _plot_curve(r: dict[str, Any], methods: tuple[str, ...], out: Path) -> str:
    fig, axes = figure(size=(5.5, 3.6))
    ax = axes[0][0]
    for m in methods:
        curve = r["learning_curve_mae_h"][m]
        ax.plot(np.arange(1, len(curve) + 1), curve, marker="o", ms=3, label=common.label(m))
    ax.set_xlabel("training epoch (online error while learning)")
    ax.set_ylabel("MAE at the horizon (rad)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return save_figure(fig, out, "compare_learning_curve")
