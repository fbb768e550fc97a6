"""Helpers for tests that run real node processes over DDS.

Every test gets its own ROS_DOMAIN_ID (so parallel runs and other tests never cross-talk),
LOCALHOST discovery, ROS_LOG_DIR in tmp_path and one log file per process. Processes are always
stopped at teardown: SIGINT, then SIGTERM, then SIGKILL (+ `fastdds shm clean`) after timeouts.
The test process talks to them through a `Probe`: a node on its own rclpy Context.
"""

from __future__ import annotations

import contextlib
import fcntl
import itertools
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile

from gwr_predictor.nodes import messages
from gwr_predictor.nodes.qos import status_qos, stream_qos

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
# The test process itself must never discover (or multicast to) anything off this machine.
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"

PROBE_DEPTH = 1000
_domain_counter = itertools.count()
_used_domains: set[int] = set()
#: One lock file per domain id for every test run on this machine: a run holds an id's lock while a test
#: uses the domain, so concurrent runs (checkouts, CI jobs) with overlapping ranges never share a domain
#: (their nodes have the same names and would read each other's streams and statuses).
DOMAIN_LOCKS = Path(tempfile.gettempdir()) / "gwr_predictor_ros_domains"
DOMAIN_WAIT_S = 120.0
_held_domains: dict[int, int] = {}  # domain id -> descriptor of its locked file


def _domain_range() -> tuple[int, int]:
    """Domain ids this run may use: `GWR_TEST_DOMAINS=LO-HI` (parallel checkouts), else 20..99."""
    text = os.environ.get("GWR_TEST_DOMAINS", "20-99")
    lo, hi = (int(v) for v in text.split("-"))
    if not 0 <= lo <= hi <= 101:
        raise ValueError(f"GWR_TEST_DOMAINS={text!r}: expected LO-HI within 0..101")
    return lo, hi


def _lock_domain(domain: int) -> bool:
    """Take the machine-wide lock of `domain` (True; also if this process holds it), False if another does.
    The lock goes with the process: a run that dies leaves no id taken."""
    if domain in _held_domains:
        return True
    DOMAIN_LOCKS.mkdir(exist_ok=True)
    fd = os.open(DOMAIN_LOCKS / f"{domain}.lock", os.O_RDWR | os.O_CREAT, 0o666)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return False
    _held_domains[domain] = fd
    return True


def allocate_domain_id() -> int:
    """A domain id not used before in this pytest run (spread over runs by the pid) and not in use by
    another run on this machine (waits up to DOMAIN_WAIT_S for one).

    Once the whole range is used it starts over: tests run one after another and each stops its
    processes at teardown, so a small range (GWR_TEST_DOMAINS=90-99) still runs the whole suite."""
    lo, hi = _domain_range()
    size = hi - lo + 1
    deadline = time.monotonic() + DOMAIN_WAIT_S
    while True:
        if len(_used_domains) >= size:
            _used_domains.clear()
        for _ in range(size):
            domain = (os.getpid() * 7 + next(_domain_counter)) % size + lo
            if domain not in _used_domains and _lock_domain(domain):
                _used_domains.add(domain)
                return domain
        if time.monotonic() > deadline:
            raise RuntimeError(f"no free ROS domain id in {lo}..{hi}: other test runs on this machine hold "
                               f"them (locks in {DOMAIN_LOCKS}); give this run its own GWR_TEST_DOMAINS")
        _used_domains.clear()  # the ids this run used are its own to reuse, as when the range is used up
        time.sleep(0.2)


def release_domain_id(domain: int) -> None:
    """Give an id back (a session or an in-process fixture that is done with it): other runs may take it."""
    _used_domains.discard(domain)
    fd = _held_domains.pop(domain, None)
    if fd is not None:
        os.close(fd)  # releases the lock


