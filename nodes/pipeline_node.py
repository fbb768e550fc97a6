"""Plumbing every pipeline node shares, so that each node file only converts, calls and publishes.

- `declare_parameters`: `gwr_predictor.parameters.spec.ParamSpec`s as described ROS parameters; a bad
  value stops the node with a `ParameterError` naming the parameter and what is allowed.
- the counters and input gates are library code (`gwr_predictor.pipeline.gates`).
- `PipelineNode`: a Node with the above plus a periodic DiagnosticArray on /diagnostics carrying
  every counter, a `done` future for nodes that finish on their own, and an `on_shutdown` hook.
  Every timer and stamp uses the node clock, so `use_sim_time:=true` with a /clock source (e.g.
  `bag_player clock:=true rate:=2.0`) runs the node on simulated time, faster than real time too;
  without /clock that clock stands at 0 and nothing timed happens, so the node warns
  (`SimClockWatch`). Diagnostics run on the wall clock: a node reports even while its clock stands.
  `use_sim_time` is read at start only: a live change is refused with the reason (and counted as
  `parameters.refused`), since every timer, stamp and staleness check holds times of the start clock.
- `run_node`: init, build, spin, quiet exit on Ctrl-C / SIGTERM, final hook, destroy, shutdown;
  params files and ROS arguments are checked first (exit 2 with a message), unknown parameter names
  warned about (`gwr_predictor.pipeline.params_file`).
"""

from __future__ import annotations

import math
import os
import signal
import socket
import sys
import time
from collections.abc import Iterable, Sequence
from typing import Any

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.exceptions import (
    InvalidNamespaceException,
    InvalidNodeNameException,
    InvalidParameterTypeException,
    InvalidParameterValueException,
    InvalidTopicNameException,
)
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future

from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.learning.blas import single_threaded_blas
from gwr_predictor.parameters.spec import ParameterError, ParamSpec
from gwr_predictor.pipeline import conventions, params_file, stamps
from gwr_predictor.pipeline.gates import ArmAnglesGate, RejectionCounter, check_stamp

from . import messages

EXIT_OK = 0
EXIT_FATAL = 1
EXIT_BAD_PARAMETER = 2
#: /diagnostics value naming the node process (host:pid:start ns): restarts and duplicates show.
INSTANCE_KEY = conventions.INSTANCE_KEY
#: rclpy's own parameter choosing the node clock (declared by rclpy's time source, not by a ParamSpec).
USE_SIM_TIME = "use_sim_time"


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


#: Why a parameter is read-only, shown by `ros2 param describe` next to its allowed values.
READ_ONLY_REASON = "read-only: read once at start (it shapes the node's model, topics or timers); restart to change"
LIVE_NOTE = "can be changed while the node runs (set_parameters), with the same check"
_INT64_MAX = 2**63 - 1


def value_range(spec: ParamSpec) -> dict[str, list]:
    """The spec's bounds as a descriptor's FloatingPointRange / IntegerRange, so that `ros2 param
    describe` and rqt show them. ROS ranges are closed and two-sided: a missing bound becomes
    +-inf (doubles) or the int64 limit, an open end is shown closed (the spec's check still refuses
    it), and a `none_value` outside the bounds (e.g. 0 = unlimited) widens the range to include it."""
    if spec.kind not in ("double", "integer") or (spec.lo is None and spec.hi is None):
        return {}
    if spec.kind == "double":
        lo = -math.inf if spec.lo is None else float(spec.lo)
        hi = math.inf if spec.hi is None else float(spec.hi)
        return {"floating_point_range": [FloatingPointRange(from_value=lo, to_value=hi, step=0.0)]}
    lo = -_INT64_MAX - 1 if spec.lo is None else math.ceil(spec.lo)
    hi = _INT64_MAX if spec.hi is None else math.floor(spec.hi)
    if spec.none_value is not None:
        lo, hi = min(lo, spec.none_value), max(hi, spec.none_value)
    return {"integer_range": [IntegerRange(from_value=int(lo), to_value=int(hi), step=1)]}


