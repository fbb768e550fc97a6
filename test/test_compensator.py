"""Delay compensator: fixed steps, Eq. 11, the variable delay estimate, fallbacks and clipping."""

import numpy as np
import pytest

from gwr_predictor.robot.compensator import (
    NO_PREDICTIONS,
    NO_ROBOT_STATE,
    STALE_PREDICTIONS,
    CompensatorParams,
    DelayCompensator,
    eq11_step,
    fixed_step,
    robot_lag,
)
from gwr_predictor.robot.errors import RobotError

REST = np.array([1.4, 0.2, -1.2, -0.5, 1.4, -0.2, 1.2, 0.5])
DIRECTION = np.array([-0.1, 0.05, 0.08, -0.04, -0.1, -0.05, -0.08, 0.04])


def predictions_from(pose: np.ndarray, h: int = 6) -> np.ndarray:
    """P(t+1..t+h) of a pose moving along DIRECTION by one unit per frame: P(t+i) = pose + i d."""
    return pose + DIRECTION * np.arange(1, h + 1)[:, None]


@pytest.mark.parametrize(("delay", "step"), [(0.1, 1), (0.2, 2), (0.3, 3), (0.4, 4), (0.5, 5), (0.6, 6)])
def test_fixed_mode_executes_the_step_matching_the_delay(delay, step):
    comp = DelayCompensator("fixed", delay)
    out = comp.command(10.0, REST, predictions_from(REST), 10.0)
    assert out.step_used == step
    np.testing.assert_allclose(out.angles, REST + step * DIRECTION)
    assert out.fallback_reason is None


def test_fixed_step_rounds_and_clamps_to_zero_and_the_horizon():
    assert fixed_step(0.04, 0.1, 6) == 0
    assert fixed_step(0.26, 0.1, 6) == 3
    assert fixed_step(0.9, 0.1, 6) == 6
    assert fixed_step(0.25, 0.1, 2) == 2


def test_zero_delay_executes_the_observation_itself():
    out = DelayCompensator("fixed", 0.0).command(1.0, REST, predictions_from(REST), 1.0)
    assert out.step_used == 0
    np.testing.assert_allclose(out.angles, REST)


def test_eq11_picks_the_prediction_closest_to_the_robot_state():
    preds = predictions_from(REST)
    robot = REST + 3.2 * DIRECTION  # between P(t+3) and P(t+4), nearer to P(t+3)
    assert eq11_step(robot, REST, preds) == 3
    assert eq11_step(REST + 0.01, REST, preds) == 0  # at the observation: P(t+0)
    assert eq11_step(REST + 9 * DIRECTION, REST, preds) == 6  # beyond the horizon: the last one


def test_robot_lag_locates_the_frame_the_robot_shows():
    times = np.arange(10) * 0.1
    poses = REST + DIRECTION * np.arange(10)[:, None]
    assert robot_lag(0.9, poses[5], times, poses, 0.1) == pytest.approx(0.9 - 0.5 - 0.05)
    assert robot_lag(0.3, poses[7], times, poses, 0.1) == pytest.approx(0.3 - 0.7 - 0.05)


def test_none_mode_passes_the_latest_observation_through():
    comp = DelayCompensator("none", 0.6)
    out = comp.command(5.0, REST, predictions_from(REST), 5.0)
    assert out.step_used == 0 and out.fallback_reason is None
    np.testing.assert_allclose(out.angles, REST)


@pytest.mark.parametrize("mode", ["fixed", "variable"])
def test_missing_predictions_fall_back_to_the_observation_and_are_counted(mode):
    comp = DelayCompensator(mode, 0.4)
    for _ in range(3):
        out = comp.command(1.0, REST, None, None, REST)
        assert out.fallback_reason == NO_PREDICTIONS
        assert out.step_used == 0
        np.testing.assert_allclose(out.angles, REST)
    assert comp.fallbacks[NO_PREDICTIONS] == 3 and comp.fallback_count == 3


