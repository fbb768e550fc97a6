"""A delayed Nao arm without a physics engine: transport delay line + motor latency + rate limits.

Why: closed-loop experiments need thousands of robot seconds per minute, and the delay logic has
to be the same whether the arm is this kinematic model or the PyBullet simulator. The chain is

    command --DelayLine(delay_s)--> motor input --DelayLine(latency_s)--> rate-limited joints

`SimulatedRobot` steps at a fixed `dt`; with ``backend="pybullet"`` the last stage is a
`NaoSimulator` driven by position control instead of the kinematic rate limiter.

`SimulatedRobot.command` is the robot's input: every command, whoever sends it (the closed loop's
compensator, the nao_sim node for the compensator node, a bag or a user), is clipped into the joint
limits there and nowhere else; the stages behind it receive in-limit targets.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from gwr_predictor.parameters.spec import ParameterError, ParamSpec
from gwr_predictor.robot.nao import ARM_JOINTS, VELOCITY_LIMITS, RobotError, clip_to_limits
from gwr_predictor.robot.pybullet_nao import NaoSimulator  # pybullet itself only when a simulator starts

BACKENDS = ("kinematic", "pybullet")


def _check_range(owner: str, name: str, value: float, low: float, high: float) -> float:
    """`value` as float if it is a number in [low, high], else RobotError naming `owner.name`."""
    return _check(owner, ParamSpec(name, 0.0, "", low, high), value)


def _check(owner: str, spec: ParamSpec, value: Any) -> Any:
    try:
        return spec.check(value, owner)
    except ParameterError as exc:
        raise RobotError(str(exc)) from None


#: The delayed robot's parameters, declared once: `RobotParams` validates with them and the nao_sim
#: node declares its ROS parameters from them.
ROBOT_SPECS: dict[str, ParamSpec] = {s.name: s for s in (
    ParamSpec("delay_s", 0.6, "transport + sensing delay of every command (s)", 0.0, 60.0),
    ParamSpec("latency_s", 0.035, "motor response latency (s); the real Nao: 30-40 ms", 0.0, 10.0),
    ParamSpec("dt", 0.01, "control period of the robot (s)", 1e-4, 1.0),
    ParamSpec("time_constant_s", 0.0, "first-order motor approach (s); 0: a pure rate limiter", 0.0, 10.0),
    ParamSpec("state_delay_s", 0.0, "how old the reported joint states are (s)", 0.0, 60.0),
    ParamSpec("backend", "kinematic", "robot model", choices=BACKENDS),
)}


def sine_delay(t: float, delay_s: float, amplitude_s: float, period_s: float) -> float:
    """The variable delay of Sec. VI-D: delay_s + amplitude_s * sin(2 pi t / period_s), never below 0."""
    if amplitude_s <= 0.0:
        return delay_s
    return max(0.0, delay_s + amplitude_s * math.sin(2.0 * math.pi * t / period_s))


class DelayLine:
    """Time-stamped FIFO: what was pushed at time t comes out at t + delay (delay may change).

    Each value is released at its push time plus the delay in force when it was pushed. If the
    delay shrinks, a newer value can overtake older ones; those are then dropped (a receiver only
    ever acts on the newest information), and counted in `dropped`.
    """

    def __init__(self, delay_s: float, initial: Any = None) -> None:
        self._delay = _check_range("DelayLine", "delay_s", delay_s, 0.0, 3600.0)
        self._queue: deque[tuple[float, float, Any]] = deque()  # (release_t, push_t, value)
        self._value = initial
        self._value_push_t = -math.inf
        self.dropped = 0

    @property
    def delay_s(self) -> float:
        return self._delay

    @delay_s.setter
    def delay_s(self, value: float) -> None:
        """Applies to values pushed from now on (values in flight keep their release time)."""
        self._delay = _check_range("DelayLine", "delay_s", value, 0.0, 3600.0)

    def __len__(self) -> int:
        return len(self._queue)

    def push(self, t: float, value: Any, delay_s: float | None = None) -> None:
        """Enqueue `value` sent at time `t`; `delay_s` overrides the line's delay for this value."""
        d = self._delay if delay_s is None else _check_range("DelayLine", "delay_s", delay_s, 0.0, 3600.0)
        self._queue.append((t + d, t, value))

    def get(self, now: float) -> Any:
        """The newest value released by `now` (or the previous one / `initial` if none is due)."""
        released = [item for item in self._queue if item[0] <= now]
        if released:
            newest = max(released, key=lambda item: item[1])
            if newest[1] >= self._value_push_t:
                self._value, self._value_push_t = newest[2], newest[1]
            kept = deque(item for item in self._queue if item[0] > now and item[1] > self._value_push_t)
            self.dropped += len(self._queue) - len(released) - len(kept)
            self._queue = kept
        return self._value

    def clear(self, initial: Any = None) -> None:
        self._queue.clear()
        self._value, self._value_push_t = initial, -math.inf


