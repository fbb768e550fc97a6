"""What each part of the default predictor adds, on the `compare` protocol (same splits and epochs).

From the paper's P-GWR to the default: the P-GWR alone on raw frames (VQTAM read-out, absolute
targets, recursive roll-out), the same network predicting displacements from the newest frame behind
the confidence gate but without local models (`gated_vqtam`), the default's two read-outs alone behind
the gate (the global linear one, `gated_linear`; the neurons' local models, `gated_llm_local`), the
local-linear P-GWR with both without the gate (`llm_gwr`) and with it (`gated_llm_gwr`, the default);
and the gate around the paper's hierarchy
(`gated_hierarchy`), so the gate's share is also measured on the paper's model. Reported: MAE and
MSE at 600 ms on the held-out repetitions (frozen) and the held-out subject (learning online), and
the worst ratio to hold-last's MAE over the horizon steps 1..h on each split.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from gwr_predictor.evaluation.output import ExperimentOutput, markdown_table
from research.experiments import common, compare

NAME = "ablation"
METHODS = ("hold", common.FLAT, common.HIERARCHY, common.GATED_HIERARCHY, common.GATED_VQTAM, common.GATED_LINEAR,
           common.GATED_LOCAL, common.LLM, common.GATED)
SPLITS = ("heldout_repetitions/frozen", "heldout_subjects/online")


@dataclass(frozen=True)
class Config:
    base: compare.Config = field(default_factory=lambda: replace(compare.FULL, methods=METHODS))
    overrides: tuple[tuple[str, object], ...] = ()


QUICK = Config(base=replace(compare.QUICK, methods=METHODS))
FULL = Config()


def run(config: Config, out: Path, seed: int = 0, progress: bool = True) -> ExperimentOutput:
    base = replace(config.base, overrides=(*config.base.overrides, *config.overrides))
    r = compare.train_and_evaluate(base, seed, progress)
    rows = []
    worst: dict[str, dict[str, float]] = {}
    for m in base.methods:
        cells: list[Any] = [common.label(m)]
        worst[m] = {}
        for c in SPLITS:
            v = r["conditions"][c][m]
            ratio = common.worst_ratio_to_hold(r["conditions"][c], m)
            worst[m][c] = ratio
            cells += [v["mae"][-1], v["mse"][-1], ratio]
        rows.append(cells)
    heads = ["method"] + [f"{c.split('/')[0].replace('heldout_', 'new ')} {k}" for c in SPLITS
                          for k in ("MAE", "MSE", "worst MAE / hold")]
    md = [f"`compare`'s protocol ({base.epochs} epochs online on {r['splits']['train']} training demonstrations), "
          f"600 ms; 'worst MAE / hold' is the largest ratio to hold-last's MAE over steps 1..6. Neurons: "
          f"{r['neurons']}.", "", markdown_table(heads, rows, digits=4)]
    results = {**r, "worst_ratio_to_hold": worst}
    return ExperimentOutput(NAME, "Ablation of the default predictor", asdict(config), results, md, [])
