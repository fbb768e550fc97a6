"""Latency percentiles and message loss computed from a bag alone (gwr_predictor.pipeline.message_latency): a synthetic
recording with known delays and known final counters gives exactly those numbers."""

import json

import numpy as np
import pytest

from gwr_predictor.commands.cli import main as cli_main
from gwr_predictor.pipeline import bag_messages, bag_writer, conventions
from gwr_predictor.pipeline.message_latency import (
    TopicSeries,
    command_hop,
    extractor_hop,
    latency_report,
    latency_stats,
    same_stamp_hop,
)
from gwr_predictor.robot.nao import ARM_JOINTS

T = bag_messages.TYPESTORE.types
DIAGNOSTICS = "diagnostic_msgs/msg/DiagnosticArray"
TOPICS = {f"/{name}": msgtype for name, msgtype in conventions.TOPIC_TYPES.items()}
SKEL_DELAY, EXTRACT_DELAY, LEARN_DELAY, COMP_DELAY, TRANSIT = 0.004, 0.003, 0.020, 0.001, 0.002


def diagnostics_msg(stamp: float, name: str, values: dict[str, int]):
    status = T["diagnostic_msgs/msg/DiagnosticStatus"](
        level=0, name=name, message="", hardware_id="",
        values=[T["diagnostic_msgs/msg/KeyValue"](key=k, value=str(v)) for k, v in values.items()])
    header = T["std_msgs/msg/Header"](stamp=bag_messages.time_msg(stamp), frame_id="")
    return T["diagnostic_msgs/msg/DiagnosticArray"](header=header, status=[status])


def write_run(path, n_groups: int = 30, lose_predictions: int = 0, learner: str = conventions.LEARNER_NODE):
    """Skeletons at 30 fps from t=100 s; every group of 3 -> angles stamped with its middle frame,
    received EXTRACT_DELAY after the group's third skeleton; predictions LEARN_DELAY after the angles;
    a command COMP_DELAY after each prediction. Final counters: what was published."""
    ns = 1_000_000_000
    rows = []
    skel_t = 100.0 + np.arange(3 * n_groups) / 30.0
    for t in skel_t:
        rows.append(("/skeleton", t + SKEL_DELAY,
                     bag_messages.multiarray_msg(conventions.pack_skeleton(t, np.zeros((15, 3))))))
    n_pred = 0
    for g in range(n_groups):
        middle, third = skel_t[3 * g + 1], skel_t[3 * g + 2]
        angles_recv = third + SKEL_DELAY + EXTRACT_DELAY
        rows.append(("/arm_angles", angles_recv, bag_messages.joint_state_msg(ARM_JOINTS, np.zeros(8), middle)))
        pred_recv = angles_recv + LEARN_DELAY
        if g >= n_groups - lose_predictions:
            continue  # published but never recorded
        n_pred += 1
        packed = conventions.pack_predictions(middle, np.zeros((6, 8)))
        rows.append(("/predictions", pred_recv, bag_messages.multiarray_msg(packed)))
        rows.append(("/predicted_angles", pred_recv,
                     bag_messages.joint_state_msg(ARM_JOINTS, np.zeros(8), middle + 0.6)))
        rows.append(("/joint_commands", pred_recv + COMP_DELAY + TRANSIT,
                     bag_messages.joint_state_msg(ARM_JOINTS, np.zeros(8), pred_recv + COMP_DELAY)))
    end = skel_t[-1] + 1.0
    final = {
        "/skeleton_source": {"frames.published": len(skel_t)},
        "/angle_extractor": {"skeleton.accepted": len(skel_t) - 2, "rejected.skeleton.stamp": 2,
                             "angles.published": n_groups},
        f"/{learner}": {"frames.learned": n_groups, "predictions.published": n_groups},
        "/delay_compensator": {"arm_angles.received": n_groups, "predictions.received": n_pred,
                               "commands.published": n_pred},
        "/nao_sim": {"commands.accepted": n_pred, "states.published": 0},
    }
    for name, values in final.items():
        start = skel_t[0] - 0.5  # the first snapshot, before anything was published
        rows.append(("/diagnostics", start, diagnostics_msg(start, name, dict.fromkeys(values, 0))))
        rows.append(("/diagnostics", end, diagnostics_msg(end, name, values)))
    with bag_writer.BagWriter(path, TOPICS) as writer:
        for topic, recv, msg in sorted(rows, key=lambda r: r[1]):
            writer.write(topic, round(recv * ns), msg)
    return path


