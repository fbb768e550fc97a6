"""Real movements performed again and again, never twice alike: who anticipates them, and how fast.

Six movements cut from the real recordings (`research.repetitions`: a climbing move from three takes,
a box lift, a walk, the kneel), each performed `repetitions` times in one stream with its own time
warp, size, pause and tracker noise, for several seeds. Every method learns each stream from scratch
in one online pass and is scored on the same frames at every horizon step. Reported: MAE per stream
and pooled with its ratio to hold-last; the learning curve (MAE at the last step per performance
index: the pause before it, the performance and its way back); the worst ratio to hold-last per
step; how often the default's prediction is exactly hold-last; and `experiment delay`'s offline
closed loop on the same streams (tracking error and lag, compensated against uncompensated).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.evaluation.metrics import HorizonStats, future_windows, horizon_stats
from gwr_predictor.evaluation.online import compare_online
from gwr_predictor.evaluation.output import ExperimentOutput, figure, markdown_table, save_figure
from research.experiments import common
from research.experiments.delay import one_run
from research.recording import Recorded
from research.registry import DEFAULT_PREDICTOR
from research.repetitions import (
    PAUSE,
    PERFORM,
    RETURN,
    RepetitionStream,
    Segment,
    StreamSettings,
    load_segments,
    make_streams,
    synthetic_segments,
)

NAME = "repeats"
#: One movement per clip, 2.5-3 s each, chosen for the most arm motion per second with the end pose
#: close to the start pose (windows of 10 fps angles, path length minus 3 x the end-start gap).
SEGMENTS: tuple[Segment, ...] = (
    Segment("climb_0", 15.5, 18.5, "climbing move"),
    Segment("climb_2", 4.6, 7.6, "climbing move, another take"),
    Segment("climb_4", 5.1, 7.6, "climbing move, another person"),
    Segment("omomo_sub10", 3.0, 6.0, "box lift"),
    Segment("cmu_walk", 4.4, 7.4, "walking, about two strides"),
    Segment("kneel", 4.1, 7.1, "kneeling down"),
)
METHODS = ("hold", "const_velocity", "rls_ar", common.LINEAR, common.HIERARCHY, common.LLM, common.BLEND_FLAT,
           common.BLEND, common.GATED, common.EXPERTS_UNGATED)
CLOSED_LOOP_RULES = ("none", "fixed_true", "guarded_true")
#: phase -> name in the per-phase table (a frame's phase is where the prediction is made from)
PHASES = {PAUSE: "pause", PERFORM: "performance", RETURN: "way back"}


@dataclass(frozen=True)
class Config:
    segments: tuple[Segment, ...] = SEGMENTS
    synthetic: bool = False  # demonstrator stand-ins instead of the real clips (no download)
    seeds: int = 3  # streams per segment, seeded run seed, +1, ...
    repetitions: int = 8
    methods: tuple[str, ...] = METHODS  # + the node's default
    closed_loop: tuple[str, ...] = ("rls_ar", common.DEFAULT)  # () = no closed loop
    delays: tuple[float, ...] = (0.3, 0.6)
    skip_s: float = 2.0  # closed loop warm-up left out of lag and error
    overrides: tuple[tuple[str, object], ...] = ()


QUICK = Config(synthetic=True, seeds=1, repetitions=3, methods=("hold", "rls_ar", common.LLM),
               closed_loop=(common.DEFAULT,), delays=(0.6,))
FULL = Config()


def streams_for(config: Config, seed: int) -> list[RepetitionStream]:
    segments = synthetic_segments() if config.synthetic else load_segments(config.segments)
    return make_streams(segments, tuple(seed + i for i in range(config.seeds)),
                        StreamSettings(repetitions=config.repetitions))


def score_stream(stream: RepetitionStream, methods: tuple[str, ...], params: Any, seed: int, progress: bool
                 ) -> tuple[dict[str, HorizonStats], dict[str, list[HorizonStats]], dict[str, float | None]]:
    """Fresh models, one online pass: stats per method; per repetition index, then per phase; and the
    share of each method's predictions that were exactly hold-last."""
    h, joints = params.horizon, params.n_joints
    models = {m: Recorded(common.make_model(m, params, seed)) for m in methods}
    res = compare_online(models, [stream.angles], horizon=h, progress=progress, desc=f"{NAME} {stream.name}")
    preds = {m: r.predictions(h, joints) for m, r in models.items()}
    scored = np.logical_and.reduce([np.isfinite(p).all(axis=(1, 2)) for p in preds.values()])
    future = future_windows(stream.angles, h)
    reps = [scored & (stream.repetition == k) for k in range(int(stream.repetition.max()) + 1)]
    reps += [scored & (stream.phase == k) for k in PHASES]
    per_rep = {m: [horizon_stats(p[sel], future[sel]) for sel in reps] for m, p in preds.items()}
    return {m: r.stats for m, r in res.items()}, per_rep, {m: r.held_share() for m, r in models.items()}


