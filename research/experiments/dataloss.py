"""Learning with missing sensory data (Sec. VI-C, Fig. 8): 0..95 % of the frames lost in 1 s chunks.

For every loss level and pattern a fresh model learns that pattern's demonstrations for `epochs`
epochs, each epoch with newly drawn lost chunks (a lost frame is a missing sample, x = None). Two
numbers per level: the online MSE while learning, scored on the frames that did arrive and
averaged over the epochs (the paper's measure), and the MSE of the trained model, frozen, on the
complete demonstrations it learned from and on held-out repetitions (did it still learn the
movement?). Baselines run on the same frames.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.data.faults import CHUNK_FRAMES, drop_chunks
from gwr_predictor.evaluation.metrics import HorizonStats
from gwr_predictor.evaluation.online import compare_online
from gwr_predictor.evaluation.output import ExperimentOutput, figure, markdown_table, save_figure
from research.experiments import common

NAME = "dataloss"


@dataclass(frozen=True)
class Config:
    losses: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95)
    patterns: tuple[str, ...] | None = None
    subjects: int = 3
    train_repetitions: int = 2  # per subject; demonstrations per epoch = subjects * this
    test_repetitions: int = 1  # further repetitions per subject, never trained on
    epochs: int = 20
    chunk: int = CHUNK_FRAMES
    methods: tuple[str, ...] = ("hold", "rls_ar", common.HIERARCHY, common.DEFAULT)
    overrides: tuple[tuple[str, object], ...] = ()


QUICK = Config(losses=(0.0, 0.3, 0.9), patterns=("wave_one",), subjects=1, train_repetitions=2, epochs=2)
FULL = Config()


def masked(angles: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """A copy with the lost frames set to NaN (missing samples)."""
    out = np.array(angles, dtype=float)
    out[~keep] = np.nan
    return out


def one_level(config: Config, loss: float, data: tuple[Any, ...], seed: int, progress: bool) -> dict[str, Any]:
    params = common.make_params(config.overrides)
    h = params.horizon
    empty = {m: HorizonStats.empty(h) for m in config.methods}
    online, clean, heldout = dict(empty), dict(empty), dict(empty)
    kept = total = 0
    fed = {m: 0 for m in config.methods}
    predicted = {m: 0 for m in config.methods}
    rng = np.random.default_rng([seed, round(loss * 1000)])
    for pattern, seqs in common.by_pattern(data).items():
        train = [s for s in seqs if s.repetition <= config.train_repetitions]
        test = [s for s in seqs if s.repetition > config.train_repetitions]
        models = common.make_models(config.methods, params, seed)
        for epoch in range(config.epochs):
            order = common.shuffled(train, rng)
            keeps = [drop_chunks(len(s.angles), loss, config.chunk, rng) for s in order]
            kept += sum(int(k.sum()) for k in keeps)
            total += sum(k.size for k in keeps)
            res = compare_online(models, [masked(s.angles, k) for s, k in zip(order, keeps, strict=True)],
                                 horizon=h, progress=progress, desc=f"loss {loss:.0%} {pattern} {epoch + 1}")
            online = {m: online[m].merge(r.stats) for m, r in res.items()}
            for m, r in res.items():
                fed[m] += r.frames
                predicted[m] += r.predicted_frames
        for store, seqs_ in ((clean, train), (heldout, test)):
            if seqs_:
                res = compare_online(common.clone(models), seqs_, learn=False, horizon=h, progress=False)
                store.update({m: store[m].merge(r.stats) for m, r in res.items()})
    return {"loss": loss, "kept_fraction": kept / max(total, 1),
            "coverage": {m: predicted[m] / max(fed[m], 1) for m in config.methods},
            "online": {m: s.to_dict() for m, s in online.items()},
            "clean": {m: s.to_dict() for m, s in clean.items()},
            "heldout": {m: s.to_dict() for m, s in heldout.items()}}


def run(config: Config, out: Path, seed: int = 0, progress: bool = True) -> ExperimentOutput:
    reps = config.train_repetitions + config.test_repetitions
    data = common.demo_data(config.patterns, config.subjects, reps, seed)
    levels = [one_level(config, loss, data, seed, progress) for loss in config.losses]
    h = common.make_params(config.overrides).horizon
    hier = common.HIERARCHY

    def mse(level: dict[str, Any], kind: str, m: str) -> float:
        value = level[kind][m]["mse"][-1]
        return np.nan if value is None else value

    def change(level: dict[str, Any], kind: str, m: str = hier) -> str:
        ratio = mse(level, kind, m) / mse(levels[0], kind, m)
        return "–" if not np.isfinite(ratio) else f"{100 * (ratio - 1):+.1f} %"

    shown = [m for m in (hier, "rls_ar", common.DEFAULT) if m in config.methods]
    rows = [[f"{lv['loss']:.0%}", lv["kept_fraction"], lv["coverage"][hier],
             *[mse(lv, k, m) for k in ("online", "clean", "heldout") for m in shown],
             change(lv, "online"), change(lv, "clean"),
             *([change(lv, "online", common.DEFAULT)] if common.DEFAULT in config.methods else [])] for lv in levels]
    heads = ["loss", "kept", "hierarchy coverage", *[f"{k} {common.label(m)}" for k in ("online", "clean", "heldout")
                                                     for m in shown], "hier. online vs 0 %", "hier. clean vs 0 %",
             *(["default online vs 0 %"] if common.DEFAULT in config.methods else [])]
    within = [lv["loss"] for lv in levels
              if lv["loss"] <= 0.3 and mse(lv, "online", hier) <= 1.1 * mse(levels[0], "online", hier)]
    md = [f"MSE (rad²) at the {h}-frame horizon. *online*: while learning with the loss, on the frames that "
          f"arrived, over {config.epochs} epochs per pattern (the paper's measure); *clean*: the trained model, "
          f"frozen, on the complete demonstrations it learned from; *heldout*: on complete unseen repetitions. "
          f"*coverage*: share of the fed frames at which the hierarchy could predict (it needs "
          f"{common.make_params(config.overrides).span} consecutive frames after every gap).",
          "", markdown_table(heads, rows, digits=4), "",
          f"Loss levels ≤ 30 % whose online MSE is within 10 % of the loss-free MSE: "
          f"{[f'{x:.0%}' for x in within]}."]
    return ExperimentOutput(NAME, "Learning with missing sensory data", asdict(config), {"levels": levels}, md,
                            [_plot(levels, config.methods, Path(out))])


def _plot(levels: list[dict[str, Any]], methods: tuple[str, ...], out: Path) -> str:
    fig, axes = figure(1, 2, size=(10.0, 3.8))
    x = [100 * lv["loss"] for lv in levels]
    for ax, kind, title in ((axes[0][0], "online", "online, while learning"),
                            (axes[0][1], "clean", "frozen, on complete sequences")):
        for m in methods:
            ax.plot(x, [lv[kind][m]["mse"][-1] for lv in levels], marker="o", ms=3, label=common.label(m))
        if kind == "clean":
            ax.plot(x, [lv["heldout"][common.HIERARCHY]["mse"][-1] for lv in levels], "--", marker="x", ms=3,
                    color=f"C{methods.index(common.HIERARCHY)}", label="GWR hierarchy, held-out reps")
        ax.axvline(30, color="k", ls=":", lw=0.8)
        ax.set_yscale("log")
        ax.set_title(title)
        ax.set_xlabel("data removed (%)")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("MSE at the horizon (rad², log)")
    axes[0][1].legend(fontsize=8)
    return save_figure(fig, out, "dataloss_mse")
