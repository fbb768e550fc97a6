"""Closed loop offline: how far the robot lags the person, with and without delay compensation.

The person is a held-out subject doing one repetition of every pattern in a row; the robot is the
simulated Nao behind a sensorimotor delay of 100..600 ms (plus its motor latency). Predictors are
pre-trained on the training split, performed like the person (`session` sequences back to
back), and keep learning in the loop. Compensation rules
(`compensator.py`): none (execute the newest observation), fixed 600 ms (always the 6-step
prediction, the paper's setting), fixed at the true delay (an oracle that knows it), and variable
(Eq. 11 tracking the delay from the robot's own state, starting from 600 ms).

On real people (`experiment real`'s motion-capture clips, fetched on first use): the registry's
default predictor learns each clip online from scratch inside the loop, and the robot runs without
compensation, with `fixed` and with `guarded` at the true delay, so that "compensation cannot hurt"
is checked per clip where holding still is hard to beat.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.evaluation.online import train_online
from gwr_predictor.evaluation.output import ExperimentOutput, figure, markdown_table, save_figure
from gwr_predictor.learning.protocol import Predictor
from gwr_predictor.robot.closed_loop import run_closed_loop
from research.experiments import common, real
from research.experiments.splits import make_splits

NAME = "delay"
#: rule name -> (compensator mode, assumed delay: None = the true delay)
RULES: dict[str, tuple[str, float | None]] = {
    "none": ("none", None),
    "fixed_600ms": ("fixed", 0.6),
    "guarded_600ms": ("guarded", 0.6),
    "fixed_true": ("fixed", None),
    "guarded_true": ("guarded", None),
    "variable": ("variable", 0.6),
}


@dataclass(frozen=True)
class Config:
    delays: tuple[float, ...] = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
    rules: tuple[str, ...] = tuple(RULES)
    predictors: tuple[str, ...] = (common.HIERARCHY, "rls_ar", common.LLM, common.DEFAULT)
    patterns: tuple[str, ...] | None = None
    subjects: int = 3
    repetitions: int = 10
    heldout_repetitions: int = 2
    pretrain_epochs: int = 3
    session: int = 10  # training sequences performed back to back per pretraining sequence (1: each alone)
    skip_s: float = 2.0  # warm-up excluded from lag and error
    overrides: tuple[tuple[str, object], ...] = ()
    real: bool = True  # the closed loop on every real clip too
    real_clips: tuple[str, ...] | None = None  # catalogue names (None = all)
    real_max_seconds: float = 0.0  # > 0: only the first seconds of each clip
    real_rules: tuple[str, ...] = ("none", "fixed_true", "guarded_true")


QUICK = Config(delays=(0.2, 0.6), predictors=(common.HIERARCHY,), patterns=("wave_one", "raise_front_one"),
               subjects=2, repetitions=2, heldout_repetitions=1, pretrain_epochs=1, real_clips=("climb_0", "kneel"),
               real_max_seconds=12.0)
FULL = Config()


def person_sequence(heldout: tuple[Any, ...]) -> np.ndarray:
    """One repetition of every pattern by the held-out subject, back to back."""
    first = {}
    for s in heldout:
        first.setdefault(s.pattern, s)
    return np.concatenate([np.asarray(s.angles) for s in first.values()])


def sessions(sequences: list[Any], per_session: int) -> list[np.ndarray]:
    """`per_session` sequences at a time back to back, as the closed-loop person performs: the model
    also learns what follows the end of a movement (more rest, then a new one), which separate
    recordings never show it (their last frames have no targets)."""
    angles = [np.asarray(getattr(s, "angles", s)) for s in sequences]
    return [np.concatenate(angles[i:i + per_session]) for i in range(0, len(angles), per_session)]


def measure(config: Config, seed: int, progress: bool) -> dict[str, Any]:
    params = common.make_params(config.overrides)
    data = common.demo_data(config.patterns, config.subjects, config.repetitions, seed)
    splits = make_splits(data, 1, config.heldout_repetitions)
    person = person_sequence(splits.heldout_subjects)
    trained = {}
    for name in config.predictors:  # every predictor pretrained on the same sessions in the same order
        rng = np.random.default_rng(seed)
        model = common.make_model(name, params, seed)
        for epoch in range(config.pretrain_epochs):
            train_online(model, sessions(common.shuffled(splits.train, rng), config.session), progress=progress,
                         desc=f"{NAME} pretrain {name} {epoch + 1}")
        trained[name] = model
    rows = []
    for name, model in trained.items():
        for delay in config.delays:
            for rule in config.rules:
                rows.append({"predictor": name, "delay_s": delay, "rule": rule,
                             **one_run(person, lambda m=model: copy.deepcopy(m), delay, rule, config.skip_s)})
    oracle = [{"delay_s": d, **one_run(person, lambda: Oracle(person, params.horizon), d, "fixed_true", config.skip_s)}
              for d in config.delays]
    out = {"params": params.to_flat(), "person_frames": int(person.shape[0]), "runs": rows, "oracle": oracle}
    if config.real:
        out["real"] = measure_clips(load_real_clips(config), config, params, seed)
    return out


class Oracle:
    """A perfect predictor (the person's true next frames): what is left is the robot's own lag."""

    def __init__(self, angles: np.ndarray, horizon: int) -> None:
        self.angles, self.horizon, self.t = np.asarray(angles, float), horizon, -1

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray:
        self.t += 1
        return self.angles[np.minimum(self.t + 1 + np.arange(self.horizon), len(self.angles) - 1)]

    def reset_sequence(self) -> None:
        self.t = -1


def one_run(angles: np.ndarray, model: Callable[[], Predictor], delay: float, rule: str, skip_s: float
            ) -> dict[str, Any]:
    """Lag, tracking error, mean step and fallbacks of one closed loop (`model()` builds the predictor),
    and `command_mae`: how far the commands were from where the person was `delay` later (for
    ``none``, holding still's error), which tells prediction error from what the motors add."""
    mode, assumed = RULES[rule]
    res = run_closed_loop(angles, model(), delay_s=delay, compensation=mode,  # type: ignore[arg-type]
                          compensator_delay_s=delay if assumed is None else assumed)
    err = res.errors(skip_s=skip_s)
    steps = res.steps_used[res.steps_used >= 0]
    period = float(res.t[1] - res.t[0])
    k, start = round(delay / period), round(skip_s / period)
    gap = np.abs(res.commands[start:len(angles) - k] - angles[start + k:])
    return {"lag_s": res.lag_s(skip_s=skip_s), "mae": err["mae"], "rmse": err["rmse"],
            "command_mae": float(np.nanmean(gap)) if np.isfinite(gap).any() else None,
            "mean_step": float(steps.mean()) if steps.size else None, "fallbacks": int(res.fallback_count)}


def load_real_clips(config: Config) -> list[dict[str, Any]]:
    """The real clips at 10 fps (`experiment real`'s loader and cache)."""

    return real.load_clips(real.Config(clips=config.real_clips, max_seconds=config.real_max_seconds))


def measure_clips(clips: list[dict[str, Any]], config: Config, params: Any, seed: int) -> dict[str, Any]:
    """Per clip ({name, angles}), delay and rule of `config.real_rules`: the closed loop with the registry's
    default predictor learning the clip online from scratch."""
    rows = []
    for clip in clips:
        for delay in config.delays:
            for rule in config.real_rules:
                rows.append({"clip": clip["name"], "delay_s": delay, "rule": rule,
                             **one_run(clip["angles"], lambda: common.make_model(common.DEFAULT, params, seed),
                                       delay, rule, config.skip_s)})
    return {"predictor": common.DEFAULT, "clips": [c["name"] for c in clips],
            "frames": {c["name"]: len(c["angles"]) for c in clips}, "runs": rows}


def run(config: Config, out: Path, seed: int = 0, progress: bool = True) -> ExperimentOutput:
    r = measure(config, seed, progress)
    md = [f"Held-out subject, {r['person_frames']} frames (every pattern once, back to back). Lag: time shift "
          f"that best aligns the robot's executed angles with the person's (after {config.skip_s:g} s); "
          "MAE: robot vs person (rad). The robot adds its motor latency to every delay."]
    for name in config.predictors:
        table = []
        for delay in config.delays:
            cells = {x["rule"]: x for x in r["runs"] if x["predictor"] == name and x["delay_s"] == delay}
            table.append([f"{1000 * delay:.0f} ms", *[f"{1000 * cells[k]['lag_s']:.0f} ms / {cells[k]['mae']:.3f}"
                                                       for k in config.rules]])
        md += ["", f"**{common.label(name)}** (lag / MAE rad)", "",
               markdown_table(["delay", *config.rules], table)]
        if {"none", "guarded_true"} <= set(config.rules):
            md += ["", _breakdown(r, name, max(config.delays))]
    figures = [_plot(r, config, Path(out))]
    if "real" in r:
        md += _real_markdown(r["real"], config)
        figures.append(_plot_real(r["real"], config, Path(out)))
    return ExperimentOutput(NAME, "Closed-loop delay compensation", asdict(config), r, md, figures)


def _breakdown(r: dict[str, Any], name: str, delay: float) -> str:
    """Where the compensated robot's error comes from at `delay`: the commands' own error, the motors."""
    cell = {x["rule"]: x for x in r["runs"] if x["predictor"] == name and x["delay_s"] == delay}
    oracle = next(x for x in r["oracle"] if x["delay_s"] == delay)
    g, n = cell["guarded_true"], cell["none"]
    return (f"At {1000 * delay:.0f} ms, guarded at the true delay: tracking {g['mae']:.3f} vs {n['mae']:.3f} "
            f"uncompensated ({100 * (g['mae'] / n['mae'] - 1):+.1f} %), mean step {g['mean_step']:.2f}; its commands "
            f"are {g['command_mae']:.3f} rad from where the person was {1000 * delay:.0f} ms later (holding still: "
            f"{n['command_mae']:.3f}); a perfect predictor tracks at {oracle['mae']:.3f} (motor latency and rate "
            "limits).")


def _ratio(runs: list[dict[str, Any]], clip: str, delay: float, rule: str) -> float:
    cell = {x["rule"]: x["mae"] for x in runs if x["clip"] == clip and x["delay_s"] == delay}
    return cell[rule] / cell["none"]


def _real_markdown(real: dict[str, Any], config: Config) -> list[str]:
    runs, rules = real["runs"], [x for x in config.real_rules if x != "none"]
    table = []
    for clip in real["clips"]:
        cells = []
        for delay in config.delays:
            mae = {x["rule"]: x["mae"] for x in runs if x["clip"] == clip and x["delay_s"] == delay}
            changes = [f"{mae[k]:.3f} ({100 * (mae[k] / mae['none'] - 1):+.1f} %)" for k in rules]
            cells.append(" / ".join([f"{mae['none']:.3f}", *changes]))
        table.append([f"{clip} ({real['frames'][clip]})", *cells])
    worst = {k: max(_ratio(runs, c, d, k) for c in real["clips"] for d in config.delays) for k in rules}
    return ["", f"**Real people** ({common.label(real['predictor'])} learning each clip online from scratch; tracking "
            f"MAE rad: none / {' / '.join(rules)}, change against none; clip (frames))", "",
            markdown_table(["clip", *[f"{1000 * d:.0f} ms" for d in config.delays]], table), "",
            "Worst compensated / uncompensated over clips and delays: "
            + ", ".join(f"{k} {worst[k]:.3f}" for k in rules) + "."]


def _plot_real(real: dict[str, Any], config: Config, out: Path) -> str:
    fig, axes = figure(1, 1, size=(6.5, 3.8))
    ax = axes[0][0]
    d = np.array(config.delays) * 1000
    for i, clip in enumerate(real["clips"]):
        for rule, style in (("guarded_true", "-"), ("fixed_true", ":")):
            if rule in config.real_rules:
                ax.plot(d, [100 * (_ratio(real["runs"], clip, x, rule) - 1) for x in config.delays], style,
                        color=f"C{i % 10}", marker="o" if style == "-" else None, ms=3,
                        label=clip if style == "-" else None)
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xlabel("sensorimotor delay (ms)")
    ax.set_ylabel("tracking MAE vs uncompensated (%)")
    ax.set_title("real clips: guarded (solid), fixed (dotted)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=6, ncol=2)
    return save_figure(fig, out, "delay_real")


def _plot(r: dict[str, Any], config: Config, out: Path) -> str:
    fig, axes = figure(1, 2, size=(10.0, 3.8))
    d = np.array(config.delays) * 1000
    for name, style in zip(config.predictors, ("-", "--", ":"), strict=False):
        for i, rule in enumerate(config.rules):
            sel = [x for x in r["runs"] if x["predictor"] == name and x["rule"] == rule]
            label = f"{rule} ({common.label(name)})"
            axes[0][0].plot(d, [1000 * x["lag_s"] for x in sel], style, color=f"C{i}", marker="o", ms=3, label=label)
            axes[0][1].plot(d, [x["mae"] for x in sel], style, color=f"C{i}", marker="o", ms=3, label=label)
    axes[0][0].plot(d, d, "k:", lw=0.8, label="lag = delay")
    axes[0][0].set_ylabel("robot lag behind the person (ms)")
    axes[0][1].set_ylabel("tracking MAE (rad)")
    for ax in axes[0]:
        ax.set_xlabel("sensorimotor delay (ms)")
        ax.grid(alpha=0.3)
    axes[0][1].legend(fontsize=6)
    return save_figure(fig, out, "delay_lag")
