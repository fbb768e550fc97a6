"""The base of every pipeline node, so that each node file only converts, calls and publishes.

`PipelineNode`: a Node with validated parameters (`ros_parameters`; `COMMON_PARAMS` on every node),
live changes checked as at start, rejection counters and the input checks (library code,
`gwr_predictor.pipeline.input_rules`), a periodic DiagnosticArray on /diagnostics carrying every counter, a
`done` future for nodes that finish on their own, and an `on_shutdown` hook (`runner.run_node` runs it).
Every timer and stamp uses the node clock, so `use_sim_time:=true` with a /clock source (e.g.
`bag_player clock:=true rate:=2.0`) runs the node on simulated time, faster than real time too;
without /clock that clock stands at 0 and nothing timed happens, so the node warns (`sim_clock`).
Diagnostics run on the wall clock: a node reports even while its clock stands. `use_sim_time` is read
at start only: a live change is refused with the reason (and counted as `parameters.refused`), since
every timer, stamp and staleness check holds times of the start clock. A second instance of the node on
the same domain stops it (`duplicates`).
"""

from __future__ import annotations

import os
import socket
import time
from collections.abc import Sequence
from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.task import Future

from gwr_predictor.parameters.spec import ParameterError, ParamSpec
from gwr_predictor.pipeline import conventions, params_file, stamps
from gwr_predictor.pipeline.input_rules import ArmAnglesCheck, RejectionCounter, check_stamp

from . import messages
from .duplicates import DuplicateWatch
from .exits import EXIT_FATAL, EXIT_OK
from .qos import status_qos
from .ros_parameters import declare_parameters
from .sim_clock import SimClockWatch

#: /diagnostics value naming the node process (host:pid:start ns): restarts and duplicates show.
INSTANCE_KEY = conventions.INSTANCE_KEY
#: rclpy's own parameter choosing the node clock (declared by rclpy's time source, not by a ParamSpec).
USE_SIM_TIME = "use_sim_time"

COMMON_PARAMS = (
    ParamSpec("diagnostics_period_s", 1.0, "period of the counters on /diagnostics (s)", 0.05, 60.0),
    ParamSpec("warn_throttle_s", 5.0, "at most one warning per rejection reason per this many seconds", 0.0, 3600.0),
    ParamSpec("stop_if_duplicate", True, "stop (exit 1) if another live node of this name and namespace runs on "
              "this ROS_DOMAIN_ID and started earlier: two pipelines on one domain mix their streams"),
    ParamSpec("max_stamp_ahead_s", stamps.MAX_STAMP_AHEAD_S, "input stamps further ahead of the node clock (wall "
              "or sim) are rejected, so that one future stamp cannot block the stamps after it", 0.0, 1e9),
)


