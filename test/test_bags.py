"""rosbag2/MCAP bags: round trips, independent readers, errors naming the path, crash recovery."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from fakes import FullDisk
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.rosbag2 import Reader

from gwr_predictor.pipeline import bag_messages, bag_reader, bag_recovery, bag_writer
from gwr_predictor.pipeline.conventions import (
    TOPIC_ANGLES,
    TOPIC_PREDICTIONS,
    TOPIC_TYPES,
    pack_predictions,
    unpack_predictions,
)
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.robot.nao import ARM_JOINTS

TOPICS = {TOPIC_ANGLES: TOPIC_TYPES[TOPIC_ANGLES], TOPIC_PREDICTIONS: TOPIC_TYPES[TOPIC_PREDICTIONS]}
T0 = 1_700_000_000_000_000_000


def angles(k: int) -> np.ndarray:
    return np.sin(np.arange(8) + 0.1 * k) * (1.0 + 1e-13 * k)


def write_session(path, frames: int = 20) -> None:
    with bag_writer.BagWriter(path, TOPICS) as writer:
        for k in range(frames):
            stamp = 1_700_000_000.0 + 0.1 * k
            writer.write(TOPIC_ANGLES, T0 + k * 100_000_000, bag_messages.joint_state_msg(ARM_JOINTS, angles(k), stamp))
            preds = np.outer(np.arange(1, 7), angles(k))
            writer.write(TOPIC_PREDICTIONS, T0 + k * 100_000_000 + 1,
                         bag_messages.multiarray_msg(pack_predictions(stamp, preds)))


def test_written_bag_has_rosbag2_metadata_and_counts(tmp_path):
    path = tmp_path / "session"
    write_session(path)
    info = bag_reader.bag_info(path)
    assert info.message_count == 40 and info.storage == "mcap"
    assert info.topics == {TOPIC_ANGLES: (bag_messages.JOINT_STATE, 20),
                           TOPIC_PREDICTIONS: (bag_messages.FLOAT64_MULTIARRAY, 20)}
    assert info.start_ns == T0 and info.end_ns == T0 + 19 * 100_000_000 + 1
    meta = (path / "metadata.yaml").read_text()
    assert "version: 9" in meta and "storage_identifier: mcap" in meta
    with Reader(path) as reader:  # rosbags' own reader agrees
        assert reader.message_count == 40


def test_joint_states_round_trip_exactly(tmp_path):
    path = tmp_path / "session"
    write_session(path)
    got = [bag_messages.joint_state_arrays(m.msg) for m in bag_reader.read_bag(path, [TOPIC_ANGLES])]
    assert len(got) == 20
    for k, (stamp, names, positions) in enumerate(got):
        assert names == ARM_JOINTS
        assert stamp == pytest.approx(1_700_000_000.0 + 0.1 * k, abs=1e-9)
        np.testing.assert_array_equal(positions, angles(k))


def test_prediction_arrays_round_trip_exactly(tmp_path):
    path = tmp_path / "session"
    write_session(path)
    msgs = list(bag_reader.read_bag(path, [TOPIC_PREDICTIONS]))
    for k, m in enumerate(msgs):
        assert m.timestamp_ns == T0 + k * 100_000_000 + 1
        stamp, names, preds = unpack_predictions(bag_messages.packed_array(m.msg))
        assert names == ARM_JOINTS and stamp == 1_700_000_000.0 + 0.1 * k
        np.testing.assert_array_equal(preds, np.outer(np.arange(1, 7), angles(k)))


def test_mcap_ros2_decoder_reads_the_same_messages(tmp_path):
    path = tmp_path / "session"
    write_session(path)
    (mcap_file,) = path.glob("*.mcap")
    with mcap_file.open("rb") as f:
        decoded = [(c.topic, m.log_time, d) for _, c, m, d in
                   make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages()]
    states = [(t, d) for topic, t, d in decoded if topic == TOPIC_ANGLES]
    assert len(decoded) == 40 and len(states) == 20
    np.testing.assert_array_equal(np.asarray(states[5][1].position), angles(5))
    assert list(states[5][1].name) == list(ARM_JOINTS)


def test_raw_cdr_is_stored_unchanged(tmp_path):
    msg = bag_messages.joint_state_msg(ARM_JOINTS, angles(1), 3.25)
    raw = bag_messages.serialize(msg)
    with bag_writer.BagWriter(tmp_path / "raw", {TOPIC_ANGLES: bag_messages.JOINT_STATE}) as writer:
        writer.write_raw(TOPIC_ANGLES, 5, raw)
    (stored,) = bag_reader.read_bag(tmp_path / "raw")
    assert stored.raw == raw and stored.timestamp_ns == 5 and stored.msgtype == bag_messages.JOINT_STATE
    assert writer.messages_written == {TOPIC_ANGLES: 1}


def test_an_exception_inside_the_with_block_still_leaves_a_readable_bag(tmp_path):
    path = tmp_path / "interrupted"
    with pytest.raises(KeyboardInterrupt), bag_writer.BagWriter(path, TOPICS) as writer:
        writer.write(TOPIC_ANGLES, 1, bag_messages.joint_state_msg(ARM_JOINTS, angles(0), 0.0))
        raise KeyboardInterrupt
    assert [m.topic for m in bag_reader.read_bag(path)] == [TOPIC_ANGLES]


def test_existing_path_is_refused_naming_it(tmp_path):
    path = tmp_path / "taken"
    path.mkdir()
    with pytest.raises(PipelineError, match=r"taken.*exists"), bag_writer.BagWriter(path, TOPICS):
        pass


def test_unwritable_path_is_reported_naming_it(tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a directory")
    with pytest.raises(PipelineError, match="a_file/bag"), bag_writer.BagWriter(blocker / "bag", TOPICS):
        pass


def test_full_disk_is_reported_naming_the_bag(tmp_path):
    path = tmp_path / "full"
    writer = bag_writer.BagWriter(path, TOPICS, flush_every=1)
    writer.open()
    storage = writer._writer.storage
    storage.bio = FullDisk(storage.bio)
    with pytest.raises(PipelineError, match=r"full.*No space left"):
        writer.write(TOPIC_ANGLES, 1, bag_messages.joint_state_msg(ARM_JOINTS, angles(0), 0.0))
    with pytest.raises(PipelineError, match="not open"):
        writer.write(TOPIC_ANGLES, 2, bag_messages.joint_state_msg(ARM_JOINTS, angles(0), 0.0))


def test_undeclared_topics_and_unknown_types_are_refused(tmp_path):
    with pytest.raises(PipelineError, match="my_msgs/msg/Thing"):
        bag_writer.BagWriter(tmp_path / "x", {"thing": "my_msgs/msg/Thing"})
    with bag_writer.BagWriter(tmp_path / "y", TOPICS) as writer, pytest.raises(PipelineError, match="'other'"):
        writer.write_raw("other", 1, b"")


def test_reading_something_that_is_not_a_bag_names_it(tmp_path):
    with pytest.raises(PipelineError, match="nothing_here"):
        list(bag_reader.read_bag(tmp_path / "nothing_here"))
    (tmp_path / "half").mkdir()
    with pytest.raises(PipelineError, match=r"half.*metadata.yaml"):
        bag_reader.bag_info(tmp_path / "half")


CRASHING_RECORDER = textwrap.dedent("""
    import os, sys
    import numpy as np
    from gwr_predictor.pipeline import bag_messages, bag_reader, bag_recovery, bag_writer
    from gwr_predictor.robot.nao import ARM_JOINTS
    writer = bag_writer.BagWriter(sys.argv[1], {"arm_angles": bag_messages.JOINT_STATE}, flush_every=int(sys.argv[2]))
    writer.open()
    for k in range(int(sys.argv[3])):
        writer.write("arm_angles", 1000 + k, bag_messages.joint_state_msg(ARM_JOINTS, np.full(8, float(k)), k * 0.1))
    os._exit(9)  # a crash: no close, no atexit, no buffer flush
