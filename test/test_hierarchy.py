"""The online hierarchy: windows, delayed targets, gaps, bookkeeping, parameters, CLI smoke runs."""

import json
import math

import numpy as np
import pytest

from gwr_predictor.commands import cli
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.hierarchy import FlatPredictor, Hierarchy
from gwr_predictor.learning.online_loop import ErrorTracker
from gwr_predictor.learning.params import HIERARCHY_MAX_NEURONS, GWRParams, HierarchyParams, hierarchy_parameter_specs

H = 6


def movement(n: int, period: int = 30, offset: int = 0) -> np.ndarray:
    """A smooth periodic 8-joint arm movement (radians) around a plausible pose."""
    t = np.arange(offset, offset + n)[:, None]
    phase = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    amp = np.linspace(0.3, 0.9, 8)
    base = np.array([1.2, 0.3, -1.0, -0.5, 1.2, -0.3, 1.0, 0.5])
    return base + amp * np.sin(2 * np.pi * t / period + phase) + 0.2 * amp * np.sin(4 * np.pi * t / period + phase)


def run(model, frames, learn=True):
    return [model.step(x, learn=learn) for x in frames]


class Spy:
    """Records what the P-GWR is trained on, at which step."""

    def __init__(self, model):
        self.model, self.calls = model, []
        self._learn = model.pgwr.learn_unchecked
        model.pgwr.learn_unchecked = self

    def __call__(self, x_in, x_out):
        self.calls.append((self.model.errors()["steps"] - 1, np.array(x_in), np.array(x_out)))
        return self._learn(x_in, x_out)


# --- parameters ---------------------------------------------------------------------------------
def test_default_hierarchy_follows_the_paper():
    p = HierarchyParams()
    assert (p.tau1, p.tau2, p.horizon, p.mode, p.regressor_dim) == (3, 3, 6, "recursive", 72)
    assert (p.input_scale, p.normalise_distance) == (0.1, True)  # see docs/learning.md
    assert [getattr(p, n).max_edge_age for n in ("gwr1", "gwr2", "pgwr")] == [100, 200, 300]
    assert p.gwr1.activation_threshold == 0.98


def test_flat_round_trip_and_specs_cover_every_key():
    p = HierarchyParams(mode="vector", input_scale=0.3, gwr2=GWRParams(max_edge_age=250, max_neurons=900))
    flat = p.to_flat()
    assert flat["gwr2.max_edge_age"] == 250 and flat["gwr1.max_neurons"] == HIERARCHY_MAX_NEURONS
    assert HierarchyParams.from_flat(flat) == p
    specs = hierarchy_parameter_specs()
    assert {s.name for s in specs} == set(flat)
    assert all(s.default == HierarchyParams().to_flat()[s.name] for s in specs)


@pytest.mark.parametrize("flat, needle", [
    ({"gwr3.eps_b": 0.1}, "gwr3.eps_b"), ({"horizons": 6}, "horizons"), ({"mode": "both"}, "mode"),
    ({"gwr1.eps_b": 2.0}, "eps_b"), ({"tau1": 2.5}, "tau1"), ({"input_scale": 0}, "input_scale"),
    ({"pgwr.max_edge_age": "300"}, "pgwr.max_edge_age"),
])
def test_from_flat_rejects_unknown_keys_and_bad_values_by_name(flat, needle):
    with pytest.raises(ValueError, match=needle):
        HierarchyParams.from_flat(flat)


def test_ros_style_numbers_are_accepted():
    p = HierarchyParams.from_flat({"horizon": 4.0, "input_scale": 1, "gwr1.max_neurons": 0})
    assert (p.horizon, p.input_scale, p.gwr1.max_neurons) == (4, 1.0, None)


# --- windows and prediction ---------------------------------------------------------------------
@pytest.mark.parametrize("mode", ["recursive", "vector"])
def test_first_prediction_comes_when_both_windows_are_full(mode):
    out = run(Hierarchy(HierarchyParams(mode=mode), seed=1), movement(8))
    assert [o is None for o in out] == [True] * 4 + [False] * 4  # tau1 + tau2 - 1 = 5 frames
    assert out[4].shape == (H, 8) and np.isfinite(out[4]).all()


