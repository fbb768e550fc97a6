"""A deep copy of a learner is an independent learner in the same state: the experiments evaluate copies
of trained models (`research/experiments/common.clone`), so a copy must predict and learn exactly as
the original would. Views stored beside the arrays they view broke this (a copy holds them apart):
a copy of the paper's hierarchy that went on with the same sequence predicted up to 1.2 rad away from
the original, frozen; copies of every GWR learner drifted while learning."""

from __future__ import annotations

import copy

import numpy as np
import pytest

import gwr_predictor as gp
from gwr_predictor.learning.hierarchy import FlatPredictor, Hierarchy
from gwr_predictor.registry import make_predictor

LEARNERS = {"hierarchy": Hierarchy, "flat": FlatPredictor, "gated_llm_gwr": lambda: make_predictor("gated_llm_gwr"),
            "gwr_experts": lambda: make_predictor("gwr_experts")}


@pytest.fixture(scope="module")
def frames() -> np.ndarray:
    seqs = gp.demo_angle_sequences(patterns=("wave_one", "raise_front_both"), subjects=1)
    return np.concatenate([s.angles for s in seqs])[:500]


@pytest.mark.parametrize("name", LEARNERS)
@pytest.mark.parametrize("learn", [False, True])
def test_a_deep_copy_continues_exactly_as_the_original(name, learn, frames):
    model = LEARNERS[name]()
    for f in frames[:300]:
        model.step(f)
    twin = copy.deepcopy(model)
    for f in frames[300:]:
        a, b = model.step(f, learn=learn), twin.step(f, learn=learn)
        assert (a is None) == (b is None)
        if a is not None:
            np.testing.assert_array_equal(a, b)
