"""Clock jumps: a node clock that leaps is followed by restarting the time line there, never by catching up.

A node clock can jump: a looping replay (`bag_player loop:=true clock:=true`) goes back to its first
stamp, a restarted or wrong clock source leaps hours ahead, a process stopped for a while (SIGSTOP,
a suspended machine) sees the wall clock leap. A node that simulates on its clock must not simulate
the gap (nao_sim would spend minutes in one callback, deaf to signals), and a node that stamps on it
must not keep stamping on the old time line (a new loop's commands would lie a loop ahead of the
replayed clock and be refused as `stamp_ahead`). A step beyond `max_clock_jump_s`, either way, is a
jump: the node logs and counts it and carries on from the new reading.
"""

from __future__ import annotations

from gwr_predictor.parameters.spec import ParamSpec

#: The bound, declared once; nodes that simulate or stamp on their clock declare this parameter.
CLOCK_JUMP_SPEC = ParamSpec(
    "max_clock_jump_s", 1.0, "a node-clock step beyond this, forward or back, is a clock jump (a looping replay, "
    "a restarted clock source): logged, counted and followed by restarting the time line there; it also bounds "
    "the robot time simulated in one step (s)", 0.01, 10.0)

#: Spacing of two commands stamped on one tick of a stepped /clock (a robot refuses a repeated stamp).
STAMP_STEP_S = 1e-6


class RobotTimeBase:
    """Robot time that follows the node clock by at most `max_jump_s` per step.

    `origin` is the node-clock time of robot time 0. Within the bound the robot is stepped up to
    the clock (or waits, for a small step back); beyond it the origin moves so that robot time
    continues from where it is: a jump costs no simulation at all.
    """

    def __init__(self, max_jump_s: float) -> None:
        self.max_jump_s = max_jump_s
        self.origin: float | None = None

    def target(self, now: float, robot_t: float) -> tuple[float, float]:
        """(robot time to step to, the clock jump that moved the origin, 0.0 if none) for clock reading `now`."""
        if self.origin is None:
            self.origin = now - robot_t
            return robot_t, 0.0
        gap = now - self.origin - robot_t
        if abs(gap) > self.max_jump_s:
            self.origin = now - robot_t
            return robot_t, gap
        return max(robot_t, now - self.origin), 0.0


class ClockJumpWatch:
    """The previous reading of a clock; `check(now)` is the jump since it beyond `max_jump_s` (signed), else 0.0.

    A reading of 0 (sim time before the first /clock) is no reading: the first /clock is not a jump.
    """

    def __init__(self, max_jump_s: float) -> None:
        self.max_jump_s = max_jump_s
        self.last: float | None = None

    def check(self, now: float) -> float:
        if now == 0.0:
            return 0.0
        last, self.last = self.last, now
        if last is None or abs(now - last) <= self.max_jump_s:
            return 0.0
        return now - last


class CommandStamps:
    """Strictly increasing command stamps on the node clock.

    Two commands on one tick of a stepped /clock get stamps `STAMP_STEP_S` apart; a clock that jumps
    back by more than `max_jump_s` restarts the stamps at the new reading (counted in `restarts`),
    instead of stamping a loop ahead of the clock from then on.
    """

    def __init__(self, max_jump_s: float) -> None:
        self.max_jump_s = max_jump_s
        self.last = 0.0
        self.restarts = 0

    def next(self, now: float) -> float:
        if now < self.last - self.max_jump_s:
            self.restarts += 1
            self.last = now
        else:
            self.last = max(now, self.last + STAMP_STEP_S)
        return self.last