def test_stale_predictions_fall_back_to_the_observation():
    comp = DelayCompensator("fixed", 0.4, stale_after_s=0.5)
    fresh = comp.command(10.4, REST, predictions_from(REST), 10.0)
    stale = comp.command(10.6, REST, predictions_from(REST), 10.0)
    assert fresh.fallback_reason is None and fresh.step_used == 4
    assert stale.fallback_reason == STALE_PREDICTIONS and stale.step_used == 0
    assert comp.fallbacks == {STALE_PREDICTIONS: 1}


def test_non_finite_predictions_count_as_missing():
    preds = predictions_from(REST)
    preds[2, 1] = np.nan
    out = DelayCompensator("fixed", 0.3).command(0.0, REST, preds, 0.0)
    assert out.fallback_reason == NO_PREDICTIONS


def test_a_sensing_delay_is_not_mistaken_for_staleness_when_the_observation_stamp_is_given():
    comp = DelayCompensator("fixed", 0.6, stale_after_s=0.5)
    out = comp.command(now=10.55, observation=REST, predictions=predictions_from(REST), pred_stamp=10.0,
                       obs_stamp=10.0)
    assert out.fallback_reason is None and out.step_used == 6


def test_predictions_a_frame_older_than_the_observation_shift_the_step():
    comp = DelayCompensator("fixed", 0.3)
    out = comp.command(10.1, REST + DIRECTION, predictions_from(REST), pred_stamp=10.0, obs_stamp=10.1)
    assert out.step_used == 4  # aims at 10.1 + 0.3 = P(10.0 + 4 frames)


def test_output_is_the_chosen_pose_unclipped_and_a_copy():
    """The robot's input clips commands (test_robot); the compensator hands on what it chose."""
    wild = np.full((6, 8), 5.0)
    out = DelayCompensator("fixed", 0.3).command(0.0, REST, wild, 0.0)
    assert out.step_used == 3
    np.testing.assert_array_equal(out.angles, wild[2])
    out.angles[:] = 0.0
    assert np.all(wild == 5.0)  # not a view of the caller's predictions


def feed_history(comp: DelayCompensator, frames: int) -> None:
    """Observations REST + k d at stamps k * 0.1 with a robot in sync (so nothing is learned)."""
    for k in range(frames):
        obs = REST + k * DIRECTION
        comp.command(k * 0.1, obs, None, None, obs)


def test_variable_mode_raises_its_delay_estimate_when_the_robot_lags():
    comp = DelayCompensator("variable", 0.3)
    feed_history(comp, 10)
    now = 0.9
    obs = REST + 9 * DIRECTION
    out = comp.command(now, obs, predictions_from(obs), now, robot_state=REST + 4 * DIRECTION)
    lag = now - 0.4 - 0.05  # the robot shows frame 4 at t = 0.9
    assert comp.last_robot_lag_s == pytest.approx(lag)
    assert comp.delay_estimate_s == pytest.approx(0.3 + comp.params.tracking_gain * lag)
    assert out.step_used == 4  # round(0.3675 / 0.1)


def test_variable_mode_lowers_its_delay_estimate_when_the_robot_leads():
    comp = DelayCompensator("variable", 0.6)
    feed_history(comp, 5)
    obs = REST + 4 * DIRECTION
    comp.command(0.4, obs, predictions_from(obs), 0.4, robot_state=obs + 5 * DIRECTION)  # shows frame 9
    assert comp.last_robot_lag_s == pytest.approx(0.4 - 0.9 - 0.05)
    assert comp.delay_estimate_s < 0.6


def test_variable_mode_keeps_its_estimate_inside_the_deadband():
    comp = DelayCompensator("variable", 0.6)
    feed_history(comp, 5)
    obs = REST + 4 * DIRECTION
    out = comp.command(0.4, obs, predictions_from(obs), 0.4, robot_state=REST + 3 * DIRECTION)  # lag 0.05 s
    assert comp.delay_estimate_s == 0.6 and out.step_used == 6