@pytest.mark.parametrize("mode", ["recursive", "vector"])
@pytest.mark.parametrize("normalise, step_ratio", [(False, 0.05), (True, 0.3)], ids=["plain", "normalised"])
def test_learns_a_periodic_movement_and_beats_holding_the_last_value(mode, normalise, step_ratio):
    # normalised distances make the upper layers coarser: the 1-step error is then a larger share
    # of the (small) 1-step change, while 6 steps ahead both stay far below holding the last value
    model = Hierarchy(HierarchyParams(mode=mode, normalise_distance=normalise), seed=0)
    frames = movement(1700)
    run(model, frames[:1400])
    model.reset_errors()
    run(model, frames[1400:])
    err = model.errors()
    hold = [np.mean((frames[k:] - frames[:-k]) ** 2) for k in range(1, H + 1)]
    assert all(c < step_ratio * hk for c, hk in zip(err["cpe"], hold, strict=True))
    assert err["cpe"][-1] < 0.05 * hold[-1]
    # P.E. is measured against GWR1's prototype of the target, so it includes GWR1's quantization
    assert all(0 < pe < 0.05 * hold[-1] for pe in err["pe"])
    assert err["scored"] == [300] * H and err["predictions"] == 1700 - 4
    assert set(err["quantization_mean"]) == {"gwr1", "gwr2", "pgwr"}


def test_input_scale_sets_the_insertion_distance_in_radians():
    scale = 0.1  # -ln(0.98) / 0.1 = 0.202 rad
    x0 = movement(1)[0]
    for jump, grows in ((0.15, False), (0.25, True)):
        model = Hierarchy(HierarchyParams(input_scale=scale), seed=0)
        run(model, [x0] * 60)
        before = model.neuron_counts[0]
        model.step(x0 + np.eye(8)[0] * jump)
        assert (model.neuron_counts[0] == before + 1) is grows


def test_distance_normalisation_divides_each_layer_by_the_root_of_its_frames():
    plain, normed = Hierarchy(HierarchyParams(normalise_distance=False)), Hierarchy()
    assert [n.distance_factor for n in (plain.gwr1, plain.gwr2, plain.pgwr)] == [1.0, 1.0, 1.0]
    assert [n.distance_factor for n in (normed.gwr1, normed.gwr2, normed.pgwr)] == pytest.approx(
        [1.0, 1 / math.sqrt(3), 1 / 3])


def test_random_initial_neurons_lie_inside_the_scaled_joint_limits():
    model = Hierarchy(HierarchyParams(input_scale=0.5), seed=9)
    lo, hi = model.scaling.frame_bounds()
    w = model.gwr1.weights
    assert ((w >= lo) & (w <= hi)).all() and np.allclose(hi, 0.5 * np.array([2.08567, 1.32645, 2.08567, -0.0349066,
                                                                             2.08567, 0.314159, 2.08567, 1.54462]))


# --- no peeking ---------------------------------------------------------------------------------
@pytest.mark.parametrize("mode", ["recursive", "vector"])
def test_predictions_never_depend_on_later_frames(mode):
    a, b = movement(300), movement(300)
    b[150:] = movement(150, period=17)  # a different future after step 149
    ma, mb = Hierarchy(HierarchyParams(mode=mode), seed=3), Hierarchy(HierarchyParams(mode=mode), seed=3)
    for t in range(150):
        pa, pb = ma.step(a[t]), mb.step(b[t])
        assert (pa is None and pb is None) or np.array_equal(pa, pb)


@pytest.mark.parametrize("mode, lag", [("recursive", 1), ("vector", H)])
def test_pgwr_trains_only_on_targets_already_observed(mode, lag):
    params = HierarchyParams(mode=mode)
    model = Hierarchy(params, seed=0)
    spy = Spy(model)
    frames = movement(60)
    run(model, frames)
    first = params.span - 1 + lag  # the first regressor exists at step 4; its target is complete at 4 + lag
    assert [c[0] for c in spy.calls] == list(range(first, 60))
    for t, _, x_out in spy.calls:
        np.testing.assert_array_equal(x_out, frames[t - lag + 1:t + 1].ravel() * params.input_scale)


