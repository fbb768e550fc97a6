"""nao_sim: a simulated Nao whose arms execute commands after a transport delay and a motor latency.

The robot is `gwr_predictor.robot.delayed_arm.SimulatedRobot` (PyBullet by default, DIRECT mode, or the
kinematic model): commands reach its motors `delay_s` later (the paper's 600 ms of sensing and
transport) plus `latency_s` of motor response. A timer advances it to the node clock in control
periods (the physics runs at 240 Hz inside) and publishes what the robot reports on `joint_states`.
`delay_amplitude_s` makes the delay vary as a sine (the variable-delay scenario of Sec. VI-D).
A node-clock jump beyond `max_clock_jump_s` (a looping replay, a leaping /clock, a stopped process)
restarts the robot's time base there, logged and counted as `clock_jumps.forward` / `clock_jumps.back`:
the gap is never simulated, so every step stays short and the node answers signals throughout.
Commands are checked by the input check (layout, finite, stamps) and clipped into the joint limits
once, at the robot's input (`SimulatedRobot.command`), counted as `joint_commands.clipped`.

For URDF viewers (RViz's RobotModel, Foxglove's 3D panel) it also publishes the URDF on
`robot_description` (std_msgs/String, transient-local, as robot_state_publisher does) and
`joint_states` carries every movable URDF joint: the 8 arm joints plus both WristYaw, which
nothing commands (they hold their start pose).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

from gwr_predictor.parameters.spec import ParameterError, ParamSpec
from gwr_predictor.pipeline import conventions
from gwr_predictor.pipeline.clock_jumps import CLOCK_JUMP_SPEC, RobotTimeBase
from gwr_predictor.pipeline.input_rules import ArmAnglesCheck
from gwr_predictor.robot.delayed_arm import ROBOT_SPECS, SimulatedRobot, sine_delay
from gwr_predictor.robot.errors import RobotError
from gwr_predictor.robot.nao import ROBOT_ARM_JOINTS, robot_arm_positions
from gwr_predictor.robot.pybullet_nao import NaoSimulator, save_png
from gwr_predictor.robot.urdf import default_urdf_path

from . import messages, standard_messages
from .exits import NodeFatalError
from .pipeline_node import PipelineNode
from .qos import stream_qos
from .runner import run_node

PARAMS = (
    ParamSpec("backend", "pybullet", "robot model", choices=("pybullet", "kinematic")),
    ParamSpec("gui", False, "open the PyBullet window, a live view (needs DISPLAY; without one: a warning, headless)"),
    replace(ROBOT_SPECS["delay_s"], live=True),
    ParamSpec("delay_amplitude_s", 0.0, "variable delay: delay_s + amplitude * sin(2 pi t / delay_period_s)",
              0.0, 30.0),
    ParamSpec("delay_period_s", 20.0, "period of the delay variation (s)", 0.1, 3600.0),
    ROBOT_SPECS["latency_s"],
    ParamSpec("control_period_s", 0.01, "robot control period; physics steps at 240 Hz within it (s)", 0.001, 0.1),
    CLOCK_JUMP_SPEC,
    ParamSpec("state_rate_hz", 50.0, "rate of joint_states", 1.0, 1000.0),
    ParamSpec("render_dir", "", "write offscreen PNG pictures of the robot here (pybullet backend); empty: none"),
    ParamSpec("render_period_s", 1.0, "one picture every this many seconds", 0.05, 3600.0),
    ParamSpec("render_width", 320, "picture width (px)", 16, 4096),
    ParamSpec("render_height", 240, "picture height (px)", 16, 4096),
)


class NaoSimNode(PipelineNode):
    NODE_NAME = "nao_sim"

    def __init__(self) -> None:
        super().__init__(self.NODE_NAME, PARAMS)
        p = self.params
        if p["render_dir"] and p["backend"] != "pybullet":
            raise ParameterError("parameter 'render_dir' needs backend 'pybullet'")
        self.sim = None
        if p["backend"] == "pybullet":
            step = min(p["control_period_s"], 1.0 / 240.0)
            try:
                try:
                    self.sim = NaoSimulator(gui=p["gui"], time_step=step)
                except RobotError as exc:
                    if not p["gui"]:
                        raise
                    self.get_logger().warning(f"parameter 'gui': {exc}; running headless instead")
                    self.sim = NaoSimulator(gui=False, time_step=step)
            except RobotError as exc:
                raise NodeFatalError(f"cannot start the PyBullet simulator: {exc}") from None
        try:
            self.robot = SimulatedRobot(p["delay_s"], p["latency_s"], p["control_period_s"], p["backend"],
                                        simulator=self.sim)
        except RobotError as exc:
            raise ParameterError(str(exc)) from None
        # robot time 0 is the first tick's node-clock time (under sim time, /clock)
        self.time_base = RobotTimeBase(p["max_clock_jump_s"])
        self.commands = self.command_check()
        self.state_pub = self.create_publisher(messages.JointState, conventions.TOPIC_ROBOT_STATE, stream_qos())
        self.publish_robot_description()
        self.create_subscription(messages.JointState, conventions.TOPIC_COMMAND, self.on_command, stream_qos())
        self.create_timer(1.0 / p["state_rate_hz"], self.on_tick)
        self.render_dir = Path(p["render_dir"]) if p["render_dir"] else None
        if self.render_dir is not None:
            try:
                self.render_dir.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise NodeFatalError(f"parameter 'render_dir': cannot create {self.render_dir}: {exc}") from None
            self.create_timer(p["render_period_s"], self.render)
        self.get_logger().info(f"{p['backend']} Nao, delay {p['delay_s']} s (+/- {p['delay_amplitude_s']}), "
                               f"motor latency {p['latency_s']} s")

    def advance(self) -> None:
        """Step the robot up to the node clock (whole control periods, at most `max_clock_jump_s`), with the
        delay in force."""
        p = self.params
        now = self.now_s()
        if now == 0.0:
            return  # use_sim_time and no /clock yet: no time has passed
        t, jump = self.time_base.target(now, self.robot.t)
        if jump:
            self.on_clock_jump(now, jump)
        if p["delay_amplitude_s"] > 0.0:
            self.robot.delay_s = sine_delay(t, p["delay_s"], p["delay_amplitude_s"], p["delay_period_s"])
        if t > self.robot.t:
            self.robot.advance(t - self.robot.t)

    def on_clock_jump(self, now: float, jump: float) -> None:
        """Say so; after a jump back the command stamps start over too (the clock source's new time line)."""
        direction = "forward" if jump > 0.0 else "back"
        self.counters.count(f"clock_jumps.{direction}")
        self.counters.warn_throttled(
            f"clock_jumps.{direction}",
            f"node clock jumped {direction} by {abs(jump):.3f} s to {now:.3f} s (more than max_clock_jump_s "
            f"{self.params['max_clock_jump_s']} s): the robot's time continues from here, the gap is not simulated")
        if jump < 0.0:
            self.commands = self.command_check()

    def command_check(self) -> ArmAnglesCheck:
        """No limit rule in the check: the robot's input clips every command, once (SimulatedRobot.command)."""
        return self.arm_check("joint_commands", limit_margin=None)

    def on_live_parameter(self, name: str, value: Any) -> None:
        """A new delay applies to commands sent from now on (with a sine, `advance` uses it next step)."""
        if name == "delay_s" and self.params["delay_amplitude_s"] == 0.0:
            self.robot.delay_s = float(value)

    def on_command(self, msg: messages.JointState) -> None:
        self.advance()  # first: a clock jump back renews the check's stamp rule for the new time line
        accepted = self.commands.accept(*messages.joint_state_fields(msg))
        if accepted is None:
            return
        if self.robot.command(accepted[1]):
            self.counters.count("joint_commands.clipped")
        self.counters.count("commands.accepted")

    def on_tick(self) -> None:
        """Advance and report the joint angles."""
        self.advance()
        self.state_pub.publish(messages.joint_state(self.now_s(), ROBOT_ARM_JOINTS,
                                                    robot_arm_positions(self.robot.state(), self.wrists())))
        self.counters.count("states.published")

    def wrists(self) -> tuple[float, float]:
        """(left, right) WristYaw: read from the simulator when there is one, else the start pose 0."""
        if self.sim is None:
            return (0.0, 0.0)
        return tuple(self.sim.joint_positions(("LWristYaw", "RWristYaw")))

    def publish_robot_description(self) -> None:
        """The URDF the simulator runs, once, latched: a viewer that starts later still gets it."""
        path = self.sim.urdf_path if self.sim is not None else default_urdf_path()
        try:
            urdf = Path(path).read_text(encoding="utf-8")
        except OSError as exc:
            raise NodeFatalError(f"cannot read the URDF {path}: {exc}") from None
        self.description_pub = self.create_publisher(standard_messages.String, conventions.TOPIC_ROBOT_DESCRIPTION,
                                                     standard_messages.latched_qos())
        self.description_pub.publish(standard_messages.String(data=urdf))

    def hardware_id(self) -> str:
        return f"simulated Nao ({self.params['backend']}) on {super().hardware_id()}"

    def render(self) -> None:
        index = self.counters.get("frames.rendered")
        path = self.render_dir / f"nao_{index:05d}.png"
        try:
            save_png(self.sim.render(self.params["render_width"], self.params["render_height"]), path)
        except OSError as exc:
            raise NodeFatalError(f"cannot write {path}: {exc}") from None
        self.counters.count("frames.rendered")

    def diagnostic_values(self) -> dict[str, object]:
        return {**super().diagnostic_values(), "delay_s": self.robot.delay_s}

    def on_shutdown(self) -> None:
        self.robot.close()
        if self.sim is not None:
            self.sim.close()


def main(args: list[str] | None = None) -> int:
    return run_node(NaoSimNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
