"""Two pipelines side by side in one ROS domain, each under its own namespace, never crossing.

scripts/run_pipeline.sh --namespace runs every node of a pipeline in that namespace, the
uncompensated pair in <ns>/uncompensated reading <ns>/arm_angles. Two pipelines with different
demonstrator motions run in one domain; each robot's commands must come from its own pipeline only
(graph: publishers and subscribers of each topic are that pipeline's nodes; content: every
uncompensated command is one of its own pipeline's angle frames, none of the other's).

The probe starts listening before the pipelines, but under load its subscription may match a publisher
only after the first frames went out, and a command can arrive before the frame it repeats: the content
check therefore compares with its own stream only the commands whose frame the probe must have received
(`comparable`); every command, those included, must be none of the other pipeline's frames.
"""

from __future__ import annotations

import os
import signal
import subprocess
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from ros_harness import ROOT, Probe, allocate_domain_id, release_domain_id, ros_env

from gwr_predictor.nodes import messages
from gwr_predictor.nodes.messages import JointState
from gwr_predictor.pipeline import bag_messages, bag_reader
from gwr_predictor.pipeline.message_latency import latency_report
from gwr_predictor.pipeline.run_report import compute_report, read_run
from gwr_predictor.robot.nao import ARM_JOINTS

SCRIPT = ROOT / "scripts" / "run_pipeline.sh"
#: a different motion per pipeline, so a crossed stream is visible in the values
MOTIONS = {"/robot_a": "raise_front_both", "/robot_b": "rotate_cw_both"}
#: commands per robot compared with its own stream
COMPARED = 8
#: a command repeats a frame exactly (mode none)
SAME = 1e-9


def stamped_values(msgs: Sequence[JointState]) -> tuple[np.ndarray, np.ndarray]:
    """(stamps (n,), values (n, joints)) of JointStates in arrival order."""
    read = [messages.read_joint_state(m) for m in msgs]
    return np.array([r[0] for r in read]), np.array([r[2] for r in read]).reshape(len(read), len(ARM_JOINTS))


