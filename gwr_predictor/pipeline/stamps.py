"""The one rule every node applies to the stamp of an input message (docs/reliability.md).

A stamp is accepted when it is finite, positive, after the previous accepted stamp and not more
than `max_ahead_s` ahead of the node's clock (wall or sim time). Two rules keep a single hostile
message from silencing a node ("stamp poisoning"):

- a stamp far in the future is rejected outright (`ahead`), so it never becomes "the previous
  stamp" and never makes a prediction look fresh for ever;
- a run of `restart_after` consecutive stamps that go back but increase among themselves (a bag
  replayed again, a tracker restarted with its own clock, a stamp accepted that was a little
  ahead) is a new sequence: the run's last stamp is accepted (`restarted`) and the check
  continues from it. Repeats of one stamp never form such a run.

When the node's clock reads 0 (sim time before the first /clock message) the `ahead` rule is
skipped: there is no clock to compare with yet.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: Default of the nodes' `max_stamp_ahead_s` parameter: generous for clock skew between two
#: machines, far below the 1e6 s of a poisoned stamp.
MAX_STAMP_AHEAD_S = 2.0
#: Default length of a run of back-jumps that starts a new sequence.
RESTART_AFTER = 3

ACCEPTED = "accepted"
RESTARTED = "restarted"
NON_FINITE = "non_finite"
NOT_POSITIVE = "not_positive"
AHEAD = "ahead"
NOT_AFTER = "not_after_previous"


def stamp_is_usable(stamp: float) -> bool:
    """Finite and positive: the test every stamp passes at the boundary before anything uses it."""
    return isinstance(stamp, (int, float)) and math.isfinite(stamp) and stamp > 0.0


@dataclass
class StampCheck:
    """Stamp rule of one input stream; `check(stamp, now)` returns one of the verdicts above."""

    max_ahead_s: float = MAX_STAMP_AHEAD_S
    restart_after: int = RESTART_AFTER
    monotonic: bool = True
    last: float | None = None
    _run: int = 0
    _run_last: float = -math.inf

    def check(self, stamp: float, now: float | None = None) -> str:
        """Verdict for `stamp` given the node clock `now` (seconds, None/0: unknown); updates `last`."""
        if not isinstance(stamp, (int, float)) or not math.isfinite(stamp):
            return NON_FINITE
        if stamp <= 0.0:
            return NOT_POSITIVE
        if now is not None and now > 0.0 and stamp > now + self.max_ahead_s:
            return AHEAD
        if not self.monotonic or self.last is None or stamp > self.last:
            self.last, self._run = stamp, 0
            return ACCEPTED
        self._run = self._run + 1 if stamp > self._run_last else 1
        self._run_last = stamp
        if self._run >= self.restart_after:
            self.last, self._run = stamp, 0
            return RESTARTED
        return NOT_AFTER

    def reset(self) -> None:
        self.last, self._run, self._run_last = None, 0, -math.inf

    def describe(self, verdict: str, stamp: float, now: float | None) -> str:
        """The warning text of a rejection."""
        if verdict == AHEAD:
            ahead = stamp - (now or 0.0)
            return f"stamp {stamp:.3f} is {ahead:.3g} s ahead of the node clock (max {self.max_ahead_s} s)"
        if verdict == NOT_AFTER:
            return f"stamp {stamp:.3f} not after the previous {self.last:.3f}"
        return f"stamp {stamp} is not a positive finite time"
