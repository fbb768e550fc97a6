"""Two pipelines side by side in one ROS domain, each under its own namespace, never crossing.

scripts/run_pipeline.sh --namespace runs every node of a pipeline in that namespace, the
uncompensated pair in <ns>/uncompensated reading <ns>/arm_angles. Two pipelines with different
demonstrator motions run in one domain; each robot's commands must come from its own pipeline only
(graph: publishers and subscribers of each topic are that pipeline's nodes; content: every
uncompensated command is one of its own pipeline's angle frames, none of the other's).
"""

from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path

import numpy as np
import pytest
from ros_harness import ROOT, Probe, allocate_domain_id, release_domain_id, ros_env

from gwr_predictor.nodes import messages
from gwr_predictor.nodes.messages import JointState

SCRIPT = ROOT / "scripts" / "run_pipeline.sh"
#: a different motion per pipeline, so a crossed stream is visible in the values
MOTIONS = {"/robot_a": "raise_front_both", "/robot_b": "rotate_cw_both"}


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

        def enough() -> bool:
            assert all(p.poll() is None for p in pipelines.values()), f"a pipeline stopped:\n{logs()}"
            return all(len(commands[ns]) >= 8 for ns in MOTIONS)

        probe.spin_until(enough, 45, lambda: f"8 uncompensated commands per robot:\n{logs()}")
        node = probe.node
        for ns in MOTIONS:
            # each shared topic has its own pipeline's publisher, and only its own pipeline's subscribers
            for topic, publisher in ((f"{ns}/arm_angles", "angle_extractor"), (f"{ns}/predictions", "gwr_hierarchy")):
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
        frames = {ns: np.stack([messages.read_joint_state(m)[2] for m in angles[ns]]) for ns in MOTIONS}
        for ns, other in (("/robot_a", "/robot_b"), ("/robot_b", "/robot_a")):
            for msg in commands[ns]:
                values = messages.read_joint_state(msg)[2]
                own = np.abs(frames[ns] - values).max(axis=1).min()
                theirs = np.abs(frames[other] - values).max(axis=1).min()
                assert own < 1e-9 < theirs, f"{ns}: a command {own=} {theirs=}"
    finally:
        for proc in pipelines.values():
            stop(proc)
        probe.close()
        release_domain_id(domain)
    for ns, proc in pipelines.items():
        assert proc.returncode in (0, 130), f"{ns}: run_pipeline.sh exit code {proc.returncode}"
