"""How sure: does the interval stated with every prediction hold the share it states, and how wide is it?

The default states a central interval (80 % by default) around every predicted angle, learned online
(`default_predictor/spread.py`); `hold` and `rls_ar` state one of their own residuals, learned the same way.
Per method and horizon step: the share of the true angles inside their stated interval (coverage) and the
interval's mean width (rad), every method scored on the same frames, on data the spread was not tuned on
(its tuning set: `research/spread_tuning.py`, research/tuning.md):
- the demonstrator's held-out repetitions and held-out person (`experiment compare`'s protocol, seed 0: 5
  online epochs over the training split, then each split frozen and still learning);
- the real clips (`experiment real`): one pass from scratch each, and each climbing take learned after the
  other four;
- real movements repeated 8 times (`experiment repeats`' 18 streams): pooled, and per performance (the
  first performance of a movement, then how the width shrinks as it repeats);
- the compensator's `spread_shrink` option in the offline closed loop (`experiment delay`'s robot, guarded at
  the true delay) on the repeated streams and the real clips: tracking error and lag with the option against
  without. The predictors never see the robot, so the loop replays the predictions and intervals recorded in
  the open loop.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.evaluation.metrics import IntervalStats, future_windows, interval_stats
from gwr_predictor.evaluation.online import compare_online, train_online
from gwr_predictor.evaluation.output import ExperimentOutput, figure, markdown_table, save_figure
from gwr_predictor.robot.closed_loop import run_closed_loop
from research.experiments import common, real, repeats
from research.experiments.splits import make_splits
from research.recording import Recorded
from research.registry import DEFAULT_PREDICTOR

NAME = "calibration"
#: the target band around the stated share, in share points
BAND = 0.05


@dataclass(frozen=True)
class Config:
    methods: tuple[str, ...] = ("hold", "rls_ar")  # + the node's default; each must state an interval
    patterns: tuple[str, ...] | None = None  # the demonstrator: compare's protocol
    subjects: int = 3
    repetitions: int = 10
    heldout_repetitions: int = 2
    epochs: int = 5
    real: bool = True  # the real clips, one pass and left out
    real_clips: tuple[str, ...] | None = None
    real_max_seconds: float = 0.0
    synthetic: bool = False  # the repeated streams from demonstrator stand-ins (no download)
    seeds: int = 3
    performances: int = 8
    delays: tuple[float, ...] = (0.3, 0.6)  # the compensator option's closed loop
    shrinks: tuple[float, ...] = (0.25, 1.0, 4.0)
    skip_s: float = 2.0
    overrides: tuple[tuple[str, object], ...] = ()


QUICK = Config(patterns=("wave_one", "raise_front_both"), subjects=2, repetitions=3, heldout_repetitions=1, epochs=1,
               real=False, synthetic=True, seeds=1, performances=3, delays=(0.6,), shrinks=(1.0,))
FULL = Config()


def _stats(results: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {m: {"nominal": r.interval_nominal, **r.interval.to_dict()} for m, r in results.items()
            if r.interval is not None}


def demonstrator(config: Config, methods: tuple[str, ...], params: Any, seed: int, progress: bool
                 ) -> dict[str, Any]:
    """`experiment compare`'s protocol: trained online on the training split, each held-out split scored
    frozen and still learning (the spread keeps learning in both, as the gates do)."""
    data = common.demo_data(config.patterns, config.subjects, config.repetitions, seed)
    splits = make_splits(data, 1, config.heldout_repetitions)
    models = common.make_models(methods, params, seed)
    rng = np.random.default_rng(seed)
    for epoch in range(config.epochs):
        compare_online(models, common.shuffled(splits.train, rng), horizon=params.horizon, progress=progress,
                       desc=f"{NAME} epoch {epoch + 1}/{config.epochs}")
    out = {}
    for split, seqs in (("heldout_repetitions", splits.heldout_repetitions),
                        ("heldout_subjects", splits.heldout_subjects)):
        for learn in (False, True):
            res = compare_online(common.clone(models), seqs, learn=learn, horizon=params.horizon, progress=progress,
                                 desc=f"{NAME} {split} learn={learn}")
            out[f"{split}/{'online' if learn else 'frozen'}"] = _stats(res)
    return out


class _Replay:
    """A sequence's recorded predictions and intervals, in order (the closed loop's predictor)."""

    def __init__(self, recorded: Recorded) -> None:
        self.recorded, self.t, self.nominal = recorded, 0, recorded.interval_nominal

    @property
    def interval_nominal(self) -> float:
        return self.nominal

    def interval(self) -> tuple[np.ndarray, np.ndarray] | None:
        return self.recorded.intervals[self.t - 1]

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        self.t += 1
        return self.recorded.outputs[self.t - 1]

    def reset_sequence(self) -> None:
        self.t = 0


def _closed_loop(name: str, angles: np.ndarray, recorded: Recorded, config: Config) -> list[dict[str, Any]]:
    """Guarded at the true delay, without the option (0) and with each `shrinks`."""

    rows = []
    for delay in config.delays:
        for c in (0.0, *config.shrinks):
            res = run_closed_loop(angles, _Replay(recorded), delay_s=delay, compensation="guarded", spread_shrink=c)
            rows.append({"sequence": name, "delay_s": delay, "spread_shrink": c,
                         "mae": res.errors(skip_s=config.skip_s)["mae"], "lag_s": res.lag_s(skip_s=config.skip_s)})
    return rows


def _one_pass(name: str, angles: np.ndarray, methods: tuple[str, ...], params: Any, seed: int, progress: bool,
              trained: dict[str, Any] | None = None
              ) -> tuple[dict[str, Any], dict[str, Recorded], np.ndarray, np.ndarray]:
    """Models (fresh, or `trained`) recorded over one sequence: the results, the recordings, the frames
    every method predicted and the truth per frame."""
    models = {m: Recorded(model) for m, model in (trained or common.make_models(methods, params, seed)).items()}
    res = compare_online(models, [angles], horizon=params.horizon, progress=progress, desc=f"{NAME} {name}")
    preds = [r.predictions(params.horizon, params.n_joints) for r in models.values()]
    scored = np.logical_and.reduce([np.isfinite(p).all(axis=(1, 2)) for p in preds])
    return res, models, scored, future_windows(angles, params.horizon)


def real_clips(config: Config, methods: tuple[str, ...], params: Any, seed: int, progress: bool
               ) -> dict[str, Any]:
    """One pass from scratch per clip, and each climbing take learned after the others; pooled and per clip."""

    clips = real.load_clips(real.Config(clips=config.real_clips, max_seconds=config.real_max_seconds))
    empty = {m: IntervalStats.empty(params.horizon, params.n_joints) for m in methods}
    pooled, per_clip, loop = dict(empty), {}, []
    for clip in clips:
        res, models, _, _ = _one_pass(clip["name"], clip["angles"], methods, params, seed, progress)
        per_clip[clip["name"]] = _stats(res)
        pooled = {m: pooled[m].merge(res[m].interval) for m in methods}
        loop += _closed_loop(clip["name"], clip["angles"], models[DEFAULT_PREDICTOR], config)
    left, per_take = dict(empty), {}
    for held, others in real.left_out_takes(clips):
        trained = common.make_models(methods, params, seed)
        for model in trained.values():
            train_online(model, others, progress=progress, desc=f"{NAME} train without {held['name']}")
        res, _, _, _ = _one_pass(held["name"], held["angles"], methods, params, seed, progress, trained)
        per_take[held["name"]] = _stats(res)
        left = {m: left[m].merge(res[m].interval) for m in methods}
    return {"one_pass": {m: s.to_dict() for m, s in pooled.items()}, "per_clip": per_clip,
            "left_out": {m: s.to_dict() for m, s in left.items()}, "per_take": per_take,
            "clips": [c["name"] for c in clips], "closed_loop": loop}


def repeated(config: Config, methods: tuple[str, ...], params: Any, seed: int, progress: bool) -> dict[str, Any]:
    """`experiment repeats`' streams, one pass from scratch each: pooled, and per performance index."""

    streams = repeats.streams_for(repeats.Config(synthetic=config.synthetic, seeds=config.seeds,
                                                 repetitions=config.performances), seed)
    h, joints = params.horizon, params.n_joints
    pooled = {m: IntervalStats.empty(h, joints) for m in methods}
    per_rep = {m: [IntervalStats.empty(h, joints) for _ in range(config.performances)] for m in methods}
    loop = []
    for s in streams:
        res, models, scored, future = _one_pass(s.name, s.angles, methods, params, seed, progress)
        for m, recorded in models.items():
            pooled[m] = pooled[m].merge(res[m].interval)
            bounds = recorded.bounds(h, joints)
            for k in range(config.performances):
                sel = scored & (s.repetition == k)
                per_rep[m][k] = per_rep[m][k].merge(interval_stats(bounds[0, sel], bounds[1, sel], future[sel]))
        loop += _closed_loop(s.name, s.angles, models[DEFAULT_PREDICTOR], config)
    return {"pooled": {m: st.to_dict() for m, st in pooled.items()},
            "per_performance": {m: [st.to_dict() for st in per_rep[m]] for m in methods},
            "streams": [s.name for s in streams], "closed_loop": loop}