def test_variable_mode_without_robot_state_uses_the_configured_delay_and_says_so():
    comp = DelayCompensator("variable", 0.2)
    out = comp.command(1.0, REST, predictions_from(REST), 1.0, robot_state=None)
    assert out.step_used == 2
    assert out.fallback_reason == NO_ROBOT_STATE
    assert comp.fallbacks[NO_ROBOT_STATE] == 1


def test_reset_restores_the_configured_delay_and_clears_counters():
    comp = DelayCompensator("variable", 0.3)
    feed_history(comp, 10)
    obs = REST + 9 * DIRECTION
    comp.command(0.9, obs, predictions_from(obs), 0.9, robot_state=REST)
    assert comp.delay_estimate_s != 0.3
    comp.reset()
    assert comp.delay_estimate_s == 0.3 and comp.fallback_count == 0 and comp.commands == 0


def test_wrong_shapes_raise_compensator_errors_naming_the_input():
    comp = DelayCompensator("fixed", 0.3)
    with pytest.raises(RobotError, match="observation"):
        comp.command(0.0, np.zeros(7), predictions_from(REST), 0.0)
    with pytest.raises(RobotError, match="predictions"):
        comp.command(0.0, REST, np.zeros((6, 7)), 0.0)
    with pytest.raises(RobotError, match="robot_state"):
        comp.command(0.0, REST, predictions_from(REST), 0.0, robot_state=np.zeros(3))


@pytest.mark.parametrize(("field", "value"), [("mode", "smith"), ("delay_s", -0.1), ("frame_period", 0.0),
                                              ("stale_after_s", -1.0), ("tracking_gain", 1.5),
                                              ("history_frames", 0), ("history_frames", 2.5)])
def test_params_reject_bad_values_naming_the_field(field, value):
    with pytest.raises(RobotError, match=field):
        CompensatorParams(**{field: value})


def test_literal_eq11_cannot_pull_a_lagging_robot_forward():
    """Why `variable` estimates the delay instead of executing P*: a robot behind the observation
    is closest to P(t+0), so the printed rule re-issues the observation, the uncompensated command."""
    for frames_behind in (1, 3, 6):
        robot = REST - frames_behind * DIRECTION
        assert eq11_step(robot, REST, predictions_from(REST)) == 0


def test_robot_lag_is_undefined_where_the_person_is_still():
    times = np.arange(6) * 0.1
    poses = np.repeat(REST[None, :], 6, axis=0)
    assert np.isnan(robot_lag(0.5, REST, times, poses, 0.1, min_motion=0.03))


def test_variable_mode_leaves_its_estimate_alone_while_the_person_is_still():
    comp = DelayCompensator("variable", 0.3)
    for k in range(10):
        comp.command(k * 0.1, REST, None, None, REST)
    noisy = REST + np.random.default_rng(0).normal(0.0, 0.1, (6, 8))  # predictions that wander
    comp.command(1.0, REST, noisy, 1.0, robot_state=noisy[5])  # the robot happens to match P(t+6)
    assert np.isnan(comp.last_robot_lag_s)
    assert comp.delay_estimate_s == 0.3


def _guarded_run(stamps, poses, preds, comp=None):
    """Feed (stamp, pose, P(t+1..t+h)) commands to a guarded compensator; return it."""
    comp = comp or DelayCompensator("guarded", delay_s=0.3)
    for t, x, p in zip(stamps, poses, preds, strict=True):
        comp.command(t, x, p, t, obs_stamp=t)
    return comp


def _walk(n, start=0, h=6):
    """Poses REST + i d for frames start..start+n-1 and the exact predictions of each."""
    poses = [REST + DIRECTION * k for k in range(start, start + n)]
    return [0.1 * k for k in range(start, start + n)], poses, [predictions_from(x, h) for x in poses]