def test_percentiles_of_known_values():
    s = latency_stats(np.arange(1, 101) / 1000.0)
    assert (s.n, s.max) == (100, 0.1)
    assert s.p50 == pytest.approx(0.0505) and s.p90 == pytest.approx(0.0901) and s.p99 == pytest.approx(0.09901)
    empty = latency_stats([np.nan])
    assert empty.n == 0 and np.isnan(empty.p50)


def test_each_hop_is_measured_from_the_source_stamp_and_the_receive_times(tmp_path):
    report = latency_report(write_run(tmp_path / "bag"))
    lat = {k: v for k, v in report.latencies.items()}
    assert lat["source -> skeleton"].p50 == pytest.approx(SKEL_DELAY, abs=1e-6)
    assert lat["hop angle_extractor"].max == pytest.approx(EXTRACT_DELAY, abs=1e-6)
    assert lat["hop angle_extractor"].n == 30
    # the angles are stamped with the middle frame: one skeleton period more than the hops
    assert lat["source -> arm_angles"].p50 == pytest.approx(1 / 30 + SKEL_DELAY + EXTRACT_DELAY, abs=1e-6)
    assert lat["hop arm_predictor"].p99 == pytest.approx(LEARN_DELAY, abs=1e-6)
    assert lat["hop delay_compensator"].p50 == pytest.approx(COMP_DELAY, abs=1e-6)
    assert lat["joint_commands transit"].p50 == pytest.approx(TRANSIT, abs=1e-6)
    assert lat["source -> joint_commands"].max == pytest.approx(
        1 / 30 + SKEL_DELAY + EXTRACT_DELAY + LEARN_DELAY + COMP_DELAY + TRANSIT, abs=1e-6)
    assert report.total_lost == 0
    counts = {(c.topic, c.consumer): c for c in report.counts}
    assert counts[("/skeleton", "angle_extractor")].consumed == 90  # accepted + rejected = received
    assert all(c.lost_recorder == 0 for c in report.counts)


def test_lost_messages_are_counted_per_hop(tmp_path):
    report = latency_report(write_run(tmp_path / "bag", lose_predictions=3))
    pred = next(c for c in report.counts if c.topic == "/predictions")
    assert (pred.published, pred.recorded, pred.consumed) == (30, 27, 27)
    assert (pred.lost_recorder, pred.lost_consumer) == (3, 3)
    assert report.total_lost == 3 + 3 + 3  # predictions (recorder, compensator), predicted_angles (recorder)


def test_a_run_of_the_learners_deprecated_executable_counts_under_its_old_name(tmp_path):
    # bags recorded before the rename (and by the deprecated executable) hold the old name's statuses
    report = latency_report(write_run(tmp_path / "bag", lose_predictions=3, learner="gwr_hierarchy"))
    counts = {(c.topic, c.publisher): c for c in report.counts}
    pred = counts[("/predictions", "gwr_hierarchy")]
    assert (pred.published, pred.recorded, pred.lost_recorder) == (30, 27, 3)
    learned = next(c for c in report.counts if c.topic == "/arm_angles" and c.consumer == "gwr_hierarchy")
    assert (learned.published, learned.consumed) == (30, 30)
    assert report.total_lost == 3 + 3 + 3