def default_velocity_limits(names: tuple[str, ...] = ARM_JOINTS) -> tuple[float, ...]:
    return tuple(VELOCITY_LIMITS[n] for n in names)


@dataclass(frozen=True)
class MotorParams:
    """Motor stage: commands act after `latency_s`, joints follow under velocity limits.

    `time_constant_s` > 0 adds a first-order approach (speed = error / tau, capped by the velocity
    limit), so small corrections slow down like a real servo; 0 gives a pure rate limiter.
    """

    latency_s: float = 0.035
    velocity_limits: tuple[float, ...] = field(default_factory=default_velocity_limits)
    time_constant_s: float = 0.0
    joint_names: tuple[str, ...] = ARM_JOINTS

    def __post_init__(self) -> None:
        _check_range("MotorParams", "latency_s", self.latency_s, 0.0, 10.0)
        _check_range("MotorParams", "time_constant_s", self.time_constant_s, 0.0, 10.0)
        if len(self.velocity_limits) != len(self.joint_names):
            raise RobotError(f"MotorParams.velocity_limits needs {len(self.joint_names)} values "
                             f"(one per joint), got {len(self.velocity_limits)}")
        for name, v in zip(self.joint_names, self.velocity_limits, strict=True):
            _check_range("MotorParams", f"velocity_limits[{name}]", v, 1e-6, 1e3)


class MotorModel:
    """Joint positions that move toward the latest command, `latency_s` after it was given."""

    def __init__(self, params: MotorParams | None = None, initial: np.ndarray | None = None) -> None:
        self.params = params or MotorParams()
        n = len(self.params.joint_names)
        self._vmax = np.asarray(self.params.velocity_limits, dtype=float)
        start = np.zeros(n) if initial is None else _as_angles(initial, n, "MotorModel initial")
        self.position = clip_to_limits(start, self.params.joint_names)
        self.t = 0.0
        self._inputs = DelayLine(self.params.latency_s, initial=self.position.copy())

    @property
    def target(self) -> np.ndarray:
        """The command currently acting on the joints (after the latency)."""
        return self._inputs.get(self.t)

    def command(self, target: np.ndarray) -> None:
        """Give a new target at the motor's current time.

        The target must lie within the joint limits: it is not clipped again here, because
        `SimulatedRobot.command` clipped it at the robot's input (a target beyond a limit would be
        followed beyond it).
        """
        self._inputs.push(self.t, _as_angles(target, len(self.params.joint_names), "MotorModel.command"))

    def step(self, dt: float) -> np.ndarray:
        """Advance by `dt` seconds and return the new joint positions."""
        self.t += dt
        error = self.target - self.position
        tau = self.params.time_constant_s
        speed_cap = self._vmax * dt
        move = error if tau <= 0.0 else error * min(1.0, dt / tau)
        self.position = self.position + np.clip(move, -speed_cap, speed_cap)
        return self.position

    def reset(self, angles: np.ndarray) -> None:
        self.position = clip_to_limits(_as_angles(angles, len(self.params.joint_names), "MotorModel.reset"),
                                       self.params.joint_names)
        self._inputs.clear(initial=self.position.copy())