# --- gaps and sequence boundaries ---------------------------------------------------------------
@pytest.mark.parametrize("missing", [None, np.full(8, np.nan), np.r_[np.nan, np.zeros(7)]])
def test_missing_sample_is_counted_resets_windows_and_leaves_networks(missing):
    model = Hierarchy(seed=0)
    frames = movement(40)
    run(model, frames[:20])
    weights = [net.weights.copy() for net in (model.gwr1, model.gwr2, model.pgwr)]
    assert model.step(missing) is None
    assert model.errors()["missing"] == 1 and model.errors()["frames"] == 20
    for w, net in zip(weights, (model.gwr1, model.gwr2, model.pgwr), strict=True):
        np.testing.assert_array_equal(w, net.weights)
    out = run(model, frames[21:27])
    assert [o is None for o in out] == [True] * 4 + [False] * 2


def test_gap_is_never_bridged_by_a_training_pair():
    model = Hierarchy(seed=0)
    spy = Spy(model)
    frames = movement(40)
    run(model, frames[:20])
    model.step(None)  # step 20
    run(model, frames[21:])
    steps = [c[0] for c in spy.calls]
    # before the gap: pairs up to step 19; after it, the first regressor is built at step 25
    assert max(s for s in steps if s < 20) == 19 and min(s for s in steps if s > 20) == 26
    assert not any(20 <= s <= 25 for s in steps)


def test_reset_sequence_clears_windows_and_pending_but_not_networks():
    model = Hierarchy(seed=0)
    run(model, movement(50))
    counts = model.neuron_counts
    model.reset_sequence()
    assert model.predict() is None and model.neuron_counts == counts
    out = run(model, movement(5, offset=7), learn=False)
    assert [o is None for o in out] == [True] * 4 + [False]
    err = model.errors()
    assert err["sequences"] == 1 and err["missing"] == 0


# --- the rest of the API ------------------------------------------------------------------------
def test_predict_repeats_the_last_output_without_changing_state():
    model, twin = Hierarchy(seed=2), Hierarchy(seed=2)
    frames = movement(80)
    for x in frames[:60]:
        last = model.step(x)
        twin.step(x)
    np.testing.assert_array_equal(model.predict(), last)
    model.predict()
    for x in frames[60:]:
        np.testing.assert_array_equal(model.step(x), twin.step(x))


def test_learn_false_changes_no_network():
    model = Hierarchy(seed=0)
    run(model, movement(30))
    before = [net.weights.copy() for net in (model.gwr1, model.gwr2, model.pgwr)]
    out = run(model, movement(30, offset=11), learn=False)
    assert out[-1] is not None
    for w, net in zip(before, (model.gwr1, model.gwr2, model.pgwr), strict=True):
        np.testing.assert_array_equal(w, net.weights)


def test_frozen_layers_keep_their_weights_while_pgwr_learns():
    model = Hierarchy(seed=0)
    run(model, movement(100))
    model.freeze_layers(("gwr1", "gwr2"))
    w1, w2, n3 = model.gwr1.weights.copy(), model.gwr2.weights.copy(), model.pgwr.n_neurons
    p3 = model.pgwr.weights.copy()
    run(model, movement(100, period=23))
    np.testing.assert_array_equal(w1, model.gwr1.weights)
    np.testing.assert_array_equal(w2, model.gwr2.weights)
    assert model.pgwr.n_neurons != n3 or not np.array_equal(p3, model.pgwr.weights)
    assert model.frozen_layers == ("gwr1", "gwr2")
    with pytest.raises(ValueError, match="gwr9"):
        model.freeze_layers(("gwr9",))


def test_reset_layer_starts_a_fresh_pgwr_with_new_parameters():
    model = Hierarchy(seed=0)
    run(model, movement(200))
    new = model.params.pgwr.replace(activation_threshold=0.6)
    model.reset_layer("pgwr", new)
    assert model.neuron_counts[2] == 2 and model.params.pgwr.activation_threshold == 0.6
    assert model.pgwr.params == new


def test_seed_makes_runs_reproducible():
    frames = movement(120)
    outs = [run(Hierarchy(seed=s), frames)[-1] for s in (5, 5, 6)]
    np.testing.assert_array_equal(outs[0], outs[1])
    assert not np.array_equal(outs[0], outs[2])


def test_frame_of_wrong_shape_is_an_error_not_a_gap():
    with pytest.raises(LearningError, match=r"\(8,\)"):
        Hierarchy().step(np.zeros(7))


