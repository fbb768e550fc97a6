"""Delay compensation (paper Sec. VI-D): which of the predicted poses the robot should execute now.

The predictor, given the frame stamped t, returns P(t+1..t+h) (h x 8); the newest observation is
P(t+0). Every rule executes P(t+k) for one step k in [0, h]:

- ``none``: k = 0, the newest observation (the uncompensated baseline);
- ``fixed``: k = round(delay_s / frame_period), the configured delay (clamped to [0, h]);
- ``guarded`` (the default): as ``fixed``, but per command the largest step k' <= k whose pose
  has recently been clearly closer than holding still (k' = 0) to where the person was k frames
  later: the compensator scores every prediction set it was given against the observations that
  later arrive for its target frames (running MSE with `guard_decay` per scored frame, for every
  candidate P(t+j), j = 0..h), and a candidate must have an MSE below `guard_margin` times holding
  still's; k' = 0 until the lead has been scored on `guard_min_frames` frames. So a predictor that
  is failing right now costs nothing. Why the margin and the evidence: in the closed loop a lead
  that is only a little better than holding on the scored frames, or better on a handful of them,
  is not better on the robot (with neither, the robot was up to 8 % worse than uncompensated on
  real motion; docs/robot.md);
- ``variable``: k = round(xi / frame_period) for a delay estimate xi that the robot's own joint
  state keeps up to date through the paper's Eq. 11, P* = argmin_i ||J_xi(t) - P(t+i)||.

What J_xi(t) is here: the joint angles (ARM_JOINTS order, rad) that the robot *reports* when the
command is chosen (its /joint_states), i.e. the configuration of a robot that executes commands
xi seconds late. Taken literally, executing the P* closest to that configuration re-issues the
pose the robot already shows and keeps whatever lag it has (measured in docs/robot.md). Eq. 11
is used instead for what it can tell: *which person frame* the robot is showing. Searched over
the person's trajectory (the recent observations, i <= 0, and the predictions, i > 0), the argmin
i* gives the robot's residual lag, now - (t + i* frame_period) - frame_period / 2 (the half frame
is the mean age of a 10 fps pose). The estimate xi (starting at `delay_s`) integrates that lag
with `tracking_gain` whenever it exceeds `deadband` frames and the arm moves (at least
`min_motion` rad per frame in the last observations and around the matched frame), so a delay that changes with the
state of the hardware is followed; the paper leaves the estimation of xi out of scope.

Without usable predictions (none yet, not finite, or older than `stale_after_s`) every mode
falls back to the newest observation and says why.

With `spread_shrink` c > 0 and the interval the predictor states with its predictions (the default's
spread: `default_predictor/spread.py`), the chosen pose is pulled towards the newest observation per joint
by how wide the interval is against the step it predicts: with d = P(t+k) - x(t) and w the interval's
half-width at step k, the command is x(t) + d^2 / (d^2 + c w^2) d. A prediction whose interval dwarfs the
move it predicts is a guess, and the robot then moves less on it; 0 (the default) leaves every command
as chosen (its measured effect: docs/pipeline.md).

The command is the chosen pose as it is, not clipped into the joint limits: the robot's input
clips every command once (`SimulatedRobot.command`; `trajectory.command_trajectory` for a real
robot's controller), whichever source it comes from.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from dataclasses import dataclass
from typing import Literal, NamedTuple

import numpy as np

from gwr_predictor.parameters.spec import ParamSpec, check_fields
from gwr_predictor.robot.errors import RobotError
from gwr_predictor.robot.nao import ARM_JOINTS

MODES = ("none", "guarded", "fixed", "variable")
Mode = Literal["none", "guarded", "fixed", "variable"]

#: Fallback reasons (the strings reported in `CompensatorOutput.fallback_reason` and counted).
NO_PREDICTIONS = "no_predictions"
STALE_PREDICTIONS = "stale_predictions"
NO_ROBOT_STATE = "no_robot_state"


#: The compensator's parameters, declared once: `CompensatorParams` validates with them and the
#: delay_compensator node declares its ROS parameters from them.
PARAM_SPECS: dict[str, ParamSpec] = {s.name: s for s in (
    ParamSpec("mode", "guarded", "none: forward observations; guarded: the prediction delay_s ahead, or the "
              "longest shorter lead whose recent error beats holding still; fixed: the prediction delay_s ahead; "
              "variable: Eq. 11 against the robot's reported state", choices=MODES),
    ParamSpec("delay_s", 0.6, "robot delay to compensate (s); sets the step in fixed and guarded mode", 0.0, 60.0),
    ParamSpec("frame_period", 0.1, "spacing of the predicted frames (s)", 1e-4, 10.0),
    ParamSpec("stale_after_s", 0.5, "predictions older than this (now - their stamp) are not used", 0.0, 3600.0),
    ParamSpec("tracking_gain", 0.15, "variable: share of the measured lag added to the delay estimate", 0.0, 1.0),
    ParamSpec("deadband", 0.6, "variable: lags below this many frames leave the estimate alone", 0.0, 10.0),
    ParamSpec("history_frames", 20, "variable: observations searched for the robot's pose", 1, 10_000),
    ParamSpec("min_motion", 0.03, "variable: rad per frame below which the arm counts as still", 0.0, 10.0),
    ParamSpec("guard_decay", 0.98, "guarded: forgetting of the running errors per scored frame", 0.5, 1.0),
    ParamSpec("guard_margin", 0.93, "guarded: a lead is used only if its recent MSE is below this share of "
              "holding still's", 0.0, 1.0, lo_open=True),
    ParamSpec("guard_min_frames", 10, "guarded: frames a lead must have been scored on before it is used", 1, 100_000),
    ParamSpec("spread_shrink", 0.0, "pull each joint of the command towards the observation by d^2 / (d^2 + c w^2), "
              "d the predicted move, w the half-width of the predictor's stated interval at that step (0: off)",
              0.0, 1e6),
)}


@dataclass(frozen=True)
class CompensatorParams:
    """Rule and timing of the compensator (`frame_period`: the predictor's frame spacing).

    `tracking_gain`, `deadband` (in frames), `history_frames` (observations searched for the
    robot's pose) and `min_motion` (rad per frame below which the arm counts as still and the
    estimate is left alone) matter to ``variable`` only; `guard_decay` (forgetting of the running
    errors per scored frame), `guard_margin` (the share of holding still's MSE a lead must stay
    below) and `guard_min_frames` (the evidence it needs first) to ``guarded`` only. `spread_shrink`: how
    much a wide stated interval pulls the command towards the observation (0: not at all).
    """

    mode: Mode = PARAM_SPECS["mode"].default
    delay_s: float = PARAM_SPECS["delay_s"].default
    frame_period: float = PARAM_SPECS["frame_period"].default
    stale_after_s: float = PARAM_SPECS["stale_after_s"].default
    tracking_gain: float = PARAM_SPECS["tracking_gain"].default
    deadband: float = PARAM_SPECS["deadband"].default
    history_frames: int = PARAM_SPECS["history_frames"].default
    min_motion: float = PARAM_SPECS["min_motion"].default
    guard_decay: float = PARAM_SPECS["guard_decay"].default
    guard_margin: float = PARAM_SPECS["guard_margin"].default
    guard_min_frames: int = PARAM_SPECS["guard_min_frames"].default
    spread_shrink: float = PARAM_SPECS["spread_shrink"].default

    def __post_init__(self) -> None:
        check_fields(self, PARAM_SPECS.values(), RobotError)


class CompensatorOutput(NamedTuple):
    """The angles to command, the step of P(t+i) they came from (0 = observation), and why not."""

    angles: np.ndarray
    step_used: int
    fallback_reason: str | None


def recent_state(state: np.ndarray | None, received_at: float, now: float, timeout_s: float) -> np.ndarray | None:
    """The robot's reported state if it arrived at most `timeout_s` before `now`, else None: an old
    state says nothing about the robot's current lag (``variable`` then keeps its delay estimate)."""
    return state if state is not None and now - received_at <= timeout_s else None


def fixed_step(lead_s: float, frame_period: float, horizon: int) -> int:
    """k = round(lead / frame_period) clamped to [0, horizon] (0 means the observation itself)."""
    return int(min(max(math.floor(lead_s / frame_period + 0.5), 0), horizon))


def eq11_step(reference: np.ndarray, observation: np.ndarray, predictions: np.ndarray) -> int:
    """Eq. 11 as printed: the i in [0, h] minimising ||reference - P(t+i)||, P(t+0) = observation.

    Ties go to the smallest i (the least extrapolated pose).
    """
    candidates = np.vstack([np.asarray(observation, float)[None, :], np.asarray(predictions, float)])
    return int(np.argmin(np.linalg.norm(candidates - np.asarray(reference, float)[None, :], axis=1)))


def robot_lag(now: float, robot_state: np.ndarray, times: np.ndarray, poses: np.ndarray,
              frame_period: float, min_motion: float = 0.0) -> float:
    """Residual lag (s) of a robot showing `robot_state`, on a person trajectory `poses` at `times`.

    Eq. 11's argmin over the trajectory names the frame the robot shows; a robot in sync shows,
    on average, a pose half a frame old, hence the half frame. Ties go to the latest frame. NaN
    when the person moves less than `min_motion` (rad per frame) around that frame: a still arm
    matches many frames, so the match says nothing about time.
    """
    dist = np.linalg.norm(poses - robot_state[None, :], axis=1)
    i = len(dist) - 1 - int(np.argmin(dist[::-1]))
    lo, hi = max(i - 1, 0), min(i + 1, len(dist) - 1)
    if hi == lo or np.linalg.norm(poses[hi] - poses[lo]) / (hi - lo) < min_motion:
        return math.nan
    return float(now - times[i] - 0.5 * frame_period)


class DelayCompensator:
    """Stateful wrapper: validation, staleness, fallback counters, the delay estimate (the
    commands it returns are not clipped: the robot's input does that)."""

    def __init__(self, mode: Mode = "guarded", delay_s: float = 0.6, frame_period: float = 0.1,
                 stale_after_s: float = 0.5, *, joint_names: tuple[str, ...] = ARM_JOINTS,
                 params: CompensatorParams | None = None) -> None:
        self.params = params or CompensatorParams(mode, delay_s, frame_period, stale_after_s)
        self.joint_names = tuple(joint_names)
        #: How often each fallback reason occurred, and how many commands were issued.
        self.fallbacks: Counter[str] = Counter()
        self.commands = 0
        #: The delay xi (s) the compensator currently assumes (``variable`` updates it).
        self.delay_estimate_s = self.params.delay_s
        #: The last residual lag measured from the robot's state (``variable``), NaN before any.
        self.last_robot_lag_s = math.nan
        self._history: deque[tuple[float, np.ndarray]] = deque(maxlen=self.params.history_frames)
        self._guard = self._new_guard()

    def _new_guard(self) -> _Guard:
        p = self.params
        # the longest step a usable prediction can be asked for: the delay plus the staleness allowance
        reach = fixed_step(p.delay_s + p.stale_after_s, p.frame_period, 2**31) + 1
        return _Guard(p.guard_decay, p.frame_period, p.guard_margin, p.guard_min_frames, reach)

    @property
    def fallback_count(self) -> int:
        return sum(self.fallbacks.values())

    def reset(self) -> None:
        """Forget counters, history and the delay estimate (a new session)."""
        self.fallbacks.clear()
        self.commands = 0
        self.delay_estimate_s = self.params.delay_s
        self.last_robot_lag_s = math.nan
        self._history.clear()
        self._guard = self._new_guard()

    @property
    def guard_mse(self) -> tuple[np.ndarray, np.ndarray]:
        """``guarded``: running MSE (rad^2) per step 1..h of the predictions and of holding still
        (NaN where nothing was scored yet)."""
        return self._guard.mse()

    def command(self, now: float, observation: np.ndarray, predictions: np.ndarray | None = None,
                pred_stamp: float | None = None, robot_state: np.ndarray | None = None,
                obs_stamp: float | None = None, interval: tuple[np.ndarray, np.ndarray] | None = None
                ) -> CompensatorOutput:
        """The angles to send to the robot now.

        `now`, `pred_stamp` and `obs_stamp` share one clock (seconds); `predictions` (h x J) are
        P(t+1..t+h) for t = `pred_stamp`; `observation` (J) is the newest observed pose, stamped
        `obs_stamp` (default: `pred_stamp`, else `now`); `robot_state` (J) is what the robot
        reports (used by ``variable``). Predictions are stale when `obs_stamp` (default `now`)
        is more than `stale_after_s` past `pred_stamp`: pass `obs_stamp` when stamps are capture
        times that arrive late, so that a sensing delay is not taken for staleness. The step
        aims at person time `obs_stamp + delay`, so predictions a frame older than the
        observation still hit it. `interval`: the (lower, upper) bounds (h x J each) the predictor stated
        with `predictions`, used with `spread_shrink` (None: none stated, the command is not pulled).
        """
        p = self.params
        obs = self._vector(observation, "observation")
        state = None if robot_state is None else self._vector(robot_state, "robot_state")
        self.commands += 1
        if p.mode == "none":
            return CompensatorOutput(self._output(obs), 0, None)
        stamp = obs_stamp if obs_stamp is not None else (pred_stamp if pred_stamp is not None else now)
        if self._history and stamp < self._history[-1][0]:
            self._history.clear()  # stamps went back: a new sequence (a replay, a restarted source)
        if not self._history or stamp > self._history[-1][0]:
            self._history.append((stamp, obs))
            if p.mode == "guarded":
                self._guard.observe(stamp, obs)
        reason = self._unusable(now if obs_stamp is None else obs_stamp, predictions, pred_stamp)
        if reason is not None:
            self.fallbacks[reason] += 1
            return CompensatorOutput(self._output(obs), 0, reason)
        preds = np.asarray(predictions, dtype=float)
        assert pred_stamp is not None
        if p.mode == "variable":
            if state is None:
                self.fallbacks[NO_ROBOT_STATE] += 1
                reason = NO_ROBOT_STATE
            else:
                self._track(now, state, preds, pred_stamp, stamp)
        lead = self.delay_estimate_s + stamp - pred_stamp
        step = fixed_step(lead, p.frame_period, preds.shape[0])
        if p.mode == "guarded":
            base = self._pose_at(pred_stamp, obs, stamp)
            if base is not None:
                self._guard.expect(pred_stamp, preds, base)
            step = self._guard.allowed(step)
        if step == 0:
            return CompensatorOutput(self._output(obs), 0, reason)
        return CompensatorOutput(self._shrunk(preds[step - 1], obs, interval, step), step, reason)

    def _shrunk(self, pose: np.ndarray, obs: np.ndarray, interval: tuple[np.ndarray, np.ndarray] | None,
                step: int) -> np.ndarray:
        """The chosen pose P(t+step), pulled towards the observation where the stated interval is wide
        (`spread_shrink`); as it is without an interval or with the option off."""
        c = self.params.spread_shrink
        if not c or interval is None:
            return self._output(pose)
        lower, upper = (np.asarray(b, dtype=float) for b in interval)
        if lower.shape != upper.shape or lower.ndim != 2 or lower.shape[0] < step or lower.shape[1] != pose.size:
            raise RobotError(f"interval bounds must be (horizon >= {step}, {pose.size}) each, got "
                             f"{lower.shape} and {upper.shape}")
        half = 0.5 * (upper[step - 1] - lower[step - 1])
        move = pose - obs
        moved = move * move
        keep = np.divide(moved, moved + c * half * half, out=np.ones_like(moved), where=moved > 0.0)
        if not np.isfinite(keep).all():  # a NaN or inf bound says nothing: the pose as chosen
            return self._output(pose)
        return obs + keep * move

    def _pose_at(self, t: float, obs: np.ndarray, obs_t: float) -> np.ndarray | None:
        """The observed pose stamped t (the P(t+0) of predictions made at t), if still known."""
        tol = 0.5 * self.params.frame_period
        if abs(obs_t - t) < tol:
            return obs
        for ts, x in reversed(self._history):
            if abs(ts - t) < tol:
                return x
        return None

    def _track(self, now: float, state: np.ndarray, preds: np.ndarray, pred_stamp: float, stamp: float) -> None:
        """Update the delay estimate from where the robot is on the person's trajectory."""
        p = self.params
        future_t = pred_stamp + p.frame_period * np.arange(1, preds.shape[0] + 1)
        ahead = future_t > stamp + 1e-9
        times = np.concatenate([[t for t, _ in self._history], future_t[ahead]])
        poses = np.vstack([np.stack([x for _, x in self._history]), preds[ahead]])
        lag = robot_lag(now, state, times, poses, p.frame_period, p.min_motion)
        if len(self._history) >= 3 and np.linalg.norm(self._history[-1][1] - self._history[-3][1]) < 2 * p.min_motion:
            lag = math.nan  # the person is still: predictions only add noise to the match
        self.last_robot_lag_s = lag
        if abs(lag) > p.deadband * p.frame_period:  # False for NaN: no update while the arm is still
            ceiling = (preds.shape[0] + 1) * p.frame_period
            self.delay_estimate_s = float(np.clip(self.delay_estimate_s + p.tracking_gain * lag, 0.0, ceiling))

    def _unusable(self, latest: float, predictions: np.ndarray | None, pred_stamp: float | None) -> str | None:
        if predictions is None or pred_stamp is None:
            return NO_PREDICTIONS
        preds = np.asarray(predictions, dtype=float)
        if preds.ndim != 2 or preds.shape[1] != len(self.joint_names) or preds.shape[0] < 1:
            raise RobotError(f"predictions must be (horizon >= 1, {len(self.joint_names)}), got {preds.shape}")
        if not np.all(np.isfinite(preds)):
            return NO_PREDICTIONS
        if self.stale(latest, pred_stamp):
            return STALE_PREDICTIONS
        return None

    def stale(self, latest: float, pred_stamp: float | None) -> bool:
        """True when there are no predictions or they are more than `stale_after_s` older than `latest`
        (the newest observation's stamp, or the clock): then the observation is commanded instead."""
        return pred_stamp is None or latest - pred_stamp > self.params.stale_after_s

    def _vector(self, values: np.ndarray, name: str) -> np.ndarray:
        arr = np.asarray(values, dtype=float)
        if arr.shape != (len(self.joint_names),):
            raise RobotError(f"{name} must have {len(self.joint_names)} joint angles, got shape {arr.shape}")
        return arr

    @staticmethod
    def _output(angles: np.ndarray) -> np.ndarray:
        """A copy of the chosen pose (the caller's arrays are not handed back), unclipped."""
        return np.array(angles, dtype=float)


class _Guard:
    """Running MSE of executing P(t+j) (j = 0: the pose held since t) when the person is at t + k.

    Only steps up to `reach` can ever be commanded (the delay plus the staleness allowance), so the
    guard keeps the first `reach` rows of a prediction set and ignores the rest: its memory is
    O(reach^2 x joints), whatever horizon a message claims. The set made at frame t waits in a ring of
    `reach` slots (slot t mod reach) until its targets t + k (k = 1..reach) are observed; each observed
    target frame scores every candidate j = 0..reach against it (mean over joints), so `allowed(k)` can
    pick the candidate that has recently been closest to where the person was k frames later. Only
    observations that arrive count (no peeking); each set is filed once per frame and scored once per
    target; a target never observed is never scored; stamps that go back (a new sequence) or a gap
    longer than `reach` drop every pending set, and a change of the kept horizon restarts the statistics.
    """

    _EMPTY = np.iinfo(np.int64).min

    def __init__(self, decay: float, frame_period: float, margin: float = 1.0, min_frames: int = 1,
                 reach: int | None = None) -> None:
        self.decay, self.period, self.margin, self.min_frames = decay, frame_period, margin, min_frames
        self.reach = reach  # None: every row of every set
        self._sets = np.zeros((0, 1, 0))  # (slot, candidate j, joint): [base, P(t+1..t+k)] of the set in the slot
        self._made = np.zeros(0, dtype=np.int64)  # by slot: the frame its set was made at (_EMPTY: none)
        self._clock: int | None = None  # the last frame observed
        self._sse = np.zeros((0, 1))  # (target step k - 1, candidate j)
        self._weight = np.zeros(0)
        self._scored = np.zeros(0, dtype=np.int64)  # frames scored per target step, not decayed

    def _index(self, t: float) -> int:
        return math.floor(t / self.period + 0.5)

    def expect(self, t: float, preds: np.ndarray, base: np.ndarray) -> None:
        """File the candidates of the prediction set made at t (the first one given for its frame)."""
        i, (h, joints) = self._index(t), preds.shape
        k = h if self.reach is None else min(h, self.reach)
        if self._sets.shape != (k, k + 1, joints):
            self._sets = np.zeros((k, k + 1, joints))
            self._made = np.full(k, self._EMPTY, dtype=np.int64)
            self._sse, self._weight, self._scored = np.zeros((k, k + 1)), np.zeros(k), np.zeros(k, dtype=np.int64)
        if self._clock is None:
            self._clock = i
        slot = i % k
        if self._made[slot] == i or i + k <= self._clock:
            return  # filed already, or every target has passed
        self._made[slot] = i
        self._sets[slot, 0] = base
        self._sets[slot, 1:] = preds[:k]

    def observe(self, t: float, obs: np.ndarray) -> None:
        """Score the candidates of every pending set that targets the frame stamped t."""
        j = self._index(t)
        k = self._made.shape[0]
        if self._clock is None or j < self._clock or (k and j - self._clock > k):
            self._made[:] = self._EMPTY  # a new sequence, or a gap that every pending target falls into
            self._clock = j
            return
        if j == self._clock or not k:
            self._clock = j
            return  # this frame was scored already, or nothing was filed yet
        self._clock = j
        lead = j - self._made
        due = (lead >= 1) & (lead <= k)
        if due.any():
            rows = lead[due] - 1
            err = np.mean((self._sets[due] - obs) ** 2, axis=-1)  # (scored rows, candidate)
            self._sse[rows] = self.decay * self._sse[rows] + err
            self._weight[rows] = self.decay * self._weight[rows] + 1.0
            self._scored[rows] += 1

    def mse(self) -> tuple[np.ndarray, np.ndarray]:
        """(MSE of P(t+k) at step k, MSE of holding still at step k), k = 1..kept horizon; NaN before any score."""
        with np.errstate(invalid="ignore", divide="ignore"):
            m = np.where(self._weight[:, None] > 0, self._sse / np.maximum(self._weight, 1e-300)[:, None], np.nan)
        k = np.arange(m.shape[0])
        return m[k, k + 1], m[:, 0]

    def allowed(self, step: int) -> int:
        """The largest j <= step whose recent error at target step `step` is below `margin` times
        holding still's (j = 0); 0 (the observation) until that step has been scored `min_frames` times."""
        if step < 1 or step > self._weight.shape[0] or self._scored[step - 1] < self.min_frames:
            return 0
        row = self._sse[step - 1, :step + 1]
        better = (row[1:] < self.margin * row[0]).nonzero()[0]
        return int(better[-1]) + 1 if better.size else 0
