"""How fast does the architecture adapt to a new sequence? (Sec. VI-B1, Fig. 4)

The models first learn every pattern but one; then the demonstrations of the left-out pattern by
one subject are presented three times, learning on. The per-frame prediction error at the horizon
(Euclidean distance over the 8 joints) is traced with its linear trend. The settling frame is the
first frame after which the smoothed error stays within `tolerance` (+ `floor`) of the smoothed
error of the last presentation at the same point of the sequence: compared frame by frame, the
rise and fall of the error with the movement itself does not count as "not settled". Repeated for
several left-out patterns; the baselines adapt on the same frames.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.evaluation.metrics import linear_trend, moving_average, settling_frame
from gwr_predictor.evaluation.online import compare_online, train_online
from gwr_predictor.evaluation.output import ExperimentOutput, figure, markdown_table, save_figure
from research.experiments import common

NAME = "unseen"


@dataclass(frozen=True)
class Config:
    unseen_patterns: tuple[str, ...] = ("wave_both", "rotate_cw_one", "raise_front_both")
    subjects: int = 3
    repetitions: int = 10
    subject_index: int = 0  # whose demonstrations form the unseen sequence
    pretrain_epochs: int = 3
    pretrain_repetitions: int = 5  # repetitions per subject and known pattern used for pre-training
    presentations: int = 3
    window: int = 30  # smoothing window of the settling rule (frames)
    tolerance: float = 0.2
    floor: float = 0.02  # rad added to the settling band
    methods: tuple[str, ...] = ("hold", "rls_ar", common.HIERARCHY, common.DEFAULT)
    overrides: tuple[tuple[str, object], ...] = ()


QUICK = Config(unseen_patterns=("wave_one",), subjects=2, repetitions=2, pretrain_epochs=1, pretrain_repetitions=1,
               presentations=2, window=10)
FULL = Config()


def one_pattern(config: Config, pattern: str, seed: int, progress: bool) -> dict[str, Any]:
    params = common.make_params(config.overrides)
    data = common.demo_data(None, config.subjects, config.repetitions, seed)
    known = [s for s in data if s.pattern != pattern and s.repetition <= config.pretrain_repetitions]
    subject = sorted({s.subject for s in data})[config.subject_index]
    unseen = [s for s in data if s.pattern == pattern and s.subject == subject]
    models = common.make_models(config.methods, params, seed)
    rng = np.random.default_rng(seed)
    for epoch in range(config.pretrain_epochs):
        order = common.shuffled(known, rng)
        for name, model in models.items():
            train_online(model, order, progress=progress, desc=f"{NAME} {pattern} pretrain {epoch + 1} {name}")
    res = compare_online(models, unseen, horizon=params.horizon, passes=config.presentations, trace=True,
                         progress=progress, desc=f"{NAME} {pattern}")
    out: dict[str, Any] = {"pattern": pattern, "subject": subject, "frames_per_presentation": common.frames_in(unseen),
                           "methods": {}}
    for name, r in res.items():
        err = r.trace.error[:, -1]
        trend = linear_trend(err)
        out["methods"][name] = {
            "error": np.round(err, 3),  # per-frame trace for the figure (NaN = not scored)
            "trend": {"slope": trend.slope, "intercept": trend.intercept},
            "settling_frame": settling_frame(err, config.window, config.tolerance, floor=config.floor,
                                             reference=err[-out["frames_per_presentation"]:]),
            "beats_hold_from": (settling_frame(err, config.window, 0.0, reference=res["hold"].trace.error[:, -1])
                                if "hold" in res else None),
            "mae_per_presentation": [float(s.mae[-1]) for s in r.pass_stats],
            "neurons_after": common.neuron_counts(models[name]),
        }
    return out


def run(config: Config, out: Path, seed: int = 0, progress: bool = True) -> ExperimentOutput:
    runs = [one_pattern(config, p, seed, progress) for p in config.unseen_patterns]
    rows = []
    for r in runs:
        for m, v in r["methods"].items():
            rows.append([r["pattern"], common.label(m), v["settling_frame"], v["beats_hold_from"],
                         *v["mae_per_presentation"],
                         f"{v['trend']['slope'] * 100:+.4f}"])
    heads = ["unseen pattern", "method", "settles at frame", "better than hold from frame",
             *[f"MAE pres. {i + 1}" for i in range(config.presentations)], "trend (rad / 100 frames)"]
    hier = [r["methods"][common.HIERARCHY]["settling_frame"] for r in runs if common.HIERARCHY in r["methods"]]
    horizon = common.make_params(config.overrides).horizon
    md = [f"Pre-trained {config.pretrain_epochs} epochs on the other patterns; the left-out pattern of one "
          f"subject ({runs[0]['frames_per_presentation']} frames) presented {config.presentations} times, "
          f"learning on. Error: Euclidean distance over the 8 joints at the {horizon}-frame horizon. "
          f"Settling: smoothed ({config.window} frames) error within {config.tolerance:.0%} + {config.floor} rad "
          "of the last presentation's at the same point of the sequence. 'Better than hold from': first frame "
          "after which the smoothed error stays below hold-last's (– = never for good).", "",
          markdown_table(heads, rows), "",
          f"Hierarchy settling frames: {hier} (target: within ~100 frames)."]
    figs = [_plot(r, config, Path(out)) for r in runs]
    results = {"runs": runs}
    return ExperimentOutput(NAME, "Online response to an unseen sequence", asdict(config), results, md, figs)


def _plot(r: dict[str, Any], config: Config, out: Path) -> str:
    fig, axes = figure(size=(8.0, 3.6))
    ax = axes[0][0]
    for m, v in r["methods"].items():
        err = np.asarray(v["error"], float)
        frames = np.arange(err.size)
        smooth = moving_average(err, config.window, centered=True)
        line, = ax.plot(frames, smooth, lw=1.2, label=f"{common.label(m)} (smoothed)")
        if m == common.HIERARCHY:
            ax.plot(frames, err, color=line.get_color(), lw=0.5, alpha=0.35)
            ax.plot(frames, v["trend"]["intercept"] + v["trend"]["slope"] * frames, "r--", lw=1, label="trend")
            if v["settling_frame"] is not None:
                ax.axvline(v["settling_frame"], color="g", lw=1, label="settled")
    for i in range(1, config.presentations):
        ax.axvline(i * r["frames_per_presentation"], color="k", ls=":", lw=0.8)
    ax.set_xlabel("frame of the unseen sequence (10 fps)")
    ax.set_ylabel("error at the horizon (rad)")
    ax.set_title(f"unseen: {r['pattern']} by {r['subject']}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return save_figure(fig, out, f"unseen_{r['pattern']}")
