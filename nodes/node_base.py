"""Plumbing every pipeline node shares, so that each node file only converts, calls and publishes.

- `declare_parameters`: `gwr_predictor.parameter_spec.ParamSpec`s as described ROS parameters; a bad
  value stops the node with a `ParameterError` naming the parameter and what is allowed.
- the counters and input gates are library code (`gwr_predictor.pipeline.gates`).
- `PipelineNode`: a Node with the above plus a periodic DiagnosticArray on /diagnostics carrying
  every counter, a `done` future for nodes that finish on their own, and an `on_shutdown` hook.
  Every timer and stamp uses the node clock, so `use_sim_time:=true` with a /clock source (e.g.
  `bag_player clock:=true rate:=2.0`) runs the node on simulated time, faster than real time too;
  without /clock that clock stands at 0 and nothing timed happens, so the node warns
  (`SimClockWatch`). Diagnostics run on the wall clock: a node reports even while its clock stands.
- `run_node`: init, build, spin, quiet exit on Ctrl-C / SIGTERM, final hook, destroy, shutdown.
"""

from __future__ import annotations

import signal
import socket
import time
from collections.abc import Iterable, Sequence
from typing import Any

import rclpy
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future

from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.parameter_spec import ParameterError, ParamSpec
from gwr_predictor.pipeline import conventions
from gwr_predictor.pipeline.gates import RejectionCounter

from . import messages

EXIT_OK = 0
EXIT_FATAL = 1
EXIT_BAD_PARAMETER = 2


class NodeFatalError(GwrPredictorError):
    """A condition that stops the node (unwritable path, full disk, unreadable file); the message says which."""


# --- QoS: chosen once, documented in docs/pipeline.md --------------------------------------------


def stream_qos(depth: int = conventions.QOS_DEPTH_STREAM, reliable: bool = True) -> QoSProfile:
    """Data streams (skeleton, angles, predictions, commands, joint states).

    Reliable by default: the learner should see every frame and a replay should reproduce a run;
    keep-last with a queue of about a second absorbs bursts without unbounded memory; volatile,
    because a late joiner has no use for old frames.
    """
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.VOLATILE)


def status_qos() -> QoSProfile:
    """Status topics (diagnostics, learner status): ROS defaults (reliable, keep last 10)."""
    return stream_qos(conventions.QOS_DEPTH_STATUS)


# --- parameters ----------------------------------------------------------------------------------


_ARRAY_TYPES = {"string list": Parameter.Type.STRING_ARRAY, "double list": Parameter.Type.DOUBLE_ARRAY}


def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """The ROS descriptor of a spec: described, allowed values in `additional_constraints`, read-only
    unless the spec is `live`.

    Ranges are checked by `ParamSpec.check` rather than by the descriptor's integer/floating-point
    ranges so that the error names the rejected value; doubles are dynamically typed so that
    `-p rate_hz:=30` (an integer) is accepted and converted.
    """
    return ParameterDescriptor(description=spec.description, read_only=spec.read_only,
                               dynamic_typing=spec.kind == "double",
                               additional_constraints=f"allowed: {spec.allowed()}")


def declare_parameters(node: Node, specs: Iterable[ParamSpec]) -> dict[str, Any]:
    """Declare every spec and return {name: validated value}; a bad value raises ParameterError."""
    values: dict[str, Any] = {}
    for spec in specs:
        kind = spec.kind
        desc = descriptor(spec)
        default = spec.default
        if kind in _ARRAY_TYPES:  # an empty list has no type of its own
            default = list(spec.default) if spec.default else _ARRAY_TYPES[kind]
        try:
            value = node.declare_parameter(spec.name, default, desc).value
        except InvalidParameterTypeException as exc:
            raise ParameterError(f"parameter '{spec.name}' must be of type {kind} ({spec.allowed()}): {exc}") from None
        except InvalidParameterValueException as exc:
            raise ParameterError(f"parameter '{spec.name}' ({spec.allowed()}): {exc}") from None
        values[spec.name] = spec.check(value)
    return values


# --- the base node -------------------------------------------------------------------------------