@contextlib.contextmanager
def in_process(args: Sequence[str], **makers: Callable[[], Node]) -> Iterator[dict[str, Any]]:
    """Nodes built in this process by `makers` (tests call their callbacks directly: no DDS round trip), in a
    ROS domain of their own, with `args` after `--ros-args`; destroyed, and the domain released, after."""
    domain = allocate_domain_id()
    rclpy.init(args=["--ros-args", *args], domain_id=domain)
    built: dict[str, Any] = {}
    try:
        for name, make in makers.items():
            built[name] = make()
        yield built
    finally:
        for node in built.values():
            node.destroy_node()
        rclpy.try_shutdown()
        release_domain_id(domain)


def ros_env(domain_id: int, log_dir: Path, extra: dict[str, str] | None = None) -> dict[str, str]:
    """Environment of a node process: isolated domain, local discovery, logs in the test folder."""
    env = dict(os.environ)
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)  # let the child's bootstrapper set up its own libraries
    env.update({
        "ROS_DOMAIN_ID": str(domain_id),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "ROS_LOG_DIR": str(log_dir),
        "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
        "MPLBACKEND": "Agg",
        "PYTHONUNBUFFERED": "1",
        "RCUTILS_COLORIZED_OUTPUT": "0",
        "RCUTILS_LOGGING_BUFFERED_STREAM": "0",
    })
    env.update(extra or {})
    return env


def node_args(params: dict[str, Any] | None = None, params_file: Path | None = None,
              remaps: dict[str, str] | None = None, namespace: str | None = None) -> list[str]:
    """`--ros-args` for parameters (`-p`), a params file and remappings."""
    args = ["--ros-args"]
    if params_file is not None:
        args += ["--params-file", str(params_file)]
    for name, value in (params or {}).items():
        args += ["-p", f"{name}:={format_param(value)}"]
    for src, dst in (remaps or {}).items():
        args += ["-r", f"{src}:={dst}"]
    if namespace:
        args += ["-r", f"__ns:={namespace}"]
    return args