def test_a_bag_without_final_counters_reports_unknown_published_counts(tmp_path):
    path = tmp_path / "bare"
    with bag_writer.BagWriter(path, {"/skeleton": bag_messages.FLOAT64_MULTIARRAY}) as writer:
        writer.write("/skeleton", 1_000_000_000,
                     bag_messages.multiarray_msg(conventions.pack_skeleton(0.5, np.zeros((15, 3)))))
    report = latency_report(path)
    assert report.latencies["source -> skeleton"].p50 == pytest.approx(0.5)
    assert [(c.topic, c.published, c.recorded) for c in report.counts] == [("/skeleton", None, 1)]
    assert report.total_lost == 0


def test_hops_pair_messages_by_stamp_not_by_position():
    skel = TopicSeries(np.array([1.01, 1.05, 1.08]), np.array([1.0, 1.0333, 1.0667]))
    angles = TopicSeries(np.array([1.09]), np.array([1.0333]))
    np.testing.assert_allclose(extractor_hop(skel, angles), [0.01])
    preds = TopicSeries(np.array([2.0, 1.2]), np.array([5.0, 1.0333]))  # 5.0: no angles with that stamp
    np.testing.assert_allclose(same_stamp_hop(angles, preds), [0.11])
    # the recorder got the command (stamped 1.201) before the prediction (1.202): still paired
    cmds = TopicSeries(np.array([1.2015, 3.0]), np.array([1.201, 2.9]))
    hop, total = command_hop(TopicSeries(np.array([1.202]), np.array([1.0333])), cmds)
    np.testing.assert_allclose(hop, [-0.001])
    np.testing.assert_allclose(total, [1.2015 - 1.0333])


def test_latency_command_prints_writes_json_and_fails_on_loss(tmp_path, capsys):
    run = tmp_path / "run"
    write_run(run / "bag", lose_predictions=1)
    assert cli_main(["latency", str(run)]) == 0
    out = capsys.readouterr().out
    assert "hop arm_predictor" in out and "messages lost: 3 (" in out
    saved = json.loads((run / "latency.json").read_text())
    assert saved["total_lost"] == 3
    assert saved["latency_ms"]["hop arm_predictor"]["p50"] == pytest.approx(1e3 * LEARN_DELAY, abs=1e-3)
    assert cli_main(["latency", str(run), "--max-lost", "2"]) == 3
    assert "3 messages lost" in capsys.readouterr().err
    assert cli_main(["latency", str(tmp_path / "nothing")]) == 1
    assert "nothing" in capsys.readouterr().err


@pytest.mark.parametrize(("recorded_after", "lost"), [(7, 0), (6, 1)])
def test_the_recorder_loss_counts_from_the_publishers_first_diagnostics(tmp_path, recorded_after, lost):
    """States published before the recorder matched (volatile QoS: never delivered) are not a loss."""
    path = tmp_path / "bag"
    rows = [(1.0 + 0.02 * k, k) for k in range(3)]  # 2 of the first 5 never reached the recorder
    rows += [(2.0 + 0.02 * k, k) for k in range(recorded_after)]
    with bag_writer.BagWriter(path, {"/joint_states": bag_messages.JOINT_STATE, "/diagnostics": DIAGNOSTICS}) as writer:
        writer.write("/diagnostics", 1_500_000_000, diagnostics_msg(1.5, "/nao_sim", {"states.published": 5}))
        for recv, _ in rows:
            writer.write("/joint_states", round(recv * 1e9),
                         bag_messages.joint_state_msg(ARM_JOINTS, np.zeros(8), recv))
        writer.write("/diagnostics", 3_000_000_000, diagnostics_msg(3.0, "/nao_sim", {"states.published": 12}))
    states = next(c for c in latency_report(path).counts if c.topic == "/joint_states")
    assert (states.published, states.published_early, states.recorded_after) == (12, 5, recorded_after)
    assert states.lost_recorder == lost