COMMON_PARAMS = (
    ParamSpec("diagnostics_period_s", 1.0, "period of the counters on /diagnostics (s)", 0.05, 60.0),
    ParamSpec("warn_throttle_s", 5.0, "at most one warning per rejection reason per this many seconds", 0.0, 3600.0),
)


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


class PipelineNode(Node):
    """A Node with validated parameters, counters published on /diagnostics and a final hook."""

    def __init__(self, name: str, specs: Sequence[ParamSpec], **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.params = declare_parameters(self, (*COMMON_PARAMS, *specs))
        self.counters = RejectionCounter(self.get_logger(), self.params["warn_throttle_s"])
        self.done = Future()
        # absolute: diagnostic_aggregator listens on /diagnostics whatever the node's namespace
        self._diag_pub = self.create_publisher(messages.DiagnosticArray, conventions.DIAGNOSTICS_TOPIC, status_qos())
        self._diag_timer = self.create_timer(self.params["diagnostics_period_s"], self.publish_diagnostics,
                                             clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.uses_sim_time = bool(self.get_parameter("use_sim_time").value)
        self._sim_clock_watch = SimClockWatch(self, self.counters) if self.uses_sim_time else None

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
        status = messages.diagnostic_status(self.get_fully_qualified_name(), self.diagnostic_values(),
                                            f"{rejected} inputs rejected" if rejected else "ok", level,
                                            self.hardware_id())
        self._diag_pub.publish(messages.diagnostic_array(self.now_s(), [status]))

    def publish_final_diagnostics(self, timeout_s: float = 1.0) -> None:
        """The counters once more as the node stops, so that a recording holds each node's final
        counts (what `gwr_predictor.pipeline.message_latency` compares with the messages recorded); waits until the
        reliable subscribers acknowledged them."""
        self.publish_diagnostics()
        self._diag_pub.wait_for_all_acked(Duration(seconds=timeout_s))

    def finish(self, exit_code: int = EXIT_OK) -> None:
        """Stop spinning (for nodes that end on their own, e.g. a player at the end of its bag)."""
        if not self.done.done():
            self.done.set_result(exit_code)

    def on_shutdown(self) -> None:
        """Final hook, run once after spinning stops for any reason (the context may be shut down)."""


class _StopSignals:
    """SIGINT and SIGTERM request a clean stop: spinning ends, the final hook runs while the context
    is still valid (it may log and publish), then the node is destroyed and rclpy shut down."""

    def __init__(self) -> None:
        self.received: int | None = None
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, self._handle)

    def _handle(self, signum: int, _frame: Any) -> None:
        self.received = signum


def run_node(node_cls: type[PipelineNode], args: list[str] | None = None) -> int:
    """init, build, spin until done / Ctrl-C / SIGTERM, final hook, destroy, shutdown; returns the exit code."""
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stop = _StopSignals()
    logger = rclpy.logging.get_logger(getattr(node_cls, "NODE_NAME", node_cls.__name__))
    node: PipelineNode | None = None
    code = EXIT_OK
    try:
        node = node_cls()
        logger = node.get_logger()
        logger.info("ready")  # scripts wait for this line
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        # spin_once with a timeout so that a signal is noticed within 0.1 s even when nothing arrives
        while stop.received is None and not node.done.done() and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
        if stop.received is not None:
            logger.info(f"{signal.Signals(stop.received).name} received: shutting down")
        elif node.done.done():
            code = int(node.done.result())
    except ParameterError as exc:
        logger.error(f"bad parameter: {exc}")
        code = EXIT_BAD_PARAMETER
    except NodeFatalError as exc:
        logger.error(f"stopping: {exc}")
        code = EXIT_FATAL
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            try:
                node.on_shutdown()
            except NodeFatalError as exc:
                logger.error(f"shutdown: {exc}")
                code = code or EXIT_FATAL
            if node.context.ok():
                try:
                    node.publish_final_diagnostics()
                except Exception as exc:  # the counters are a courtesy: stopping must go on
                    logger.warning(f"final diagnostics not published: {exc}")
            node.destroy_node()
        rclpy.try_shutdown()
    return code
