"""`gwr-predictor bench`: speed of learn+predict through the hierarchy, and what bounds it.

Prints readable lines, then one JSON object as the last line:
  frames_per_s      learn + predict per frame through the full hierarchy, ~1,000 neurons per layer,
                    median over 1,000-frame chunks (default mode; `frames_per_s_<mode>` for both)
  predict_p99_ms    99th percentile of one `predict()` (wall clock) with ~5,000 neurons in the
                    P-GWR, best of 3 passes (also over all passes, and in CPU time)
  speedup_vs_loop   vectorised GWR step vs loop_gwr.py (plain per-neuron loops), same data, same
                    process, ~1,000 neurons
  search_us_<mode>  of one frame's time (1e6 / frames_per_s_<mode>), the part spent in its BMU
                    products (timed alone on the same networks; 6 per layer in recursive mode, see
                    `products_per_frame`); the rest is numpy call overhead, learning updates, copies
  frames_per_s_default  the same for the node's default predictor (the gated experts: the network
                    grown on the stream to the size the data asks for, `neurons_default`, and the
                    snippet memory filled on it)
  spread_us_default / spread_share_default  of the default's frames timed above, the time per frame
                    in the interval it states with every prediction (`Spread.step`) and its share of
                    the default's whole step
  default_vs_recursive  the default's speed over the recursive hierarchy's: median over chunks of
                    the ratio, each chunk timed on both back to back (in alternating order), so
                    that a load coming and going hits both alike (their separate runs do not)
  frames_per_s_default_full / default_full_vs_recursive  the same once the default has learned
                    `20 x size` frames of motion that never repeats (a smooth random walk): every
                    frame is a new snippet, as on real motion, so its snippet memories are near their
                    capacity (`snippets_default_full`) and their search is what bounds it
  peak_rss_mb       peak resident memory with the benchmark models (before the loop/BMU probes and
                    the full default; `peak_rss_mb_default_full` after it)
  bmu_overhead_us / bmu_ns_per_value  fit of one BMU search time = overhead + n * dim * cost,
                    to tell call overhead from memory bandwidth
The data are synthetic smooth periodic multi-joint arm trajectories (data/synthetic.py, no
dependency on the demonstrator). Networks are pre-grown to the target sizes with `max_neurons`.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from typing import Any

import numpy as np
from tqdm import tqdm

from gwr_predictor.data.synthetic import synthetic_arm_stream
from gwr_predictor.learning.gwr import GWR
from gwr_predictor.learning.gwr_loop import LoopGWR
from gwr_predictor.learning.hierarchy import Hierarchy
from gwr_predictor.learning.params import GWRParams, HierarchyParams
from research import day
from research.memory_use import peak_rss_mb
from research.registry import DEFAULT_PREDICTOR, RESEARCH
from research.streams import random_walk_stream


def _log(quiet: bool, text: str) -> None:
    if not quiet:
        print(text, flush=True)


def grown_hierarchy(params: HierarchyParams, stream: np.ndarray, targets: tuple[int, int, int],
                    max_frames: int, seed: int = 0, progress: bool = False) -> tuple[Hierarchy, int]:
    """A hierarchy trained on `stream` (cycled) until every layer has its target size (capped by
    max_neurons) or `max_frames` frames; returns it and the frames used."""
    h = Hierarchy(params, seed=seed)
    used = 0
    with tqdm(total=max_frames, desc=f"growing to {targets}", unit="frame", file=sys.stderr, leave=False,
              disable=not progress or not sys.stderr.isatty()) as bar:
        while used < max_frames and any(n < t for n, t in zip(h.neuron_counts, targets, strict=True)):
            part = stream[:min(len(stream), max_frames - used)]
            for x in part:
                h.step(x)
            used += len(part)
            bar.update(len(part))
    return h, used


def bench_params(size: int, pgwr_size: int, mode: str, input_scale: float) -> HierarchyParams:
    """Parameters that let each layer grow to `size` neurons (P-GWR to `pgwr_size`)."""
    base = HierarchyParams(mode=mode, input_scale=input_scale)
    return base.replace(gwr1=base.gwr1.replace(max_neurons=size), gwr2=base.gwr2.replace(max_neurons=size),
                        pgwr=base.pgwr.replace(max_neurons=pgwr_size))


def _chunks(stream: np.ndarray, chunk: int) -> list[np.ndarray]:
    return [stream[start:start + chunk] for start in range(0, len(stream), chunk)]


def _chunk_seconds(model: Any, part: np.ndarray) -> float:
    """Wall time of step() (learn + predict) over the frames of `part`."""
    t0 = time.perf_counter()
    for x in part:
        model.step(x)
    return time.perf_counter() - t0


def measure_throughput(h: Hierarchy, stream: np.ndarray, chunk: int = 1000) -> tuple[float, float]:
    """(median, best) frames per second of step() (learn + predict) over chunks of `stream`.
    The median of chunks resists other processes stealing the CPU for a while."""
    rates = [len(part) / _chunk_seconds(h, part) for part in _chunks(stream, chunk)]
    return float(np.median(rates)), float(np.max(rates))


def measure_against(reference: Any, model: Any, stream: np.ndarray, chunk: int) -> tuple[float, float, float]:
    """(median, best) frames/s of `model`, and the median over chunks of its speed over `reference`'s
    on the same chunk, the two timed back to back in alternating order (a passing load hits both)."""
    rates, ratios = [], []
    for i, part in enumerate(_chunks(stream, chunk)):
        if i % 2:
            t_model = _chunk_seconds(model, part)
            t_reference = _chunk_seconds(reference, part)
        else:
            t_reference = _chunk_seconds(reference, part)
            t_model = _chunk_seconds(model, part)
        rates.append(len(part) / t_model)
        ratios.append(t_reference / t_model)
    return float(np.median(rates)), float(np.max(rates)), float(np.median(ratios))


def measure_default(reference: Hierarchy, stream: np.ndarray, frames: int,
                    chunk: int) -> tuple[float, float, float, int, float]:
    """(median, best) frames/s of the node's default predictor (the registry's), its speed over
    `reference`'s (`measure_against`), its neurons, after it learned the rest of `stream` first (it
    grows to the size the data asks for), and the seconds its spread took in the timed frames."""

    model = RESEARCH.make_predictor(DEFAULT_PREDICTOR)
    for x in stream[frames:]:
        model.step(x)
    spread, spent = model.spread, [0.0]  # type: ignore[attr-defined]
    step = spread.step

    def timed(*args: Any) -> None:
        start = time.perf_counter()
        step(*args)
        spent[0] += time.perf_counter() - start

    spread.step = timed
    fps, best, ratio = measure_against(reference, model, stream[:frames], chunk)
    return fps, best, ratio, int(model.neuron_counts[0]), spent[0]


def measure_default_full(reference: Hierarchy, learned: int, frames: int, chunk: int,
                         progress: bool) -> tuple[float, float, int]:
    """(median frames/s, speed over `reference`'s, snippets stored) of the default predictor after
    `learned` frames of motion that never repeats (`random_walk_stream`)."""

    stream = random_walk_stream(learned + frames)
    model = RESEARCH.make_predictor(DEFAULT_PREDICTOR)
    for x in tqdm(stream[:learned], desc="default, filling its memories", unit="frame", disable=not progress):
        model.step(x)
    fps, _, ratio = measure_against(reference, model, stream[learned:], chunk)
    snippets = sum(held["stored"] for held in model.errors()["snippets"].values())
    return fps, ratio, snippets


def products_per_frame(params: HierarchyParams) -> tuple[int, int, int]:
    """BMU matrix-vector products per learned frame, per layer (GWR1, GWR2, P-GWR), once windows
    are full: one per learning step, one for the forecast and three per roll-out step; in
    recursive mode the P-GWR's learning step reuses the forecast's product of the previous frame."""
    if params.mode == "vector":
        return 1, 1, 2
    steps = params.horizon - 1
    return 1 + steps, 1 + steps, 1 + steps


def measure_products(h: Hierarchy, reps: int = 2000) -> tuple[float, float, float]:
    """Time (us) of one BMU matrix-vector product per layer at its current size (best of 3)."""
    times = []
    for net in (h.gwr1, h.gwr2, h.pgwr):
        a, xa, buf, _ = net.search_views()
        xa[:-1] = 0.1
        best = math.inf
        for _ in range(3):
            t0 = time.perf_counter()
            for _ in range(reps):
                np.dot(a, xa, out=buf)
            best = min(best, (time.perf_counter() - t0) / reps)
        times.append(best * 1e6)
    return times[0], times[1], times[2]


def measure_predict(h: Hierarchy, stream: np.ndarray, calls: int) -> tuple[np.ndarray, np.ndarray]:
    """Wall-clock and CPU durations (ms) of `predict()` after each frame of `stream` (the frames
    themselves are matched untimed, without learning, so the network size stays fixed)."""
    wall, cpu = np.empty(calls), np.empty(calls)
    for i in range(calls):
        h.step(stream[i % len(stream)], learn=False)
        c0, t0 = time.process_time(), time.perf_counter()
        h.predict()
        wall[i], cpu[i] = time.perf_counter() - t0, time.process_time() - c0
    return wall * 1e3, cpu * 1e3


def measure_speedup(size: int, dim: int, steps: int, seed: int = 0) -> tuple[float, float, float]:
    """(vectorised us/step, loop us/step, ratio) on the same pre-grown network and data."""
    rng = np.random.default_rng(seed)
    weights = rng.uniform(-1, 1, (size, dim))
    chain = np.stack([np.arange(size - 1), np.arange(1, size), np.zeros(size - 1, int)], axis=1)
    params = GWRParams(max_neurons=size)
    data = rng.uniform(-1, 1, (steps, dim))
    fast = GWR.from_arrays(weights, params, edges=chain)
    slow = LoopGWR.from_gwr(fast)
    t0 = time.perf_counter()
    for x in data:
        fast.learn(x)
    t_fast = (time.perf_counter() - t0) / steps
    t0 = time.perf_counter()
    for x in data:
        slow.learn(x)
    t_slow = (time.perf_counter() - t0) / steps
    return t_fast * 1e6, t_slow * 1e6, t_slow / t_fast


def measure_bmu_cost(dims: tuple[int, ...] = (8, 24, 72), sizes: tuple[int, ...] = (250, 1000, 2500, 5000),
                     reps: int = 300) -> dict[str, Any]:
    """Time of one BMU search vs n * dim: intercept = per-call overhead, slope = cost per value."""
    rng = np.random.default_rng(1)
    xs, ts = [], []
    for dim in dims:
        for n in sizes:
            net = None  # free the previous network (its n x n edge matrix) first
            net = GWR.from_arrays(rng.uniform(-1, 1, (n, dim)), GWRParams())
            x = rng.uniform(-1, 1, dim)
            best = math.inf
            for _ in range(3):
                t0 = time.perf_counter()
                for _ in range(reps):
                    net.nearest(x)
                best = min(best, (time.perf_counter() - t0) / reps)
            xs.append(n * dim)
            ts.append(best * 1e6)
    slope, intercept = np.polyfit(np.array(xs, float), np.array(ts), 1)
    return {"bmu_overhead_us": float(intercept), "bmu_ns_per_value": float(slope * 1e3),
            "bmu_points": [[x, round(t, 2)] for x, t in zip(xs, ts, strict=True)]}


def configure(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="what", metavar="day", help="`day`: a robot's day, compressed (research/day.py)")
    day.configure(sub.add_parser("day", description=day.__doc__.splitlines()[0]))
    parser.add_argument("--quick", action="store_true", help="small sizes and few frames (a smoke run)")
    parser.add_argument("--size", type=int, default=1000, help="neurons per layer for frames_per_s")
    parser.add_argument("--pgwr-size", type=int, default=5000, help="P-GWR neurons for predict_p99_ms")
    parser.add_argument("--frames", type=int, default=20000, help="frames timed for frames_per_s")
    parser.add_argument("--input-scale", type=float, default=1.0,
                        help="input scale used to grow the networks quickly (fine-grained layers)")
    parser.add_argument("--quiet", action="store_true", help="only the JSON line")


def run(args: argparse.Namespace) -> int:
    if args.what == "day":
        return day.run(args)
    size, pgwr_size, frames = args.size, args.pgwr_size, args.frames
    if args.quick:
        size, pgwr_size, frames = min(size, 100), min(pgwr_size, 300), min(frames, 300)
    stream = synthetic_arm_stream(max(frames, 40000 if not args.quick else 2000))
    result: dict[str, Any] = {"size_per_layer": size, "pgwr_size": pgwr_size, "frames_timed": frames}
    chunk = 100 if args.quick else 1000
    for mode in ("recursive", "vector"):
        params = bench_params(size, size, mode, args.input_scale)
        h, used = grown_hierarchy(params, stream, (size, size, size), max_frames=40 * size + 2000,
                                  progress=not args.quiet)
        fps, best = measure_throughput(h, stream[:frames], chunk)
        result[f"frames_per_s_{mode}"] = round(fps, 1)
        result[f"frames_per_s_{mode}_best"] = round(best, 1)
        result[f"neurons_{mode}"] = list(h.neuron_counts)
        counts = products_per_frame(params)
        search = float(np.dot(counts, measure_products(h, 200 if args.quick else 2000)))
        result[f"search_us_{mode}"] = round(search, 1)
        _log(args.quiet, f"{mode:9s}: {fps:9.0f} frames/s learn+predict (median of {chunk}-frame chunks; best "
                         f"{best:.0f}), neurons {h.neuron_counts} (grown on {used} frames); per frame "
                         f"{1e6 / fps:.0f} us, of which {search:.0f} us in {sum(counts)} BMU products "
                         f"{counts}, {1e6 / fps - search:.0f} us the rest")
        if mode == "recursive":  # the default against this hierarchy, chunk by chunk
            fps, best, ratio, neurons, spread_s = measure_default(h, stream, frames, chunk)
            spread_us = 1e6 * spread_s / frames
            result.update(frames_per_s_default=round(fps, 1), neurons_default=neurons,
                          default_vs_recursive=round(ratio, 3), spread_us_default=round(spread_us, 1),
                          spread_share_default=round(spread_us * fps / 1e6, 4))
            _log(args.quiet, f"default  : {fps:9.0f} frames/s learn+predict, gwr_experts (the node's default), "
                             f"{neurons} P-GWR neurons after the warm-up (best {best:.0f}); "
                             f"{ratio:.3f}x the recursive hierarchy's speed (median of paired chunks); "
                             f"its interval {spread_us:.1f} us per frame, {100 * spread_us * fps / 1e6:.1f} % of "
                             "its step")
            reference = h  # for the full default, timed last (its memories would count in the peak RSS)
        del h
    result["frames_per_s"] = result[f"frames_per_s_{HierarchyParams().mode}"]

    mode = HierarchyParams().mode
    params = bench_params(size, pgwr_size, mode, args.input_scale)
    h, used = grown_hierarchy(params, stream, (0, 0, pgwr_size), max_frames=40 * pgwr_size + 2000,
                              progress=not args.quiet)
    calls = 300 if args.quick else 3000
    passes = [measure_predict(h, stream, calls) for _ in range(3)]
    wall = np.concatenate([w for w, _ in passes])
    cpu = np.concatenate([c for _, c in passes])
    result["predict_p50_ms"] = round(float(np.percentile(wall, 50)), 4)
    result["predict_p99_ms"] = round(float(min(np.percentile(w, 99) for w, _ in passes)), 4)
    result["predict_p99_ms_all_passes"] = round(float(np.percentile(wall, 99)), 4)
    result["predict_p99_cpu_ms"] = round(float(np.percentile(cpu, 99)), 4)
    result["predict_neurons"] = list(h.neuron_counts)
    result["predict_mode"] = mode
    _log(args.quiet, f"predict() ({mode}, neurons {h.neuron_counts}): p50 {result['predict_p50_ms']:.3f} ms; p99 "
                     f"{result['predict_p99_ms']:.3f} ms wall (best of 3 passes of {calls}; "
                     f"{result['predict_p99_ms_all_passes']:.3f} ms over all), "
                     f"{result['predict_p99_cpu_ms']:.3f} ms CPU")

    result["peak_rss_mb"] = round(peak_rss_mb(), 1)  # the sized models; the probes below allocate more
    del h

    learned = 2000 if args.quick else 20 * size
    fps, ratio, snippets = measure_default_full(reference, learned, frames, chunk, progress=not args.quiet)
    del reference
    result.update(frames_per_s_default_full=round(fps, 1), snippets_default_full=snippets,
                  default_full_vs_recursive=round(ratio, 3), peak_rss_mb_default_full=round(peak_rss_mb(), 1))
    _log(args.quiet, f"default, full: {fps:5.0f} frames/s learn+predict after {learned} frames of motion that never "
                     f"repeats ({snippets} snippets in its memories); {ratio:.3f}x the recursive hierarchy's speed")

    fast_us, loop_us, ratio = measure_speedup(size, 8, 100 if args.quick else 400)
    result.update(vector_step_us=round(fast_us, 2), loop_step_us=round(loop_us, 1), speedup_vs_loop=round(ratio, 1))
    _log(args.quiet, f"GWR step, {size} neurons, 8-d: vectorised {fast_us:.1f} us, loop {loop_us:.0f} us "
                     f"-> x{ratio:.0f}")

    cost = measure_bmu_cost(sizes=(100, 400) if args.quick else (250, 1000, 2500, 5000),
                            reps=50 if args.quick else 300)
    result.update(bmu_overhead_us=round(cost["bmu_overhead_us"], 2),
                  bmu_ns_per_value=round(cost["bmu_ns_per_value"], 4))
    _log(args.quiet, f"BMU search: {cost['bmu_overhead_us']:.1f} us per call + {cost['bmu_ns_per_value']:.3f} ns "
                     f"per weight value (n * dim); points {cost['bmu_points']}")
    result["peak_rss_mb_process"] = round(peak_rss_mb(), 1)
    result["load_average_1min"] = round(os.getloadavg()[0], 2)
    _log(args.quiet, f"peak RSS {result['peak_rss_mb']:.0f} MB with the benchmark models "
                     f"({result['peak_rss_mb_process']:.0f} MB after the BMU probes); 1-min load average "
                     f"{result['load_average_1min']} on {os.cpu_count()} CPUs (other processes inflate "
                     f"wall-clock figures)")
    print(json.dumps(result), file=sys.stdout, flush=True)
    return 0
