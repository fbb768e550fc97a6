"""Issue 15 on real node processes: hostile stamps, paths and start-up arguments.

No single message can silence a node (a stamp far in the future, a NaN stamp); the compensator
keeps commanding (its fallback fires); the checkpoint place is checked at start and a failed save
shows as ERROR on /diagnostics; bad params files, names and parameters stop a node with exit 2.
"""

import math
import shutil
import time

import numpy as np
import pytest
from test_node_bad_input import FAST, POSE, joint_state, skeleton, wait_counters

from gwr_predictor.data.demonstrator import default_subjects, demonstrate_one
from gwr_predictor.nodes import messages
from gwr_predictor.nodes.messages import DiagnosticArray, Float64MultiArray, JointState
from gwr_predictor.registry import DEFAULT_PREDICTOR, make_predictor

POISON_S = 1e6  # the "now + 1e6 s"


@pytest.mark.ros
def test_one_poisoned_stamp_silences_no_node_and_the_compensator_keeps_commanding(ros):
    probe = ros.probe
    diagnostics = probe.subscribe_diagnostics()
    procs = [
        ros.start("angle_extractor", params=FAST, remaps={"arm_angles": "/extracted"}),
        ros.start("arm_predictor", params=FAST, remaps={"arm_angles": "/h_angles", "predictions": "/h_preds"}),
        ros.start("delay_compensator", params=FAST, remaps={"arm_angles": "/c_angles", "predictions": "/c_preds",
                                                            "joint_commands": "/c_cmds"}),
        ros.start("nao_sim", params={**FAST, "backend": "kinematic"}, remaps={"joint_commands": "/n_cmds"}),
    ]
    for name in ("/angle_extractor", "/arm_predictor", "/delay_compensator", "/nao_sim"):
        ros.wait_for_node(diagnostics, name, timeout=60)
    extracted = probe.subscribe("/extracted", JointState)
    commands = probe.subscribe("/c_cmds", JointState)
    skel_pub = probe.publisher("/skeleton", Float64MultiArray)
    learner_pub = probe.publisher("/h_angles", JointState)
    obs_pub = probe.publisher("/c_angles", JointState)
    preds_pub = probe.publisher("/c_preds", Float64MultiArray)
    cmd_pub = probe.publisher("/n_cmds", JointState)
    for pub in (skel_pub, learner_pub, obs_pub, preds_pub, cmd_pub):
        probe.wait_for_subscribers(pub)
    frame = demonstrate_one("wave_both", default_subjects(1)[0], 1).positions[10]
    now = time.time()
    preds = np.tile(POSE, (6, 1))

    # skeleton: 3 good frames, a poisoned and a NaN stamp, 3 good frames -> 2 JointStates
    for k in range(3):
        skel_pub.publish(skeleton(now - 1.0 + k / 30, frame))
    skel_pub.publish(skeleton(now + POISON_S, frame))
    skel_pub.publish(skeleton(math.nan, frame))
    for k in range(3, 6):
        skel_pub.publish(skeleton(now - 1.0 + k / 30, frame))
    # learner: 5 frames, a poisoned one, 5 frames -> all 10 genuine ones learned
    for k in range(5):
        learner_pub.publish(joint_state(now - 2.0 + 0.1 * k))
    learner_pub.publish(joint_state(now + POISON_S))
    for k in range(5, 10):
        learner_pub.publish(joint_state(now - 2.0 + 0.1 * k))
    # robot: a command, a poisoned one, a command
    cmd_pub.publish(joint_state(now - 0.2))
    cmd_pub.publish(joint_state(now + POISON_S))
    cmd_pub.publish(joint_state(now - 0.1))
    # compensator: an observation, then predictions stamped far ahead and NaN: rejected, and the
    # observations that follow are still commanded (the fallback fires), then a genuine prediction is used
    obs_pub.publish(joint_state(time.time()))
    probe.spin_for(0.3)
    preds_pub.publish(messages.predictions_msg(time.time() + POISON_S, preds))
    preds_pub.publish(messages.predictions_msg(math.nan, preds))
    probe.spin_for(0.3)
    before = len(commands)
    for _ in range(5):
        obs_pub.publish(joint_state(time.time()))
        probe.spin_for(0.15)
    probe.spin_until(lambda: len(commands) >= before + 5, 10, "a fallback command for every observation", procs)
    preds_pub.publish(messages.predictions_msg(time.time(), preds))

    wait_counters(ros, diagnostics, "/angle_extractor", {
        "rejected.skeleton.stamp_ahead": 1, "rejected.skeleton.stamp": 1, "angles.published": 2}, procs)
    assert len(extracted) == 2
    wait_counters(ros, diagnostics, "/arm_predictor", {
        "rejected.arm_angles.stamp_ahead": 1, "frames.learned": 10}, procs)
    wait_counters(ros, diagnostics, "/nao_sim", {
        "rejected.joint_commands.stamp_ahead": 1, "commands.accepted": 2}, procs)
    wait_counters(ros, diagnostics, "/delay_compensator", {
        "rejected.predictions.stamp_ahead": 1, "rejected.predictions.stamp": 1, "predictions.received": 1,
        "arm_angles.received": 6}, procs)
    assert int(diagnostics["/delay_compensator"]["fallback.no_predictions"]) >= 6
    assert all(proc.running() for proc in procs)


