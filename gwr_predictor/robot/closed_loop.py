"""Offline closed loop: person -> (sensing delay) -> predictor -> compensator -> delayed robot.

Why: to measure what delay compensation buys without DDS, faster than real time, with the same
compensator and robot model the ROS nodes use. Time runs in control periods of `dt`:

- frame k of the person (stamp k * frame_period) reaches the predictor `sensing_delay_s` later;
- the predictor learns it and predicts P(t+1..t+h); the compensator picks the command at once;
- the command travels `delay_s - sensing_delay_s` to the robot, whose motors add `latency_s`.

So an uncompensated robot lags the person by about delay_s + latency_s, and one that executes
P(t + delay_s) of a perfect predictor lags by about latency_s (plus the time its rate-limited
joints need to reach each 10 Hz command).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from gwr_predictor.learning.protocol import Predictor, Spreading
from gwr_predictor.robot.compensator import CompensatorParams, DelayCompensator, Mode
from gwr_predictor.robot.delayed_arm import RobotError, RobotParams, SimulatedRobot
from gwr_predictor.robot.nao import ARM_JOINTS
from gwr_predictor.robot.tracking import estimate_lag, tracking_error


@dataclass(frozen=True)
class ClosedLoopResult:
    """Per frame (t: stamps): person, what the predictor saw, commands, robot pose; plus fine traces.

    `executed[k]` is the robot's mean pose over frame k's interval [t_k, t_k + frame_period).
    The fine traces (every control period) hold the person as the pose last shown (zero-order
    hold of the 10 fps frames) and the robot's pose, for sub-frame lag estimates.
    `commands[k]` is the compensator's pose as sent, unclipped (the robot's input clips it).
    `observed[k]` / `commands[k]` are NaN for frames that had not reached the loop before the end.
    """

    t: np.ndarray
    person: np.ndarray
    observed: np.ndarray
    commands: np.ndarray
    executed: np.ndarray
    steps_used: np.ndarray
    fallback_count: int
    t_fine: np.ndarray
    person_fine: np.ndarray
    executed_fine: np.ndarray
    dt: float

    def lag_s(self, max_lag_s: float = 1.5, skip_s: float = 0.0) -> float:
        """How far the robot lags the person (fine traces, after `skip_s` of warm-up)."""
        start = round(skip_s / self.dt)
        return estimate_lag(self.person_fine[start:], self.executed_fine[start:], self.dt, max_lag_s)

    def errors(self, skip_s: float = 0.0) -> dict[str, float]:
        """Tracking error of the robot against the person (fine traces, after `skip_s`)."""
        start = round(skip_s / self.dt)
        return tracking_error(self.person_fine[start:], self.executed_fine[start:])


def run_closed_loop(angles: np.ndarray, predictor: Predictor, delay_s: float = 0.6,
                    compensation: Mode = "fixed", *, robot: RobotParams | None = None,
                    sensing_delay_s: float = 0.0, dt: float = 0.01, frame_period: float = 0.1,
                    compensator_delay_s: float | None = None, stale_after_s: float = 0.5,
                    transport_delay: Callable[[float], float] | None = None,
                    learn: bool = True, spread_shrink: float = 0.0) -> ClosedLoopResult:
    """Drive a simulated robot from `angles` (T x 8, one row per frame) through the full chain.

    `delay_s` is the sensorimotor delay without the motor latency, `sensing_delay_s` of it before
    the predictor; `robot` sets latency, motor time constant and backend (its delay is replaced).
    The compensator assumes `compensator_delay_s` (default: `delay_s`). `transport_delay(t)`,
    if given, sets the command transport delay at every control period (a variable delay).
    `spread_shrink`: the compensator's option of that name, fed the interval a `Spreading` predictor
    states with each prediction.
    """
    person = np.asarray(angles, dtype=float)
    if person.ndim != 2 or person.shape[1] != len(ARM_JOINTS) or person.shape[0] < 2:
        raise RobotError(f"angles must be (T >= 2, {len(ARM_JOINTS)}), got {person.shape}")
    if not (0.0 <= sensing_delay_s <= delay_s):
        raise RobotError(f"sensing_delay_s must be in [0, delay_s={delay_s:g}], got {sensing_delay_s!r}")
    if not (0 < dt <= frame_period):
        raise RobotError(f"dt must be in (0, frame_period={frame_period:g}], got {dt!r}")
    if abs(frame_period / dt - round(frame_period / dt)) > 1e-6:
        raise RobotError(f"dt={dt!r} must divide frame_period={frame_period!r} into whole control periods")
    n_frames = person.shape[0]
    params = replace(robot or RobotParams(), delay_s=delay_s - sensing_delay_s, dt=dt)
    comp = DelayCompensator(params=CompensatorParams(
        compensation, delay_s if compensator_delay_s is None else compensator_delay_s, frame_period, stale_after_s,
        spread_shrink=spread_shrink))
    spreads = isinstance(predictor, Spreading)
    predictor.reset_sequence()

    per_frame = round(frame_period / dt)
    n_steps = n_frames * per_frame
    nan = np.full_like(person, np.nan)
    observed, commands = nan.copy(), nan.copy()
    steps_used = np.full(n_frames, -1, dtype=int)
    executed_fine = np.empty((n_steps, person.shape[1]))
    arrival_step = [math.ceil((k * frame_period + sensing_delay_s) / dt - 1e-9) for k in range(n_frames)]

    with SimulatedRobot(params=params, initial=person[0]) as bot:
        k = 0
        for n in range(n_steps):
            if transport_delay is not None:
                bot.delay_s = transport_delay(bot.t)
            while k < n_frames and arrival_step[k] <= n:
                observed[k] = person[k]
                preds = predictor.step(person[k], learn=learn)
                interval = predictor.interval() if spreads else None  # type: ignore[attr-defined]
                out = comp.command(bot.t, person[k], preds, k * frame_period, bot.state(), obs_stamp=k * frame_period,
                                   interval=interval)
                bot.command(out.angles)
                commands[k], steps_used[k] = out.angles, out.step_used
                k += 1
            executed_fine[n] = bot.step()

    t_fine = np.arange(1, n_steps + 1) * dt
    person_fine = person[np.minimum(np.arange(1, n_steps + 1) // per_frame, n_frames - 1)]
    executed = executed_fine.reshape(n_frames, per_frame, -1).mean(axis=1)
    return ClosedLoopResult(np.arange(n_frames) * frame_period, person, observed, commands, executed, steps_used,
                            comp.fallback_count, t_fine, person_fine, executed_fine, dt)
