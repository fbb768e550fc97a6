"""Replay with the offered QoS and on simulated time: real node processes over DDS.

- the recorder stores the QoS a publisher offers, the player (given a bare .mcap file) publishes with
  it again, so a transient-local subscriber, which a volatile publisher cannot serve, gets the data;
- bag_player clock:=true rate:=2 drives learner, compensator and robot started with use_sim_time:=true
  at twice real time: their timers, stamps and staleness checks follow the recorded time;
- a node on sim time without /clock says so in its log.
"""

import re
import time

import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosbags.interfaces import QosDurability, QosReliability
from rosbags.rosbag2 import Reader

from gwr_predictor.nodes import messages
from gwr_predictor.nodes.bag_player import publisher_qos
from gwr_predictor.pipeline import bag_messages, bag_qos, bag_reader, bag_writer, conventions
from gwr_predictor.robot.nao import ARM_JOINTS

FAST = {"diagnostics_period_s": 0.5}
SIM = {**FAST, "use_sim_time": True}
LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=7, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
T0 = 1000.0  # recorded time of the first frame (s): far from the wall clock, so a mix-up shows


def arm_pose(t: float) -> np.ndarray:
    """A smooth, repeating arm motion well inside the joint limits."""
    return 0.3 * np.sin(2 * np.pi * t / 2.0 + np.arange(8)) * np.array([1, 0.5, 1, 0.5, 1, 0.5, 1, 0.5])


def write_angles_bag(path, seconds: float = 6.0, period: float = 0.1) -> int:
    """/arm_angles at 10 Hz, stamped T0.., received 2 ms after each stamp (as a recorder stores them)."""
    frames = round(seconds / period)
    with bag_writer.BagWriter(path, {conventions.TOPIC_ANGLES: bag_messages.JOINT_STATE}) as writer:
        for k in range(frames):
            stamp = T0 + k * period
            writer.write(conventions.TOPIC_ANGLES, round((stamp + 0.002) * 1e9),
                         bag_messages.joint_state_msg(ARM_JOINTS, arm_pose(k * period), stamp))
    return frames


def test_player_qos_follows_the_recording_and_defaults_for_old_bags():
    latched = publisher_qos([bag_qos.qos_profile(history="keep_last", depth=7, reliability="reliable",
                                              durability="transient_local")])
    assert (latched.reliability, latched.durability, latched.depth) == (
        ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL, 7)
    old = publisher_qos([])  # bags written before QoS was recorded
    assert (old.reliability, old.durability) == (ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)
    assert old.depth == conventions.QOS_DEPTH_STREAM


@pytest.mark.ros
def test_recorded_qos_is_offered_again_by_the_player_from_a_bare_mcap_file(ros, tmp_path):
    probe = ros.probe
    pub = probe.publisher(conventions.TOPIC_ANGLES, messages.JointState, LATCHED)
    recorder = ros.start("bag_recorder", params={**FAST, "path": str(tmp_path / "bag"), "topics": ["arm_angles"]})
    probe.wait_for_subscribers(pub, 1, timeout=60)
    for k in range(5):
        pub.publish(messages.joint_state(T0 + k, ARM_JOINTS, arm_pose(k)))
    diagnostics = probe.subscribe_diagnostics()
    probe.spin_until(lambda: diagnostics.get("/bag_recorder", {}).get("recorded./arm_angles") == "5", 20,
                     "5 messages recorded", [recorder])
    code, killed = recorder.stop()
    assert code == 0 and not killed, recorder.output()
    with Reader(tmp_path / "bag") as reader:  # an independent reader sees the offer
        (conn,) = reader.connections
        (offered,) = conn.ext.offered_qos_profiles
    assert offered.reliability == QosReliability.RELIABLE and offered.durability == QosDurability.TRANSIENT_LOCAL

    probe.node.destroy_publisher(pub)  # its history would reach the new subscription too
    (mcap_file,) = (tmp_path / "bag").glob("*.mcap")
    got = probe.subscribe(conventions.TOPIC_ANGLES, messages.JointState, LATCHED)  # volatile offers cannot serve it
    code, output = ros.run("bag_player", timeout=60, params={
        **FAST, "bag": str(mcap_file), "wait_for_subscribers": 1, "rate": 5.0})
    assert code == 0, output
    assert "(reliable, transient_local" in output
    probe.spin_until(lambda: len(got) == 5, 10, "the 5 replayed messages")
    assert [messages.read_joint_state(m)[0] for m in got] == [T0 + k for k in range(5)]


