"""Simulated time made visible: a node on `use_sim_time` says in its log when /clock is missing or has
stopped, instead of standing silently at 0."""

from __future__ import annotations

import time

from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from gwr_predictor.pipeline.input_rules import RejectionCounter


class SimClockWatch:
    """Under use_sim_time, says in the log when /clock is missing or has stopped, instead of silence.

    Checked once per wall-clock second: no /clock `no_clock_after_s` after the start (the ROS clock
    still at 0) is warned about every `throttle_s`; the first /clock is logged; a simulated time that
    stands still for `stalled_after_s` (the clock source stopped or paused) is logged once per stall.
    """

    def __init__(self, node: Node, counters: RejectionCounter, no_clock_after_s: float = 5.0,
                 stalled_after_s: float = 5.0) -> None:
        self._node = node
        self._counters = counters
        self._no_clock_after_s = no_clock_after_s
        self._stalled_after_s = stalled_after_s
        self._started = time.monotonic()
        self._last_ns = 0
        self._last_change = self._started
        self._stall_reported = False
        self.timer = node.create_timer(1.0, self.check, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def check(self) -> None:
        now_ns = self._node.get_clock().now().nanoseconds
        wall = time.monotonic()
        logger = self._node.get_logger()
        if now_ns == 0:
            waited = wall - self._started
            if waited >= self._no_clock_after_s:
                self._counters.count("sim_time.no_clock_checks")
                self._counters.warn_throttled(
                    "sim_time.no_clock_checks",
                    f"use_sim_time is true but no /clock received for {waited:.0f} s: the node clock stands at 0, "
                    "so its timers do not fire and it publishes nothing timed; start a clock source "
                    "(bag_player clock:=true) or run with use_sim_time:=false")
            return
        if self._last_ns == 0:
            logger.info(f"/clock received: simulated time {now_ns * 1e-9:.3f} s")
        if now_ns != self._last_ns:
            self._last_ns, self._last_change, self._stall_reported = now_ns, wall, False
        elif not self._stall_reported and wall - self._last_change >= self._stalled_after_s:
            self._stall_reported = True
            self._counters.count("sim_time.stalls")
            logger.warning(f"simulated time has stood at {now_ns * 1e-9:.3f} s for {self._stalled_after_s:.0f} s "
                           "(the /clock source stopped or paused): timers wait until it moves again")
