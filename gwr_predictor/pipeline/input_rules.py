"""The stated rules for bad input, shared by every node that reads arm angles; no ROS here.

- `RejectionCounter`: named counters; rejections are counted per reason and warned about at most
  once per `throttle_s` per reason, so a flood of bad input cannot flood the log.
- `missing_frames`: the gap rule, how many frames a stamp gap stands for (or a new sequence);
- `SkeletonReorder`: skeleton joints in any order -> `SKELETON_JOINTS` order;
- `ArmAnglesCheck`: checks one stream of arm joint angles (layout, missing joints, non-finite values,
  stamps, joint limits) and counts every rejection under its reason.
Nodes convert the message (`gwr_predictor.nodes.messages.joint_state_fields`) and pass the fields.
"""

from __future__ import annotations

import time
from collections import OrderedDict
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from gwr_predictor.pipeline import stamps
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS, select_joints
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.robot.nao import ARM_JOINTS, limits_array

# --- counters and throttled warnings ---------------------------------------------------------------


class RejectionCounter:
    """Named event counters; `reject` also warns, at most once per `throttle_s` for each reason."""

    def __init__(self, logger: Any, throttle_s: float = 5.0) -> None:
        self._logger = logger
        self._throttle_s = throttle_s
        self._counts: dict[str, int] = {}
        self._last_warned: dict[str, float] = {}
        self._suppressed: dict[str, int] = {}

    def count(self, key: str, n: int = 1) -> None:
        self._counts[key] = self._counts.get(key, 0) + n

    def reject(self, reason: str, detail: str = "") -> None:
        """Count one rejected input under `rejected.<reason>` and warn (throttled per reason)."""
        self.count("rejected." + reason)
        self.warn_throttled("rejected." + reason, f"rejected input [{reason}]: {detail}")

    def warn_throttled(self, key: str, message: str, level: str = "warning") -> None:
        """Log `message` (at `level`: warning or info) unless `key` was logged less than `throttle_s` ago;
        suppressed repeats are counted and reported with the next message."""
        now = time.monotonic()
        last = self._last_warned.get(key)
        if last is not None and now - last < self._throttle_s:
            self._suppressed[key] = self._suppressed.get(key, 0) + 1
            return
        suppressed = self._suppressed.pop(key, 0)
        more = f" ({suppressed} more since the last warning)" if suppressed else ""
        total = self._counts.get(key)
        so_far = f"; {total} so far" if total else ""
        text = f"{message}{more}{so_far}"
        if level == "info":  # two call sites: rclpy fixes the severity per call site
            self._logger.info(text)
        else:
            self._logger.warning(text)
        self._last_warned[key] = now

    def get(self, key: str) -> int:
        return self._counts.get(key, 0)

    @property
    def rejected(self) -> int:
        return sum(v for k, v in self._counts.items() if k.startswith("rejected."))

    def snapshot(self) -> dict[str, int]:
        return dict(sorted(self._counts.items()))


# --- input checks --------------------------------------------------------------------------------


def check_stamp(counters: RejectionCounter, check: stamps.StampCheck, input_name: str, stamp: float,
                now: float | None) -> bool:
    """Apply the stamp rule (`gwr_predictor.pipeline.stamps`) to one input's stamp against the node
    clock `now`: a rejection is counted as `rejected.<input>.stamp` or `.stamp_ahead` (and warned),
    a new sequence after a run of back-jumps as `<input>.stamp_restarts`; True if accepted."""
    verdict = check.check(stamp, now)
    if verdict == stamps.ACCEPTED:
        return True
    if verdict == stamps.RESTARTED:
        counters.count(f"{input_name}.stamp_restarts")
        counters.warn_throttled(f"{input_name}.stamp_restarts", f"{input_name}: stamps went back "
                                f"{check.restart_after} times in a row; new sequence from {stamp:.3f}")
        return True
    reason = "stamp_ahead" if verdict == stamps.AHEAD else "stamp"
    counters.reject(f"{input_name}.{reason}", check.describe(verdict, stamp, now))
    return False