def test_error_tracker_scores_each_horizon_step_when_its_target_arrives():
    tracker = ErrorTracker(3, 2, ("gwr1",))
    tracker.expect(0, np.array([[1.0, 1.0], [2.0, 2.0], [3.0, 3.0]]))  # for steps 1, 2, 3
    for t, frame in ((1, [0.0, 0.0]), (2, [2.0, 0.0]), (3, [3.0, 3.0])):
        tracker.score(t, np.array(frame), np.array(frame) * 0.5)
    s = tracker.summary()
    assert s["cpe"] == [1.0, 2.0, 0.0] and s["scored"] == [1, 1, 1]
    assert s["pe"] == [1.0, pytest.approx(((2 - 1) ** 2 + 2 ** 2) / 2), pytest.approx(1.5 ** 2)]


# --- the flat ablation --------------------------------------------------------------------------
def test_flat_predictor_uses_the_same_span_and_learns():
    model = FlatPredictor(seed=0)
    assert model.order == 5 and model.pgwr.in_dim == 40
    frames = movement(1400)
    out = run(model, frames[:1200])
    assert [o is None for o in out[:6]] == [True] * 4 + [False] * 2
    model.reset_errors()
    run(model, frames[1200:])
    hold = np.mean((frames[H:] - frames[:-H]) ** 2)
    assert model.errors()["cpe"][-1] < 0.05 * hold and len(model.neuron_counts) == 1


# --- command-line smoke runs (figures are printed, never asserted as speed targets) ---------------
def _last_json(capsys):
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


def test_bench_quick_prints_its_figures_as_json(capsys):
    assert cli.main(["bench", "--quick", "--quiet"]) == 0
    result = _last_json(capsys)
    for key in ("frames_per_s", "predict_p99_ms", "peak_rss_mb", "speedup_vs_loop", "frames_per_s_default",
                "default_vs_recursive", "frames_per_s_default_full", "default_full_vs_recursive"):
        assert key in result and math.isfinite(result[key]) and result[key] > 0
    assert result["predict_p99_ms"] >= result["predict_p50_ms"]
    assert result["snippets_default_full"] > 2000  # motion that never repeats: nearly every frame stored, twice


def test_soak_short_run_reports_memory_and_throughput(capsys):
    assert cli.main(["soak", "--frames", "300", "--quiet"]) == 0
    result = _last_json(capsys)
    assert result["frames"] == 300 and result["frames_per_s"] > 0
    assert 0 < result["rss_start_mb"] <= result["peak_rss_mb"] and result["rss_end_mb"] > 0
    assert all(0 < n <= m for n, m in zip(result["neurons"], result["max_neurons"], strict=True))


# --- beyond the paper: options ------------------------------------------------------------------
def test_paper_preset_is_the_papers_learner_and_options_round_trip():
    p = HierarchyParams.paper()
    assert (p.mode, p.target, p.readout_k, p.tau1, p.tau2, p.horizon) == ("recursive", "absolute", 1, 3, 3, 6)
    assert (p.input_scale, p.normalise_distance) == (0.1, True)
    assert p.gwr1 == GWRParams(max_edge_age=100) and p.pgwr == GWRParams(max_edge_age=300)
    assert HierarchyParams.paper(mode="vector").mode == "vector"
    q = HierarchyParams(target="delta", readout_k=3, mode="vector")
    assert HierarchyParams.from_flat(q.to_flat()) == q
    specs = {s.name: s for s in hierarchy_parameter_specs()}
    assert specs["target"].choices == ("absolute", "delta")
    assert (specs["readout_k"].minimum, specs["readout_k"].maximum) == (1, 16)


@pytest.mark.parametrize("flat, needle", [({"target": "relative"}, "target"), ({"target": 1}, "target"),
                                          ({"readout_k": 0}, "readout_k"), ({"readout_k": 1.5}, "readout_k")])
def test_bad_option_values_are_rejected_by_name(flat, needle):
    with pytest.raises(ValueError, match=needle):
        HierarchyParams.from_flat(flat)
    with pytest.raises(ValueError, match=needle):
        HierarchyParams(**flat)


@pytest.mark.parametrize("mode, lag", [("recursive", 1), ("vector", H)])
def test_delta_targets_are_displacements_from_the_regressors_newest_frame(mode, lag):
    params = HierarchyParams.paper(mode=mode, target="delta")
    model = Hierarchy(params, seed=0)
    spy = Spy(model)
    frames = movement(60)
    run(model, frames)
    assert [c[0] for c in spy.calls] == list(range(params.span - 1 + lag, 60))  # still no peeking
    for t, _, x_out in spy.calls:
        base = frames[t - lag]  # the newest frame when the regressor was made
        np.testing.assert_allclose(x_out, (frames[t - lag + 1:t + 1] - base).ravel() * params.input_scale,
                                   atol=1e-15)


