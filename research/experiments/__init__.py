"""The paper's experiments (Sec. VI) plus baselines and splits, each a module with `Config`,
`QUICK`, `FULL` and `run(config, out, seed, progress) -> ExperimentOutput`.

`gwr-predictor experiment NAME` runs one; `output.write_output` writes results.json/results.md.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from gwr_predictor.errors import GwrPredictorError

#: name -> one-line description (the module is research.experiments.<name>).
EXPERIMENTS: dict[str, str] = {
    "incremental": "Sec. VI-B: patterns learned one after another; C.P.E., P.E. and neurons per epoch",
    "threshold": "Sec. VI-B3: P-GWR retrained with a_T 0.5..0.99 on frozen lower layers; neurons vs MSE",
    "horizon": "Sec. VI-B4: MAE/std for horizons 1..20, recursive and vector prediction",
    "dataloss": "Sec. VI-C: 0..95 % of the data removed in 1 s chunks; MSE vs loss",
    "unseen": "Sec. VI-B1: online response to an unseen sequence presented three times; settling",
    "delay": "Closed loop offline: lag of the robot behind the person, without and with compensation",
    "compare": "Hierarchy vs P-GWR alone vs hold / constant velocity / RLS-AR on train and held-out data",
    "scale": "Input-scale sweep: neurons per layer and 600 ms error on train and held-out data",
    "real": "Real people: mocap recordings, one pass from scratch and leave-one-take-out, vs every baseline",
    "ablation": "What each part of the default predictor adds (gate, displacements, local models), compare's protocol",
    "gate": "The confidence gate's settings: worst ratio to hold-last per clip vs the gain where motion repeats",
    "repeats": "Real movements performed 8 times with variation: one pass from scratch, learning curve, closed loop",
    "tune": "Settings of the default predictor and of RLS-AR, chosen by one protocol (same split, same budget)",
    "calibration": "How sure: coverage and width of the interval stated with every prediction, per step and data set",
}


class UnknownExperiment(GwrPredictorError, KeyError):
    """A name that is not in EXPERIMENTS."""


def load(name: str) -> ModuleType:
    if name not in EXPERIMENTS:
        raise UnknownExperiment(f"unknown experiment {name!r}; choose from {', '.join(EXPERIMENTS)}")
    return importlib.import_module(f"research.experiments.{name}")
