"""`gwr-predictor bench day`: a robot's day, compressed. Hours of motion at 10 fps, run offline at full
speed through the default predictor as the learner node runs it (learn and predict every frame, a
checkpoint every hour snapshot between two frames and written by a thread of its own), with RLS-AR and
holding the pose on the same frames. Three sessions:

- `new`: smooth arm motion that keeps being new (each joint's velocity a damped random walk): every
  bound is reached and every learned structure must make room;
- `still`: a person standing still, the tracker's noise (0.01 rad) on one pose: nothing should grow;
- `repeats`: the demonstrator's movements (one person, ten patterns) again and again, each between
  stretches of new motion: what recurs must stay learned while the new motion passes through.

Per hour of each session: the units held (network neurons, snippets of each memory, evicted and replaced
so far), resident memory, CPU per frame of the default (p50, p99, mean; one BLAS thread) and of RLS-AR
(the ratio: a flat baseline in the same run), the worst frame (wall clock), the checkpoint (MB, the
snapshot's ms on the learner's path, the write's ms off it) and MAE at 600 ms as a share of holding the
pose and of RLS-AR (on the `repeats` session also on the demonstrator's frames alone). The last line is
one JSON object; `--out` gets results.json, results.md and day.png.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from gwr_predictor.data.datasets import demo_angle_sequences
from gwr_predictor.default_predictor import make_default
from gwr_predictor.evaluation.errors import EvaluationError
from gwr_predictor.evaluation.output import figure, save_figure
from gwr_predictor.files.user_files import write_output
from gwr_predictor.learning.blas import blas_threads, single_threaded_blas
from gwr_predictor.learning.saver import CheckpointSaver
from gwr_predictor.predictors.baselines import RLSAutoregressive, RLSParams
from research.memory_use import current_rss_mb
from research.streams import random_walk_stream

FPS = 10
HORIZON = 6
SESSIONS = ("new", "still", "repeats")
STILL_NOISE_RAD = 0.01
#: The pose the `still` person holds (rad, the Nao arm joints): arms hanging, elbows a little bent.
STILL_POSE = np.array([1.4, 0.15, -1.2, -0.4, 1.4, -0.15, 1.2, 0.4])
BLEND_FRAMES = 10  # the `repeats` session joins its segments by 1 s of linear motion


def session_stream(name: str, frames: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(frames, 8) angles of a session and, per frame, whether it belongs to a repeated movement."""
    rng = np.random.default_rng(seed)
    if name == "new":
        return random_walk_stream(frames, seed), np.zeros(frames, dtype=bool)
    if name == "still":
        return STILL_POSE + rng.normal(0.0, STILL_NOISE_RAD, (frames, len(STILL_POSE))), np.zeros(frames, dtype=bool)
    if name == "repeats":
        return _repeats(frames, rng, seed)
    raise ValueError(f"unknown session {name!r}; sessions: {', '.join(SESSIONS)}")


