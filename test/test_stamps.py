"""The stamp rule (gwr_predictor.pipeline.stamps): finite, positive, increasing, not far ahead of the
clock, and no single message can make every later genuine stamp a rejection (stamp poisoning)."""

import math

import pytest

from gwr_predictor.pipeline import stamps
from gwr_predictor.pipeline.stamps import StampCheck


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, 0.0, -1.0])
def test_non_finite_and_non_positive_stamps_are_rejected_and_leave_no_trace(bad):
    check = StampCheck()
    assert check.check(100.0, 100.0) == stamps.ACCEPTED
    assert check.check(bad, 100.0) in (stamps.NON_FINITE, stamps.NOT_POSITIVE)
    assert check.last == 100.0
    assert check.check(100.1, 100.1) == stamps.ACCEPTED


def test_one_future_stamp_is_rejected_and_does_not_block_the_genuine_ones():
    check = StampCheck(max_ahead_s=2.0)
    now = 1000.0
    assert check.check(now, now) == stamps.ACCEPTED
    assert check.check(now + 1e6, now) == stamps.AHEAD
    for k in range(1, 20):  # every genuine stamp after the poisoned one is accepted
        assert check.check(now + 0.1 * k, now + 0.1 * k) == stamps.ACCEPTED


def test_a_stamp_a_little_ahead_costs_at_most_a_run_of_restart_after_messages():
    check = StampCheck(max_ahead_s=2.0, restart_after=3)
    assert check.check(10.0, 10.0) == stamps.ACCEPTED
    assert check.check(11.9, 10.0) == stamps.ACCEPTED  # within the allowed skew
    verdicts = [check.check(10.0 + 0.1 * k, 10.0 + 0.1 * k) for k in range(1, 6)]
    assert verdicts == [stamps.NOT_AFTER, stamps.NOT_AFTER, stamps.RESTARTED, stamps.ACCEPTED, stamps.ACCEPTED]


def test_repeats_and_single_jumps_back_stay_rejected():
    check = StampCheck(restart_after=3)
    check.check(50.0)
    assert [check.check(49.0) for _ in range(10)] == [stamps.NOT_AFTER] * 10  # a repeated stale message
    assert check.check(20.0) == stamps.NOT_AFTER
    assert check.last == 50.0


def test_a_replay_that_starts_again_from_the_beginning_is_a_new_sequence():
    check = StampCheck()
    for k in range(100):
        check.check(1.0 + 0.1 * k)
    verdicts = [check.check(1.0 + 0.1 * k) for k in range(5)]
    assert verdicts[:3] == [stamps.NOT_AFTER, stamps.NOT_AFTER, stamps.RESTARTED]
    assert verdicts[3:] == [stamps.ACCEPTED] * 2


def test_sim_time_before_the_first_clock_message_skips_the_ahead_rule():
    check = StampCheck(max_ahead_s=1.0)
    assert check.check(5000.0, 0.0) == stamps.ACCEPTED
    assert check.check(9000.0, 5000.0) == stamps.AHEAD


def test_non_monotonic_streams_only_check_finite_and_ahead():
    check = StampCheck(monotonic=False)
    assert check.check(10.0, 10.0) == stamps.ACCEPTED
    assert check.check(5.0, 10.0) == stamps.ACCEPTED
    assert check.check(math.nan, 10.0) == stamps.NON_FINITE