@pytest.mark.ros
@pytest.mark.parametrize("place", ["folder", "user_file", "proc"])
def test_a_checkpoint_place_that_is_not_ours_or_not_writable_is_refused_at_start(ros, tmp_path, place):
    if place == "folder":
        target = tmp_path / "my_models"
        target.mkdir()
        (target / "notes.txt").write_text("mine")
    elif place == "user_file":
        target = tmp_path / "thesis.txt"
        target.write_text("three years of work")
    else:
        target = "/proc/self/gwr_model.npz"  # a place no one can write
    before = sorted(p.name for p in tmp_path.rglob("*"))
    code, output = ros.run("arm_predictor", params={**FAST, "checkpoint": str(target)}, timeout=60)
    assert code == 1, output
    assert "parameter 'checkpoint'" in output and "ready" not in output
    if place != "proc":
        assert sorted(p.name for p in tmp_path.rglob("*") if not p.name.endswith(".log")) == \
            [n for n in before if not n.endswith(".log")]  # nothing moved aside, nothing written
    if place == "folder":
        assert (target / "notes.txt").read_text() == "mine"
        assert "is an existing folder" in output
    if place == "user_file":
        assert target.read_text() == "three years of work"
        assert "not a gwr_predictor checkpoint" in output


@pytest.mark.ros
def test_stale_temp_files_are_removed_and_a_failed_save_is_an_error_on_diagnostics(ros, tmp_path):
    folder = tmp_path / "models"
    folder.mkdir()
    checkpoint = folder / "model.npz"
    make_predictor(DEFAULT_PREDICTOR).save(checkpoint)  # a checkpoint of the node's default predictor
    stale = [folder / ".model.npz.abc123.tmp", folder / ".model.npz.x.tmp"]
    for path in stale:
        path.write_bytes(b"half a save")
    (folder / ".other.npz.y.tmp").write_bytes(b"not ours")
    statuses = ros.probe.subscribe("/diagnostics", DiagnosticArray)
    diagnostics = ros.probe.subscribe_diagnostics()
    learner = ros.start("arm_predictor", params={**FAST, "checkpoint": str(checkpoint),
                                                 "checkpoint_interval_s": 0.5})
    ros.wait_for_node(diagnostics, "/arm_predictor", timeout=60)
    assert not any(path.exists() for path in stale)
    assert (folder / ".other.npz.y.tmp").exists()
    assert diagnostics["/arm_predictor"]["checkpoint.stale_temp_removed"] == "2"
    ros.probe.spin_until(lambda: int(diagnostics["/arm_predictor"].get("checkpoint.saved", "0")) >= 1, 20,
                         "a periodic save", [learner])
    shutil.rmtree(folder)
    folder.write_text("the folder is gone: every save fails")  # works as root too (unlike chmod)

    def error_seen() -> bool:
        return any(s.name == "/arm_predictor" and s.level == messages.ERROR for m in statuses for s in m.status)

    ros.probe.spin_until(error_seen, 20, "an ERROR status after the failed save", [learner])
    status = next(s for m in statuses for s in m.status if s.name == "/arm_predictor" and s.level == messages.ERROR)
    assert "checkpoint save failed" in status.message
    code, _ = learner.stop()
    assert code == 1  # the final save failed too


