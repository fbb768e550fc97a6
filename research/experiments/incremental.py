"""Incremental learning of the 10 patterns, one after another (Sec. VI-B2, Fig. 5).

Each pattern is presented for `epochs_per_pattern` epochs (an epoch = its demonstrations, shuffled)
before the next one comes; the presentation order is random and the run is repeated for several
orders. After every `eval_every` epochs the model is scored, frozen, on the demonstrations of every
pattern learned so far: C.P.E. (MSE against the true frames) and P.E. (MSE against the frames as
GWR1 represents them, the hierarchy's own bookkeeping, which removes the quantization error of the
lower layers). Neurons per layer are recorded after every epoch.

Forgetting is measured per pattern: its own MSE right after its block and after the last block.
A rise there mixes two things: forgetting, and the harder task of a model that knows every pattern
(where several patterns pass through the same poses, their futures are ambiguous from the regressor
alone). `together` separates them: a fresh model is trained on all the patterns at once, shuffled
together, with as many presentations as the sequential run, and scored on each pattern the same
way; what the sequential model loses beyond that reference is forgetting.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.evaluation.online import compare_online
from gwr_predictor.evaluation.output import ExperimentOutput, figure, markdown_table, save_figure
from research.blend import gwr_member
from research.experiments import common

NAME = "incremental"
LAYER_LABELS = {"gwr1": "GWR1", "gwr2": "GWR2", "pgwr": "P-GWR"}


@dataclass(frozen=True)
class Config:
    patterns: tuple[str, ...] | None = None
    subjects: int = 3
    repetitions: int = 3  # per subject: demonstrations per epoch = subjects * repetitions
    epochs_per_pattern: int = 50
    orders: int = 3
    eval_every: int = 10
    eval_repetitions: int = 1  # per subject and learned pattern, for the C.P.E./P.E.
    together: bool = True  # also train a fresh model on all patterns at once (the forgetting reference)
    # and on the first k patterns of each order at once, for these k (the C.P.E. a learner that never
    # forgets would have after k patterns; needs `together`)
    together_at: tuple[int, ...] = (3, 5)
    method: str = common.HIERARCHY  # or common.DEFAULT, the node's default (`--method`)
    overrides: tuple[tuple[str, object], ...] = ()


QUICK = Config(patterns=("wave_one", "raise_lateral_one", "rotate_cw_both"), subjects=1, repetitions=1,
               epochs_per_pattern=3, orders=1, eval_every=1, together_at=(2,))
FULL = Config()


def one_order(config: Config, order: list[str], by_pattern: dict[str, list[Any]], seed: int,
              progress: bool) -> dict[str, Any]:
    params = common.make_params(config.overrides)
    model = common.make_model(config.method, params, seed)
    learner = gwr_member(model)  # the GWR learner keeping the P.E. bookkeeping
    rng = np.random.default_rng([seed, 1])
    neurons, online, cpe, pe, evaluated_at = [], [], [], [], []
    learned: list[Any] = []
    per_pattern: dict[str, list[float]] = {}  # pattern -> MSE on it at the end of every block since it was learned
    epoch = 0
    for pattern in order:
        demos = by_pattern[pattern]
        learned += [s for s in demos if s.repetition <= config.eval_repetitions]
        for e in range(config.epochs_per_pattern):
            res = compare_online({"h": model}, common.shuffled(demos, rng), horizon=params.horizon,
                                 progress=progress, desc=f"{NAME} {pattern} {e + 1}")["h"]
            online.append(res.stats.overall_mse())
            neurons.append(list(model.neuron_counts))
            epoch += 1
            if (e + 1) % config.eval_every == 0 or e + 1 == config.epochs_per_pattern:
                learner.reset_errors()
                ev = compare_online({"h": model}, learned, learn=False, horizon=params.horizon, progress=False)["h"]
                errs = learner.errors()
                cpe.append(ev.stats.mse[-1])
                pe.append(errs["pe"][-1])
                evaluated_at.append(epoch)
        for old in order[:order.index(pattern) + 1]:  # forgetting: each learned pattern on its own
            seqs = [s for s in learned if s.pattern == old]
            per_pattern.setdefault(old, []).append(_frozen_mse(model, seqs, params.horizon))
    run = {"order": order, "neurons": neurons, "online_mse": online, "cpe": cpe, "pe": pe,
           "evaluated_at": evaluated_at, "layers": [LAYER_LABELS.get(n, n) for n in learner.layer_names],
           "per_pattern_mse": per_pattern}
    if config.together:
        run["together"] = trained_together(config, params, order, by_pattern, learned, seed, progress)
        run["together_curve"] = [[k, trained_together(config, params, order[:k], by_pattern,
                                                      [s for s in learned if s.pattern in order[:k]], seed,
                                                      progress)["cpe"]]
                                 for k in config.together_at if 0 < k < len(order)]
    return run


def trained_together(config: Config, params: Any, order: list[str], by_pattern: dict[str, list[Any]],
                     scored: list[Any], seed: int, progress: bool) -> dict[str, Any]:
    """A fresh model trained on every pattern of `order` at once, as many presentations as the
    sequential run gave them (epochs_per_pattern epochs of all their demonstrations, shuffled
    together): each pattern's own MSE and the C.P.E. on `scored`, frozen like the sequential model."""
    model = common.make_model(config.method, params, seed)
    rng = np.random.default_rng([seed, 2])
    everything = [s for p in order for s in by_pattern[p]]
    for e in range(config.epochs_per_pattern):
        compare_online({"h": model}, common.shuffled(everything, rng), horizon=params.horizon,
                       progress=progress, desc=f"{NAME} together {e + 1}")
    mse = {p: _frozen_mse(model, [s for s in scored if s.pattern == p], params.horizon) for p in order}
    return {"per_pattern_mse": mse, "cpe": _frozen_mse(model, scored, params.horizon),
            "neurons": list(model.neuron_counts)}