def closed_loop(stream: RepetitionStream, config: Config, params: Any, seed: int) -> list[dict[str, Any]]:
    """`experiment delay`'s closed loop per predictor, delay and rule, the predictor learning from scratch."""

    return [{"stream": stream.name, "predictor": name, "delay_s": d, "rule": rule,
             **one_run(stream.angles, lambda n=name: common.make_model(n, params, seed), d, rule, config.skip_s)}
            for name in config.closed_loop for d in config.delays for rule in CLOSED_LOOP_RULES]


def _ratio(stats: dict[str, Any], m: str, step: int = -1) -> float | None:
    v, hold = stats[m]["mae"][step], stats["hold"]["mae"][step]
    return None if v is None or not hold else v / hold


def measure(config: Config, seed: int, progress: bool) -> dict[str, Any]:
    params = common.make_params(config.overrides)
    default = DEFAULT_PREDICTOR
    methods = tuple(dict.fromkeys((*config.methods, default)))
    if "hold" not in methods:
        methods = ("hold", *methods)
    streams = streams_for(config, seed)
    pooled = {m: HorizonStats.empty(params.horizon, params.n_joints) for m in methods}
    curve = {m: [HorizonStats.empty(params.horizon, params.n_joints)] * (config.repetitions + len(PHASES))
             for m in methods}
    per_stream, held, loop = {}, {}, []
    for s in streams:
        stats, per_rep, shares = score_stream(s, methods, params, seed, progress)
        per_stream[s.name] = {m: st.to_dict() for m, st in stats.items()}
        held[s.name] = shares[default]
        for m in methods:
            pooled[m] = pooled[m].merge(stats[m])
            curve[m] = [c.merge(r) for c, r in zip(curve[m], per_rep[m], strict=True)]
        loop += closed_loop(s, config, params, seed)
    per_segment = _per_segment(per_stream, streams, methods)
    h, reps = params.horizon, config.repetitions
    return {
        "params": params.to_flat(), "default_method": default, "methods": list(methods),
        "streams": [{"name": s.name, "seconds": s.seconds, "frames": len(s.angles),
                     "clipped_share": float(np.mean(s.angles != s.raw)), "rates": s.rates, "sizes": s.sizes,
                     "pauses_s": s.pauses_s} for s in streams],
        "per_stream": per_stream, "per_segment": per_segment,
        "pooled": {m: st.to_dict() for m, st in pooled.items()},
        "ratio_to_hold": {"pooled": {m: _ratio({k: v.to_dict() for k, v in pooled.items()}, m) for m in methods},
                          "per_stream": {n: {m: _ratio(st, m) for m in methods} for n, st in per_stream.items()},
                          "per_segment": {n: {m: _ratio(st, m) for m in methods} for n, st in per_segment.items()}},
        "learning_curve": {m: [float(c.mae[-1]) for c in curve[m][:reps]] for m in methods},
        "learning_curve_ratio": {m: [_safe(c.mae[-1], hold.mae[-1])
                                     for c, hold in zip(curve[m][:reps], curve["hold"][:reps], strict=True)]
                                 for m in methods},
        "per_phase": {name: {m: curve[m][reps + i].to_dict() for m in methods}
                      for i, name in enumerate(PHASES.values())},
        "worst_ratio_per_step": {m: [max(_ratio(st, m, k) or 0.0 for st in per_stream.values()) for k in range(h)]
                                 for m in methods},
        "default_exactly_hold_share": held,
        "closed_loop": loop,
    }


def _safe(a: float, b: float) -> float | None:
    return None if not np.isfinite(a) or not b else float(a / b)