@pytest.mark.ros
def test_bad_start_up_arguments_exit_2_with_a_message_and_unknown_names_are_warned(ros, tmp_path):
    bad_yaml = tmp_path / "bad.yaml"
    bad_yaml.write_text("arm_predictor:\n  ros__parameters:\n    horizon: [6\n")
    no_section = tmp_path / "flat.yaml"
    no_section.write_text("horizon: 6\n")
    cases = [
        ({"params": {"horizon": 101}}, "parameter 'horizon' = 101"),
        ({"params_file": tmp_path / "missing.yaml"}, "no such file"),
        ({"params_file": bad_yaml}, "not valid YAML at line"),
        ({"params_file": no_section}, "ros__parameters"),
        ({"remaps": {"arm_angles": "my angles"}}, "bad ROS arguments"),
    ]
    for kwargs, message in cases:
        code, output = ros.run("arm_predictor", timeout=60, **kwargs)
        assert code == 2, (kwargs, output)
        assert message in output and "Traceback" not in output, (kwargs, output)
    code, output = ros.run("bag_recorder", params={"path": str(tmp_path / "bag"), "topics": ["my topic"]}, timeout=60)
    assert code == 2 and "Traceback" not in output and "my topic" in output, output

    typo = tmp_path / "typo.yaml"
    typo.write_text("/**/delay_compensator:\n  ros__parameters:\n    stale_after_z: 1.0\n    horizon: 6\n")
    comp = ros.start("delay_compensator", params_file=typo, params={**FAST, "delay_sec": 0.3})
    ros.wait_for_log(comp, "ready")
    out = comp.output()
    assert "'stale_after_z' is not a parameter of this node" in out and "did you mean 'stale_after_s'" in out
    assert "'horizon' is not a parameter of this node" in out
    assert "'delay_sec' is not a parameter of this node" in out and "'delay_s'" in out
    code, _ = comp.stop()
    assert code == 0


@pytest.mark.ros
def test_the_joint_name_cache_of_angle_extractor_is_bounded():
    """A stream of ever new joint-name lists (in-process: the node's own method) keeps memory flat."""
    import rclpy
    from ros_harness import allocate_domain_id, release_domain_id

    from gwr_predictor.nodes.angle_extractor import AngleExtractorNode
    from gwr_predictor.pipeline.conventions import SKELETON_JOINTS

    domain = allocate_domain_id()
    rclpy.init(args=["--ros-args"], domain_id=domain)
    try:
        node = AngleExtractorNode()
        positions = np.zeros((len(SKELETON_JOINTS) + 1, 3))
        for k in range(500):
            names = (*SKELETON_JOINTS, f"extra_{k}")
            out = node.reorder(names, positions)
            assert out.shape == (len(SKELETON_JOINTS), 3)
        size = node.reorder.cache_size
        assert len(node.reorder._order) <= size
        assert node.counters.get("skeleton.name_cache_evictions") == 500 - size
        node.destroy_node()
    finally:
        rclpy.try_shutdown()
        release_domain_id(domain)


@pytest.mark.ros
def test_a_second_pipeline_on_the_same_domain_is_detected_and_stops(ros):
    first = ros.start_ready("angle_extractor", label="first", params=FAST)
    second = ros.start("angle_extractor", label="second", params=FAST)
    code = second.wait(30)
    assert code == 1, second.output()
    assert "another /angle_extractor" in second.output() and "ROS_DOMAIN_ID" in second.output()
    ros.probe.spin_for(1.5)
    assert first.running(), first.output()  # the one that was there first goes on
    assert "another" not in first.output()
    code, _ = first.stop()
    assert code == 0


@pytest.mark.ros
def test_bag_player_skips_undecodable_messages_and_replays_the_rest(ros, tmp_path):
    from test_hostile_bags import angles_bag

    bag = angles_bag(tmp_path / "bag", n=20, garbage_at=(5, 6))
    code, output = ros.run("bag_player", params={**FAST, "bag": str(bag), "restamp": True}, timeout=60)
    assert code == 0, output
    assert "2 messages on /arm_angles do not decode: skipped" in output
    assert "18 messages published" in output
