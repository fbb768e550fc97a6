"""Input-scale sweep: how `HierarchyParams.input_scale` (model units per radian) and
`normalise_distance` trade neurons against error, to choose their defaults with evidence.

With a_T fixed, the scale sets the insertion distance in radians (-ln a_T / scale, times
sqrt(frames in a layer's input) when distances are normalised). For each variant
the `compare` protocol runs (online training on the training split, then frozen and online
evaluation on trained, held-out-repetition and held-out-subject data) for the hierarchy, the P-GWR
alone and RLS-AR as the reference, recording neurons after every epoch.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.evaluation.output import ExperimentOutput, figure, markdown_table, save_figure
from research.experiments import common, compare

NAME = "scale"
SHOWN = ("train/frozen", "heldout_repetitions/frozen", "heldout_subjects/online")


@dataclass(frozen=True)
class Config:
    #: (input_scale, normalise_distance) pairs
    variants: tuple[tuple[float, bool], ...] = ((0.05, True), (0.07, True), (0.1, True), (0.14, True),
                                                (0.03, False), (0.05, False))
    base: compare.Config = field(default_factory=lambda: compare.Config(
        epochs=4, methods=("rls_ar", common.FLAT, common.HIERARCHY)))
    overrides: tuple[tuple[str, object], ...] = ()


QUICK = Config(variants=((0.03, False), (0.1, False)),
               base=replace(compare.QUICK, methods=("rls_ar", common.HIERARCHY), overrides=()))
FULL = Config()


def run(config: Config, out: Path, seed: int = 0, progress: bool = True) -> ExperimentOutput:
    defaults = common.make_params(config.overrides)
    a_t, tau1, tau2 = defaults.gwr1.activation_threshold, defaults.tau1, defaults.tau2
    points = []
    for scale, norm in config.variants:
        cfg = replace(config.base, overrides=(*config.overrides, ("input_scale", scale), ("normalise_distance", norm)))
        points.append({"input_scale": scale, "normalise_distance": norm,
                       **compare.train_and_evaluate(cfg, seed, progress)})
    methods = config.base.methods
    rows = []
    for p in points:
        for m in methods:
            if m == "rls_ar" and p is not points[0]:
                continue  # independent of the scaling
            neurons = p["neurons"][m]
            dist = -math.log(a_t) / p["input_scale"]
            dists = [dist * (math.sqrt(f) if p["normalise_distance"] else 1.0) for f in (1, tau1, tau1 * tau2)]
            rows.append([f"{p['input_scale']:g}", "yes" if p["normalise_distance"] else "no",
                         "/".join(f"{d:.2f}" for d in dists), common.label(m),
                         "–" if neurons is None else "/".join(str(n) for n in neurons),
                         *[p["conditions"][c][m][k][-1] for k in ("mae", "mse") for c in SHOWN
                           if c in p["conditions"]]])
    heads = ["input_scale", "normalised", "insertion dist. GWR1/GWR2/P-GWR (rad)", "method", "neurons",
             *[f"MAE {c}" for c in SHOWN], *[f"MSE {c}" for c in SHOWN]]
    md = [f"a_T = {a_t:g}; {config.base.epochs} epochs on the training split per variant. MAE (rad) and MSE "
          "(rad²) at the 600 ms horizon; neurons per layer at the end of training.", "",
          markdown_table(heads, rows, digits=3)]
    results = {"activation_threshold": a_t, "points": points}
    return ExperimentOutput(NAME, "Input-scale sweep", asdict(config), results, md, [_plot(points, methods, Path(out))])


def _variant(p: dict[str, Any]) -> str:
    return f"{p['input_scale']:g}{'' if p['normalise_distance'] else ' (not norm.)'}"


def _plot(points: list[dict[str, Any]], methods: tuple[str, ...], out: Path) -> str:
    fig, axes = figure(1, 2, size=(10.0, 3.8))
    colors = [f"C{i}" for i in range(10)]
    ax = axes[0][0]
    for color, p in zip(colors, points, strict=False):
        growth = p["neurons_per_epoch"].get(common.HIERARCHY)
        if growth and growth[0] is not None:
            g = np.array(growth, float)
            for k, style in enumerate(("-", "--", ":")):
                ax.plot(np.arange(1, len(g) + 1), g[:, k], style, color=color, marker="o", ms=3,
                        label=_variant(p) if k == 0 else None)
    ax.set_yscale("log")
    ax.set_xlabel("training epoch")
    ax.set_ylabel("neurons: GWR1 (-), GWR2 (--), P-GWR (:)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, title="input_scale", title_fontsize=7)
    ax = axes[0][1]
    cond = SHOWN[1]
    for color, m in zip(colors, methods, strict=False):
        if m == "rls_ar":
            ax.axhline(points[0]["conditions"][cond][m]["mae"][-1], color=color, lw=1, label=common.label(m))
            continue
        for norm, style in ((True, "-o"), (False, "--s")):
            sel = [p for p in points if p["normalise_distance"] == norm]
            if sel:
                ax.plot([p["input_scale"] for p in sel], [p["conditions"][cond][m]["mae"][-1] for p in sel], style,
                        color=color, ms=4, label=f"{common.label(m)}{'' if norm else ' (not normalised)'}")
    ax.set_xscale("log")
    ax.set_xlabel("input_scale (model units per rad)")
    ax.set_ylabel("MAE at 600 ms, held-out repetitions (rad)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return save_figure(fig, out, "scale_sweep")
