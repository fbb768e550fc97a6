"""Offline closed loop and lag metrics: what compensation does to the robot's lag behind the person."""

import numpy as np
import pytest

from gwr_predictor.robot.closed_loop import run_closed_loop
from gwr_predictor.robot.delayed_arm import RobotParams
from gwr_predictor.robot.errors import RobotError
from gwr_predictor.robot.nao import limits_array
from gwr_predictor.robot.tracking import estimate_lag, shift_mse, tracking_error

LATENCY = 0.035


def person(frames: int = 400, seed: int = 3) -> np.ndarray:
    """Smooth arm motion at 10 fps inside the joint limits (sums of slow sines)."""
    rng = np.random.default_rng(seed)
    lo, hi = limits_array()
    t = np.arange(frames)[:, None] * 0.1
    freq, phase = rng.uniform(0.15, 0.35, (2, 8)), rng.uniform(0, 2 * np.pi, (2, 8))
    wave = 0.6 * np.sin(2 * np.pi * freq[0] * t + phase[0]) + 0.4 * np.sin(2 * np.pi * freq[1] * t + phase[1])
    return (lo + hi) / 2 + 0.3 * (hi - lo) * wave


class Oracle:
    """Knows the person's future: P(t+i) is the true pose i frames ahead."""

    def __init__(self, angles: np.ndarray, horizon: int = 6, warm_up: int = 0) -> None:
        self.angles, self.horizon, self.warm_up, self.k = angles, horizon, warm_up, 0

    def reset_sequence(self) -> None:
        self.k = 0

    def step(self, x: np.ndarray, learn: bool = True) -> np.ndarray | None:
        k, self.k = self.k, self.k + 1
        np.testing.assert_array_equal(x, self.angles[k])  # frames arrive in order, once each
        if k < self.warm_up:
            return None
        return self.angles[np.minimum(np.arange(k + 1, k + 1 + self.horizon), len(self.angles) - 1)]


class HoldLast:
    """Predicts that the person freezes: every P(t+i) is the observation."""

    def reset_sequence(self) -> None:
        pass

    def step(self, x: np.ndarray, learn: bool = True) -> np.ndarray:
        return np.repeat(x[None, :], 6, axis=0)


@pytest.fixture(scope="module")
def angles() -> np.ndarray:
    return person()


def test_uncompensated_robot_lags_by_the_delay_plus_latency(angles):
    result = run_closed_loop(angles, Oracle(angles), 0.6, "none")
    assert result.lag_s(skip_s=2) == pytest.approx(0.6 + LATENCY, abs=0.03)
    assert result.fallback_count == 0


def test_oracle_with_fixed_compensation_lags_only_about_the_motor_latency(angles):
    result = run_closed_loop(angles, Oracle(angles), 0.6, "fixed")
    assert result.lag_s(skip_s=2) == pytest.approx(LATENCY, abs=0.03)
    assert set(result.steps_used) == {6}
    assert result.errors(skip_s=2)["rmse"] < 0.25 * run_closed_loop(angles, Oracle(angles), 0.6, "none").errors(
        skip_s=2)["rmse"]


def test_hold_last_predictor_leaves_the_full_delay(angles):
    result = run_closed_loop(angles, HoldLast(), 0.6, "fixed")
    assert result.lag_s(skip_s=2) == pytest.approx(0.6 + LATENCY, abs=0.03)


@pytest.mark.parametrize("sensing", [0.0, 0.25, 0.6])
def test_where_the_delay_sits_does_not_change_the_compensated_lag(angles, sensing):
    result = run_closed_loop(angles, Oracle(angles), 0.6, "fixed", sensing_delay_s=sensing)
    assert result.lag_s(skip_s=2) == pytest.approx(LATENCY, abs=0.03)


def test_variable_mode_recovers_from_a_wrong_delay_estimate(angles):
    fixed = run_closed_loop(angles, Oracle(angles), 0.5, "fixed", compensator_delay_s=0.1, sensing_delay_s=0.2)
    variable = run_closed_loop(angles, Oracle(angles), 0.5, "variable", compensator_delay_s=0.1, sensing_delay_s=0.2)
    assert fixed.lag_s(skip_s=10) == pytest.approx(0.4 + LATENCY, abs=0.03)
    assert abs(variable.lag_s(skip_s=10)) < 0.1