def descriptor(spec: ParamSpec, value_type: int = 0) -> ParameterDescriptor:
    """The ROS descriptor of a spec: described, the allowed values in `additional_constraints` (with
    why it is read-only, or that it can change live) and as a range, read-only unless `live`.

    Doubles are dynamically typed so that `-p rate_hz:=30` (an integer) is accepted and converted;
    the range then applies to doubles, and `ParamSpec.check` checks every value either way.
    """
    note = LIVE_NOTE if spec.live else READ_ONLY_REASON
    return ParameterDescriptor(description=spec.description, read_only=spec.read_only, type=value_type,
                               dynamic_typing=spec.kind == "double",
                               additional_constraints=f"allowed: {spec.allowed()}; {note}", **value_range(spec))


def declare_parameters(node: Node, specs: Iterable[ParamSpec]) -> dict[str, Any]:
    """Declare every spec and return {name: validated value}; a bad value raises ParameterError.

    Numbers are declared first without range or read-only flag, so that a bad start value gets the
    spec's own message (naming the value and the allowed range), then given their full descriptor."""
    values: dict[str, Any] = {}
    for spec in specs:
        kind = spec.kind
        default = spec.default
        if kind in _ARRAY_TYPES:  # an empty list has no type of its own
            default = list(spec.default) if spec.default else _ARRAY_TYPES[kind]
        ranged = bool(value_range(spec))
        first = (ParameterDescriptor(description=spec.description, dynamic_typing=kind == "double") if ranged
                 else descriptor(spec))
        try:
            value = node.declare_parameter(spec.name, default, first).value
        except InvalidParameterTypeException as exc:
            raise ParameterError(f"parameter '{spec.name}' must be of type {kind} ({spec.allowed()}): {exc}") from None
        except InvalidParameterValueException as exc:
            raise ParameterError(f"parameter '{spec.name}' ({spec.allowed()}): {exc}") from None
        values[spec.name] = spec.check(value)
        if ranged:
            node.set_descriptor(spec.name, descriptor(spec, node.describe_parameter(spec.name).type))
    return values


# --- the base node -------------------------------------------------------------------------------