def _per_segment(per_stream: dict[str, dict[str, Any]], streams: list[RepetitionStream], methods: tuple[str, ...]
                 ) -> dict[str, dict[str, Any]]:
    """MAE per segment, pooled over its seeds (weighted by scored entries, as the pooled figures)."""
    out: dict[str, dict[str, Any]] = {}
    for s in streams:
        out.setdefault(s.name.split(" ")[0], {})
    for seg in out:
        names = [s.name for s in streams if s.name.split(" ")[0] == seg]
        for m in methods:
            n = np.array([per_stream[x][m]["n"] for x in names], dtype=float)
            mae = np.array([[np.nan if v is None else v for v in per_stream[x][m]["mae"]] for x in names])
            out[seg][m] = {"mae": list((n * mae).sum(axis=0) / n.sum(axis=0)), "n": n.sum(axis=0).tolist()}
    return out


def run(config: Config, out: Path, seed: int = 0, progress: bool = True) -> ExperimentOutput:
    r = measure(config, seed, progress)
    out = Path(out)
    figures = [_plot_curve(r, out)]
    return ExperimentOutput(NAME, "Real movements repeated with variation: one pass from scratch", asdict(config), r,
                            _markdown(r, config), figures)


def _label(m: str, default: str) -> str:
    return common.label(m) + (" (node default)" if m == default and "default" not in common.label(m) else "")


def _cell(v: float | None, best: bool = False) -> str:
    return "–" if v is None else (f"**{v:.3f}**" if best else f"{v:.3f}")


def _markdown(r: dict[str, Any], config: Config) -> list[str]:
    methods, default, h = r["methods"], r["default_method"], len(r["pooled"]["hold"]["mae"])
    ratio = r["ratio_to_hold"]
    step = f"{100 * h} ms"
    md = [f"{len(r['streams'])} streams ({config.seeds} seeds x {len(r['per_segment'])} movements, "
          f"{config.repetitions} performances each: time warp 0.8-1.25x with a slow speed change, size 0.9-1.1x, "
          "0.3-1.5 s pauses in the start pose, 1 cm tracker noise; see `research/repetitions.py`). Every method "
          "learns each stream from scratch in one online pass and is scored on the same frames.", "",
          markdown_table(["stream", "seconds", "angles clipped", "speeds (first performance)", "sizes"],
                         [[s["name"], f"{s['seconds']:.1f}", f"{100 * s['clipped_share']:.1f} %",
                           f"{s['rates'][0][0]:.2f} -> {s['rates'][0][1]:.2f}",
                           f"{min(s['sizes']):.2f}-{max(s['sizes']):.2f}"] for s in r["streams"]]), "",
          "## Pooled over every stream", "",
          markdown_table(["method", *[f"{100 * k} ms" for k in range(1, h + 1)], f"ratio to hold at {step}"],
                         [[_label(m, default), *r["pooled"][m]["mae"], _cell(ratio["pooled"][m])] for m in methods]),
          "", f"## Ratio to hold-last at {step}, per movement (pooled over its seeds; best in bold)", ""]
    segs = list(r["per_segment"])
    best = {s: min((m for m in methods if ratio["per_segment"][s][m] is not None),
                   key=lambda m, s=s: ratio["per_segment"][s][m]) for s in segs}
    md += [markdown_table(["method", *segs], [[_label(m, default), *[_cell(ratio["per_segment"][s][m], best[s] == m)
                                                                      for s in segs]] for m in methods]), ""]
    md += [f"Per stream, ratio to hold-last at {step} (hold's MAE in rad; the default's share of frames predicted "
           "exactly as hold-last):", "",
           markdown_table(["stream", "hold MAE", *[common.label(m) for m in methods if m != "hold"], "default = hold"],
                          [[n, st["hold"]["mae"][-1], *[_cell(ratio["per_stream"][n][m]) for m in methods
                                                        if m != "hold"],
                            _share(r["default_exactly_hold_share"][n])] for n, st in r["per_stream"].items()]), ""]
    reps = len(r["learning_curve"]["hold"])
    md += [f"## Learning curve: MAE at {step} per performance (the pause before it, the performance, its way back), "
           "pooled over streams", "",
           markdown_table(["method", *[f"#{k + 1}" for k in range(reps)]],
                          [[_label(m, default), *r["learning_curve"][m]] for m in methods]), "",
           "The same, as ratio to hold-last:", "",
           markdown_table(["method", *[f"#{k + 1}" for k in range(reps)]],
                          [[_label(m, default), *[_cell(v) for v in r["learning_curve_ratio"][m]]] for m in methods]),
           "", f"Pooled by where the prediction is made from (frames of each phase; ratio to hold-last at {step}):", "",
           markdown_table(["method", *[f"{p} ({r['per_phase'][p]['hold']['n'][-1] // 8} frames)"
                                       for p in r["per_phase"]]],
                          [[_label(m, default), *[_cell(_ratio(st, m)) for st in r["per_phase"].values()]]
                           for m in methods]),
           "", "## Worst ratio to hold-last over the streams, per horizon step", "",
           markdown_table(["method", *[f"{100 * k} ms" for k in range(1, h + 1)]],
                          [[_label(m, default), *r["worst_ratio_per_step"][m]] for m in methods if m != "hold"])]
    md += ["", _verdict(r)]
    if r["closed_loop"]:
        md += ["", *_closed_loop_markdown(r["closed_loop"], config)]
    return md