@pytest.mark.parametrize("mode", ["recursive", "vector"])
def test_delta_targets_predict_a_shifted_trajectory_without_the_offset(mode):
    # A movement learned at one posture, replayed 0.04 rad higher on every joint (well inside the
    # 0.2 rad quantization, so the hierarchy matches the same prototypes): absolute targets predict
    # the learned posture (off by the shift), delta targets add the shift back.
    frames, shift = movement(1200), 0.04
    gap = {}
    for target in ("absolute", "delta"):
        model = Hierarchy(HierarchyParams.paper(mode=mode, target=target), seed=0)
        run(model, frames[:1000])
        test = frames[1000:]
        plain = np.array(run(model, test, learn=False)[10:])
        model.reset_sequence()
        moved = np.array(run(model, test + shift, learn=False)[10:])
        gap[target] = np.abs(moved - plain - shift).mean()  # 0 = prediction moved with the input
    assert gap["absolute"] > 0.8 * shift
    assert gap["delta"] < 0.25 * shift


def test_delta_targets_start_from_neurons_that_predict_no_movement():
    model = Hierarchy(HierarchyParams(target="delta"), seed=0)
    np.testing.assert_array_equal(model.pgwr.weights_out, 0.0)
    x = movement(1)[0]
    pred = run(model, [x] * 5)[-1]
    np.testing.assert_allclose(pred, np.tile(x, (H, 1)), atol=1e-12)  # learned zero displacement


@pytest.mark.parametrize("options", [dict(target="delta"), dict(readout_k=2), dict(target="delta", readout_k=3),
                                     dict(target="delta", mode="vector"), dict(readout_k=2, mode="vector")])
def test_each_option_learns_a_periodic_movement_and_predict_repeats_step(options):
    params = HierarchyParams.paper(**options)
    model = Hierarchy(params, seed=0)
    frames = movement(1700)
    run(model, frames[:1400])
    model.reset_errors()
    out = run(model, frames[1400:])
    np.testing.assert_array_equal(model.predict(), out[-1])
    err = model.errors()
    hold = [np.mean((frames[k:] - frames[:-k]) ** 2) for k in range(1, H + 1)]
    assert all(c < 0.3 * hk for c, hk in zip(err["cpe"], hold, strict=True))
    assert err["cpe"][-1] < 0.05 * hold[-1]


@pytest.mark.parametrize("options", [dict(target="delta"), dict(readout_k=2)])
def test_flat_predictor_supports_the_options(options):
    model = FlatPredictor(HierarchyParams.paper(**options), seed=0)
    frames = movement(900)
    run(model, frames[:700])
    model.reset_errors()
    run(model, frames[700:])
    hold = np.mean((frames[H:] - frames[:-H]) ** 2)
    assert model.errors()["cpe"][-1] < 0.1 * hold


@pytest.mark.parametrize("options", [{}, dict(target="delta", readout_k=2)])
def test_fast_rollout_matches_a_plain_chain_of_searches(options):
    model = Hierarchy(HierarchyParams.paper(**options), seed=2)
    frames = movement(400)
    run(model, frames[:-1])
    pred = model.step(frames[-1])
    p, g1, g2, pg = model.params, model.gwr1, model.gwr2, model.pgwr
    w1, w2 = model._window1.rows.copy(), model._window2.rows.copy()
    y = pred[0] * p.input_scale
    for k in range(1, H):  # the roll-out of the docs, written out naively
        w1 = np.vstack([g1.weights[g1.bmu(y)[0]], w1[:-1]])
        w2 = np.vstack([g2.weights[g2.bmu(w1.ravel())[0]], w2[:-1]])
        reg = w2.ravel()
        if p.readout_k == 1:
            step = pg.weights_out[pg.bmu(reg)[0]]
        else:
            d = np.linalg.norm(pg.weights_in - reg, axis=1)
            near = np.argsort(d)[:p.readout_k]
            step = (pg.weights_out[near] / d[near, None]).sum(0) / (1 / d[near]).sum()
        y = y + step if p.target == "delta" else step
        np.testing.assert_allclose(pred[k] * p.input_scale, y, rtol=0, atol=1e-12)
