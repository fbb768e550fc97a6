"""Running a node: `run_node` inits rclpy, builds the node, spins, exits quietly on Ctrl-C / SIGTERM,
runs the final hook, destroys and shuts down; params files and ROS arguments are checked first (exit 2
with a message), unknown parameter names warned about (`gwr_predictor.pipeline.params_file`).
"""

from __future__ import annotations

import signal
import sys
import time
from typing import Any

import rclpy
from rclpy.exceptions import InvalidNamespaceException, InvalidNodeNameException, InvalidTopicNameException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions

from gwr_predictor.learning.blas import single_threaded_blas
from gwr_predictor.parameters.spec import ParameterError
from gwr_predictor.pipeline import params_file
from gwr_predictor.pipeline.errors import PipelineError

from .exits import EXIT_BAD_PARAMETER, EXIT_FATAL, EXIT_OK, NodeFatalError
from .pipeline_node import PipelineNode


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
    except PipelineError as exc:
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
