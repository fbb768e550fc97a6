"""Settings of the default predictor and of the linear baselines chosen by one protocol (same split, same budget).

Why: a ranking against an untuned baseline says little. The local-linear P-GWR behind the gate
(`gated_llm_gwr`), RLS-AR and the direct linear model (`linear`) each get a grid of the same size;
every point is trained online for `epochs` passes over the training split (random order, same seed)
and scored frozen on the held-out repetitions at the last horizon step; the point with the lowest MAE
there wins, except that for the default predictor, among the points within `tie` (0.5 %) of that MAE,
the finest insertion threshold (smallest `insertion_scale`) wins: more neurons share less of the
regressor space between movements, so a newly learned movement rewrites less of the old ones
(`experiment incremental`), and a 0.5 % difference on one split is within what the seed changes. The
held-out subject never takes part in the choice (it is reported, not used). The data are the
demonstrator's tuning recordings (`data_seed` 7), disjoint from the recordings of every reported
demonstrator figure (`experiment compare` and the others run on seeds 0-2): no setting is chosen on
a figure the docs report. The grid runs with the
library's recruitment settings; then, at the chosen point, a second stage sweeps `recruit_surprise`
(0 = no recruitment): among the values within `tie` of the best MAE of that stage, the most eager
recruitment (smallest value > 0) wins, for the same reason: a recruited neuron keeps an old
movement's neurons from being rewritten, and held-out accuracy says how far that can go before it
fits the training pairs' noise. The chosen settings are the library defaults (`LocalLinearParams()`,
`RLSParams()`, `DirectLinearParams()`); this experiment checks that they still are the winners."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.default_predictor import make_gated_network
from gwr_predictor.evaluation.online import compare_online
from gwr_predictor.evaluation.output import ExperimentOutput, markdown_table
from gwr_predictor.predictors.baselines import RLSAutoregressive, RLSParams
from gwr_predictor.predictors.direct_linear import DirectLinear, DirectLinearParams
from research.experiments import common
from research.experiments.splits import make_splits

NAME = "tune"
RECRUIT = f"{common.GATED}:recruitment"  # the default predictor's second stage
#: The demonstrator's tuning recordings: no reported figure uses this demonstrator seed.
TUNING_DATA_SEED = 7


@dataclass(frozen=True)
class Config:
    patterns: tuple[str, ...] | None = None
    subjects: int = 3
    repetitions: int = 10
    heldout_repetitions: int = 2
    epochs: int = 5
    # the default predictor's grid: rate x insertion_scale x neighbour_rate (18 points; readout_k 3,
    # which beat 1 at every point of the earlier rate x insertion_scale x readout_k grid)
    rates: tuple[float, ...] = (0.05, 0.1, 0.2)
    insertion_scales: tuple[float, ...] = (1.0, 1.5, 2.0)
    neighbour_rates: tuple[float, ...] = (0.02, 0.05)
    tie: float = 0.005  # default predictor: within this share of the best MAE, the finest insertion wins
    # direct linear: within this share of the best MAE, the prior variance nearest 1 wins (see `_prior_near_one`)
    linear_tie: float = 0.001
    # the default predictor's second stage, at the chosen point (0 = no recruitment; the most eager within `tie` wins)
    recruit_surprises: tuple[float, ...] = (0.0, 6.0, 9.0, 12.0, 16.0)
    # RLS-AR's grid: order x forgetting (18 points)
    orders: tuple[int, ...] = (3, 5, 8, 10, 12, 15)
    forgettings: tuple[float, ...] = (0.995, 0.999, 1.0)
    # the direct linear model's grid: order x prior variance of the weights (18 points; with forgetting its
    # RLS winds up on this data, from rest frames that excite few directions, and predicts wildly)
    linear_orders: tuple[int, ...] = (2, 3, 4, 6, 8, 12)
    linear_deltas: tuple[float, ...] = (0.1, 1.0, 10.0)
    overrides: tuple[tuple[str, object], ...] = ()
    data_seed: int = TUNING_DATA_SEED  # the demonstrator recordings tuned on (`--seed` seeds the training order)


QUICK = Config(patterns=("wave_one", "raise_front_both"), subjects=2, repetitions=3, heldout_repetitions=1,
               epochs=1, rates=(0.1,), insertion_scales=(2.0,), neighbour_rates=(0.02, 0.05), orders=(5, 10),
               forgettings=(1.0,), linear_orders=(2, 12), linear_deltas=(1.0,), recruit_surprises=(0.0, 6.0))
FULL = Config()


def _gated(horizon: int, **settings: Any) -> Any:
    return make_gated_network(horizon, settings={f"network.{name}": value for name, value in settings.items()})


def _candidates(config: Config, horizon: int) -> dict[str, list[tuple[dict[str, Any], Any]]]:
    llm = [{"rate": r, "insertion_scale": i, "neighbour_rate": n}
           for r, i, n in itertools.product(config.rates, config.insertion_scales, config.neighbour_rates)]
    rls = [{"order": o, "forgetting": f} for o, f in itertools.product(config.orders, config.forgettings)]
    linear = [{"order": o, "delta": d} for o, d in itertools.product(config.linear_orders, config.linear_deltas)]
    return {common.GATED: [(s, lambda s=s: _gated(horizon, **s)) for s in llm],
            "rls_ar": [(s, lambda s=s: RLSAutoregressive(RLSParams(**s), horizon)) for s in rls],
            common.LINEAR: [(s, lambda s=s: DirectLinear(DirectLinearParams(horizon=horizon, **s))) for s in linear]}


def _finest_insertion(settings: dict[str, Any]) -> float:
    return settings["insertion_scale"]


def _prior_near_one(settings: dict[str, Any]) -> float:
    """After 5 epochs the demonstrator cannot tell the linear model's prior variances apart (equal MAE to 4
    digits): they only matter while it learns from its first frames. One pass from scratch over the
    repetition tuning streams (`research/tuning.md`) ranks delta 1 first (0.692 x hold at 600 ms against
    0.722 for 0.1 and 0.744 for 10), so among near-ties the prior variance nearest 1 wins."""
    return abs(math.log10(settings["delta"]))


def _most_eager_recruitment(settings: dict[str, Any]) -> float:
    return settings["recruit_surprise"] or math.inf  # 0 = no recruitment: the least eager


def choose(rows: list[dict[str, Any]], tie: float,
           prefer: Callable[[dict[str, Any]], float] = _finest_insertion) -> dict[str, Any]:
    """The lowest held-out-repetitions MAE; with `tie` > 0, among the rows within that share of it,
    the one `prefer` ranks first (default: the smallest insertion_scale), then the lowest MAE."""
    def mae(r: dict[str, Any]) -> float:
        return r["heldout_repetitions"]["mae"]

    best = min(rows, key=mae)
    if tie <= 0:
        return best
    close = [r for r in rows if mae(r) <= mae(best) * (1.0 + tie)]
    return min(close, key=lambda r: (prefer(r["settings"]), mae(r)))


def _score(factory: Callable[[], Any], settings: dict[str, Any], splits: Any, config: Config, params: Any,
           seed: int) -> dict[str, Any]:
    """Train a fresh model `config.epochs` passes over the training split; score it on both held-out splits."""
    models = {"m": factory()}
    rng = np.random.default_rng(seed)
    for _ in range(config.epochs):
        compare_online(models, common.shuffled(splits.train, rng), horizon=params.horizon, progress=False)
    row: dict[str, Any] = {"settings": settings}
    for split, seqs, learn in (("heldout_repetitions", splits.heldout_repetitions, False),
                               ("heldout_subjects", splits.heldout_subjects, True)):
        r = compare_online(common.clone(models), seqs, learn=learn, horizon=params.horizon, progress=False)["m"]
        row[split] = {"mae": float(r.stats.mae[-1]), "mse": float(r.stats.mse[-1])}
    return row


def measure(config: Config, seed: int, progress: bool) -> dict[str, Any]:
    params = common.make_params(config.overrides)
    data = common.demo_data(config.patterns, config.subjects, config.repetitions, config.data_seed)
    splits = make_splits(data, 1, config.heldout_repetitions)
    out: dict[str, Any] = {}
    for method, grid in _candidates(config, params.horizon).items():
        rows = []
        for settings, factory in grid:
            rows.append(_score(factory, settings, splits, config, params, seed))
            if progress:
                print(f"{method} {settings}: {rows[-1]['heldout_repetitions']}", flush=True)
        if method == common.LINEAR:
            best = choose(rows, config.linear_tie, _prior_near_one)
        else:
            best = choose(rows, config.tie if method == common.GATED else 0.0)
        out[method] = {"grid": rows, "chosen": best["settings"], "chosen_scores": best}
    if config.recruit_surprises:
        out[RECRUIT] = _recruitment_stage(out[common.GATED]["chosen"], splits, config, params, seed, progress)
    return {"params": params.to_flat(), "splits": splits.sizes(), "methods": out}


def _recruitment_stage(base: dict[str, Any], splits: Any, config: Config, params: Any, seed: int,
                       progress: bool) -> dict[str, Any]:
    """The default predictor at its chosen point, for each `recruit_surprise`; the most eager within `tie`."""
    rows = []
    for surprise in config.recruit_surprises:
        settings = {"recruit_surprise": surprise}
        rows.append(_score(lambda s=settings: _gated(params.horizon, **base, **s), settings, splits, config, params,
                           seed))
        if progress:
            print(f"{RECRUIT} {settings}: {rows[-1]['heldout_repetitions']}", flush=True)
    best = choose(rows, config.tie, _most_eager_recruitment)
    return {"grid": rows, "chosen": best["settings"], "chosen_scores": best, "at": base}


def run(config: Config, out: Path, seed: int = 0, progress: bool = True) -> ExperimentOutput:
    r = measure(config, seed, progress)
    horizon = int(r["params"]["horizon"])
    md = [f"Demonstrator recordings of seed {config.data_seed} (the tuning data; no reported figure uses them). "
          f"Every grid point trained {config.epochs} epochs online on the training split ({r['splits']}), "
          f"scored frozen on the held-out repetitions at {100 * horizon} ms (the choice) and, learning online, "
          "on the held-out subject (reported only). Same split, same grid size for every method."]
    for method, res in r["methods"].items():
        keys = list(res["grid"][0]["settings"])
        rows = [[*[g["settings"][k] for k in keys], g["heldout_repetitions"]["mae"], g["heldout_repetitions"]["mse"],
                 g["heldout_subjects"]["mae"], g["heldout_subjects"]["mse"]] for g in res["grid"]]
        title = (f"{common.label(common.GATED)}, then `recruit_surprise` at {res['at']}" if method == RECRUIT
                 else common.label(method))
        md += ["", f"**{title}**: chosen {res['chosen']}", "",
               markdown_table([*keys, "new reps MAE", "new reps MSE", "new person MAE", "new person MSE"], rows,
                              digits=4)]
    return ExperimentOutput(NAME, "Settings of the default predictor and the linear baselines, one protocol",
                            asdict(config), r, md, [])