def _as_angles(values: Any, n: int, where: str) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    if arr.shape != (n,):
        raise RobotError(f"{where}: expected {n} joint angles, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise RobotError(f"{where}: joint angles must be finite, got {arr}")
    return arr


@dataclass(frozen=True)
class RobotParams:
    """A delayed robot: transport+sensing delay, motor stage, control period, backend.

    `delay_s` is the command transport delay (everything between deciding a command and the
    motor receiving it); the total lag of an uncompensated robot is about delay_s + latency_s.
    `state_delay_s` delays what the robot reports about itself (0: joint_states are fresh).
    """

    delay_s: float = ROBOT_SPECS["delay_s"].default
    latency_s: float = ROBOT_SPECS["latency_s"].default
    dt: float = ROBOT_SPECS["dt"].default
    time_constant_s: float = ROBOT_SPECS["time_constant_s"].default
    state_delay_s: float = ROBOT_SPECS["state_delay_s"].default
    backend: Literal["kinematic", "pybullet"] = ROBOT_SPECS["backend"].default

    def __post_init__(self) -> None:
        for name, spec in ROBOT_SPECS.items():
            _check("RobotParams", spec, getattr(self, name))


class SimulatedRobot:
    """The Nao's 8 arm joints behind a delay, stepped at a fixed dt (context manager).

    `command(angles)` sends a target at the robot's current time; `advance(seconds)` steps;
    `state()` is what the robot reports (its joint angles, `state_delay_s` old). `params`, if
    given, replaces the scalar arguments; a `simulator` passed in (pybullet backend) is used
    and left open, one created here is closed with the robot.
    """

    def __init__(self, delay_s: float = 0.6, latency_s: float = 0.035, dt: float = 0.01,
                 backend: Literal["kinematic", "pybullet"] = "kinematic", *, time_constant_s: float = 0.0,
                 state_delay_s: float = 0.0, initial: np.ndarray | None = None,
                 params: RobotParams | None = None, simulator: Any = None) -> None:
        self.params = params or RobotParams(delay_s, latency_s, dt, time_constant_s, state_delay_s, backend)
        p = self.params
        n = len(ARM_JOINTS)
        start = clip_to_limits(np.zeros(n) if initial is None else _as_angles(initial, n, "SimulatedRobot initial"))
        self.t = 0.0
        self._transport = DelayLine(p.delay_s, initial=start.copy())
        self._reports = DelayLine(p.state_delay_s, initial=start.copy())
        self._sim = None
        self._owns_sim = False
        if p.backend == "pybullet":
            self._sim, self._owns_sim = simulator, simulator is None
            if self._sim is None:
                self._sim = NaoSimulator(time_step=p.dt / math.ceil(p.dt * 240.0 - 1e-9))  # <= 1/240 s
            self._sim.reset(start)
            self._latency = DelayLine(p.latency_s, initial=start.copy())
            self._position = self._sim.joint_positions()
        else:
            self._motor = MotorModel(MotorParams(latency_s=p.latency_s, time_constant_s=p.time_constant_s),
                                     initial=start)
            self._position = self._motor.position.copy()
        self._reports.push(self.t, self._position.copy())

    def __enter__(self) -> SimulatedRobot:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Disconnect the simulator if this robot created it."""
        if self._sim is not None and self._owns_sim:
            self._sim.close()
        self._sim = None

    @property
    def delay_s(self) -> float:
        return self._transport.delay_s

    @delay_s.setter
    def delay_s(self, value: float) -> None:
        """Change the transport delay for commands sent from now on (a variable-delay robot)."""
        self._transport.delay_s = value

    def command(self, angles: np.ndarray) -> bool:
        """Send target angles (ARM_JOINTS order) now; they reach the motors `delay_s` later.

        The robot's input, the one place a command is clipped into the joint limits (the callers
        send what they chose, unclipped). Returns True when the command had to be clipped.
        """
        target = _as_angles(angles, len(ARM_JOINTS), "SimulatedRobot.command")
        clipped = clip_to_limits(target)
        self._transport.push(self.t, clipped)
        return bool(np.any(clipped != target))

    def joint_positions(self) -> np.ndarray:
        """The true current joint angles (no reporting delay)."""
        return self._position.copy()

    def state(self) -> np.ndarray:
        """The joint angles the robot reports now (`state_delay_s` old)."""
        return np.array(self._reports.get(self.t), dtype=float)

    def step(self) -> np.ndarray:
        """One control period: deliver due commands, move the joints, return the positions."""
        dt = self.params.dt
        delivered = self._transport.get(self.t)
        if self._sim is not None:
            self._latency.push(self.t, delivered)
            self.t += dt
            self._sim.command(self._latency.get(self.t))
            self._sim.step(dt)
            self._position = self._sim.joint_positions()
        else:
            self._motor.command(delivered)
            self._position = self._motor.step(dt).copy()
            self.t = self._motor.t
        self._reports.push(self.t, self._position.copy())
        return self._position.copy()

    def advance(self, seconds: float) -> np.ndarray:
        """Step until `seconds` more have passed (whole control periods); return the positions."""
        end = self.t + seconds - 1e-9
        while self.t < end:
            self.step()
        return self._position.copy()
