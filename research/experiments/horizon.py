"""Sensitivity to the prediction horizon (Sec. VI-B4, Fig. 7): MAE and std for 1..20 frames.

Two hierarchies are trained on the training split, one predicting recursively and one with vector
outputs spanning all 20 steps (the vector mode needs its own training, Sec. III-E); the baselines
run alongside. Then all are evaluated frozen on the data they trained on (the paper's figure) and
on held-out repetitions and subjects.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.evaluation.online import compare_online
from gwr_predictor.evaluation.output import ExperimentOutput, figure, markdown_table, save_figure
from research.experiments import common
from research.experiments.splits import make_splits

NAME = "horizon"
RECURSIVE, VECTOR = "hierarchy_recursive", "hierarchy_vector"
_LABELS = {RECURSIVE: "hierarchy (recursive)", VECTOR: "hierarchy (vector)"}


def _label(name: str) -> str:
    return _LABELS.get(name) or common.label(name)


@dataclass(frozen=True)
class Config:
    patterns: tuple[str, ...] | None = None
    subjects: int = 3
    repetitions: int = 10
    heldout_subjects: int = 1
    heldout_repetitions: int = 2
    epochs: int = 5
    max_horizon: int = 20
    baselines: tuple[str, ...] = ("hold", "rls_ar")
    overrides: tuple[tuple[str, object], ...] = ()


QUICK = Config(patterns=("wave_one", "rotate_cw_both"), subjects=2, repetitions=3, heldout_repetitions=1,
               epochs=1, max_horizon=8)
FULL = Config()


def measure(config: Config, seed: int, progress: bool) -> dict[str, Any]:
    h = config.max_horizon
    rec = common.make_params(config.overrides, horizon=h, mode="recursive")
    vec = common.make_params(config.overrides, horizon=h, mode="vector")
    data = common.demo_data(config.patterns, config.subjects, config.repetitions, seed)
    splits = make_splits(data, config.heldout_subjects, config.heldout_repetitions)
    models = {RECURSIVE: common.make_model(common.HIERARCHY, rec, seed),
              VECTOR: common.make_model(common.HIERARCHY, vec, seed),
              **common.make_models(config.baselines, rec, seed)}
    rng = np.random.default_rng(seed)
    for epoch in range(config.epochs):
        compare_online(models, common.shuffled(splits.train, rng), horizon=h, progress=progress,
                       desc=f"{NAME} train {epoch + 1}/{config.epochs}")
    results: dict[str, Any] = {}
    for split_name, seqs in splits.items():
        if seqs:
            res = compare_online(common.clone(models), seqs, learn=False, horizon=h, progress=progress,
                                 desc=f"{NAME} {split_name}")
            results[split_name] = {m: r.summary() for m, r in res.items()}
    return {"params_recursive": rec.to_flat(), "splits": splits.sizes(), "evaluation": results,
            "neurons": {m: common.neuron_counts(models[m]) for m in models}}


def run(config: Config, out: Path, seed: int = 0, progress: bool = True) -> ExperimentOutput:
    r = measure(config, seed, progress)
    ev = r["evaluation"]
    steps = [k for k in (1, 3, 6, 10, 15, 20) if k <= config.max_horizon]
    md = [f"MAE ± std (rad) of the absolute error per horizon step (frames of 100 ms), models frozen after "
          f"{config.epochs} epochs on the training split; neurons {r['neurons']}."]
    for split_name, res in ev.items():
        rows = [[_label(m), *[f"{res[m]['mae'][k - 1]:.3f} ± {res[m]['std'][k - 1]:.3f}" for k in steps],
                 max(res[m]["mae"])] for m in res]
        md += ["", f"**{split_name.replace('_', ' ')}**", "",
               markdown_table(["method", *[f"h={k}" for k in steps], "max MAE"], rows)]
    worst = max(max(ev[s][m]["mae"]) for s in ev for m in (RECURSIVE, VECTOR))
    md += ["", f"Largest hierarchy MAE over all horizons and splits: {worst:.3f} rad (target < 0.25)."]
    return ExperimentOutput(NAME, "Sensitivity to the prediction horizon", asdict(config), r, md,
                            [_plot(ev, config.max_horizon, Path(out))])


def _plot(ev: dict[str, Any], horizon: int, out: Path) -> str:
    fig, axes = figure(1, len(ev), size=(4.2 * len(ev), 3.6))
    k = np.arange(1, horizon + 1)
    for ax, (split_name, res) in zip(axes[0], ev.items(), strict=True):
        for m, style in ((RECURSIVE, "-"), (VECTOR, "-"), ("rls_ar", "--"), ("hold", ":")):
            if m not in res:
                continue
            mae, std = np.array(res[m]["mae"], float), np.array(res[m]["std"], float)
            line, = ax.plot(k, mae, style, marker="o", ms=3, label=_label(m))
            if m in (RECURSIVE, VECTOR):
                ax.fill_between(k, mae - std, mae + std, color=line.get_color(), alpha=0.15)
        ax.axhline(0.25, color="k", lw=0.8, ls="--")
        ax.set_title(split_name.replace("_", " "))
        ax.set_xlabel("horizon (frames)")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("MAE ± std (rad)")
    axes[0][-1].legend(fontsize=8)
    return save_figure(fig, out, "horizon_mae")