class PipelineNode(Node):
    """A Node with validated parameters, counters published on /diagnostics and a final hook."""

    def __init__(self, name: str, specs: Sequence[ParamSpec], **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        all_specs = (*COMMON_PARAMS, *specs)
        self.params = declare_parameters(self, all_specs)
        chosen = tuple(self.chosen_specs(self.params))
        if chosen:
            self.params.update(declare_parameters(self, chosen))
            all_specs = (*all_specs, *chosen)
        declared = {*self._parameters, *self.other_options_parameters()}
        for warning in params_file.unknown_parameters(self._parameter_overrides, declared):
            self.get_logger().warning(warning)  # -p and --params-file keys alike (misspelt, another node's)
        self._specs = {spec.name: spec for spec in all_specs}
        self.add_on_set_parameters_callback(self._check_live_parameters)
        self.add_post_set_parameters_callback(self._apply_live_parameters)
        self.counters = RejectionCounter(self.get_logger(), self.params["warn_throttle_s"])
        self.done = Future()
        #: A condition that makes the node's /diagnostics level ERROR (e.g. a failed checkpoint save).
        self.error: str | None = None
        #: Tells this process's statuses from those of a restarted or second instance (value `instance`).
        self.started_ns = time.time_ns()
        self.instance_id = f"{socket.gethostname()}:{os.getpid()}:{self.started_ns}"
        # absolute: diagnostic_aggregator listens on /diagnostics whatever the node's namespace
        self._diag_pub = self.create_publisher(messages.DiagnosticArray, conventions.DIAGNOSTICS_TOPIC, status_qos())
        self._diag_timer = self.create_timer(self.params["diagnostics_period_s"], self.publish_diagnostics,
                                             clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.uses_sim_time = bool(self.get_parameter(USE_SIM_TIME).value)
        self._sim_clock_watch = SimClockWatch(self, self.counters) if self.uses_sim_time else None
        self._duplicate_watch = (DuplicateWatch(self, self.counters, self.instance_id, self.started_ns,
                                                self._stop_with_error) if self.params["stop_if_duplicate"] else None)

    def chosen_specs(self, params: dict[str, Any]) -> Sequence[ParamSpec]:
        """Parameters that exist only for the option `params` chose (the learner: its predictor's own
        settings), declared after the node's own; none by default."""
        return ()

    def other_options_parameters(self) -> set[str]:
        """Names that belong to an option not chosen (another predictor's settings): a params file may
        hold them for every option, so they are not warned about as unknown."""
        return set()

    def drain_progress(self) -> int | None:
        """A count that grows while the node still takes in messages it must not lose on a stop (the
        recorder's received messages); None (the default): nothing to drain, stop at once."""
        return None

    def arm_check(self, input_name: str, check_stamps: bool = True, limit_margin: float | None = 0.2) -> ArmAnglesCheck:
        """The check of one JointState input, its stamps checked against this node's clock."""
        return ArmAnglesCheck(self.counters, input_name, limit_margin=limit_margin, check_stamps=check_stamps,
                              clock=self.now_s, max_ahead_s=self.params["max_stamp_ahead_s"])

    def stamp_check(self) -> stamps.StampCheck:
        """The stamp rule (gwr_predictor.pipeline.stamps) of one more input stream of this node."""
        return stamps.StampCheck(self.params["max_stamp_ahead_s"])

    def check_stamp(self, check: stamps.StampCheck, input_name: str, stamp: float) -> bool:
        """`input_rules.check_stamp` against the node clock."""
        return check_stamp(self.counters, check, input_name, stamp, self.now_s())

    # --- live parameters: checked like at start, then applied by the node -------------------------

    def _check_live_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        """set_parameters on a `live` spec: the spec's check, then the node's own (`check_live`).
        Read-only ones never get here (rclpy refuses them; their descriptor says why); rclpy's own
        `use_sim_time` is refused here (called before rclpy's time source, which would switch at once)."""
        for parameter in parameters:
            if parameter.name == USE_SIM_TIME:
                refused = self._refuse_clock_switch(parameter.value)
                if refused is not None:
                    return refused
                continue
            spec = self._specs.get(parameter.name)
            if spec is None:  # not ours: rclpy's business
                continue
            try:
                self.check_live(parameter.name, spec.check(parameter.value))
            except ParameterError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _refuse_clock_switch(self, value: Any) -> SetParametersResult | None:
        """A refusal for a live `use_sim_time` that differs from the running value, else None.

        Why: timers, stamps, the stamp rules, staleness checks and the robot's time base all hold
        times of the clock chosen at start; switched live, a node on sim time without /clock stands
        at 0 and silently stops (nao_sim publishes nothing, the compensator's fallback never fires)."""
        current = self.get_parameter(USE_SIM_TIME).value
        if value == current:
            return None
        reason = (f"parameter '{USE_SIM_TIME}' is read once at start (every timer, stamp and staleness check "
                  f"follows the clock chosen then): restart the node with {USE_SIM_TIME}:={str(value).lower()} "
                  "to change it")
        self.counters.count("parameters.refused")
        self.get_logger().warning(f"refused a live change of '{USE_SIM_TIME}' to {value!r}: {reason}")
        return SetParametersResult(successful=False, reason=reason)

    def _apply_live_parameters(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            spec = self._specs.get(parameter.name)
            if spec is None:
                continue
            value = spec.check(parameter.value)
            old, self.params[parameter.name] = self.params[parameter.name], value
            self.counters.count("parameters.changed")
            self.get_logger().info(f"parameter '{parameter.name}' changed: {old!r} -> {value!r}")
            self.on_live_parameter(parameter.name, value)

    def check_live(self, name: str, value: Any) -> None:
        """Raise ParameterError if a live change to `name` cannot be applied (cross-parameter rules)."""

    def on_live_parameter(self, name: str, value: Any) -> None:
        """Apply a live change (self.params already holds the new value); nodes with live specs override."""

    def now_s(self) -> float:
        """The node clock in seconds (the stamp source of every message the pipeline creates)."""
        return self.get_clock().now().nanoseconds * 1e-9

    def diagnostic_values(self) -> dict[str, object]:
        """Counters plus anything a node adds by overriding this."""
        return dict(self.counters.snapshot())

    def hardware_id(self) -> str:
        """What the status is about, for diagnostic tools: the machine the node runs on (nodes that
        stand for a device, like the simulated robot, say so)."""
        return socket.gethostname()

    def publish_diagnostics(self) -> None:
        rejected = self.counters.rejected
        level = messages.WARN if rejected else messages.OK
        text = f"{rejected} inputs rejected" if rejected else "ok"
        if self.error is not None:
            level, text = messages.ERROR, self.error
        values = {**self.diagnostic_values(), INSTANCE_KEY: self.instance_id}
        status = messages.diagnostic_status(self.get_fully_qualified_name(), values, text, level, self.hardware_id())
        self._diag_pub.publish(messages.diagnostic_array(self.now_s(), [status]))

    def publish_final_diagnostics(self, timeout_s: float = 1.0) -> None:
        """The counters once more as the node stops, so that a recording holds each node's final
        counts (what `gwr_predictor.pipeline.message_latency` compares with the messages recorded); waits until the
        reliable subscribers acknowledged them."""
        self.publish_diagnostics()
        self._diag_pub.wait_for_all_acked(Duration(seconds=timeout_s))

    def _stop_with_error(self, reason: str) -> None:
        """Make `reason` the node's /diagnostics ERROR, log it and stop with exit code 1."""
        self.error = reason
        self.get_logger().error(self.error)
        self.finish(EXIT_FATAL)

    def finish(self, exit_code: int = EXIT_OK) -> None:
        """Stop spinning (for nodes that end on their own, e.g. a player at the end of its bag)."""
        if not self.done.done():
            self.done.set_result(exit_code)

    def on_shutdown(self) -> None:
        """Final hook, run once after spinning stops for any reason (the context may be shut down)."""
