"""scripts/replay.sh and scripts/record.sh on namespaced runs and on the ROS4HRI input, as a user runs them.

- A bag of the pipeline in /robot1 (its person's skeleton, as `run_pipeline.sh --namespace robot1` records
  it) replays with the default topic into a pipeline in /robot2: every frame reaches the new bag as
  /robot2/skeleton, the pipeline learns and commands, nothing lands in the root namespace, and the report
  reads the new bag.
- `record.sh --hri --namespace robot1` records a tracked body that appears after the start (every frame
  published once the recorder subscribed) and the pipeline's topics in /robot1; `replay.sh --hri` plays
  that body through hri_bodies into the pipeline: the angles are those of the recorded body.
"""

from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path

import numpy as np
import pytest
from ros_harness import ROOT, Probe, allocate_domain_id, release_domain_id, ros_env
from test_hri_bodies import hri_joint_state
from test_namespaced_runs import SAMPLE

from gwr_predictor.commands.cli import main as cli_main
from gwr_predictor.data import hri_bodies
from gwr_predictor.nodes import messages
from gwr_predictor.nodes.messages import JointState
from gwr_predictor.pipeline import bag_messages, bag_reader, bag_writer
from gwr_predictor.robot.nao import ARM_JOINTS

SCRIPTS = ROOT / "scripts"
SKELETON_FRAMES = 120  # 4 s of the sample's person
BODY_FRAMES = 60  # 2 s of a tracked body at 30 fps


def counts(bag: Path) -> dict[str, int]:
    return {topic: n for topic, (_, n) in bag_reader.bag_info(bag).topics.items() if n}


def person_bag(path: Path, namespace: str) -> Path:
    """The first SKELETON_FRAMES skeletons of the sample, recorded in `namespace`."""
    topic = f"{namespace}/skeleton"
    with bag_writer.BagWriter(path, {topic: bag_messages.FLOAT64_MULTIARRAY}) as writer:
        for i, message in enumerate(bag_reader.read_bag(SAMPLE, ["/skeleton"], decode=False)):
            if i == SKELETON_FRAMES:
                break
            writer.write_raw(topic, message.timestamp_ns, message.raw)
    return path


def script(name: str, *args: str, env: dict[str, str], timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", str(SCRIPTS / name), *args], env=env, capture_output=True, text=True,
                          timeout=timeout, stdin=subprocess.DEVNULL)


@pytest.fixture
def domain_env(tmp_path):
    domain = allocate_domain_id()
    yield domain, ros_env(domain, tmp_path / "ros_log")
    release_domain_id(domain)


@pytest.mark.ros
def test_a_namespaced_bag_replays_into_another_namespace(tmp_path, domain_env, capsys):
    _, env = domain_env
    source = person_bag(tmp_path / "robot1_bag", "/robot1")
    result = script("replay.sh", str(source), "--namespace", "robot2", "--no-baseline", "--out", str(tmp_path / "run"),
                    env=env)
    assert result.returncode == 0, result.stderr[-3000:]
    got = counts(tmp_path / "run" / "bag")
    assert got["/robot2/skeleton"] == SKELETON_FRAMES  # every frame, renamed into the replay's namespace
    assert got["/robot2/arm_angles"] >= SKELETON_FRAMES // 3 - 2 and got["/robot2/predictions"] > 0
    assert got["/robot2/joint_commands"] > 0
    assert not [t for t in got if not t.startswith("/robot2/") and t != "/diagnostics"], got
    assert cli_main(["report", str(tmp_path / "run")]) == 0
    assert "pipeline /robot2" in capsys.readouterr().out


def stop(proc: subprocess.Popen) -> int:
    """Ctrl-C, as a user stops record.sh."""
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
    try:
        return proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        return proc.wait(timeout=10)


@pytest.mark.ros
def test_the_hri_input_is_recorded_and_replayed_through_hri_bodies(tmp_path, domain_env):
    domain, env = domain_env
    bag = tmp_path / "session"
    probe = Probe(domain)
    with open(tmp_path / "record.log", "wb") as log:
        recorder = subprocess.Popen(["bash", str(SCRIPTS / "record.sh"), "--hri", "--namespace", "robot1", "--out",
                                     str(bag)], env=env, stdout=log, stderr=subprocess.STDOUT,
                                    stdin=subprocess.DEVNULL, start_new_session=True)
    rng = np.random.default_rng(3)
    human = np.cumsum(rng.normal(0.0, 0.05, (BODY_FRAMES, 8)), axis=0)  # a moving body
    t0 = 1000.0
    try:
        angles = probe.publisher("/robot1/arm_angles", JointState)
        probe.wait_for_subscribers(angles, 1, timeout=60)  # the recorder runs (and records /robot1)
        # a body the tracker starts tracking after the recording started
        tracker = probe.publisher(f"{hri_bodies.BODIES_NAMESPACE}/b7/joint_states", JointState)
        probe.wait_for_subscribers(tracker, 1, timeout=30)
        for i in range(BODY_FRAMES):
            tracker.publish(hri_joint_state(t0 + i / 30, "b7", human[i]))
            if i % 3 == 1:
                angles.publish(messages.joint_state(t0 + i / 30, ARM_JOINTS, np.zeros(8)))
            probe.spin_for(1 / 30)
        probe.spin_for(1.5)
    finally:
        code = stop(recorder)
        probe.close()
    assert code == 0, (tmp_path / "record.log").read_text()[-3000:]
    got = counts(bag)
    assert got["/humans/bodies/b7/joint_states"] == BODY_FRAMES
    assert got["/robot1/arm_angles"] == BODY_FRAMES // 3

    result = script("replay.sh", str(bag), "--hri", "--no-baseline", "--out", str(tmp_path / "replay"), env=env)
    assert result.returncode == 0, result.stderr[-3000:]
    replayed = list(bag_reader.read_bag(tmp_path / "replay" / "bag", ["/arm_angles"]))
    assert len(replayed) == BODY_FRAMES // 3
    # hri_bodies' median of every 3 frames of the recorded body, mapped to the Nao
    groups = human.reshape(-1, 3, 8)
    expected = hri_bodies.body_to_nao(np.median(groups, axis=1))[0]
    got_angles = np.array([bag_messages.joint_state_arrays(m.msg)[2] for m in replayed])
    np.testing.assert_allclose(got_angles, expected, atol=1e-9)
    assert counts(tmp_path / "replay" / "bag")["/predictions"] > 0
