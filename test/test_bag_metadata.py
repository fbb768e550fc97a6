"""What the recorder writes into a bag's metadata is what rosbag2 writes, and the shipped sample bag has it.

`ros2 bag info` and other tools read `ros_distro` from metadata.yaml and from the MCAP's `rosbag2`
metadata record; rosbag2 on Jazzy writes `jazzy` there. Replay needs each topic's offered QoS.
"""

from pathlib import Path

import numpy as np
import yaml
from mcap.reader import make_reader

from gwr_predictor.pipeline import bag_messages, bag_reader, bag_writer

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "bags" / "demo_sample"


def mcap_rosbag2_metadata(mcap_path: Path) -> dict:
    """The `rosbag2` metadata record of an MCAP file, its serialized_metadata parsed."""
    with mcap_path.open("rb") as f:
        (record,) = [m for m in make_reader(f).iter_metadata() if m.name == "rosbag2"]
    return yaml.safe_load(record.metadata["serialized_metadata"])


def test_bag_writer_writes_the_ros_distro_rosbag2_writes(tmp_path):
    path = tmp_path / "bag"
    with bag_writer.BagWriter(path, {"/arm_angles": bag_messages.JOINT_STATE}) as writer:
        writer.write("/arm_angles", 1_000, bag_messages.joint_state_msg(["a"], np.zeros(1), 1.0))
    metadata = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert metadata["ros_distro"] == "jazzy"
    (mcap_file,) = path.glob("*.mcap")
    assert mcap_rosbag2_metadata(mcap_file)["ros_distro"] == "jazzy"
    assert bag_reader.bag_info(path).topics["/arm_angles"] == (bag_messages.JOINT_STATE, 1)  # still a bag rosbags reads


def test_shipped_sample_bag_has_stored_qos_and_the_jazzy_distro():
    metadata = yaml.safe_load((SAMPLE / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert metadata["ros_distro"] == "jazzy"
    topics = {t["topic_metadata"]["name"]: t for t in metadata["topics_with_message_count"]}
    assert {"/skeleton", "/arm_angles", "/predictions", "/joint_commands", "/joint_states",
            "/uncompensated/joint_commands", "/uncompensated/joint_states"} <= set(topics)
    for name, topic in topics.items():
        if topic["message_count"]:
            assert topic["topic_metadata"]["offered_qos_profiles"], f"{name}: no stored QoS"
    assert sum(f.stat().st_size for f in SAMPLE.iterdir()) < 2_500_000  # small enough to ship