@pytest.mark.ros
@pytest.mark.slow
def test_replay_on_simulated_time_twice_as_fast_as_real_time(ros, tmp_path):
    frames = write_angles_bag(tmp_path / "angles")
    probe = ros.probe
    diagnostics = probe.subscribe_diagnostics()
    commands = probe.subscribe(conventions.TOPIC_COMMAND, messages.JointState)
    arrivals: list[tuple[float, float]] = []  # (wall time, stamp) of every robot state
    probe.node.create_subscription(messages.JointState, conventions.TOPIC_ROBOT_STATE,
                                   lambda m: arrivals.append((time.monotonic(), messages.read_joint_state(m)[0])),
                                   QoSProfile(depth=1000))
    nodes = [ros.start("bag_recorder", params={**SIM, "path": str(tmp_path / "replayed"),
                                               "topics": ["joint_commands", "diagnostics"]}),
             ros.start("arm_predictor", params={**SIM, "seed": 1}),
             # stale_after_s 1 s of recorded time = 0.5 s of wall time at rate 2: a loaded machine's
             # learner lag (doubled on the recorded time line) stays within it
             ros.start("delay_compensator", params={**SIM, "mode": "fixed", "stale_after_s": 1.0}),
             ros.start("nao_sim", params={**SIM, "backend": "kinematic"})]
    for name in ("/bag_recorder", "/arm_predictor", "/delay_compensator", "/nao_sim"):
        ros.wait_for_node(diagnostics, name, timeout=60)  # diagnostics run on the wall clock, /clock or not
    probe.wait_for_graph({"/predictions": ("arm_predictor", ["delay_compensator"]),  # every hop, so nothing is lost
                          "/joint_commands": ("delay_compensator", ["nao_sim", "bag_recorder"]),
                          "/diagnostics": ("nao_sim", ["bag_recorder"])})
    player = ros.start("bag_player", params={
        **FAST, "bag": str(tmp_path / "angles"), "clock": True, "rate": 2.0, "wait_for_subscribers": 2})
    probe.spin_until(lambda: not player.running(), 60, "the end of the replay", [player])  # arrivals timed live
    output = player.output()
    assert player.wait(1) == 0, output
    assert f"{frames} messages published" in output and "publishing /clock" in output
    probe.spin_for(1.0)
    for proc in reversed(nodes):
        code, killed = proc.stop()
        assert code == 0 and not killed, proc.output()
        first = re.search(r"/clock received: simulated time ([0-9.]+) s", proc.output())
        assert first and T0 <= float(first.group(1)) <= T0 + frames * 0.1, proc.output()

    # the robot's timer ran on the recorded time, twice as fast as the wall clock
    during = [(w, s) for w, s in arrivals if T0 + 0.5 <= s <= T0 + frames * 0.1 - 0.5]
    (w0, s0), (w1, s1) = during[0], during[-1]
    assert (s1 - s0) / (w1 - w0) == pytest.approx(2.0, rel=0.2)
    # state_rate_hz 50 per *simulated* second: 0.02 s of recorded time between states (a wall-clock
    # timer would give 0.04); the median, because a loaded machine skips a tick now and then
    assert float(np.median(np.diff([st for _, st in during]))) == pytest.approx(0.02, abs=0.006)
    # commands are stamped on the recorded time line, and predictions were fresh by that clock
    stamps = [messages.read_joint_state(m)[0] for m in commands]
    assert len(stamps) >= frames - 5 and T0 <= min(stamps) and max(stamps) <= T0 + frames * 0.1 + 1.0
    comp = diagnostics["/delay_compensator"]
    predicted = int(comp.get("predictions.received", "0"))
    assert predicted >= frames - 10, comp
    # judged on the wall clock, every check would find the year-1970 stamps stale (about 60)
    assert int(comp.get("fallback.stale_predictions", "0")) <= 2, comp
    # the recorder on sim time: the bag's time line is the recorded one, also for what came before /clock
    info = bag_reader.bag_info(tmp_path / "replayed")
    assert info.topics["/joint_commands"][1] == len(stamps)
    assert T0 * 1e9 <= info.start_ns and info.end_ns <= (T0 + frames * 0.1 + 1.0) * 1e9, info
    robot = diagnostics["/nao_sim"]  # every command accepted, none refused as a repeated stamp
    assert not any(k.startswith("rejected.") for k in robot) and int(robot["commands.accepted"]) == len(stamps), robot


@pytest.mark.ros
def test_a_node_on_sim_time_without_clock_says_so(ros):
    probe = ros.probe
    node = ros.start("delay_compensator", params=SIM)
    ros.wait_for_log(node, "use_sim_time is true but no /clock received", timeout=60)
    clock = probe.publisher("/clock", messages.Clock,
                            QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
    ros.probe.spin_until(lambda: (clock.publish(messages.clock_msg(5_000_000_000)) or True)
                         and "/clock received: simulated time 5.000" in node.output(), 20,
                         "the first /clock logged", [node])


@pytest.mark.ros
def test_clock_and_restamp_together_are_refused(ros, tmp_path):
    write_angles_bag(tmp_path / "angles", seconds=0.5)
    code, output = ros.run("bag_player", params={"bag": str(tmp_path / "angles"), "clock": True, "restamp": True})
    assert code == 2 and "'clock' and 'restamp' exclude each other" in output
