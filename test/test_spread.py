"""The interval stated with every prediction (`default_predictor/spread.py`): it holds the share it states,
per step and per group, narrows where the prediction is good and as a movement repeats, never peeks, is saved
with the default; and what reads it (the metrics, the layout on the wire, the compensator's option)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gwr_predictor.default_predictor import Spread, SpreadParams, WithSpread, make_default
from gwr_predictor.default_predictor.errors import DefaultPredictorError
from gwr_predictor.evaluation.metrics import IntervalStats, future_windows, interval_stats
from gwr_predictor.evaluation.online import compare_online
from gwr_predictor.learning.protocol import Spreading
from gwr_predictor.pipeline import conventions
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.predictors.baselines import HoldLast
from gwr_predictor.registry import DEFAULT_PREDICTOR, load_predictor, make_predictor
from gwr_predictor.robot.compensator import CompensatorParams, DelayCompensator
from gwr_predictor.robot.errors import RobotError


def _walk(n: int = 3000, seed: int = 0) -> np.ndarray:
    """A smooth random walk of 8 joints (rad, 10 fps): speed that changes slowly, never repeats."""
    rng = np.random.default_rng(seed)
    velocity = np.zeros((n, 8))
    for t in range(1, n):
        velocity[t] = 0.95 * velocity[t - 1] + 0.01 * rng.normal(size=8)
    return 0.5 + np.cumsum(velocity, axis=0)


def _reach(speed: float, n: int = 45) -> np.ndarray:
    phase = np.clip(np.arange(n) * 0.1 * speed / 3.0, 0.0, 1.0)
    return 0.2 + 0.6 * np.sin(np.pi * phase)[:, None] * np.linspace(0.5, 1.0, 8)[None, :]


def _repeated(performances: int = 8, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A reach performed again and again at slightly different speeds, with tracker noise; and each frame's
    performance index."""
    rng = np.random.default_rng(seed)
    parts = [_reach(s) for s in rng.uniform(0.85, 1.15, performances)]
    x = np.concatenate(parts)
    return x + rng.normal(scale=0.003, size=x.shape), np.concatenate([np.full(len(p), i) for i, p in enumerate(parts)])


@pytest.mark.parametrize("nominal", [0.8, 0.5])
def test_the_stated_share_holds_at_every_step(nominal):
    """Holding the pose on a random walk: its interval holds the stated share at every step within 2 points."""
    model = WithSpread(HoldLast(), SpreadParams(nominal=nominal, groups=1))
    assert isinstance(model, Spreading) and model.interval_nominal == nominal
    res = compare_online({"hold": model}, [_walk()], progress=False)["hold"]
    assert res.interval_nominal == nominal
    np.testing.assert_allclose(res.interval.coverage, nominal, atol=0.02)
    assert np.all(np.diff(res.interval.width) > 0)  # the further ahead, the wider


def test_the_interval_narrows_where_the_prediction_is_good_and_as_a_movement_repeats():
    """On a reach performed 8 times the default's interval at 600 ms is less than half as wide on the last
    performance as on the first, and narrower than holding the pose's, at about the stated share; holding the
    pose, which learns nothing, keeps its width."""
    x, index = _repeated()
    models = {"hold": make_predictor("hold"), "default": make_default()}
    recorded = {}
    for name, model in models.items():
        bounds = np.full((2, len(x), 6, 8), np.nan)
        model.reset_sequence()
        for t, frame in enumerate(x):
            model.step(frame)
            stated = model.interval()
            if stated is not None:
                bounds[:, t] = stated
        recorded[name] = bounds
    future = future_windows(x, 6)
    stats = {name: [interval_stats(b[0, index == k], b[1, index == k], future[index == k]) for k in range(8)]
             for name, b in recorded.items()}
    width = {name: np.array([s.width[-1] for s in per]) for name, per in stats.items()}
    assert width["default"][-1] < 0.5 * width["default"][0]
    assert width["default"][-1] < 0.5 * width["hold"][-1]
    assert width["hold"][-1] > 0.7 * width["hold"][0]
    pooled = IntervalStats.empty(6)
    for s in stats["default"][1:]:
        pooled = pooled.merge(s)
    assert np.all(np.abs(pooled.coverage - 0.8) < 0.1)


