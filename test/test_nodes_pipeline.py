"""The real multi-process pipeline over DDS: skeleton_source -> angle_extractor -> arm_predictor ->
delay_compensator -> nao_sim (PyBullet), recorded by bag_recorder; clean SIGTERM with checkpoint."""

import signal
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from gwr_predictor.data import faults
from gwr_predictor.data.demonstrator import default_subjects, demonstrate_one
from gwr_predictor.data.skeleton_files import save_skeleton
from gwr_predictor.default_predictor.gate import inner_model
from gwr_predictor.learning.hierarchy import Hierarchy
from gwr_predictor.learning.params import HierarchyParams
from gwr_predictor.nodes import messages
from gwr_predictor.nodes.messages import DiagnosticArray, Float64MultiArray, JointState
from gwr_predictor.pipeline import bag_reader
from gwr_predictor.pipeline.conventions import NEURON_KEYS, SKELETON_JOINTS, TOPIC_TYPES
from gwr_predictor.pipeline.run_report import compute_report, read_run
from gwr_predictor.registry import DEFAULT_PREDICTOR, load_predictor
from gwr_predictor.robot.nao import ARM_JOINTS

FAST = {"diagnostics_period_s": 0.5}
RUN_S = 14.0


def neurons(status_msg) -> dict:
    """Neurons per layer of the learner's status (the default predictor has one layer, pgwr)."""
    values = next(iter(messages.read_diagnostics(status_msg).values()))
    return {layer: int(values[key]) for layer, key in NEURON_KEYS.items() if key in values}


@pytest.mark.ros
@pytest.mark.slow
def test_pipeline_flows_learns_moves_the_robot_and_records(ros, tmp_path):
    probe = ros.probe
    diagnostics = probe.subscribe_diagnostics()
    got = {
        "skeleton": probe.subscribe("/skeleton", Float64MultiArray),
        "arm_angles": probe.subscribe("/arm_angles", JointState),
        "predictions": probe.subscribe("/predictions", Float64MultiArray),
        "predicted_angles": probe.subscribe("/predicted_angles", JointState),
        "joint_commands": probe.subscribe("/joint_commands", JointState),
        "joint_states": probe.subscribe("/joint_states", JointState),
        "learner_status": probe.subscribe("/learner_status", DiagnosticArray),
    }
    checkpoint = tmp_path / "model.npz"
    recorder = ros.start("bag_recorder", params={**FAST, "path": str(tmp_path / "bag")})
    ros.wait_for_node(diagnostics, "/bag_recorder", timeout=60)
    procs = [recorder,
             ros.start("nao_sim", params=FAST),
             ros.start("delay_compensator", params=FAST),
             # BLAS as a 2-core machine's default would run it: the learner pins it to one thread
             ros.start("arm_predictor", params={**FAST, "checkpoint": str(checkpoint), "status_period_s": 0.5,
                                                "checkpoint_interval_s": 2.0}, env={"OPENBLAS_NUM_THREADS": "2"}),
             ros.start("angle_extractor", params=FAST)]
    for name in ("/nao_sim", "/delay_compensator", "/arm_predictor", "/angle_extractor"):
        ros.wait_for_node(diagnostics, name, timeout=60)
    source = ros.start("skeleton_source", params={**FAST, "patterns": ["wave_both", "raise_front_both"],
                                                  "repetitions": 1, "loop": True, "pause_s": 0.7,
                                                  "wait_for_subscribers": 3})  # extractor, recorder, probe
    procs.append(source)
    probe.spin_until(lambda: len(got["skeleton"]) > 0, 60, "the first skeleton", procs)
    probe.spin_for(RUN_S)

    # every topic carries messages of the right layout
    n_skel = len(got["skeleton"])
    assert n_skel > 0.6 * 30 * RUN_S
    _, names, positions = messages.read_skeleton(got["skeleton"][-1])
    assert names == SKELETON_JOINTS and positions.shape == (15, 3)
    angle_stamps = [messages.read_joint_state(m)[0] for m in got["arm_angles"]]
    assert all(messages.read_joint_state(m)[1] == ARM_JOINTS for m in got["arm_angles"])
    assert abs(len(angle_stamps) - n_skel / 3) <= 6  # median of 3, a partial group per sequence
    assert np.all(np.diff(angle_stamps) > 0)
    preds = [messages.read_predictions(m) for m in got["predictions"]]
    assert len(preds) > 0.5 * len(angle_stamps)
    assert all(p[1] == ARM_JOINTS and p[2].shape == (6, 8) for p in preds)
    assert {p[0] for p in preds} <= set(angle_stamps)  # stamped with the frame they were made at
    ahead = [messages.read_joint_state(m) for m in got["predicted_angles"]]
    np.testing.assert_allclose([a[0] for a in ahead[:len(preds)]], [p[0] + 0.6 for p in preds[:len(ahead)]],
                               atol=1e-6)
    np.testing.assert_allclose(ahead[-1][2], preds[len(ahead) - 1][2][-1])
    commands = [messages.read_joint_state(m) for m in got["joint_commands"]]
    # a command per prediction (plus fallbacks between sequences), but one for what queued behind a busy callback
    assert len(commands) >= 0.8 * len(preds) and all(c[1] == ARM_JOINTS for c in commands)
    states = np.array([messages.read_joint_state(m)[2] for m in got["joint_states"]])
    assert len(states) > 0.7 * 50 * RUN_S
    assert np.max(np.ptp(states, axis=0)) > 0.3  # the robot moves

    # the learner grows while it runs
    counts = [neurons(m) for m in got["learner_status"]]
    assert len(counts) >= RUN_S
    assert sum(counts[-1].values()) > sum(counts[0].values())
    assert counts[-1]["pgwr"] > 10
    last = next(iter(messages.read_diagnostics(got["learner_status"][-1]).values()))
    assert {"mix_weight_local_h6", "mix_weight_global_h6"} <= set(last)  # the default's two read-outs
    assert all(np.isfinite(float(last[k])) for k in ("mix_weight_local_h6", "mix_weight_global_h6"))
    assert 0 <= int(last["neurons_recruited"]) <= counts[-1]["pgwr"]  # the default's recruited neurons
    assert 0 <= int(last["frames_recognised"]) <= int(last["frames"])  # the default's recognition switch
    assert 0 < int(last["snippets_memory"]) <= int(last["frames"])  # its snippet memories fill as it learns
    assert 0 < int(last["snippets_long_memory"]) <= int(last["frames"])
    assert int(last["snippets_replaced_memory"]) == 0
    assert int(last["neurons_evicted"]) == 0  # far below the network's bound
    assert int(last["blas_threads"]) == 1
    # the periodic saves: a snapshot between two frames, written by the saver's thread
    assert float(last["checkpoint_snapshot_ms"]) > 0 and float(last["checkpoint_write_ms"]) > 0
    assert float(last["checkpoint_mb"]) > 0
    assert int(diagnostics["/arm_predictor"]["checkpoint.saved"]) >= 3

    # SIGTERM: clean exit, checkpoint written and loadable, with every learned frame
    learner = procs[3]
    learned = int(diagnostics["/arm_predictor"]["frames.learned"])
    learner.send_signal(signal.SIGTERM)
    assert learner.wait(30) == 0, learner.output()
    assert "SIGTERM received" in learner.output()
    model = load_predictor(DEFAULT_PREDICTOR, checkpoint)
    assert inner_model(model).frames_seen >= learned
    assert model.neuron_counts[-1] >= counts[-1]["pgwr"]

    for proc in reversed(procs):
        code, killed = proc.stop()
        assert code == 0 and not killed, proc.output()
    info = bag_reader.bag_info(tmp_path / "bag")
    recorded = {t.lstrip("/"): n for t, (_, n) in info.topics.items()}
    assert set(recorded) == set(TOPIC_TYPES)
    assert all(n > 0 for n in recorded.values()), recorded
    # an independent reader (mcap + mcap-ros2-support) decodes the standard views from the bag
    first = {}
    with open(next((tmp_path / "bag").glob("*.mcap")), "rb") as f:
        for _, channel, _, msg in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(
                topics=["/robot_description", "/skeleton_markers", "/predicted_trajectory", "/joint_states"]):
            first.setdefault(channel.topic, msg)
    urdf = ET.fromstring(first["/robot_description"].data)
    movable = {j.get("name") for j in urdf.findall("joint") if j.get("type") != "fixed"}
    assert set(first["/joint_states"].name) == movable and len(movable) == 10
    joints, bones = first["/skeleton_markers"].markers
    assert joints.header.frame_id == "skeleton_camera" and len(joints.points) == 15 and len(bones.points) == 30
    assert [p.time_from_start.nanosec for p in first["/predicted_trajectory"].points] == [
        k * 100_000_000 for k in range(1, 7)]
    report = compute_report(read_run(tmp_path / "bag"))
    assert report.scored_predictions > 20
    assert report.robots[""]["mode"] == "guarded"
    assert 0.0 < report.robots[""]["states"]