def measure(config: Config, seed: int, progress: bool) -> dict[str, Any]:
    params = common.make_params(config.overrides)
    default = DEFAULT_PREDICTOR
    methods = tuple(dict.fromkeys((*config.methods, default)))
    out: dict[str, Any] = {"params": params.to_flat(), "default_method": default, "methods": list(methods),
                           "band": BAND, "demonstrator": demonstrator(config, methods, params, seed, progress),
                           "repeated": repeated(config, methods, params, seed, progress)}
    if config.real:
        out["real"] = real_clips(config, methods, params, seed, progress)
    return out


def conditions(r: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Every reported condition: {method: {"nominal", "coverage", "width", "n"}}."""
    names = {"heldout_repetitions": "new repetitions", "heldout_subjects": "new person"}
    out = {}
    for key, per in r["demonstrator"].items():
        split, learn = key.split("/")
        out[f"demonstrator, {names[split]}, {learn}"] = per
    rep = r["repeated"]
    out["real repeated, pooled"] = rep["pooled"]
    out["real repeated, 1st performance"] = {m: v[0] for m, v in rep["per_performance"].items()}
    if "real" in r:
        out["real clips, one pass"] = r["real"]["one_pass"]
        out["real climbing takes, left out"] = r["real"]["left_out"]
    return out


def run(config: Config, out: Path, seed: int = 0, progress: bool = True) -> ExperimentOutput:
    r = measure(config, seed, progress)
    nominal = next(iter(r["demonstrator"].values()))[r["default_method"]]["nominal"]
    r["nominal"] = nominal
    conds = conditions(r)
    r["misses_band"] = {c: {m: _misses(s, nominal) for m, s in per.items()} for c, per in conds.items()}
    r["misses_band_per_performance"] = {f"performance {k + 1}": {m: _misses(per[k], nominal) for m, per in
                                                                 r["repeated"]["per_performance"].items()}
                                        for k in range(config.performances)}
    if "real" in r:
        r["misses_band_per_clip"] = {c: {m: _misses(s, nominal) for m, s in per.items()}
                                     for c, per in r["real"]["per_clip"].items()}
    md = _markdown(r, conds, config, nominal)
    figs = [_plot_coverage(conds, r, Path(out)), _plot_performances(r, Path(out))]
    return ExperimentOutput(NAME, "How sure: the stated interval's coverage and width", asdict(config), r, md, figs)


def _misses(stats: dict[str, Any], nominal: float) -> list[int]:
    """The steps (1-based) whose coverage is outside the band around `nominal` (or was not scored)."""
    return [k + 1 for k, v in enumerate(stats["coverage"]) if v is None or abs(v - nominal) > BAND]


def _outside(misses: dict[str, dict[str, list[int]]], default: str) -> str:
    found = [f"{c}: {_label(m, default)} at step {', '.join(map(str, ks))}" for c, per in misses.items()
             for m, ks in per.items() if ks]
    return "; ".join(found) if found else "nowhere"


def _label(m: str, default: str) -> str:
    return common.label(m) + (" (node default)" if m == default and "default" not in common.label(m) else "")


def _cells(s: dict[str, Any]) -> list[str]:
    return [f"{100 * c:.1f} % / {w:.3f}" if c is not None else "–" for c, w in zip(s["coverage"], s["width"],
                                                                                   strict=True)]


def _markdown(r: dict[str, Any], conds: dict[str, dict[str, Any]], config: Config, nominal: float) -> list[str]:
    default, methods = r["default_method"], r["methods"]
    h = len(next(iter(next(iter(conds.values())).values()))["coverage"])
    md = [f"Stated share {100 * nominal:.0f} %. Per horizon step: the share of the true angles inside the stated "
          "interval / its mean width (rad), every method on the same frames; the target is the stated share "
          f"within ±{100 * BAND:.0f} points at every step. The spread's settings were chosen on the tuning set "
          "(`research/spread_tuning.py`: other real segments and seeds, the demonstrator's seed 7), none of these.",
          ""]
    for cond, per in conds.items():
        md += [f"**{cond}**", "", markdown_table(["method", *[f"{100 * k} ms" for k in range(1, h + 1)]],
                                                 [[_label(m, default), *_cells(per[m])] for m in methods if m in per]),
               ""]
    md += [f"Outside the band (±{100 * BAND:.0f} points), pooled per condition: "
           f"{_outside(r['misses_band'], default)}.", ""]
    rep = r["repeated"]["per_performance"]
    md += [f"Real movements repeated: coverage / mean width at {100 * h} ms per performance:", "",
           markdown_table(["method", *[f"{k + 1}." for k in range(config.performances)]],
                          [[_label(m, default), *[f"{100 * s['coverage'][-1]:.1f} % / {s['width'][-1]:.3f}"
                                                  if s["coverage"][-1] is not None else "–" for s in rep[m]]]
                           for m in methods]), "",
           f"Outside the band per performance: {_outside(r['misses_band_per_performance'], default)}.", ""]
    if "real" in r:
        per = r["real"]["per_clip"]
        md += [f"Real clips one pass, per clip, the default's coverage / width at {100 * h} ms:", "",
               markdown_table(list(per), [[_cells(per[c][default])[-1] for c in per]]), "",
               f"Outside the band per clip: {_outside(r['misses_band_per_clip'], default)}.", ""]
    md += _closed_loop_markdown(r, config)
    return md


def _closed_loop_markdown(r: dict[str, Any], config: Config) -> list[str]:
    """Tracking MAE and lag with the compensator's `spread_shrink` against without, per data set and delay."""
    sets = [("real repeated", r["repeated"]["closed_loop"])]
    if "real" in r:
        sets.append(("real clips, one pass", r["real"]["closed_loop"]))
    rows = []
    for name, loop in sets:
        for delay in config.delays:
            off = {x["sequence"]: x for x in loop if x["delay_s"] == delay and x["spread_shrink"] == 0.0}
            for c in config.shrinks:
                on = [x for x in loop if x["delay_s"] == delay and x["spread_shrink"] == c]
                ratio = [x["mae"] / off[x["sequence"]]["mae"] for x in on]
                lag = [x["lag_s"] - off[x["sequence"]]["lag_s"] for x in on]
                before = float(np.mean([off[x["sequence"]]["mae"] for x in on]))
                rows.append([name, f"{1000 * delay:.0f} ms", f"{c:g}", before,
                             float(np.mean([x["mae"] for x in on])), f"{100 * (np.mean(ratio) - 1):+.1f} %",
                             f"{max(ratio):.3f}", f"{sum(v < 1 for v in ratio)} of {len(ratio)}",
                             f"{1000 * np.mean(lag):+.0f} ms"])
    return ["The compensator's `spread_shrink` (guarded at the true delay, the default's predictions and intervals): "
            "mean tracking MAE (rad) without and with it, the mean change per sequence, the worst ratio, the "
            "sequences it helps, the mean change of the robot's lag:", "",
            markdown_table(["data", "delay", "spread_shrink", "MAE off", "MAE on", "change", "worst ratio", "helps on",
                            "lag change"], rows, digits=4)]


def _plot_coverage(conds: dict[str, dict[str, Any]], r: dict[str, Any], out: Path) -> str:
    names = list(conds)
    cols = min(3, len(names))
    rows = -(-len(names) // cols)
    fig, axes = figure(rows, cols, size=(4.2 * cols, 3.0 * rows))
    nominal, default = r["nominal"], r["default_method"]
    for i, cond in enumerate(names):
        ax = axes[i // cols][i % cols]
        for m, s in conds[cond].items():
            cov = np.array([np.nan if v is None else v for v in s["coverage"]])
            ax.plot(np.arange(1, cov.size + 1) * 100, 100 * cov, marker="o", ms=3, label=common.label(m),
                    ls="-" if m == default else "--")
        ax.axhspan(100 * (nominal - BAND), 100 * (nominal + BAND), color="0.85", zorder=0)
        ax.axhline(100 * nominal, color="0.5", lw=0.8)
        ax.set_title(cond, fontsize=8)
        ax.set_ylim(100 * (nominal - 3 * BAND), 100 * min(1.0, nominal + 3 * BAND))
        ax.grid(alpha=0.3)
        if i % cols == 0:
            ax.set_ylabel("inside the interval (%)")
        if i // cols == rows - 1:
            ax.set_xlabel("horizon (ms)")
    for j in range(len(names), rows * cols):
        axes[j // cols][j % cols].axis("off")
    axes[0][0].legend(fontsize=7)
    return save_figure(fig, out, "calibration_coverage")


def _plot_performances(r: dict[str, Any], out: Path) -> str:
    per = r["repeated"]["per_performance"]
    fig, axes = figure(1, 2, size=(9.0, 3.4))
    for m, stats in per.items():
        k = np.arange(1, len(stats) + 1)
        width = [np.nan if s["width"][-1] is None else s["width"][-1] for s in stats]
        cov = [np.nan if s["coverage"][-1] is None else 100 * s["coverage"][-1] for s in stats]
        style = "-" if m == r["default_method"] else "--"
        axes[0][0].plot(k, width, marker="o", ms=3, ls=style, label=common.label(m))
        axes[0][1].plot(k, cov, marker="o", ms=3, ls=style, label=common.label(m))
    axes[0][0].set_ylabel("mean width at the last step (rad)")
    axes[0][1].set_ylabel("inside the interval at the last step (%)")
    axes[0][1].axhspan(100 * (r["nominal"] - BAND), 100 * (r["nominal"] + BAND), color="0.85", zorder=0)
    for ax in axes[0]:
        ax.set_xlabel("performance of the movement")
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7)
    return save_figure(fig, out, "calibration_per_performance")