def _frozen_mse(model: Any, sequences: list[Any], horizon: int) -> float:
    ev = compare_online(common.clone({"h": model}), sequences, learn=False, horizon=horizon, progress=False)["h"]
    return float(ev.stats.mse[-1])


def forgetting(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """Per pattern: MSE right after its block and after the last block (mean over orders), and the
    largest rise any pattern showed; a C.P.E. that rises because harder patterns join the set scored
    is not forgetting, a pattern whose own error rises is."""
    first: dict[str, list[float]] = {}
    last: dict[str, list[float]] = {}
    for r in runs:
        for pattern, mses in r["per_pattern_mse"].items():
            first.setdefault(pattern, []).append(mses[0])
            last.setdefault(pattern, []).append(mses[-1])
    rise = [b - a for p in first for a, b in zip(first[p], last[p], strict=True)]
    out = {"just_learned": {p: float(np.mean(v)) for p, v in first.items()},
           "after_all": {p: float(np.mean(v)) for p, v in last.items()},
           "mean_rise": float(np.mean(rise)), "max_rise": float(np.max(rise))}
    if all("together" in r for r in runs):
        together = {p: float(np.mean([r["together"]["per_pattern_mse"][p] for r in runs])) for p in first}
        lost = [r["per_pattern_mse"][p][-1] - r["together"]["per_pattern_mse"][p] for r in runs for p in first]
        out |= {"together": together, "mean_forgotten": float(np.mean(lost)),
                "cpe_together": float(np.mean([r["together"]["cpe"] for r in runs]))}
    return out


def together_curve(runs: list[dict[str, Any]], cpe_mean: np.ndarray, evaluated_at: list[int], block: int,
                   cpe_together: float | None) -> list[dict[str, float]]:
    """Per number of patterns learned k (those with a reference, and all of them): the sequential C.P.E.
    at the end of block k and the C.P.E. of fresh models trained on the same k patterns at once, means
    over the orders. The gap between the two is forgetting; a C.P.E. that rises along with the
    reference is the patterns getting harder to tell apart, which no learner can avoid."""
    n = len(runs[0]["order"])
    ks = [k for k, _ in runs[0].get("together_curve", [])]
    refs = {k: float(np.mean([dict(r["together_curve"])[k] for r in runs])) for k in ks}
    if cpe_together is not None:
        refs[n] = cpe_together
    return [{"patterns": k, "sequential": float(cpe_mean[evaluated_at.index(k * block)]), "together": v}
            for k, v in sorted(refs.items())]


def growth_share(neurons: np.ndarray, block: int) -> np.ndarray:
    """Per layer, the share of each pattern block's growth that happened in its last
    `block - block // 2` epochs (0 = all growth at the start of the block, i.e. levelled off;
    `steady_share(block)` = growing at a constant rate)."""
    n = np.vstack([np.zeros((1, neurons.shape[1])), neurons])
    blocks = (n.shape[0] - 1) // block
    half = block // 2
    total = np.zeros(neurons.shape[1])
    late = np.zeros(neurons.shape[1])
    for b in range(blocks):
        start, mid, end = b * block, b * block + half, (b + 1) * block
        total += np.maximum(n[end] - n[start], 0)
        late += np.maximum(n[end] - n[mid], 0)
    return np.where(total > 0, late / np.maximum(total, 1), 0.0)


def steady_share(block: int) -> float:
    return (block - block // 2) / block


def run(config: Config, out: Path, seed: int = 0, progress: bool = True) -> ExperimentOutput:
    data = common.demo_data(config.patterns, config.subjects, config.repetitions, seed)
    groups = common.by_pattern(data)
    rng = np.random.default_rng(seed)
    names = list(groups)
    runs = [one_order(config, [names[i] for i in rng.permutation(len(names))], groups, seed + k, progress)
            for k in range(config.orders)]
    neurons = np.array([r["neurons"] for r in runs], float)  # (orders, epochs, layers)
    cpe = np.array([r["cpe"] for r in runs], float)
    pe = np.array([r["pe"] for r in runs], float)
    share = growth_share(neurons.mean(axis=0), config.epochs_per_pattern)
    layer_names = runs[0]["layers"]
    results = {"runs": runs, "layers": layer_names, "neurons_mean": neurons.mean(axis=0),
               "neurons_std": neurons.std(axis=0),
               "cpe_mean": cpe.mean(axis=0), "pe_mean": pe.mean(axis=0), "late_growth_share": share,
               "evaluated_at": runs[0]["evaluated_at"], "forgetting": forgetting(runs)}
    results["together_curve"] = together_curve(runs, results["cpe_mean"], results["evaluated_at"],
                                               config.epochs_per_pattern, results["forgetting"].get("cpe_together"))
    e = config.epochs_per_pattern
    ends = [(i + 1) * e - 1 for i in range(len(names))]
    rows = [[i + 1, *[int(v) for v in neurons.mean(axis=0)[k]], cpe.mean(axis=0)[runs[0]["evaluated_at"].index(k + 1)],
             pe.mean(axis=0)[runs[0]["evaluated_at"].index(k + 1)]] for i, k in enumerate(ends)]
    md = [f"{len(names)} patterns x {e} epochs ({config.subjects * config.repetitions} demonstrations per epoch), "
          f"averaged over {config.orders} random presentation orders. C.P.E./P.E.: MSE (rad²) at the "
          f"{common.make_params(config.overrides).horizon}-frame horizon on all patterns learned so far, frozen.",
          f"Method: {common.label(config.method)}.",
          "", markdown_table(["patterns learned", *layer_names, "C.P.E.", "P.E."], rows, digits=4), "",
          "Share of each pattern's neuron growth that happened in the second half of its epochs "
          f"(0 = levelled off, {steady_share(e):.2f} = growing steadily): "
          + ", ".join(f"{n} {s:.2f}" for n, s in zip(layer_names, share, strict=True)) + ".", "",
          *_forgetting_table(results["forgetting"]), *_curve_table(results["together_curve"])]
    return ExperimentOutput(NAME, "Incremental learning of the patterns", asdict(config), results, md,
                            [_plot(results, config, len(names), Path(out))])


def _forgetting_table(f: dict[str, Any]) -> list[str]:
    together = "together" in f
    head = ["pattern", "just learned", "after all patterns", "change", *(["trained together"] * together)]
    rows = [[p, f["just_learned"][p], f["after_all"][p], f["after_all"][p] - f["just_learned"][p],
             *([f["together"][p]] if together else [])] for p in f["just_learned"]]
    lines = ["Forgetting: each pattern's own MSE (rad², frozen, last horizon step) right after its block and "
             "after the last block, mean over the orders"
             + (", and in a fresh model trained on all patterns at once (the reference: what a model that "
                "knows every pattern can do without forgetting)" if together else "") + ":", "",
             markdown_table(head, rows, digits=4), "",
             f"Mean change {f['mean_rise']:+.4f}, largest rise of any pattern in any order {f['max_rise']:+.4f} rad²."]
    if together:
        lines.append(f"Beyond the trained-together reference (forgetting proper): {f['mean_forgotten']:+.4f} rad² "
                     f"per pattern on average; C.P.E. on all patterns trained together {f['cpe_together']:.4f}.")
    return lines


def _curve_table(curve: list[dict[str, float]]) -> list[str]:
    if not curve:
        return []
    rows = [[c["patterns"], c["sequential"], c["together"], c["sequential"] / c["together"]] for c in curve]
    return ["", "C.P.E. after k patterns, learned one after another and, in fresh models, all k at once "
            "(what a learner that never forgets would reach; mean over the orders):", "",
            markdown_table(["patterns learned", "C.P.E. one after another", "C.P.E. all at once", "ratio"],
                           rows, digits=4)]


def _plot(r: dict[str, Any], config: Config, n_patterns: int, out: Path) -> str:
    fig, axes = figure(2, 1, size=(8.0, 6.5))
    e = config.epochs_per_pattern
    ax = axes[0][0]
    ax.plot(r["evaluated_at"], r["cpe_mean"], "b-", marker=".", label="C.P.E.")
    ax.plot(r["evaluated_at"], r["pe_mean"], "r-", marker=".", label="P.E.")
    if r.get("together_curve"):
        ax.plot([c["patterns"] * e for c in r["together_curve"]], [c["together"] for c in r["together_curve"]],
                "ks", ms=5, label="C.P.E. of a model trained on those patterns at once")
    ax.set_ylabel("MSE (rad²)")
    ax.legend(fontsize=8)
    ax = axes[1][0]
    mean, std = np.asarray(r["neurons_mean"]), np.asarray(r["neurons_std"])
    epochs = np.arange(1, mean.shape[0] + 1)
    for k, name in enumerate(r["layers"]):
        ax.plot(epochs, mean[:, k], label=name)
        ax.fill_between(epochs, mean[:, k] - std[:, k], mean[:, k] + std[:, k], alpha=0.2)
    ax.set_ylabel("neurons")
    ax.set_xlabel("epoch")
    ax.legend(fontsize=8)
    for a in (axes[0][0], axes[1][0]):
        for i in range(1, n_patterns):
            a.axvline(i * e + 0.5, color="k", ls="--", lw=0.6)
        a.grid(alpha=0.3)
    return save_figure(fig, out, "incremental")