COMMON_PARAMS = (
    ParamSpec("diagnostics_period_s", 1.0, "period of the counters on /diagnostics (s)", 0.05, 60.0),
    ParamSpec("warn_throttle_s", 5.0, "at most one warning per rejection reason per this many seconds", 0.0, 3600.0),
    ParamSpec("stop_if_duplicate", True, "stop (exit 1) if another live node of this name and namespace runs on "
              "this ROS_DOMAIN_ID and started earlier: two pipelines on one domain mix their streams"),
    ParamSpec("max_stamp_ahead_s", stamps.MAX_STAMP_AHEAD_S, "input stamps further ahead of the node clock (wall "
              "or sim) are rejected, so that one future stamp cannot block the stamps after it", 0.0, 1e9),
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
        if self.params["stop_if_duplicate"]:
            self._sightings = InstanceSightings()
            self.create_subscription(messages.DiagnosticArray, conventions.DIAGNOSTICS_TOPIC,
                                     self._check_duplicate, status_qos())

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

    def arm_gate(self, input_name: str, check_stamps: bool = True, limit_margin: float | None = 0.2) -> ArmAnglesGate:
        """The gate of one JointState input, its stamps checked against this node's clock."""
        return ArmAnglesGate(self.counters, input_name, limit_margin=limit_margin, check_stamps=check_stamps,
                             clock=self.now_s, max_ahead_s=self.params["max_stamp_ahead_s"])

    def stamp_check(self) -> stamps.StampCheck:
        """The stamp rule (gwr_predictor.pipeline.stamps) of one more input stream of this node."""
        return stamps.StampCheck(self.params["max_stamp_ahead_s"])

    def check_stamp(self, check: stamps.StampCheck, input_name: str, stamp: float) -> bool:
        """`gates.check_stamp` against the node clock."""
        return check_stamp(self.counters, check, input_name, stamp, self.now_s())

    def _check_duplicate(self, msg: messages.DiagnosticArray) -> None:
        """Stop if a second instance of this node (name and namespace) that started first really runs.

        One status is a stranger's word, so three kinds of evidence are needed: statuses of that
        instance repeated over `DUPLICATE_MIN_SPAN_S`; a second node of this name in the ROS graph (a
        bag replaying old /diagnostics adds none); and that second node on this node's own topics.
        A convenience against two pipelines on one domain, not security: a hostile peer can fake all
        three (SROS2 is the answer to those)."""
        me = self.get_fully_qualified_name()
        for status in msg.status:
            if status.name != me:
                continue
            instance = next((kv.value for kv in status.values if kv.key == INSTANCE_KEY), "")
            if not instance or instance == self.instance_id:
                continue
            other = started_ns(instance)
            if other is None or (other, instance) > (self.started_ns, self.instance_id):
                continue  # the other one is the newcomer: it stops
            if not self._sightings.add(instance, time.monotonic()):
                continue
            if not self._second_instance_on_own_topics(me):
                self.counters.count("duplicate.unconfirmed")
                self.counters.warn_throttled("duplicate.unconfirmed", f"statuses of another {me} (instance "
                                             f"{instance}) but no second {me} on this node's topics: ignored")
                continue
            self.error = (f"another {me} (instance {instance}) runs on ROS_DOMAIN_ID="
                          f"{os.environ.get('ROS_DOMAIN_ID', '0')}: two pipelines on one domain mix their "
                          "streams; stopping this one (set ROS_DOMAIN_ID to a free domain)")
            self.get_logger().error(self.error)
            self.finish(EXIT_FATAL)
            return

    def _second_instance_on_own_topics(self, me: str) -> bool:
        """True if the graph holds two nodes named `me` and, on a topic this node publishes (or, for a
        node that only listens, subscribes to), two endpoints of nodes named `me`."""
        if sum(1 for n, ns in self.get_node_names_and_namespaces() if _qualified(ns, n) == me) < 2:
            return False
        topics = {p.topic_name for p in self.publishers} - _COMMON_TOPICS
        endpoints = self.get_publishers_info_by_topic
        if not topics:
            topics = {s.topic_name for s in self.subscriptions} - _COMMON_TOPICS
            endpoints = self.get_subscriptions_info_by_topic
        return any(sum(1 for e in endpoints(t) if _qualified(e.node_namespace, e.node_name) == me) >= 2
                   for t in topics)

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

    def finish(self, exit_code: int = EXIT_OK) -> None:
        """Stop spinning (for nodes that end on their own, e.g. a player at the end of its bag)."""
        if not self.done.done():
            self.done.set_result(exit_code)

    def on_shutdown(self) -> None:
        """Final hook, run once after spinning stops for any reason (the context may be shut down)."""


def started_ns(instance_id: str) -> int | None:
    """The start time (ns) in an instance id `host:pid:start_ns`, None if it has another form."""
    try:
        return int(instance_id.rsplit(":", 1)[1])
    except (IndexError, ValueError):
        return None


def _qualified(namespace: str, name: str) -> str:
    return namespace.rstrip("/") + "/" + name


#: A second instance must send this many statuses, over at least this long, before this one stops.
DUPLICATE_MIN_STATUSES = 3
DUPLICATE_MIN_SPAN_S = 2.0
#: Topics every node may have: an endpoint on them says nothing about which node it is.
_COMMON_TOPICS = frozenset({conventions.DIAGNOSTICS_TOPIC, "/rosout", "/parameter_events", "/clock"})


class InstanceSightings:
    """First sighting and count of the statuses of each other instance id (at most `limit` ids, the
    oldest forgotten first, so that a flood of made-up ids costs no memory)."""

    def __init__(self, limit: int = 32) -> None:
        self._seen: dict[str, tuple[float, int]] = {}
        self._limit = limit

    def add(self, instance: str, now: float) -> bool:
        """Count one status of `instance` at `now`; True once it has been seen repeatedly over a period."""
        first, count = self._seen.pop(instance, (now, 0))
        self._seen[instance] = (first, count + 1)
        while len(self._seen) > self._limit:
            del self._seen[next(iter(self._seen))]
        return count + 1 >= DUPLICATE_MIN_STATUSES and now - first >= DUPLICATE_MIN_SPAN_S


class _StopSignals:
    """SIGINT and SIGTERM request a clean stop: spinning ends, the final hook runs while the context
    is still valid (it may log and publish), then the node is destroyed and rclpy shut down. While
    the node is being built (`starting`) there is nothing to save yet: a signal interrupts at once,
    even a read that blocks."""

    def __init__(self) -> None:
        self.received: int | None = None
        self.starting = True
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, self._handle)

    def _handle(self, signum: int, _frame: Any) -> None:
        self.received = signum
        if self.starting:
            raise KeyboardInterrupt