def test_guard_scores_each_prediction_set_once_per_target_frame():
    stamps, poses, preds = _walk(12)
    comp = _guarded_run(stamps, poses, preds)
    model, hold = comp.guard_mse
    assert np.all(model < 1e-20) and np.all(hold > 1e-3)  # exact predictions, scored at every step
    # a second observation inside the last frame (stamp 1.14 rounds to frame 11) is not scored again
    comp.command(1.14, poses[-1] + 0.5, preds[-1], 1.14, obs_stamp=1.14)
    again, _ = comp.guard_mse
    np.testing.assert_array_equal(again, model)


def test_guard_drops_what_targets_a_missing_frame_and_keeps_the_rest():
    stamps, poses, preds = _walk(12)
    wrong = [p.copy() for p in preds]
    wrong[3][1] += 1.0  # frame 3's row for frame 5, which never arrives
    keep = [k for k in range(12) if k != 5]
    comp = _guarded_run([stamps[k] for k in keep], [poses[k] for k in keep], [wrong[k] for k in keep])
    model, hold = comp.guard_mse
    assert np.all(model < 1e-20) and np.all(np.isfinite(hold))  # frame 3's other rows were still scored


def test_guard_starts_over_when_stamps_go_back():
    stamps, poses, preds = _walk(10)
    comp = _guarded_run(stamps, poses, preds)
    # a new sequence from stamp 0 on another path: predictions of the old one must not be scored on it
    other = [REST - DIRECTION * k for k in range(10)]
    comp = _guarded_run(stamps, other, [x - DIRECTION * np.arange(1, 7)[:, None] for x in other], comp)
    model, _ = comp.guard_mse
    assert np.all(model < 1e-20)


def test_guard_survives_a_jump_longer_than_its_horizon():
    stamps, poses, preds = _walk(10)
    for k, p in enumerate(preds):
        p[k + 1 + np.arange(6) >= 10] += 1.0  # wrong only for the frames 10.. that never arrive
    comp = _guarded_run(stamps, poses, preds)
    later = _walk(10, start=1000)  # frame 1000 shares its slot mod 6 with frame 10's pending rows
    comp = _guarded_run(*later, comp)
    model, hold = comp.guard_mse
    assert np.all(model < 1e-20) and np.all(hold > 1e-3)
    x = later[1][-1] + DIRECTION
    assert comp.command(100.9, x, predictions_from(x), 100.9).step_used == 3


def _scored_run(comp, poses, noisy_preds):
    out = None
    for t, (x, p) in enumerate(zip(poses, noisy_preds, strict=True)):
        out = comp.command(0.1 * t, x, p, 0.1 * t, obs_stamp=0.1 * t)
    return out


@pytest.mark.parametrize(("shrink", "margin", "step"), [(0.98, 0.93, 0), (0.98, 1.0, 3), (0.95, 0.93, 3)])
def test_guard_needs_a_lead_to_beat_holding_by_its_margin(shrink, margin, step):
    """A lead whose MSE is `shrink`^2 x holding still's is used only if that is below `guard_margin`."""
    _, poses, _ = _walk(40)
    # P(t+i) = pose + (1 - shrink) i d: its error at every step is shrink x holding still's (i d)
    partial = [x + (1 - shrink) * DIRECTION * np.arange(1, 7)[:, None] for x in poses]
    comp = DelayCompensator(params=CompensatorParams("guarded", 0.3, guard_margin=margin))
    assert _scored_run(comp, poses, partial).step_used == step


def test_guard_waits_for_its_evidence():
    _, poses, preds = _walk(30)
    comp = DelayCompensator(params=CompensatorParams("guarded", 0.3, guard_min_frames=5))
    steps = [comp.command(0.1 * t, x, p, 0.1 * t).step_used for t, (x, p) in enumerate(zip(poses, preds, strict=True))]
    # step 3 is first scored at frame 3 (on the set of frame 0), and used once scored 5 times (frame 7)
    assert steps[:8] == [0] * 7 + [3] and set(steps[8:]) == {3}