""")


def crash_recorder(path, flush_every: int, messages: int) -> None:
    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    done = subprocess.run([sys.executable, "-c", CRASHING_RECORDER, str(path), str(flush_every), str(messages)],
                          env=env, capture_output=True, timeout=120, check=False)
    assert done.returncode == 9, done.stderr.decode()


def test_a_crashed_writer_is_recovered_up_to_its_last_flush(tmp_path):
    path = tmp_path / "crashed"
    crash_recorder(path, flush_every=10, messages=37)
    with pytest.raises(PipelineError, match="recover_bag"):
        list(bag_reader.read_bag(path))
    info = bag_recovery.recover_bag(path)
    assert info.message_count == 30
    positions = [m.msg.position[0] for m in bag_reader.read_bag(path)]
    assert positions == [float(k) for k in range(30)]
    assert sorted(p.name for p in path.iterdir()) == ["crashed.mcap", "crashed.mcap.damaged", "metadata.yaml"]
    assert bag_recovery.recover_bag(path) == info  # a sound bag is left alone


def test_a_writer_that_never_flushed_is_reported_unrecoverable(tmp_path):
    path = tmp_path / "lost"
    crash_recorder(path, flush_every=0, messages=5)
    with pytest.raises(PipelineError, match=r"lost.*nothing recoverable"):
        bag_recovery.recover_bag(path)
