"""Issue 15, bags and files: undecodable messages are skipped and counted, a truncated .mcap with a
metadata.yaml is recovered, a metadata.yaml that lies is an error, loss accounting survives node
restarts and names two pipelines on one domain, and oversized files are refused before reading."""

import zipfile

import numpy as np
import pytest

from gwr_predictor.commands.cli import main as cli_main
from gwr_predictor.data.errors import DataError
from gwr_predictor.data.skeleton_files import load_skeleton
from gwr_predictor.files import limits
from gwr_predictor.learning.checkpoint import read_checkpoint
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.pipeline import bag_messages, bag_reader, bag_recovery, bag_writer
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.message_latency import latency_report
from gwr_predictor.pipeline.run_report import read_run
from gwr_predictor.robot.nao import ARM_JOINTS

T = bag_messages.TYPESTORE.types
DIAGNOSTICS = "diagnostic_msgs/msg/DiagnosticArray"
GARBAGE = b"\x00\x01\x00\x00\xff\xff\xff\x7fnot a JointState"


def diagnostics_msg(stamp: float, name: str, values: dict[str, int], instance: str = ""):
    values = {**values, "instance": instance} if instance else values
    status = T["diagnostic_msgs/msg/DiagnosticStatus"](
        level=0, name=name, message="", hardware_id="host",
        values=[T["diagnostic_msgs/msg/KeyValue"](key=k, value=str(v)) for k, v in values.items()])
    header = T["std_msgs/msg/Header"](stamp=bag_messages.time_msg(stamp), frame_id="")
    return T[DIAGNOSTICS](header=header, status=[status])


def angles_bag(path, n: int = 20, garbage_at: tuple[int, ...] = (), flush_every: int = 0):
    with bag_writer.BagWriter(path, {"/arm_angles": bag_messages.JOINT_STATE, "/diagnostics": DIAGNOSTICS},
                        flush_every=flush_every) as writer:
        for k in range(n):
            t = 10.0 + 0.1 * k
            if k in garbage_at:
                writer.write_raw("/arm_angles", round(t * 1e9), GARBAGE)
            else:
                writer.write("/arm_angles", round(t * 1e9), bag_messages.joint_state_msg(ARM_JOINTS, np.zeros(8), t))
    return path


def test_undecodable_messages_are_skipped_counted_and_reported(tmp_path, capsys):
    path = angles_bag(tmp_path / "bag", garbage_at=(3, 11))
    with pytest.raises(PipelineError, match=r"cannot decode .*/arm_angles"):
        list(bag_reader.read_bag(path))  # strict by default
    skipped: dict[str, int] = {}
    assert len(list(bag_reader.read_bag(path, undecodable=skipped))) == 18
    assert skipped == {"/arm_angles": 2}
    assert latency_report(path).undecodable == {"/arm_angles": 2}
    assert read_run(path).rejected["bag:undecodable./arm_angles"] == 2
    assert cli_main(["latency", str(path), "--out", str(tmp_path)]) == 0
    assert "undecodable messages skipped: /arm_angles 2" in capsys.readouterr().out


def test_a_metadata_yaml_that_lies_makes_latency_and_report_fail(tmp_path, capsys):
    path = angles_bag(tmp_path / "bag")
    meta = path / "metadata.yaml"
    text = meta.read_text()
    assert "message_count: 20" in text
    meta.write_text(text.replace("message_count: 20", "message_count: 25"))
    assert cli_main(["latency", str(path), "--out", str(tmp_path)]) == 1
    assert "metadata.yaml does not match" in capsys.readouterr().err
    with pytest.raises(PipelineError, match="metadata 25, file 20"):
        read_run(path)


