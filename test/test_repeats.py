"""The repetition benchmark: streams of one movement performed again and again with variation, and the
experiment that scores every method on them (`gwr-predictor experiment repeats`)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gwr_predictor.commands.cli import main
from gwr_predictor.data.demonstrator import default_subjects, demonstrate_one
from gwr_predictor.predictors.baselines import HoldLast
from research.experiments import common
from research.recording import Recorded
from research.repetitions import (
    PAUSE,
    PERFORM,
    RETURN,
    RepetitionError,
    Segment,
    StreamSettings,
    build_stream,
    cut,
    load_segments,
    make_streams,
    synthetic_segments,
    time_warp,
)


@pytest.fixture(scope="module")
def segment() -> np.ndarray:
    return np.asarray(demonstrate_one("wave_one", default_subjects(1)[0], 1, noise=False).positions)[:60]


def test_the_time_warp_is_smooth_monotone_and_within_its_speeds():
    for rates in ((0.8, 1.25), (1.25, 0.8), (1.0, 1.0)):
        u = time_warp(2.0, rates, 30.0)
        speed = np.diff(u)[:-1] * 30.0  # the last step is cut at the end of the recording
        assert u[0] == 0.0 and u[-1] == 2.0 and np.all(np.diff(u) > 0)
        assert min(rates) - 1e-9 <= speed.min() and speed.max() <= max(rates) + 1e-9
        assert np.abs(np.diff(speed)).max() < 0.03  # a slow change, no jumps
        assert len(u) == pytest.approx(1 + 2.0 * 30.0 / np.mean(rates), rel=0.06)


def test_a_stream_holds_eight_varied_performances_labelled_frame_by_frame(segment):
    st = StreamSettings()
    s = build_stream(segment, np.random.default_rng(0), st, name="wave")
    assert s.angles.shape == s.raw.shape and s.angles.shape[1] == 8 and np.isfinite(s.angles).all()
    assert len(s.repetition) == len(s.phase) == len(s.angles)
    assert list(np.unique(s.repetition)) == list(range(8)) and np.all(np.diff(s.repetition) >= 0)
    for k in range(8):  # each performance: pause, then the movement, then the way back
        phases = s.phase[s.repetition == k]
        assert phases[0] == PAUSE and PERFORM in phases and phases[-1] == RETURN
        assert np.all(np.diff(phases) >= 0)
    assert s.rates.shape == (8, 2) and np.all((0.8 <= s.rates) & (s.rates <= 1.25))
    assert np.all((0.9 <= s.sizes) & (s.sizes <= 1.1)) and np.ptp(s.sizes) > 0.02
    assert np.all((0.3 <= s.pauses_s) & (s.pauses_s <= 1.5))
    durations = [len(w) for w in s.warps]
    assert len(set(durations)) > 1  # never twice alike
    for w in s.warps:
        assert np.all(np.diff(w) > 0) and w[-1] == pytest.approx((len(segment) - 1) / 30.0)
    # pauses sit in the start pose: only the tracker noise moves them (a few degrees near this singular pose)
    pauses = s.angles[s.phase == PAUSE]
    assert 0.0 < np.abs(pauses - np.median(pauses, axis=0)).mean() < 0.1
    clean = build_stream(segment, np.random.default_rng(0), StreamSettings(noise_m=0.0))
    still = clean.raw[clean.phase == PAUSE]
    np.testing.assert_allclose(still, np.repeat(clean.raw[:1], len(still), axis=0))


def test_size_scales_the_excursion_from_the_start_pose(segment):
    quiet = {"noise_m": 0.0, "rate": (1.0, 1.0), "pause_s": (0.5, 0.5), "repetitions": 2}
    small = build_stream(segment, np.random.default_rng(1), StreamSettings(size=(0.9, 0.9), **quiet))
    big = build_stream(segment, np.random.default_rng(1), StreamSettings(size=(1.1, 1.1), **quiet))
    start = small.raw[0]
    np.testing.assert_allclose(big.raw - start, (1.1 / 0.9) * (small.raw - start), atol=1e-9)


def test_streams_are_reproducible_per_seed_and_differ_between_seeds(segment):
    segs = [(Segment("wave", 0.0, 2.0), segment)]
    a, b = make_streams(segs, (3, 4)), make_streams(segs, (3, 4))
    np.testing.assert_array_equal(a[0].angles, b[0].angles)
    assert a[0].angles.shape != a[1].angles.shape or not np.allclose(a[0].angles, a[1].angles)
    assert [s.name for s in a] == ["wave s3", "wave s4"]


def test_two_cuts_of_one_clip_make_streams_of_distinct_names(segment):
    """A tuning harness keys its figures by stream name: two cuts of one clip must not share one."""
    segs = [(Segment("wave", 0.0, 1.0), segment), (Segment("wave", 1.0, 2.0), segment),
            (Segment("lift", 0.0, 2.0), segment)]
    names = [s.name for s in make_streams(segs, (3,))]
    assert names == ["wave@0-1s s3", "wave@1-2s s3", "lift s3"]
    assert [s.name for s in make_streams(segs[2:], (3,), by_cut=True)] == ["lift@0-2s s3"]  # asked for: one cut


def test_bad_segments_and_settings_are_named(segment):
    bad = segment.copy()
    bad[5, 3] = np.nan
    with pytest.raises(RepetitionError, match="untracked"):
        build_stream(bad, np.random.default_rng(0))
    with pytest.raises(RepetitionError, match="rate"):
        StreamSettings(rate=(1.2, 0.8))
    with pytest.raises(RepetitionError, match="outside the recording"):
        cut(segment, 1.0, 9.0, name="wave")


def test_segments_are_cut_from_the_recording_cache_without_pip(tmp_path, monkeypatch):
    from mocap_files import fake_recording_cache

    from gwr_predictor.data import real_motion

    monkeypatch.setenv("GWR_REAL_DATA", str(fake_recording_cache(tmp_path / "cache")))
    monkeypatch.setattr(real_motion.subprocess, "run", lambda *a, **k: pytest.fail("pip must not run"))
    (seg, positions), = load_segments((Segment("climb_0", 1.0, 3.0),))
    assert seg.clip == "climb_0" and positions.shape == (61, 15, 3) and np.isfinite(positions).all()


def test_recorded_keeps_the_predictions_and_sees_exact_holds():
    x = np.cumsum(np.full((20, 8), 0.01), axis=0)
    hold, moving = Recorded(HoldLast()), Recorded(common.make_model("const_velocity", common.make_params(), 0))
    for f in x:
        hold.step(f)
        moving.step(f)
    assert hold.held_share() == 1.0 and moving.held_share() < 0.2
    assert hold.predictions(6, 8).shape == (20, 6, 8)


def test_quick_run_writes_every_table_and_the_curve(tmp_path):
    out = tmp_path / "repeats"
    assert main(["experiment", "repeats", "--quick", "--out", str(out), "--no-progress"]) == 0
    r = json.loads((out / "results.json").read_text())["results"]
    methods, default = r["methods"], r["default_method"]
    assert default in methods and {"hold", "rls_ar", "llm_gwr"} <= set(methods)
    reps = len(r["learning_curve"]["hold"])
    assert reps == 3 and all(len(r["learning_curve"][m]) == reps for m in methods)
    for per in r["per_stream"].values():
        assert len({tuple(v["n"]) for v in per.values()}) == 1  # every method scored on the same frames
    # the learning curve and the phases split exactly the pooled frames
    total = sum(st["hold"]["n"][-1] for st in r["per_phase"].values())
    assert total == r["pooled"]["hold"]["n"][-1]
    assert all(len(v) == 6 for v in r["worst_ratio_per_step"].values())
    assert set(r["default_exactly_hold_share"]) == set(r["per_stream"])
    assert {x["rule"] for x in r["closed_loop"]} == {"none", "fixed_true", "guarded_true"}
    md = (out / "results.md").read_text()
    assert "Learning curve" in md and "Closed loop" in md and (out / "repeats_learning_curve.png").is_file()


def test_the_learning_curve_pools_exactly_the_scored_frames():
    """Per repetition, merged over the repetitions, the stats are the evaluation loop's own."""
    from research.experiments import repeats

    stream = make_streams(synthetic_segments(("wave_one",)), (0,), StreamSettings(repetitions=2))[0]
    params = common.make_params()
    stats, per_rep, shares = repeats.score_stream(stream, ("hold", "rls_ar"), params, 0, False)
    for m in ("hold", "rls_ar"):
        merged = per_rep[m][0].merge(per_rep[m][1])
        np.testing.assert_array_equal(merged.count, stats[m].count)
        np.testing.assert_allclose(merged.sum_abs, stats[m].sum_abs)
    assert shares["hold"] == 1.0


def test_experiment_real_says_how_often_the_default_is_exactly_hold():
    """`experiment real` reports per clip the share of the default's predictions that were exactly
    hold-last (its gate shut): nearly all of them where nothing moves, few on a motion it has learned."""
    from gwr_predictor import registry
    from research.experiments import real

    t = np.arange(400)[:, None] * 0.1
    clips = [{"name": "sine", "angles": 0.5 * np.sin(2 * np.pi * 0.4 * t + np.arange(8))},
             {"name": "still", "angles": 0.3 + np.random.default_rng(0).normal(scale=1e-3, size=(200, 8))}]
    default = registry.default_name()
    per_clip, _ = real.one_pass(clips, ("hold", default), common.make_params(), 0, False)
    assert per_clip["sine"][default]["exactly_hold"] < 0.5 < 0.9 < per_clip["still"][default]["exactly_hold"]
    r = {"one_pass": {"per_clip": per_clip}, "leave_one_take_out": {"per_take": {}}}
    table = "\n".join(real._held_table(r, default))
    assert "sine (one pass)" in table and f"{100 * per_clip['still'][default]['exactly_hold']:.0f} %" in table