def test_variable_mode_follows_a_delay_that_grows_during_the_run(angles):
    def transport(t: float) -> float:
        return 0.2 if t < 20.0 else 0.5

    kwargs = dict(compensator_delay_s=0.2, transport_delay=transport)
    fixed = run_closed_loop(angles, Oracle(angles), 0.5, "fixed", **kwargs)
    variable = run_closed_loop(angles, Oracle(angles), 0.5, "variable", **kwargs)
    late = slice(int(25.0 / fixed.dt), None)  # after the change and 5 s to adapt
    fixed_lag = estimate_lag(fixed.person_fine[late], fixed.executed_fine[late], fixed.dt, 1.0)
    variable_lag = estimate_lag(variable.person_fine[late], variable.executed_fine[late], variable.dt, 1.0)
    assert fixed_lag == pytest.approx(0.3 + LATENCY, abs=0.03)
    assert abs(variable_lag) < 0.1


class NoisyOracle(Oracle):
    """The oracle plus prediction noise that grows with the step, like a learned predictor's."""

    def __init__(self, angles: np.ndarray, noise: float) -> None:
        super().__init__(angles)
        self.noise, self.rng = noise, np.random.default_rng(0)

    def step(self, x: np.ndarray, learn: bool = True) -> np.ndarray:
        preds = super().step(x, learn)
        return preds + self.rng.normal(0.0, self.noise, preds.shape) * np.arange(1, 7)[:, None] / 6


def test_variable_mode_with_a_right_estimate_does_as_well_as_fixed_through_pauses(angles):
    paused = angles.copy()
    for start in range(50, len(paused) - 30, 100):  # the person stands still for 3 s every 10 s
        paused[start + 30:] -= paused[start + 30] - paused[start]
        paused[start:start + 30] = paused[start]
    paused = np.clip(paused, *limits_array())
    fixed = run_closed_loop(paused, NoisyOracle(paused, 0.05), 0.6, "fixed", sensing_delay_s=0.1)
    variable = run_closed_loop(paused, NoisyOracle(paused, 0.05), 0.6, "variable", sensing_delay_s=0.1)
    assert variable.lag_s(skip_s=5) == pytest.approx(fixed.lag_s(skip_s=5), abs=0.02)
    assert variable.errors(skip_s=5)["rmse"] < 1.1 * fixed.errors(skip_s=5)["rmse"]


def test_predictor_warm_up_is_counted_as_fallbacks_and_executes_observations(angles):
    result = run_closed_loop(angles[:60], Oracle(angles[:60], warm_up=10), 0.3, "fixed")
    assert result.fallback_count == 10
    assert np.all(result.steps_used[:10] == 0) and np.all(result.steps_used[10:] == 3)
    np.testing.assert_allclose(result.commands[:10], angles[:10])


def test_result_arrays_share_the_person_time_base(angles):
    result = run_closed_loop(angles[:50], Oracle(angles[:50]), 0.3, "fixed", robot=RobotParams(latency_s=0.02))
    assert result.t.shape == (50,)
    for name in ("person", "observed", "commands", "executed"):
        assert getattr(result, name).shape == (50, 8), name
    assert result.executed_fine.shape == result.person_fine.shape == (500, 8)
    np.testing.assert_allclose(result.t[1] - result.t[0], 0.1)


def test_closed_loop_rejects_a_sensing_delay_longer_than_the_delay(angles):
    with pytest.raises(RobotError, match="sensing_delay_s"):
        run_closed_loop(angles, HoldLast(), 0.2, "none", sensing_delay_s=0.3)


# --- lag metrics --------------------------------------------------------------------------------


def wave(t: np.ndarray) -> np.ndarray:
    return np.stack([np.sin(1.3 * t), np.cos(0.7 * t) + 0.3 * np.sin(2.1 * t)], axis=1)


@pytest.mark.parametrize("lag", [0.0, 0.237, 0.6, -0.15])
def test_estimate_lag_recovers_a_known_shift_below_one_sample(lag):
    t = np.arange(0.0, 40.0, 0.1)
    got = estimate_lag(wave(t), wave(t - lag), 0.1, 1.0)
    assert got == pytest.approx(lag, abs=0.01)


def test_shift_mse_is_zero_at_the_true_integer_shift():
    t = np.arange(0.0, 20.0, 0.1)
    mse = shift_mse(wave(t), wave(t - 0.3), 5)
    assert np.argmin(mse) == 5 + 3
    assert mse[8] == pytest.approx(0.0, abs=1e-20)


def test_tracking_error_of_a_constant_offset():
    ref = np.zeros((10, 2))
    assert tracking_error(ref, ref + 0.2) == pytest.approx({"mae": 0.2, "rmse": 0.2})
    assert tracking_error(ref, ref) == {"mae": 0.0, "rmse": 0.0}


def test_lag_inputs_are_validated():
    with pytest.raises(RobotError, match="shape"):
        estimate_lag(np.zeros((10, 2)), np.zeros((10, 3)), 0.1, 0.3)
    with pytest.raises(RobotError, match="max_lag_s"):
        estimate_lag(np.zeros((10, 2)), np.zeros((10, 2)), 0.1, 5.0)
