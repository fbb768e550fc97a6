"""The recorder loses nothing it has flushed: Ctrl-C / SIGTERM close the bag whole; after a SIGKILL
every message up to the last periodic flush is recovered by `bag_recovery.recover_bag`; a failing write
(full disk) stops it and it says the bag is incomplete instead of reporting it closed."""

import signal

import numpy as np
import pytest
import rclpy
from fakes import FullDisk
from ros_harness import allocate_domain_id

from gwr_predictor.nodes import messages
from gwr_predictor.nodes.exits import NodeFatalError
from gwr_predictor.nodes.messages import JointState
from gwr_predictor.nodes.qos import stream_qos
from gwr_predictor.pipeline import bag_messages, bag_reader, bag_recovery
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.robot.nao import ARM_JOINTS

RECORDER = {"diagnostics_period_s": 0.2, "topics": ["arm_angles"], "flush_period_s": 0.3}


def frame(k: int) -> JointState:
    """Frame k: stamp 100 + k/10 s, first joint = k / 100 (inside its limits), so order and content are checkable."""
    return messages.joint_state(100.0 + 0.1 * k, ARM_JOINTS, np.r_[k / 100.0, np.zeros(7)])


def start_recorder(ros, path):
    diagnostics = ros.diagnostics
    recorder = ros.start_ready("bag_recorder", params={**RECORDER, "path": str(path)})
    pub = ros.probe.publisher("/arm_angles", JointState)
    ros.probe.wait_for_subscribers(pub)
    return recorder, diagnostics, pub


def recorded_frames(path) -> list[int]:
    return [round(100 * m.msg.position[0]) for m in bag_reader.read_bag(path)]


def stat(diagnostics, key: str) -> int:
    return int(diagnostics.get("/bag_recorder", {}).get(key, "0"))


@pytest.mark.ros
def test_sigkill_loses_only_what_was_not_flushed_and_recover_bag_restores_the_rest(ros, tmp_path):
    path = tmp_path / "bag"
    recorder, diagnostics, pub = start_recorder(ros, path)
    for k in range(40):
        pub.publish(frame(k))
    ros.probe.spin_until(lambda: stat(diagnostics, "messages.on_disk") >= 40, 20, "40 messages flushed to disk",
                         [recorder])
    for k in range(40, 60):  # written to the writer's memory at most: lost with the process
        pub.publish(frame(k))
    ros.probe.spin_until(lambda: stat(diagnostics, "messages.written") >= 60, 20, "60 messages received",
                         [recorder])
    on_disk = stat(diagnostics, "messages.on_disk")
    ros.kill(recorder)
    assert recorder.popen.returncode == -signal.SIGKILL

    with pytest.raises(PipelineError, match="recover_bag"):
        list(bag_reader.read_bag(path))
    info = bag_recovery.recover_bag(path)
    # everything up to the last flush survives; at most one flush period after it is lost
    assert on_disk <= info.message_count <= 60
    assert recorded_frames(path) == list(range(info.message_count))
    assert (path / "bag.mcap.damaged").is_file()


@pytest.mark.ros
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_ctrl_c_and_sigterm_close_the_bag_whole(ros, tmp_path, sig):
    path = tmp_path / "bag"
    recorder, diagnostics, pub = start_recorder(ros, path)
    for k in range(25):
        pub.publish(frame(k))
    ros.probe.spin_until(lambda: stat(diagnostics, "messages.written") >= 25, 20, "25 messages received",
                         [recorder])
    code, killed = recorder.stop(sig)
    assert code == 0 and not killed, recorder.output()
    assert "bag closed" in recorder.output() and "(25 messages)" in recorder.output()
    assert bag_reader.bag_info(path).message_count == 25  # metadata written: no recovery needed
    assert recorded_frames(path) == list(range(25))


@pytest.mark.ros
def test_sigterm_right_after_a_burst_still_records_the_whole_burst(ros, tmp_path):
    """What was published before the stop is in the bag: the recorder takes the messages still queued
    in its subscription before it closes the bag (`runner._drain`), instead of dropping them."""
    path = tmp_path / "bag"
    recorder, _, _ = start_recorder(ros, path)
    pub = ros.probe.publisher("/arm_angles", JointState, stream_qos(1000))  # deep enough to lose nothing
    ros.probe.wait_for_subscribers(pub)
    for k in range(400):
        pub.publish(frame(k))
    code, killed = recorder.stop(signal.SIGTERM)  # at once: most of the burst is still queued
    assert code == 0 and not killed, recorder.output()
    assert recorded_frames(path) == list(range(400))


def test_a_full_disk_stops_the_recorder_and_the_bag_is_reported_incomplete(tmp_path):
    """In-process (a real full disk needs a small file system): the node's own write path and shutdown hook."""
    from gwr_predictor.nodes.bag_recorder import BagRecorderNode

    path = tmp_path / "bag"
    context_args = ["--ros-args", "-p", f"path:={path}", "-p", "topics:=[arm_angles]"]
    rclpy.init(args=context_args, domain_id=allocate_domain_id())
    try:
        node = BagRecorderNode()
        raw = bag_messages.serialize(bag_messages.joint_state_msg(ARM_JOINTS, np.zeros(8), 1.0))
        node.on_message("/arm_angles", raw)
        node.flush()
        assert node.diagnostic_values()["messages.on_disk"] == 1
        node.writer._writer.storage.bio = FullDisk(node.writer._writer.storage.bio)
        node.on_message("/arm_angles", raw)  # buffered in the chunk
        with pytest.raises(NodeFatalError, match=r"recording stopped: .*bag.*No space left on device"):
            node.flush()
        with pytest.raises(NodeFatalError, match=r"INCOMPLETE.*No space left.*1 messages were flushed.*recover_bag"):
            node.on_shutdown()
        node.destroy_node()
    finally:
        rclpy.try_shutdown()
    assert not (path / "metadata.yaml").exists()  # never passed off as a complete bag
    assert bag_recovery.recover_bag(path).message_count == 1