def test_each_group_holds_its_share():
    """Predictions of two kinds mixed frame by frame, one 10 x as wrong as the other: with a multiplier per
    group each kind holds the stated share with an interval of its own size; with one for both, neither does."""
    rng = np.random.default_rng(1)
    n = 4000
    truth = np.zeros((n, 8))
    group = rng.integers(0, 2, n)
    noise = np.where(group == 0, 0.1, 0.01)[:, None, None] * rng.normal(size=(n, 6, 8))
    stated = {}
    for groups in (2, 1):
        spread = Spread(SpreadParams(groups=groups, motion_weight=0.0))
        bounds = np.full((2, n, 6, 8), np.nan)
        for t in range(n):
            spread.step(truth[t], truth[t] + noise[t], min(int(group[t]), groups - 1))
            bounds[:, t] = spread.interval()
        stated[groups] = bounds
    future = future_windows(truth, 6)
    later = np.arange(n) > 500

    def coverage(groups: int, g: int) -> np.ndarray:
        sel = later & (group == g)
        return interval_stats(stated[groups][0, sel], stated[groups][1, sel], future[sel]).coverage

    for g in (0, 1):
        np.testing.assert_allclose(coverage(2, g), 0.8, atol=0.03)
    assert np.all(coverage(1, 1) > 0.95) and np.all(coverage(1, 0) < 0.7)


def test_each_prediction_is_scored_against_the_frame_it_targets():
    """Predictions that are exactly the frames to come are hits every time: their interval shrinks to almost
    nothing. The same predictions one frame late are misses: their interval stays wide."""
    x = _walk(600, seed=2)
    future = future_windows(x, 6)
    width = {}
    for name, lag in (("exact", 0), ("a frame late", 1)):
        spread = Spread(SpreadParams(groups=1))
        for t in range(lag, 600 - 6):
            spread.step(x[t], future[t - lag])
        lower, upper = spread.interval()
        width[name] = float(np.mean(upper - lower))
    assert width["exact"] < 0.01 < 0.05 < width["a frame late"]


def test_a_step_without_a_prediction_is_neither_stated_nor_scored():
    spread = Spread(SpreadParams(groups=1))
    pred = np.zeros((6, 8))
    pred[2] = np.nan  # the predictor has nothing for step 3
    for _ in range(20):
        spread.step(np.zeros(8), pred)
    lower, upper = spread.interval()
    assert np.isnan(lower[2]).all() and np.isnan(upper[2]).all() and np.isfinite(np.delete(lower, 2, 0)).all()
    assert spread.scored[0, 2] == 0 and spread.scored[0, 0] == 19
    assert np.all(spread.log_q[0, 2] == np.log(spread.params.initial))  # nothing scored, nothing moved
    spread.step(np.zeros(8), None)
    assert spread.interval() is None
    with pytest.raises(DefaultPredictorError, match="group 3"):
        spread.step(np.zeros(8), pred, group=3)


def _stepped(model, frames):
    return [(model.step(f), model.interval()) for f in frames]


def _equal(a, b) -> bool:
    (pa, ia), (pb, ib) = a, b
    return np.array_equal(pa, pb) and all(np.array_equal(u, v) for u, v in zip(ia, ib, strict=True))


def test_the_spread_is_saved_with_the_default(tmp_path):
    """A saved default continues with the same points and intervals bit for bit."""
    x, _ = _repeated(4)
    model = make_default()
    _stepped(model, x[:120])
    model.save(tmp_path / "now.npz")
    again = load_predictor(DEFAULT_PREDICTOR, tmp_path / "now.npz")
    assert all(_equal(a, b) for a, b in zip(_stepped(model, x[120:]), _stepped(again, x[120:]), strict=True))