def _share(v: float | None) -> str:
    return "–" if v is None else f"{100 * v:.0f} %"


def _verdict(r: dict[str, Any]) -> str:
    ratio, methods, default = r["ratio_to_hold"], r["methods"], r["default_method"]
    pooled = {m: v for m, v in ratio["pooled"].items() if v is not None}
    best = min(pooled, key=pooled.get)
    beats = {m: sum(1 for s in ratio["per_stream"].values() if s[m] is not None and s[default] is not None
                    and s[m] < s[default]) for m in methods if m != default}
    return (f"Best pooled: {common.label(best)} ({pooled[best]:.3f} x hold-last); the default {pooled[default]:.3f} x. "
            f"Streams (of {len(ratio['per_stream'])}) where each method is below the default at the last step: "
            + ", ".join(f"{common.label(m)} {n}" for m, n in beats.items()) + ".")


def _closed_loop_markdown(rows: list[dict[str, Any]], config: Config) -> list[str]:
    md = ["## Closed loop (offline, `experiment delay`'s robot), pooled over streams", "",
          "Tracking MAE (rad) and lag of the robot behind the person, mean over streams, each predictor learning "
          f"the stream from scratch inside the loop (first {config.skip_s:g} s left out); change against "
          "uncompensated (`none`); worst: the largest compensated / uncompensated ratio over streams.", ""]
    table = []
    for name in config.closed_loop:
        for d in config.delays:
            cell = {rule: [x for x in rows if x["predictor"] == name and x["delay_s"] == d and x["rule"] == rule]
                    for rule in CLOSED_LOOP_RULES}
            none = np.array([x["mae"] for x in cell["none"]])
            for rule in CLOSED_LOOP_RULES:
                mae = np.array([x["mae"] for x in cell[rule]])
                lag = np.array([x["lag_s"] for x in cell[rule]])
                table.append([common.label(name), f"{1000 * d:.0f} ms", rule, f"{mae.mean():.4f}",
                              f"{100 * (mae.mean() / none.mean() - 1):+.1f} %", f"{(mae / none).max():.3f}",
                              f"{1000 * lag.mean():.0f} ms"])
    return md + [markdown_table(["predictor", "delay", "rule", "tracking MAE", "vs none", "worst stream",
                                 "lag"], table)]


def _plot_curve(r: dict[str, Any], out: Path) -> str:
    fig, axes = figure(1, 2, size=(11.0, 4.0))
    default = r["default_method"]
    for i, m in enumerate(r["methods"]):
        style = {"ls": "--" if m == "hold" else "-", "lw": 2.2 if m in (default, "rls_ar") else 1.0,
                 "marker": "o", "ms": 3, "color": f"C{i % 10}", "label": _label(m, default)}
        curve = r["learning_curve"][m]
        axes[0][0].plot(np.arange(1, len(curve) + 1), curve, **style)
        rel = [np.nan if v is None else v for v in r["learning_curve_ratio"][m]]
        axes[0][1].plot(np.arange(1, len(rel) + 1), rel, **style)
    h = len(r["pooled"]["hold"]["mae"])
    axes[0][0].set_ylabel(f"MAE at {100 * h} ms (rad)")
    axes[0][1].set_ylabel("ratio to hold-last")
    for ax in axes[0]:
        ax.set_xlabel("performance (1st, 2nd, ...)")
        ax.grid(alpha=0.3)
    axes[0][1].legend(fontsize=6)
    fig.suptitle("repeated real movements: one online pass from scratch, pooled over streams", fontsize=9)
    return save_figure(fig, out, "repeats_learning_curve")