DRAIN_LIMIT_S = 2.0


def _drain(executor: SingleThreadedExecutor, node: PipelineNode) -> None:
    """Take what has already arrived before the final hook (a recorder stopped by SIGTERM would
    otherwise lose the messages still queued in its subscriptions): spin while the node's
    `drain_progress` grows, for at most DRAIN_LIMIT_S."""
    if node.drain_progress() is None:
        return
    deadline = time.monotonic() + DRAIN_LIMIT_S
    idle = 0  # spins in a row that took nothing in: two end the drain
    while idle < 2 and time.monotonic() < deadline and rclpy.ok():
        before = node.drain_progress()
        executor.spin_once(timeout_sec=0.05)
        idle = idle + 1 if node.drain_progress() == before else 0


def run_node(node_cls: type[PipelineNode], args: list[str] | None = None) -> int:
    """init, build, spin until done / Ctrl-C / SIGTERM, final hook, destroy, shutdown; returns the exit code."""
    logger = rclpy.logging.get_logger(getattr(node_cls, "NODE_NAME", node_cls.__name__))
    single_threaded_blas()  # whatever the environment says: threads per core fight on a robot's computer
    try:
        params_file.check_params_files(sys.argv if args is None else args)
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except params_file.ParamsFileError as exc:
        logger.error(f"bad parameter: {exc}")
        return EXIT_BAD_PARAMETER
    except RuntimeError as exc:  # rcl's RCLError: a remap rule or argument it cannot parse
        logger.error(f"bad ROS arguments: {str(exc).split(', at ')[0]}")
        return EXIT_BAD_PARAMETER
    stop = _StopSignals()
    node: PipelineNode | None = None
    code = EXIT_OK
    try:
        node = node_cls()
        stop.starting = False
        logger = node.get_logger()
        logger.info("ready")  # scripts wait for this line
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        # spin_once with a timeout so that a signal is noticed within 0.1 s even when nothing arrives
        while stop.received is None and not node.done.done() and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
        if stop.received is not None:
            logger.info(f"{signal.Signals(stop.received).name} received: shutting down")
            _drain(executor, node)
        elif node.done.done():
            code = int(node.done.result())
    except ParameterError as exc:
        logger.error(f"bad parameter: {exc}")
        code = EXIT_BAD_PARAMETER
    except (InvalidTopicNameException, InvalidNamespaceException, InvalidNodeNameException) as exc:
        logger.error(f"bad name: {exc}")
        code = EXIT_BAD_PARAMETER
    except NodeFatalError as exc:
        logger.error(f"stopping: {exc}")
        code = EXIT_FATAL
    except (KeyboardInterrupt, ExternalShutdownException):
        if node is None and stop.received is not None:
            logger.info(f"{signal.Signals(stop.received).name} received while starting: stopped")
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
