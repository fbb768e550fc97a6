"""Bags keep the QoS their publishers offered (as rosbag2 does) and can be read from a bare .mcap file;
checked with independent readers: rosbags' own Reader, the `mcap` library and mcap-ros2-support."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.interfaces import QosDurability, QosReliability
from rosbags.rosbag2 import Reader

from gwr_predictor.pipeline import bag_messages, bag_qos, bag_reader, bag_recovery, bag_writer
from gwr_predictor.pipeline.conventions import TOPIC_ANGLES, TOPIC_DIAGNOSTICS, TOPIC_TYPES
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.robot.nao import ARM_JOINTS

RELIABLE = bag_qos.qos_profile(history="keep_last", depth=30, reliability="reliable", durability="volatile",
                            deadline_ns=2**63 - 1)
LATCHED = bag_qos.qos_profile(history="KEEP_LAST", depth=1, reliability="RELIABLE", durability="TRANSIENT_LOCAL",
                           lifespan_ns=1_500_000_000)
BEST_EFFORT = bag_qos.qos_profile(history="keep_last", depth=0, reliability="best_effort", durability="volatile")
OFFERED = {TOPIC_ANGLES: [RELIABLE], TOPIC_DIAGNOSTICS: [LATCHED, BEST_EFFORT]}
TOPICS = {TOPIC_ANGLES: TOPIC_TYPES[TOPIC_ANGLES], TOPIC_DIAGNOSTICS: TOPIC_TYPES[TOPIC_DIAGNOSTICS],
          "/silent": bag_messages.JOINT_STATE}


def write_bag(path, asked: list[str] | None = None):
    def offered(topic: str):
        if asked is not None:
            asked.append(topic)
        return OFFERED.get(topic, [])

    with bag_writer.BagWriter(path, TOPICS, offered_qos=offered) as writer:
        for k in range(5):
            writer.write(TOPIC_ANGLES, 1_000 + k,
                         bag_messages.joint_state_msg(ARM_JOINTS, np.full(8, 0.1 * k), 1.0 + k))
        writer.write_raw(TOPIC_DIAGNOSTICS, 2_000, bag_messages.serialize(
            bag_messages.TYPESTORE.types["diagnostic_msgs/msg/DiagnosticArray"](
                header=bag_messages.TYPESTORE.types["std_msgs/msg/Header"](
                    stamp=bag_messages.time_msg(2.0), frame_id=""),
                status=[])))


def test_offered_qos_is_in_metadata_yaml_as_rosbag2_writes_it(tmp_path):
    asked: list[str] = []
    write_bag(tmp_path / "bag", asked)
    assert sorted(asked) == sorted(TOPICS)  # once per topic, the silent one on close
    meta = yaml.safe_load((tmp_path / "bag" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    by_topic = {t["topic_metadata"]["name"]: t for t in meta["topics_with_message_count"]}
    angles_qos = by_topic[TOPIC_ANGLES]["topic_metadata"]["offered_qos_profiles"]
    assert angles_qos == [{"history": "keep_last", "depth": 30, "reliability": "reliable", "durability": "volatile",
                           "deadline": {"sec": 9223372036, "nsec": 854775807},
                           "lifespan": {"sec": 9223372036, "nsec": 854775807}, "liveliness": "automatic",
                           "liveliness_lease_duration": {"sec": 9223372036, "nsec": 854775807},
                           "avoid_ros_namespace_conventions": False}]
    diag_qos = by_topic[TOPIC_DIAGNOSTICS]["topic_metadata"]["offered_qos_profiles"]
    assert [q["durability"] for q in diag_qos] == ["transient_local", "volatile"]
    assert diag_qos[0]["lifespan"] == {"sec": 1, "nsec": 500_000_000}
    assert by_topic["/silent"]["message_count"] == 0
    assert by_topic["/silent"]["topic_metadata"]["offered_qos_profiles"] == []
    with Reader(tmp_path / "bag") as reader:  # rosbags parses them back
        qos = {c.topic: c.ext.offered_qos_profiles for c in reader.connections}
    assert qos[TOPIC_ANGLES] == [RELIABLE] and qos[TOPIC_DIAGNOSTICS] == [LATCHED, BEST_EFFORT]


def test_offered_qos_is_in_the_mcap_channel_metadata(tmp_path):
    write_bag(tmp_path / "bag")
    (mcap_file,) = (tmp_path / "bag").glob("*.mcap")
    with mcap_file.open("rb") as f:
        summary = make_reader(f).get_summary()
    channels = {c.topic: c for c in summary.channels.values()}
    assert set(channels) == set(TOPICS)
    profiles = yaml.safe_load(channels[TOPIC_ANGLES].metadata["offered_qos_profiles"])
    assert profiles[0]["reliability"] == "reliable" and profiles[0]["depth"] == 30
    profiles = yaml.safe_load(channels[TOPIC_DIAGNOSTICS].metadata["offered_qos_profiles"])
    assert [p["reliability"] for p in profiles] == ["reliable", "best_effort"]


def test_a_bare_mcap_file_reads_like_its_bag(tmp_path):
    write_bag(tmp_path / "bag")
    (mcap_file,) = (tmp_path / "bag").glob("*.mcap")
    bare = tmp_path / "copied.mcap"
    bare.write_bytes(mcap_file.read_bytes())  # without metadata.yaml next to it
    info, bare_info = bag_reader.bag_info(tmp_path / "bag"), bag_reader.bag_info(bare)
    assert bare_info.storage == "mcap" and bare_info.message_count == info.message_count == 6
    assert bare_info.topics[TOPIC_ANGLES] == (bag_messages.JOINT_STATE, 5)
    assert bare_info.offered_qos[TOPIC_ANGLES] == [RELIABLE]
    assert (bare_info.start_ns, bare_info.end_ns) == (info.start_ns, info.end_ns) == (1_000, 2_000)
    assert [m.raw for m in bag_reader.read_bag(bare)] == [m.raw for m in bag_reader.read_bag(tmp_path / "bag")]
    with bare.open("rb") as f:  # and mcap-ros2-support decodes the same file on its own
        decoded = [d for _, c, _, d in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages()
                   if c.topic == TOPIC_ANGLES]
    np.testing.assert_array_equal(np.asarray(decoded[3].position), np.full(8, 0.1 * 3))


def test_unreadable_inputs_are_named(tmp_path):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file at all")
    with pytest.raises(PipelineError, match=r"junk\.mcap: unreadable MCAP file"):
        bag_reader.bag_info(junk)
    other = tmp_path / "notes.txt"
    other.write_text("x")
    with pytest.raises(PipelineError, match=r"notes\.txt: neither a bag directory nor a \.mcap file"):
        bag_reader.bag_info(other)
    with pytest.raises(PipelineError, match="QoS reliability 'sometimes'"):
        bag_qos.qos_profile(history="keep_last", depth=1, reliability="sometimes", durability="volatile")


def test_replay_qos_is_the_offer_every_recorded_subscriber_can_match():
    assert bag_qos.replay_qos([], 10) is None  # old bags: the player keeps its default
    assert bag_qos.replay_qos([RELIABLE], 10) == bag_qos.ReplayQos("reliable", "volatile", 30)
    assert bag_qos.replay_qos([LATCHED], 10) == bag_qos.ReplayQos("reliable", "transient_local", 1)
    assert bag_qos.replay_qos([LATCHED, BEST_EFFORT], 10) == bag_qos.ReplayQos("best_effort", "volatile", 1)
    assert bag_qos.replay_qos([BEST_EFFORT], 10) == bag_qos.ReplayQos("best_effort", "volatile", 10)  # depth 0: default
    assert RELIABLE.reliability == QosReliability.RELIABLE and LATCHED.durability == QosDurability.TRANSIENT_LOCAL


CRASHING_WRITER = textwrap.dedent("""
    import os, sys
    import numpy as np
    from gwr_predictor.pipeline import bag_messages, bag_qos, bag_reader, bag_recovery, bag_writer
    from gwr_predictor.robot.nao import ARM_JOINTS
    qos = bag_qos.qos_profile(history="keep_last", depth=3, reliability="best_effort", durability="volatile")
    writer = bag_writer.BagWriter(sys.argv[1], {"/arm_angles": bag_messages.JOINT_STATE}, flush_every=5,
                            offered_qos=lambda topic: [qos])
    writer.open()
    for k in range(12):
        writer.write("/arm_angles", 1000 + k, bag_messages.joint_state_msg(ARM_JOINTS, np.full(8, float(k)), k * 0.1))
    os._exit(9)  # a crash: no close
""")


def test_a_recovered_bag_keeps_the_offered_qos(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    done = subprocess.run([sys.executable, "-c", CRASHING_WRITER, str(tmp_path / "crashed")], env=env,
                          capture_output=True, timeout=120, check=False)
    assert done.returncode == 9, done.stderr.decode()
    info = bag_recovery.recover_bag(tmp_path / "crashed")
    assert info.message_count == 10
    (offered,) = info.offered_qos["/arm_angles"]
    assert offered.reliability == QosReliability.BEST_EFFORT and offered.depth == 3
