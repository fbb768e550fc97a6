"""The research candidates for the default (research/candidates.py): each runs online from scratch,
returns (horizon, joints), copes with a missing frame, and cannot see the future."""

from __future__ import annotations

import numpy as np
import pytest

from gwr_predictor.evaluation.online import compare_online
from gwr_predictor.predictors import registry
from gwr_predictor.predictors.baselines import HoldLast
from research import candidates
from research.experiments import common

NAMES = tuple(candidates.CANDIDATES)


def _periodic(n: int = 300) -> np.ndarray:
    t = np.arange(n)[:, None] * 2 * np.pi / 25.0
    return 0.3 + 0.4 * np.sin(t + np.arange(8)[None, :] * 0.4)


def _run(name: str, x: np.ndarray) -> list[np.ndarray | None]:
    model = registry.make_predictor(name, common.make_params(), 0)
    return [model.step(frame) for frame in x]


@pytest.mark.parametrize("name", NAMES)
def test_runs_with_shapes_and_a_missing_frame(name: str) -> None:
    x = _periodic(120)
    x[60] = np.nan
    outs = _run(name, x)
    shaped = [o for o in outs if o is not None]
    assert len(shaped) >= 100
    assert all(o.shape == (6, 8) and np.isfinite(o).all() for o in shaped)


@pytest.mark.parametrize("name", NAMES)
def test_no_peeking(name: str) -> None:
    """Two streams equal up to frame 150 and different after: every prediction up to 150 is the same."""
    a = _periodic(220)
    b = a.copy()
    b[151:] += np.random.default_rng(0).normal(scale=0.5, size=b[151:].shape)
    pa, pb = _run(name, a)[:151], _run(name, b)[:151]
    assert all((u is None and v is None) or np.array_equal(u, v) for u, v in zip(pa, pb, strict=True))
    later_a, later_b = _run(name, a)[200], _run(name, b)[200]
    assert not np.array_equal(later_a, later_b)  # the differing future does reach the model once observed


def test_long_readout_spans_its_own_frames() -> None:
    model = candidates.long_model(common.make_params(), 0)
    assert model.params.order == 4 and model.linear.weights.shape[0] == candidates.GLOBAL_FRAMES * 8 + 1


def test_experts_learn_a_repeating_motion() -> None:
    """On a sine learned from scratch the gated experts end far below hold-last."""
    res = compare_online({"hold": HoldLast(), "cand": registry.make_predictor("cand_experts", common.make_params(), 0)},
                         [_periodic(400)], progress=False)
    assert res["cand"].stats.mae[-1] < 0.3 * res["hold"].stats.mae[-1]