class ArmAnglesCheck:
    """Checks one JointState input stream of the arm joints and returns (stamp, angles) or None.

    Rules, each counted as `rejected.<input>.<reason>` (with a throttled warning):
    - names and positions of different lengths, or a name twice: `layout`; more names than
      `conventions.MAX_JOINTS` or a name longer than `conventions.MAX_NAME_CHARS`: `too_large`;
    - any of `names` missing: `missing_joints` (extra joints are ignored; order does not matter);
    - NaN or inf among the wanted positions: `non_finite`;
    - a stamp of 0 or one not after the previous accepted stamp (repeat, jump back): `stamp`; one
      more than `max_ahead_s` ahead of `clock()` (the node clock): `stamp_ahead`; a run of
      back-jumps starts a new sequence (`<input>.stamp_restarts`), see `check_stamp`;
    - angles beyond the joint limits by more than `limit_margin` rad: `out_of_limits`; closer
      ones are clipped to the limits and counted as `<input>.clipped` (a repair, not a rejection).
      This is the clip of observed angles (arm_angles, joint_states). With `limit_margin=None`
      the check applies no limit rule and returns the angles unclipped: nao_sim's robot commands,
      which the robot's input (`SimulatedRobot.command`) clips, once, whatever their source; they
      are the predictor's poses, which may overshoot a limit by any amount and must reach the
      robot as the offline closed loop's do.
    """

    def __init__(self, counters: RejectionCounter, input_name: str, names: tuple[str, ...] = ARM_JOINTS,
                 limit_margin: float | None = 0.2, check_stamps: bool = True,
                 clock: Callable[[], float] | None = None, max_ahead_s: float = stamps.MAX_STAMP_AHEAD_S) -> None:
        self._counters = counters
        self._clock = clock
        self._stamps = stamps.StampCheck(max_ahead_s)
        self._input = input_name
        self._names = names
        self._lo, self._hi = limits_array(names)
        self._margin = limit_margin
        self._check_stamps = check_stamps

    def _reject(self, reason: str, detail: str) -> None:
        self._counters.reject(f"{self._input}.{reason}", detail)

    def accept(self, stamp: float, names: Sequence[str], positions: np.ndarray) -> tuple[float, np.ndarray] | None:
        """One JointState's stamp (s), names and positions -> (stamp, angles in `names` order) or None."""
        try:
            positions = np.asarray(positions, dtype=np.float64)
            if positions.size != len(names):
                raise PipelineError(f"{len(names)} joint names but {positions.size} positions")
            angles = select_joints(names, positions, self._names)
        except PipelineError as exc:
            self._reject(exc.reason if exc.reason in ("too_large", "missing_joints") else "layout", str(exc))
            return None
        if not np.all(np.isfinite(angles)):
            self._reject("non_finite", f"non-finite angles {np.array2string(angles, precision=3, separator=', ')}")
            return None
        limited = self._margin is not None
        if limited and (np.any(angles < self._lo - self._margin) or np.any(angles > self._hi + self._margin)):
            self._reject("out_of_limits", f"angles beyond the joint limits by more than {self._margin} rad")
            return None
        if self._check_stamps:  # last: the rule remembers the stamps it accepts
            now = self._clock() if self._clock is not None else None
            if not check_stamp(self._counters, self._stamps, self._input, stamp, now):
                return None
        if not limited:
            return stamp, angles
        clipped = np.clip(angles, self._lo, self._hi)
        if np.any(clipped != angles):
            self._counters.count(f"{self._input}.clipped")
        return stamp, clipped

    @property
    def last_stamp(self) -> float | None:
        """The stamp of the last accepted message (None before any, or for unchecked streams)."""
        return self._stamps.last


# --- predictions ----------------------------------------------------------------------------------

#: A predicted angle beyond its joint's limit by more than this (rad, half a turn) is no pose of that arm: a
#: predictor gone wrong. Closer overshoots are normal (a linear extrapolation past a limit) and are clipped
#: by the robot's input.
PREDICTION_MARGIN_RAD = np.pi


def absurd_predictions(predictions: np.ndarray, names: tuple[str, ...] = ARM_JOINTS,
                       margin: float = PREDICTION_MARGIN_RAD) -> str | None:
    """Why finite predictions (horizon x joints, in `names` order) cannot be poses, or None if they can."""
    lo, hi = limits_array(names)
    beyond = np.maximum(lo - margin - predictions, predictions - hi - margin)
    if not np.any(beyond > 0.0):
        return None
    step, joint = (int(i) for i in np.unravel_index(int(np.argmax(beyond)), beyond.shape))
    return (f"{names[joint]} at step {step + 1} predicted {predictions[step, joint]:.3g} rad, beyond its limits "
            f"[{lo[joint]:.3f}, {hi[joint]:.3f}] by more than {margin:.3g} rad")


# --- gaps and order -------------------------------------------------------------------------------


def missing_frames(dt: float, frame_period_s: float, max_gap_s: float) -> int | None:
    """Frames lost between two accepted frames `dt` s apart: 0 for the regular spacing, n for a gap of
    n + 1 periods (the learner steps over them so its windows stay in time), None when the gap is
    longer than `max_gap_s` or not positive (the sequence ended, or stamps went back: start a new one)."""
    if dt > max_gap_s or dt <= 0.0:
        return None
    return max(0, round(dt / frame_period_s) - 1)


class SkeletonReorder:
    """Positions of a skeleton message with joints in any order -> `SKELETON_JOINTS` order: unknown
    joints dropped, missing ones NaN (an untracked joint), each counted; index maps cached per layout,
    the `cache_size` most recently used only (a stream of ever new name lists must not grow memory)."""

    def __init__(self, counters: RejectionCounter, wanted: tuple[str, ...] = SKELETON_JOINTS,
                 cache_size: int = 16) -> None:
        self._counters = counters
        self._wanted = wanted
        self.cache_size = cache_size
        self._order: OrderedDict[tuple[str, ...], tuple[np.ndarray, np.ndarray, int]] = OrderedDict()

    def __call__(self, names: tuple[str, ...], positions: np.ndarray) -> np.ndarray:
        if names == self._wanted:
            return positions
        if names in self._order:
            self._order.move_to_end(names)
        else:
            if len(self._order) >= self.cache_size:
                self._order.popitem(last=False)
                self._counters.count("skeleton.name_cache_evictions")
            index = {n: i for i, n in enumerate(names)}
            dst = np.array([k for k, n in enumerate(self._wanted) if n in index], dtype=int)
            src = np.array([index[self._wanted[k]] for k in dst], dtype=int)
            self._order[names] = (dst, src, len(set(names) - set(self._wanted)))
        dst, src, unknown = self._order[names]
        if unknown:
            self._counters.count("skeleton.unknown_joints_ignored")
        if dst.size < len(self._wanted):
            self._counters.count("skeleton.missing_joints_filled_nan")
        out = np.full((len(self._wanted), 3), np.nan)
        out[dst] = positions[src]
        return out