def test_a_truncated_mcap_with_metadata_is_recovered_and_its_metadata_rewritten(tmp_path):
    path = angles_bag(tmp_path / "bag", n=40, flush_every=10)
    mcap = next(path.glob("*.mcap"))
    data = mcap.read_bytes()
    mcap.write_bytes(data[: len(data) * 2 // 3])  # a disk that filled up, a copy cut short
    with pytest.raises(PipelineError):
        list(bag_reader.read_bag(path))
    info = bag_recovery.recover_bag(path)
    assert 10 <= info.message_count < 40 and info.message_count % 10 == 0
    assert len(list(bag_reader.read_bag(path))) == info.message_count
    assert (path / "metadata.yaml.damaged").is_file() and (mcap.parent / (mcap.name + ".damaged")).is_file()
    assert bag_recovery.recover_bag(path) == info  # now sound: left alone


def restart_bag(path, concurrent: bool):
    """angle_extractor publishes 10 angles, is restarted (counters from 0) and publishes 10 more; the
    learner consumes them all. With `concurrent`, the two instances run at the same time instead."""
    rows = []
    first, second = (0.0, 5.0) if not concurrent else (0.0, 0.5)
    for base, inst in ((first, "a"), (second, "b")):
        rows.append((10.0 + base, "/diagnostics",
                     diagnostics_msg(0, "/angle_extractor", {"angles.published": 0}, inst)))
        for k in range(10):
            t = 10.2 + base + 0.1 * k
            rows.append((t, "/arm_angles", bag_messages.joint_state_msg(ARM_JOINTS, np.zeros(8), t)))
        rows.append((11.4 + base, "/diagnostics",
                     diagnostics_msg(0, "/angle_extractor", {"angles.published": 10}, inst)))
    rows.append((9.0, "/diagnostics", diagnostics_msg(0, "/arm_predictor", {"frames.learned": 0}, "L")))
    rows.append((20.0, "/diagnostics", diagnostics_msg(0, "/arm_predictor", {"frames.learned": 20}, "L")))
    with bag_writer.BagWriter(path, {"/arm_angles": bag_messages.JOINT_STATE, "/diagnostics": DIAGNOSTICS}) as writer:
        for t, topic, msg in sorted(rows, key=lambda r: r[0]):
            writer.write(topic, round(t * 1e9), msg)
    return path


def test_a_restarted_node_counts_with_every_instance_and_loses_nothing(tmp_path):
    report = latency_report(restart_bag(tmp_path / "bag", concurrent=False))
    hop = next(c for c in report.counts if c.topic == "/arm_angles" and c.consumer == "arm_predictor")
    assert (hop.published, hop.recorded, hop.consumed, hop.instances) == (20, 20, 20, 2)
    assert (hop.lost_recorder, hop.lost_consumer) == (0, 0)
    assert report.total_lost == 0
    assert any("restarted during the run" in line and "angle_extractor" in line for line in report.summary_lines())


def test_two_instances_at_once_are_named_and_no_consumer_loss_is_invented(tmp_path):
    report = latency_report(restart_bag(tmp_path / "bag", concurrent=True))
    hop = next(c for c in report.counts if c.topic == "/arm_angles" and c.consumer == "arm_predictor")
    assert hop.concurrent and hop.lost_consumer is None
    assert hop.published == 20 and hop.lost_recorder == 0
    assert any("two instances of a node ran at once" in line for line in report.summary_lines())


def test_files_that_cannot_be_recordings_are_refused_before_reading(tmp_path, monkeypatch):
    bomb = tmp_path / "bomb.npz"
    with zipfile.ZipFile(bomb, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("positions.npy", b"\0" * (8 << 20))  # 8 MB of zeros: a few KB on disk
    assert bomb.stat().st_size < 100_000
    monkeypatch.setattr("gwr_predictor.data.skeleton_files.MAX_RECORDING_BYTES", 4 << 20)
    with pytest.raises(DataError, match=r"bomb.npz: its arrays inflate to 8 MB.*refused before reading"):
        load_skeleton(bomb)
    big_csv = tmp_path / "big.csv"
    big_csv.write_bytes(b"t" * (3 << 20))
    monkeypatch.setattr("gwr_predictor.data.skeleton_files.MAX_CSV_BYTES", 2 << 20)
    with pytest.raises(DataError, match=r"big.csv: 3 MB is too large"):
        load_skeleton(big_csv)
    monkeypatch.setattr("gwr_predictor.learning.checkpoint.MAX_CHECKPOINT_BYTES", 4 << 20)
    with pytest.raises(LearningError, match="inflate to 8 MB"):
        read_checkpoint(bomb, "Hierarchy")
    assert limits.MAX_RECORDING_BYTES >= 200 << 20  # an hour at 30 fps is about 39 MB of positions