def test_interval_stats_count_bounds_inclusive_and_skip_what_is_missing():
    truth = np.zeros((3, 2, 1))
    lower = np.array([[[0.0], [0.1]], [[-1.0], [np.nan]], [[-0.5], [-2.0]]])
    upper = lower + np.array([[[0.2], [0.2]], [[0.5], [0.2]], [[0.5], [1.0]]])
    stats = interval_stats(lower, upper, truth)
    np.testing.assert_array_equal(stats.count[:, 0], [3, 2])
    np.testing.assert_array_equal(stats.inside[:, 0], [2, 0])  # 0 on the lower bound is inside; -1.5..-1 is not
    np.testing.assert_allclose(stats.coverage, [2 / 3, 0.0])
    np.testing.assert_allclose(stats.width, [(0.2 + 0.5 + 0.5) / 3, (0.2 + 1.0) / 2])
    both = stats.merge(stats)
    np.testing.assert_allclose(both.coverage, stats.coverage)
    assert both.to_dict()["n"] == [6, 4]
    with pytest.raises(ValueError, match="must all be"):
        interval_stats(lower, upper, truth[:2])


def test_the_interval_travels_with_its_share_and_bad_layouts_are_refused():
    lower, upper = -np.ones((6, 8)), np.arange(48.0).reshape(6, 8)
    packed = conventions.pack_interval(12.5, lower, upper, 0.8)
    assert packed.dims[0].label == "interval:0.8"
    stamp, names, share, lo, hi = conventions.unpack_interval(packed)
    assert (stamp, names, share) == (12.5, conventions.ARM_JOINTS, 0.8)
    np.testing.assert_array_equal(lo, lower)
    np.testing.assert_array_equal(hi, upper)
    first = packed.dims[0]
    bad = [replace(packed, dims=(replace(first, label="interval:1.5"), *packed.dims[1:])),
           replace(packed, dims=(replace(first, label="interval:x"), *packed.dims[1:])),
           replace(packed, dims=(replace(first, size=3), *packed.dims[1:])),
           replace(packed, dims=packed.dims[1:]),
           replace(packed, data=packed.data[:-1])]
    for b in bad:
        with pytest.raises(PipelineError):
            conventions.unpack_interval(b)
    with pytest.raises(PipelineError, match="share"):
        conventions.pack_interval(0.0, lower, upper, 1.0)


def test_spread_shrink_pulls_a_command_towards_the_observation_by_how_wide_its_interval_is():
    obs = np.zeros(8)
    preds = np.tile(np.linspace(0.1, 0.6, 6)[:, None], (1, 8))  # moves 0.1 rad per frame
    half = np.tile(np.linspace(0.05, 0.3, 6)[:, None], (1, 8))  # wider the further ahead
    half[:, 0] = 0.0  # joint 0 is sure
    interval = (preds - half, preds + half)

    def command(c: float, stated=interval) -> np.ndarray:
        comp = DelayCompensator(params=CompensatorParams("fixed", 0.3, spread_shrink=c))
        return comp.command(1.0, obs, preds, pred_stamp=1.0, interval=stated).angles

    d = preds[2]  # fixed at 300 ms: step 3, 0.3 rad ahead
    np.testing.assert_array_equal(command(0.0), d)  # off: the chosen pose as it is
    np.testing.assert_array_equal(command(4.0, None), d)  # nothing stated: as it is
    keep = d**2 / (d**2 + 4.0 * half[2] ** 2)
    np.testing.assert_allclose(command(4.0), keep * d)
    assert command(4.0)[0] == d[0] and np.all(command(4.0)[1:] < d[1:])  # only the unsure joints are pulled
    with pytest.raises(RobotError, match="interval"):
        command(1.0, (half[:2], half[:2]))