def _repeats(frames: int, rng: np.random.Generator, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The demonstrator's movements in random order, each followed by 10-60 s of new motion."""
    movements = [s.angles for s in demo_angle_sequences(subjects=1, seed=seed)]
    walk = random_walk_stream(frames, seed + 1)
    parts: list[np.ndarray] = []
    repeated: list[np.ndarray] = []
    done, walked = 0, 0
    last = movements[0][0]
    while done < frames:
        move = movements[int(rng.integers(len(movements)))]
        new = int(rng.integers(10 * FPS, 60 * FPS))
        segment = walk[walked:walked + new]
        walked = (walked + new) % max(1, frames - 60 * FPS)
        for piece, is_repeat in ((move, True), (segment - segment[0] + move[-1], False)):
            join = np.linspace(last, piece[0], BLEND_FRAMES + 2)[1:-1]
            parts += [join, piece]
            repeated += [np.zeros(len(join), dtype=bool), np.full(len(piece), is_repeat)]
            last = piece[-1]
            done += len(join) + len(piece)
    return np.concatenate(parts)[:frames], np.concatenate(repeated)[:frames]


@dataclass
class _Scores:
    """Absolute errors at the last step, summed per model, over the frames of the present hour."""

    sums: dict[str, float] = field(default_factory=dict)
    repeated: dict[str, float] = field(default_factory=dict)
    n: int = 0
    n_repeated: int = 0

    def add(self, errors: dict[str, float], is_repeat: bool) -> None:
        for name, e in errors.items():
            self.sums[name] = self.sums.get(name, 0.0) + e
            if is_repeat:
                self.repeated[name] = self.repeated.get(name, 0.0) + e
        self.n += 1
        self.n_repeated += is_repeat

    def ratios(self) -> dict[str, float | None]:
        def share(sums: dict[str, float], of: str) -> float | None:
            return sums["default"] / sums[of] if sums.get(of) else None

        out = {"mae_vs_hold": share(self.sums, "hold"), "mae_vs_rls_ar": share(self.sums, "rls_ar"),
               "mae_default_rad": self.sums.get("default", 0.0) / max(self.n, 1)}
        if self.n_repeated:
            out.update(repeated_mae_vs_hold=share(self.repeated, "hold"),
                       repeated_mae_vs_rls_ar=share(self.repeated, "rls_ar"))
        return out


def run_session(name: str, hours: float, seed: int, settings: dict[str, Any], folder: Path,
                progress: bool) -> list[dict[str, Any]]:
    """The session's figures, one dict per hour (the last hour may be partial)."""
    frames = round(hours * 3600 * FPS)
    angles, repeated = session_stream(name, frames, seed)
    model = make_default(settings=settings)
    rls = RLSAutoregressive(RLSParams(), HORIZON)
    saver = CheckpointSaver(folder / f"{name}.npz")
    hour = 3600 * FPS
    pending = {m: np.full((HORIZON, angles.shape[1]), np.nan) for m in ("default", "rls_ar", "hold")}
    rows: list[dict[str, Any]] = []
    cpu, rls_cpu, worst = [], [], 0.0
    scores = _Scores()
    snapshot_s = None
    bar = tqdm(total=frames, desc=f"day: {name}", unit="frame", disable=not progress, mininterval=2.0,
               file=sys.stderr)
    for t in range(frames):
        x = angles[t]
        slot = t % HORIZON
        if t >= HORIZON and np.isfinite(pending["default"][slot]).all():
            scores.add({m: float(np.abs(x - p[slot]).mean()) for m, p in pending.items()}, bool(repeated[t]))
        c0, w0 = time.process_time_ns(), time.perf_counter_ns()
        prediction = model.step(x)
        c1, w1 = time.process_time_ns(), time.perf_counter_ns()
        rls_prediction = rls.step(x)
        c2 = time.process_time_ns()
        cpu.append(c1 - c0)
        rls_cpu.append(c2 - c1)
        worst = max(worst, (w1 - w0) / 1e6)  # wall clock: what a node would wait, preemption included
        for m, p in (("default", prediction), ("rls_ar", rls_prediction)):
            pending[m][slot] = np.nan if p is None else p[-1]
        pending["hold"][slot] = x
        if (t + 1) % hour == 0 or t + 1 == frames:
            results = saver.results()
            snapshot_s = saver.submit(model)  # what the learner's thread spends on the save
            rows.append(_hour_row(len(rows) + 1, model, cpu, rls_cpu, worst, scores, snapshot_s, results))
            cpu, rls_cpu, worst, scores = [], [], 0.0, _Scores()
            bar.update((t + 1) - bar.n)
    bar.close()
    saver.close()
    _add_write(rows[-1], saver.results())  # the last hour's save, waited for here (the node does at shutdown)
    return rows


def _hour_row(hour: int, model: Any, cpu: list[int], rls_cpu: list[int], worst: float, scores: _Scores,
              snapshot_s: float, results: list[Any]) -> dict[str, Any]:
    errors = model.errors()
    cpu_us = np.array(cpu) / 1e3
    row: dict[str, Any] = {
        "hour": hour, "frames": len(cpu),
        "neurons": int(errors["neurons"]["pgwr"]), "neurons_evicted": int(errors.get("evicted", 0)),
        **{f"snippets_{n}": int(s["stored"]) for n, s in errors["snippets"].items()},
        **{f"snippets_replaced_{n}": int(s["replaced"]) for n, s in errors["snippets"].items()},
        "rss_mb": round(current_rss_mb(), 1),
        "cpu_us_p50": round(float(np.percentile(cpu_us, 50)), 1),
        "cpu_us_p99": round(float(np.percentile(cpu_us, 99)), 1),
        "cpu_us_mean": round(float(cpu_us.mean()), 1),
        "rls_ar_cpu_us_mean": round(float(np.mean(rls_cpu)) / 1e3, 1),
        "worst_frame_ms": round(worst, 2),
        "worst_frame_cpu_ms": round(float(cpu_us.max()) / 1e3, 2),
        "snapshot_ms": round(1e3 * snapshot_s, 2),
        **{k: (None if v is None else round(v, 4)) for k, v in scores.ratios().items()},
    }
    row["cpu_vs_rls_ar"] = round(row["cpu_us_mean"] / max(row["rls_ar_cpu_us_mean"], 1e-9), 2)
    _add_write(row, results, previous=True)
    return row


def _add_write(row: dict[str, Any], results: list[Any], previous: bool = False) -> None:
    """The write of a save (the previous hour's, collected at this hour's mark, or the last one)."""
    if not results:
        return
    last = results[-1]
    key = "previous_save" if previous else "save"
    row[f"{key}_mb"] = round(last.bytes / 2**20, 1)
    row[f"{key}_write_ms"] = round(1e3 * last.write_s, 1)
    row[f"{key}_error"] = None if last.error is None else str(last.error)


def markdown(results: dict[str, Any]) -> str:
    cols = ("hour", "neurons", "snippets_memory", "snippets_long_memory", "rss_mb", "cpu_us_p50", "cpu_us_p99",
            "cpu_vs_rls_ar", "worst_frame_ms", "worst_frame_cpu_ms", "snapshot_ms", "previous_save_mb",
            "previous_save_write_ms", "mae_vs_hold", "mae_vs_rls_ar", "repeated_mae_vs_hold")
    settings = results["settings"] or "the defaults"
    lines = [f"# A robot's day: {results['hours']} h per session at {FPS} fps, seed {results['seed']}", "",
             f"`{results['command']}`; BLAS threads {results['blas_threads']}; settings: {settings}; 1-minute load "
             f"average {results['load_average'][0]} at the start, {results['load_average'][1]} at the end on "
             f"{results['cpus']} CPUs (other processes inflate the wall-clock figures; CPU time less so).", ""]
    for name, rows in results["sessions"].items():
        present = [c for c in cols if any(c in r for r in rows)]
        lines += [f"## {name}", "", "| " + " | ".join(present) + " |", "|" + "---|" * len(present)]
        lines += ["| " + " | ".join("" if r.get(c) is None else str(r.get(c)) for c in present) + " |" for r in rows]
        last = rows[-1]
        if "save_mb" in last:
            lines += ["", f"The last hour's checkpoint: {last['save_mb']} MB written in {last['save_write_ms']} ms."]
        lines.append("")
    return "\n".join(lines)


def plot(results: dict[str, Any], path: Path) -> str:
    fig, axes = figure(2, 2, (11, 7))
    panels = ((axes[0][0], ("cpu_us_p50", "cpu_us_p99"), "CPU per frame (us)"),
              (axes[0][1], ("rss_mb",), "resident memory (MB)"),
              (axes[1][0], ("neurons", "snippets_memory", "snippets_long_memory"), "units held"),
              (axes[1][1], ("mae_vs_hold", "mae_vs_rls_ar"), "MAE at 600 ms, as a share of another's"))
    styles = {"new": "-", "still": ":", "repeats": "--"}
    for ax, keys, title in panels:
        for name, rows in results["sessions"].items():
            hours = [r["hour"] for r in rows]
            for key in keys:
                values = [np.nan if r.get(key) is None else r[key] for r in rows]
                ax.plot(hours, values, styles.get(name, "-"), marker="o", ms=3, label=f"{name}: {key}")
        ax.set_title(title)
        ax.set_xlabel("hour")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6)
    fig.tight_layout()  # the lower panels' titles clear the upper panels' axis labels
    return save_figure(fig, path.parent, path.stem)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--hours", type=float, default=8.0, help="hours of each session (default 8)")
    parser.add_argument("--sessions", nargs="+", choices=SESSIONS, default=list(SESSIONS))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--setting", action="append", default=[], metavar="KEY=VALUE",
                        help="a setting of the default, flat (e.g. network.gwr.max_neurons=2000); repeatable")
    parser.add_argument("--out", type=Path, default=None, help="folder for results.json, results.md, day.png")
    parser.add_argument("--quick", action="store_true", help="6 minutes per session (a smoke run)")
    parser.add_argument("--quiet", action="store_true", help="only the JSON line")


