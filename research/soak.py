"""`gwr-predictor soak`: a long offline run (default one million frames) through the hierarchy with
a maximum network size, to show that memory stays flat and throughput does not decay.

The stream is the synthetic demonstrations of `bench`, shuffled every epoch, with a sequence
boundary between demonstrations and about 1 % missing frames, so every path of the online loop
runs. Prints RSS and throughput at the start, at a few points and at the end; the last line is
one JSON object.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
from tqdm import tqdm

from gwr_predictor.data.synthetic import synthetic_demonstrations
from gwr_predictor.learning.hierarchy import Hierarchy
from gwr_predictor.learning.params import HierarchyParams
from research.memory_use import current_rss_mb, peak_rss_mb


def soak_stream(seed: int, missing_rate: float) -> Iterator[np.ndarray | None]:
    """Frames of shuffled demonstrations, None between demonstrations (a boundary marker is not
    a frame: the caller resets) and NaN frames at `missing_rate`."""
    rng = np.random.default_rng(seed)
    demos = [d for _, d in synthetic_demonstrations(seed)]
    nan_frame = np.full(demos[0].shape[1], np.nan)
    while True:
        for i in rng.permutation(len(demos)):
            yield None
            drops = rng.random(len(demos[i])) < missing_rate
            for x, drop in zip(demos[i], drops, strict=True):
                yield nan_frame if drop else x


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", type=int, default=1_000_000, help="frames to process (default 1e6)")
    parser.add_argument("--max-neurons", type=int, nargs=3, default=(1000, 2000, 3000),
                        metavar=("GWR1", "GWR2", "PGWR"), help="maximum size of each layer")
    parser.add_argument("--mode", choices=("recursive", "vector"), default=HierarchyParams().mode)
    parser.add_argument("--input-scale", type=float, default=HierarchyParams().input_scale,
                        help="model units per radian (larger = finer layers that reach the size caps sooner)")
    parser.add_argument("--points", type=int, default=10, help="progress reports between start and end")
    parser.add_argument("--missing-rate", type=float, default=0.01, help="fraction of frames dropped")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quiet", action="store_true", help="no progress bar, only the JSON line")


def run(args: argparse.Namespace) -> int:
    if args.frames < 1 or args.points < 1:
        print("soak: --frames and --points must be >= 1", file=sys.stderr)
        return 2
    base = HierarchyParams(mode=args.mode, input_scale=args.input_scale)
    m1, m2, m3 = args.max_neurons
    params = base.replace(gwr1=base.gwr1.replace(max_neurons=m1), gwr2=base.gwr2.replace(max_neurons=m2),
                          pgwr=base.pgwr.replace(max_neurons=m3))
    model = Hierarchy(params, seed=args.seed)
    stream = soak_stream(args.seed, args.missing_rate)
    marks = set(np.linspace(0, args.frames, args.points + 2).astype(int)[1:].tolist())
    points: list[dict[str, Any]] = []

    def report(done: int, window_fps: float) -> None:
        point = {"frame": done, "rss_mb": round(current_rss_mb(), 1), "frames_per_s": round(window_fps, 1),
                 "neurons": list(model.neuron_counts)}
        points.append(point)
        if not args.quiet:
            tqdm.write(f"frame {done:>9d}: RSS {point['rss_mb']:7.1f} MB, {window_fps:8.0f} frames/s, "
                       f"neurons {model.neuron_counts}", file=sys.stderr)

    rss_start = current_rss_mb()
    report(0, 0.0)
    done = 0
    t_start = t_mark = time.perf_counter()
    mark_done = 0
    bar = tqdm(total=args.frames, unit="frame", file=sys.stderr, disable=args.quiet or not sys.stderr.isatty(),
               mininterval=1.0)
    with bar:
        while done < args.frames:
            x = next(stream)
            if x is None:
                model.reset_sequence()
                continue
            model.step(x)
            done += 1
            if done % 1000 == 0:
                bar.update(1000)
            if done in marks:
                now = time.perf_counter()
                report(done, (done - mark_done) / (now - t_mark))
                t_mark, mark_done = now, done
    elapsed = time.perf_counter() - t_start
    errors = model.errors()
    result = {
        "frames": done,
        "elapsed_s": round(elapsed, 2),
        "frames_per_s": round(done / elapsed, 1),
        "rss_start_mb": round(rss_start, 1),
        "rss_end_mb": round(current_rss_mb(), 1),
        "peak_rss_mb": round(max(peak_rss_mb(), rss_start, *(p["rss_mb"] for p in points)), 1),
        "neurons": list(model.neuron_counts),
        "max_neurons": [m1, m2, m3],
        "input_scale": args.input_scale,
        "missing": errors["missing"],
        "cpe_mean": errors["cpe_mean"],
        "points": points,
    }
    print(json.dumps(result), flush=True)
    return 0