def format_param(value: Any) -> str:
    """A Python value in the YAML syntax `-p name:=value` expects."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return value if value else "''"
    if isinstance(value, (list, tuple)):
        return "[" + ",".join(format_param(v) if not isinstance(v, str) else f"'{v}'" for v in value) + "]"
    return repr(value)


class NodeProcess:
    """One node running as a subprocess, its output in a log file."""

    def __init__(self, name: str, argv: list[str], env: dict[str, str], log_path: Path) -> None:
        self.name = name
        self.argv = argv
        self.log_path = log_path
        self._log = open(log_path, "wb")
        self.popen = subprocess.Popen(argv, env=env, stdout=self._log, stderr=subprocess.STDOUT,
                                      stdin=subprocess.DEVNULL, cwd=str(ROOT))

    def output(self) -> str:
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text(errors="replace")

    def running(self) -> bool:
        return self.popen.poll() is None

    def wait(self, timeout: float) -> int:
        """Wait for the process to exit on its own; fails the test with its log on timeout."""
        try:
            return self.popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            pytest.fail(f"{self.name} did not exit within {timeout} s; log:\n{self.output()[-3000:]}")

    def send_signal(self, sig: int) -> None:
        if self.running():
            self.popen.send_signal(sig)

    def stop(self, sig: int = signal.SIGINT, timeout: float = 10.0) -> tuple[int, bool]:
        """Stop with `sig`, escalating to SIGTERM and SIGKILL; returns (exit code, needed SIGKILL)."""
        killed = False
        for step_sig, step_timeout in ((sig, timeout), (signal.SIGTERM, 5.0)):
            if not self.running():
                break
            self.popen.send_signal(step_sig)
            try:
                self.popen.wait(timeout=step_timeout)
            except subprocess.TimeoutExpired:
                continue
        if self.running():
            self.popen.kill()
            self.popen.wait(timeout=10)
            killed = True
        self._log.close()
        return self.popen.returncode, killed


class Probe:
    """The test's own node on a private Context: subscribe, publish, spin until a condition holds."""

    def __init__(self, domain_id: int, name: str = "probe") -> None:
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = Node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.received: dict[str, list[Any]] = {}

    def subscribe(self, topic: str, msg_type: Any, qos: QoSProfile | None = None, raw: bool = False) -> list[Any]:
        """Collect every message of `topic` in the returned list (filled while spinning).

        The queue is deep (1000) so that nothing is lost while the test does not spin."""
        box = self.received.setdefault(topic, [])
        self.node.create_subscription(msg_type, topic, box.append, qos or stream_qos(PROBE_DEPTH), raw=raw)
        return box

    def subscribe_diagnostics(self) -> dict[str, dict[str, str]]:
        """Latest diagnostic key/values per node name (fully qualified), updated while spinning."""
        latest: dict[str, dict[str, str]] = {}
        self.node.create_subscription(messages.DiagnosticArray, "/diagnostics",
                                      lambda m: latest.update(messages.read_diagnostics(m)), status_qos())
        return latest

    def publisher(self, topic: str, msg_type: Any, qos: QoSProfile | None = None) -> Any:
        return self.node.create_publisher(msg_type, topic, qos or stream_qos())

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=min(0.05, max(0.0, end - time.monotonic())))

    def spin_until(self, predicate: Callable[[], bool], timeout: float, what: str | Callable[[], str] = "condition",
                   processes: Sequence[NodeProcess] = ()) -> None:
        """Spin until `predicate()`; on timeout fail with `what` (a text, or a function giving it then)
        and the tail of every process log."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate():
                return
            self.executor.spin_once(timeout_sec=0.05)
        if predicate():
            return
        logs = "\n".join(f"--- {p.name} (running={p.running()}) ---\n{p.output()[-2500:]}" for p in processes)
        pytest.fail(f"timed out after {timeout} s waiting for {what() if callable(what) else what}\n{logs}")

    def wait_for_subscribers(self, publisher: Any, count: int = 1, timeout: float = 20.0) -> None:
        self.spin_until(lambda: publisher.get_subscription_count() >= count, timeout,
                        f"{count} subscriber(s) on {publisher.topic_name}")

    def wait_for_graph(self, links: dict[str, tuple[str, list[str]]], timeout: float = 30.0,
                       settle_s: float = 1.0) -> None:
        """Wait until, per topic, the named publisher node and every named subscriber node are in the graph.

        A node's own "N subscribers" wait covers only its output topic; a pipeline test that must see
        every message wants each hop discovered before the first message flows (under load, discovery
        of a late hop takes seconds). `settle_s` gives the endpoints time to match after discovery."""
        def missing() -> list[str]:
            gaps = []
            for topic, (publisher, subscribers) in links.items():
                pubs = {i.node_name for i in self.node.get_publishers_info_by_topic(topic)}
                subs = {i.node_name for i in self.node.get_subscriptions_info_by_topic(topic)}
                gaps += [f"{topic} publisher {publisher}"] if publisher not in pubs else []
                gaps += [f"{topic} subscriber {name}" for name in subscribers if name not in subs]
            return gaps
        self.spin_until(lambda: not missing(), timeout, lambda: "graph: " + ", ".join(missing()))
        self.spin_for(settle_s)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


class RosSession:
    """Node processes + probe of one test, on one private domain."""

    def __init__(self, tmp_path: Path) -> None:
        self.domain_id = allocate_domain_id()
        self.tmp_path = tmp_path
        self.log_dir = tmp_path / "ros_log"
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.env = ros_env(self.domain_id, self.log_dir)
        self.processes: list[NodeProcess] = []
        self._probe: Probe | None = None
        self._diagnostics: dict[str, dict[str, str]] | None = None
        self._killed = False  # a SIGKILL leaves Fast DDS segments in /dev/shm: clean them at the end

    @property
    def probe(self) -> Probe:
        if self._probe is None:
            self._probe = Probe(self.domain_id)
        return self._probe

    def executable(self, name: str) -> str:
        path = shutil.which(name, path=str(BIN))
        if path is None:
            raise FileNotFoundError(f"console script {name!r} not found in {BIN} (is the package installed?)")
        return path

    def start(self, name: str, params: dict[str, Any] | None = None, params_file: Path | None = None,
              remaps: dict[str, str] | None = None, namespace: str | None = None, label: str | None = None,
              executable: str | None = None, extra_args: Sequence[str] = (),
              env: dict[str, str] | None = None) -> NodeProcess:
        """Start console script `name` with the given ROS arguments (and environment variables `env` on top
        of the session's); its log is tmp_path/<label>.log."""
        label = label or name
        argv = [executable or self.executable(name), *extra_args,
                *node_args(params, params_file, remaps, namespace)]
        proc = NodeProcess(label, argv, {**self.env, **(env or {})}, self.tmp_path / f"{label}.log")
        self.processes.append(proc)
        return proc

    def restart(self, proc: NodeProcess, label: str) -> NodeProcess:
        """Start the same command line again (after `kill`), logging to tmp_path/<label>.log."""
        new = NodeProcess(label, proc.argv, self.env, self.tmp_path / f"{label}.log")
        self.processes.append(new)
        return new

    def kill(self, proc: NodeProcess, timeout: float = 10.0) -> None:
        """SIGKILL (a crash: no handler, no final hook) and wait until it is gone."""
        proc.popen.kill()
        proc.popen.wait(timeout=timeout)
        self._killed = True

    def wait_for_log(self, proc: NodeProcess, text: str, timeout: float = 60.0) -> None:
        """Spin the probe until `text` appears in the process's output (e.g. its 'ready' line)."""
        self.probe.spin_until(lambda: text in proc.output(), timeout, f"{text!r} in the log of {proc.name}",
                              [proc])

    def run(self, name: str, timeout: float = 30.0, **kwargs: Any) -> tuple[int, str]:
        """Start a node and wait for it to exit on its own: (exit code, output)."""
        proc = self.start(name, **kwargs)
        code = proc.wait(timeout)
        return code, proc.output()

    @property
    def diagnostics(self) -> dict[str, dict[str, str]]:
        """The probe's view of /diagnostics (one subscription per test), updated while it spins."""
        if self._diagnostics is None:
            self._diagnostics = self.probe.subscribe_diagnostics()
        return self._diagnostics

    def start_ready(self, name: str, timeout: float = 60.0, **kwargs: Any) -> NodeProcess:
        """`start` a node and wait for its first /diagnostics status (its topics then exist)."""
        proc = self.start(name, **kwargs)
        namespace = kwargs.get("namespace") or ""
        self.wait_for_node(self.diagnostics, f"{namespace.rstrip('/')}/{name}", timeout=timeout)
        return proc

    def wait_for_node(self, diagnostics: dict[str, dict[str, str]], fq_name: str, timeout: float = 30.0) -> None:
        """Ready = its first /diagnostics status arrived (so its publishers and subscriptions exist)."""
        self.probe.spin_until(lambda: fq_name in diagnostics, timeout, f"diagnostics of {fq_name}", self.processes)

    def stop_all(self) -> None:
        needed_kill = False
        for proc in reversed(self.processes):
            if proc.popen.returncode is None or not proc._log.closed:
                _, killed = proc.stop()
                needed_kill |= killed
        if needed_kill or self._killed:
            fastdds = shutil.which("fastdds", path=str(BIN))
            if fastdds:
                subprocess.run([fastdds, "shm", "clean"], env=self.env, capture_output=True, timeout=30)

    def close(self) -> None:
        try:
            self.stop_all()
        finally:
            if self._probe is not None:
                self._probe.close()
            release_domain_id(self.domain_id)


@pytest.fixture
def ros(tmp_path: Path) -> Iterator[RosSession]:
    """A RosSession that always stops its processes, even when the test fails."""
    session = RosSession(tmp_path)
    try:
        yield session
    finally:
        session.close()