@pytest.mark.ros
def test_corrupt_checkpoint_is_moved_aside_not_overwritten(ros, tmp_path):
    checkpoint = tmp_path / "model.npz"
    Hierarchy(HierarchyParams.paper()).save(checkpoint)
    truncated = checkpoint.read_bytes()[:200]  # a checkpoint cut short (a crash of another writer)
    checkpoint.write_bytes(truncated)
    diagnostics = ros.diagnostics
    learner = ros.start_ready("arm_predictor", params={**FAST, "checkpoint": str(checkpoint)})
    aside = list(tmp_path.glob("model.npz.corrupt-*"))
    assert len(aside) == 1 and aside[0].read_bytes() == truncated
    assert "unreadable checkpoint moved to" in learner.output()
    assert diagnostics["/arm_predictor"]["checkpoint.corrupt_moved_aside"] == "1"
    code, _ = learner.stop(signal.SIGINT)
    assert code == 0
    fresh = inner_model(load_predictor(DEFAULT_PREDICTOR, checkpoint))
    assert fresh.frames_seen == 0  # the fresh model, saved at shutdown


@pytest.mark.ros
def test_skeleton_source_plays_a_file_with_lost_chunks_and_exits(ros, tmp_path):
    seq = demonstrate_one("raise_front_both", default_subjects(1)[0], 1)
    path = save_skeleton(tmp_path / "person.npz", seq)
    frames = ros.probe.subscribe("/skeleton", Float64MultiArray)
    source = ros.start("skeleton_source", params={**FAST, "source": "file", "file": str(path), "drop_fraction": 0.3,
                                                  "drop_chunk_s": 0.5, "seed": 7, "wait_for_subscribers": 1})
    ros.probe.spin_until(lambda: not source.running(), 30, "the source to finish the file", [source])
    assert source.wait(1) == 0, source.output()
    ros.probe.spin_for(0.3)
    keep = faults.drop_chunks(len(seq.timestamps), 0.3, 15, np.random.default_rng(7))  # as the node draws it
    assert 0 < keep.sum() < len(keep)
    got = [messages.read_skeleton(m) for m in frames]
    assert len(got) == keep.sum()
    stamps = np.array([g[0] for g in got])
    np.testing.assert_allclose(np.diff(stamps), np.diff(seq.timestamps[keep]), atol=1e-6)  # gaps where chunks went
    np.testing.assert_array_equal(np.stack([g[2] for g in got]), seq.positions[keep])