def _settings(pairs: list[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for pair in pairs:
        key, _, value = pair.partition("=")
        out[key] = json.loads(value) if value.strip() not in ("", "true", "false") else value == "true"
    return out


def run(args: argparse.Namespace) -> int:
    single_threaded_blas()
    hours = 0.1 if args.quick else args.hours
    settings = _settings(args.setting)
    command = " ".join(["gwr-predictor bench day", *sys.argv[3:]])
    results: dict[str, Any] = {"hours": hours, "seed": args.seed, "settings": settings, "blas_threads": blas_threads(),
                               "command": command, "cpus": os.cpu_count(),
                               "load_average": [round(os.getloadavg()[0], 2)], "sessions": {}}
    with tempfile.TemporaryDirectory(prefix="gwr-day-") as tmp:
        for name in args.sessions:
            rows = run_session(name, hours, args.seed, settings, Path(tmp), progress=not args.quiet)
            results["sessions"][name] = rows
            if not args.quiet:
                for row in rows:
                    print(f"{name:8s} h{row['hour']}: {row['neurons']} neurons, snippets "
                          f"{row.get('snippets_memory')}/{row.get('snippets_long_memory')}, RSS {row['rss_mb']} MB, "
                          f"CPU {row['cpu_us_p50']}/{row['cpu_us_p99']} us (p50/p99, {row['cpu_vs_rls_ar']} x "
                          f"RLS-AR), worst {row['worst_frame_ms']} ms, snapshot {row['snapshot_ms']} ms, "
                          f"MAE {row['mae_vs_hold']} x hold, {row['mae_vs_rls_ar']} x RLS-AR", flush=True)
    results["load_average"].append(round(os.getloadavg()[0], 2))
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        for name, text in (("results.json", json.dumps(results, indent=1) + "\n"), ("results.md", markdown(results))):
            write_output(args.out / name, text, "day results", EvaluationError)
        plot(results, args.out / "day.png")
    print(json.dumps(results), flush=True)
    return 0