def distances(values: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """Per row of `values`: the largest joint difference to the nearest of `frames` (inf without frames)."""
    if len(frames) == 0:
        return np.full(len(values), np.inf)
    return np.abs(values[:, None, :] - frames[None, :, :]).max(axis=2).min(axis=1)


def comparable(commands: tuple[np.ndarray, np.ndarray], own: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Which commands (arrival order) repeat a frame the probe must have received in `own` (its angle frames).

    Those before the first command that is a received frame may repeat frames published before the probe's
    subscription matched (the compensator commands its frames in order, and both streams arrive in order);
    those stamped at or after the newest received frame may repeat a frame still on its way (a frame stamped
    after a command was captured after the command went out, so it follows that command's frame)."""
    (cmd_stamps, cmd_values), (frame_stamps, frame_values) = commands, own
    if len(frame_stamps) == 0:
        return np.zeros(len(cmd_stamps), dtype=bool)
    seen = distances(cmd_values, frame_values) < SAME
    started = np.cumsum(seen) > 0
    return started & (cmd_stamps < frame_stamps.max())


def crossing_problems(commands: tuple[np.ndarray, np.ndarray], own: tuple[np.ndarray, np.ndarray],
                      other: tuple[np.ndarray, np.ndarray]) -> list[str]:
    """Why a robot's commands are not its own pipeline's frames: any command that is a frame of the other
    pipeline, or a comparable one that is none of its own; empty when the streams did not cross."""
    values = commands[1]
    theirs = distances(values, other[1])
    problems = [f"command {i} is a frame of the other pipeline" for i in np.flatnonzero(theirs < SAME)]
    mine = distances(values, own[1])
    problems += [f"command {i} is none of its own pipeline's frames (nearest {mine[i]:.3g} rad, the other's "
                 f"{theirs[i]:.3g} rad)" for i in np.flatnonzero(comparable(commands, own) & (mine >= SAME))]
    return problems


def scenario(path: Path, pattern: str) -> Path:
    path.write_text(f"/**/skeleton_source:\n  ros__parameters:\n    patterns: [{pattern}]\n    subjects: 1\n")
    return path


def start_pipeline(tmp_path: Path, namespace: str, env: dict[str, str]) -> subprocess.Popen:
    name = namespace.strip("/")
    with open(tmp_path / f"{name}.log", "wb") as log:  # the child keeps its own descriptor
        return subprocess.Popen(
            ["bash", str(SCRIPT), "--namespace", name, "--seconds", "120", "--out", str(tmp_path / name),
             "--scenario", str(scenario(tmp_path / f"{name}.yaml", MOTIONS[namespace]))],
            env=env, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True)


def stop(proc: subprocess.Popen) -> None:
    """SIGINT: the script stops its nodes; the whole group is killed if that takes too long."""
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
    try:
        proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)


@pytest.mark.ros
def test_two_namespaced_pipelines_share_a_domain_without_crossing(tmp_path):
    domain = allocate_domain_id()
    env = ros_env(domain, tmp_path / "ros_log", {"ROS_DOMAIN_ID": str(domain)})
    probe = Probe(domain)
    pipelines = {}
    try:
        angles = {ns: probe.subscribe(f"{ns}/arm_angles", JointState) for ns in MOTIONS}
        commands = {ns: probe.subscribe(f"{ns}/uncompensated/joint_commands", JointState) for ns in MOTIONS}
        root_angles = probe.subscribe("/arm_angles", JointState)
        root_commands = probe.subscribe("/uncompensated/joint_commands", JointState)
        pipelines = {ns: start_pipeline(tmp_path, ns, env) for ns in MOTIONS}

        def logs() -> str:
            return "\n".join(f"--- {p.name}\n{p.read_text()[-2000:]}" for p in sorted(tmp_path.glob("*.log")))

        def streams(ns: str) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
            other = next(o for o in MOTIONS if o != ns)
            return stamped_values(commands[ns]), stamped_values(angles[ns]), stamped_values(angles[other])

        def enough() -> bool:
            """COMPARED comparable commands per robot, or a crossing already (then fail at once)."""
            assert all(p.poll() is None for p in pipelines.values()), f"a pipeline stopped:\n{logs()}"
            views = {ns: streams(ns) for ns in MOTIONS}
            crossed = any(distances(cmds[1], other[1]).min(initial=np.inf) < SAME for cmds, _, other in views.values())
            return crossed or all(comparable(cmds, own).sum() >= COMPARED for cmds, own, _ in views.values())

        def problems() -> dict[str, list[str]]:
            return {ns: crossing_problems(*streams(ns)) for ns in MOTIONS}

        probe.spin_until(enough, 45, lambda: f"{COMPARED} comparable uncompensated commands per robot "
                         f"({problems()}):\n{logs()}")
        node = probe.node
        for ns in MOTIONS:
            # each shared topic has its own pipeline's publisher, and only its own pipeline's subscribers
            for topic, publisher in ((f"{ns}/arm_angles", "angle_extractor"), (f"{ns}/predictions", "arm_predictor")):
                pubs = [(i.node_namespace, i.node_name) for i in node.get_publishers_info_by_topic(topic)]
                assert pubs == [(ns, publisher)], topic
                subs = {i.node_namespace for i in node.get_subscriptions_info_by_topic(topic)} - {"/"}
                assert subs <= {ns, f"{ns}/uncompensated"} and f"{ns}/uncompensated" in subs, (topic, subs)
            pubs = [(i.node_namespace, i.node_name)
                    for i in node.get_publishers_info_by_topic(f"{ns}/uncompensated/joint_commands")]
            assert pubs == [(f"{ns}/uncompensated", "delay_compensator")]
        assert not root_angles and not root_commands  # nothing left in the root namespace
        assert node.count_publishers("/arm_angles") == 0 and node.count_publishers("/uncompensated/joint_commands") == 0

        # mode none commands the latest observation: each one is a frame of its own pipeline's person
        assert problems() == {ns: [] for ns in MOTIONS}
    finally:
        for proc in pipelines.values():
            stop(proc)
        probe.close()
        release_domain_id(domain)
    for ns, proc in pipelines.items():
        assert proc.returncode in (0, 130), f"{ns}: run_pipeline.sh exit code {proc.returncode}"
        check_recording(tmp_path / ns.strip("/") / "bag", ns)


def first_stamps(bag: Path, topic: str, n: int) -> list[float]:
    """Source stamps of the first `n` messages recorded on a skeleton or angles topic."""
    out = []
    for m in bag_reader.read_bag(bag, [topic]):
        out.append(bag_messages.joint_state_arrays(m.msg)[0] if m.msgtype == bag_messages.JOINT_STATE
                   else float(m.msg.data[0]))
        if len(out) == n:
            break
    return out


def check_recording(bag: Path, ns: str) -> None:
    """Each pipeline's bag is read as that pipeline's by report and latency (its robots, its nodes only),
    and it starts with the pipeline's first angle frame (the recorder heard the extractor before the first
    skeleton went out): the median of the first 3 skeletons, stamped with the middle one."""
    report = compute_report(read_run(bag))
    assert report.namespace == ns and list(report.robots) == [ns, f"{ns}/uncompensated"]
    assert report.robots[f"{ns}/uncompensated"]["mode"] == "none" and report.robots[ns]["mode"] != "none"
    assert report.scored_predictions > 0
    assert all(key.startswith(ns + "/") for key in report.rejected), report.rejected
    latency = latency_report(bag)
    assert latency.namespace == ns and "hop arm_predictor" in latency.latencies
    hop = next(c for c in latency.counts if c.topic == f"{ns}/arm_angles")
    assert hop.publisher == f"{ns}/angle_extractor" and hop.published and not hop.concurrent
    skeletons = first_stamps(bag, f"{ns}/skeleton", 3)
    assert first_stamps(bag, f"{ns}/arm_angles", 1) == [skeletons[1]]


# --- the content check itself, on made-up streams ---------------------------------------------------

def made_up(offset: float, n: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """n frames 0.1 s apart, a different motion per `offset`."""
    stamps = 100.0 + 0.1 * np.arange(n)
    return stamps, offset + 0.01 * np.arange(n)[:, None] * np.ones((1, 8))


def commands_of(frames: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """What mode none sends for these frames: each one again, stamped when it went out (a little later)."""
    return frames[0] + 0.05, frames[1].copy()


def received(frames: tuple[np.ndarray, np.ndarray], first: int) -> tuple[np.ndarray, np.ndarray]:
    """The probe's view of a stream whose subscription matched before frame `first`."""
    return frames[0][first:], frames[1][first:]


def test_commands_of_frames_sent_before_the_probe_listened_or_still_on_the_way_are_not_compared():
    own, other = made_up(0.0), made_up(1.0)
    commands = commands_of(own)
    # the probe missed frames 0-2; command 9 went out after the newest frame the probe has (stamp 100.9)
    mask = comparable(commands, received(own, 3))
    assert mask.tolist() == [False] * 3 + [True] * 6 + [False]
    assert crossing_problems(commands, received(own, 3), other) == []
    nothing = stamped_values([])  # before the first message
    assert comparable(nothing, received(own, 3)).size == 0 and crossing_problems(nothing, nothing, nothing) == []


def test_a_command_from_the_other_pipeline_is_a_crossing_wherever_it_is():
    own, other = made_up(0.0), made_up(1.0)
    for i in (1, 5, 9):  # before the first comparable command, among them, after them
        commands = commands_of(own)
        commands[1][i] = other[1][i]
        assert f"command {i} is a frame of the other pipeline" in crossing_problems(commands, received(own, 3), other)


def test_a_wholly_crossed_stream_and_a_command_of_no_frame_are_problems():
    own, other = made_up(0.0), made_up(1.0)
    assert len(crossing_problems(commands_of(other), received(own, 3), other)) == 10
    commands = commands_of(own)
    commands[1][6] += 0.2  # after the first comparable command: a pose no pipeline sent
    assert crossing_problems(commands, received(own, 3), other) == [
        "command 6 is none of its own pipeline's frames (nearest 0.17 rad, the other's 0.74 rad)"]
