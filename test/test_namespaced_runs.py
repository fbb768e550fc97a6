"""`report`, `latency` and `render` read a namespaced run (`run_pipeline.sh --namespace NS`) as they read a
root one; a bag holding two pipelines is read one pipeline at a time; results of a bare bag stay in it.

The bags are copies of bags/demo_sample with every topic moved under a namespace (and /diagnostics status
names with it, as the nodes name themselves there): the numbers must be exactly those of the original.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gwr_predictor.commands.cli import main as cli_main
from gwr_predictor.pipeline import bag_messages, bag_reader, bag_writer, namespaces
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.message_latency import latency_report
from gwr_predictor.pipeline.replay_plan import hri_input, replay_plan
from gwr_predictor.pipeline.run_report import compute_report, read_run
from gwr_predictor.pipeline.video import read_video_run

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "bags" / "demo_sample"
DIAGNOSTICS = "/diagnostics"


def moved(message: bag_reader.BagMessage, namespace: str, extra: dict[str, dict[str, str]] | None = None
          ) -> tuple[str, bytes]:
    """(topic, CDR) of a recorded message as the pipeline in `namespace` records it: its topic below the
    namespace, or for /diagnostics (global) its status names; `extra` adds key/values to named statuses."""
    if message.topic != DIAGNOSTICS:
        return namespace + message.topic, message.raw
    msg = bag_messages.deserialize(message.raw, message.msgtype)
    for status in msg.status:
        for key, value in (extra or {}).get(status.name, {}).items():
            status.values.append(bag_messages.TYPESTORE.types["diagnostic_msgs/msg/KeyValue"](key=key, value=value))
        status.name = namespace + status.name
    return DIAGNOSTICS, bag_messages.serialize(msg, message.msgtype)


def namespaced_bag(path: Path, *pipelines: str, extra: dict[str, dict[str, dict[str, str]]] | None = None,
                   seconds: float | None = None) -> Path:
    """demo_sample as recorded by the pipelines in `pipelines` on one domain (one copy each, /diagnostics
    shared); `extra[namespace]` adds counters to that pipeline's statuses; `seconds` keeps only the start."""
    info = bag_reader.bag_info(SAMPLE)
    topics = {DIAGNOSTICS: bag_messages.DIAGNOSTIC_ARRAY}
    topics.update({ns + t: msgtype for ns in pipelines for t, (msgtype, _) in info.topics.items() if t != DIAGNOSTICS})
    end = None if seconds is None else info.start_ns + int(seconds * 1e9)
    with bag_writer.BagWriter(path, topics) as writer:
        for message in bag_reader.read_bag(SAMPLE, decode=False):
            if end is not None and message.timestamp_ns > end:
                break
            for ns in pipelines:
                topic, raw = moved(message, ns, (extra or {}).get(ns))
                writer.write_raw(topic, message.timestamp_ns, raw)
    return path


@pytest.fixture(scope="module")
def root_numbers():
    return compute_report(read_run(SAMPLE)), latency_report(SAMPLE)


def same_report(got, expected) -> None:
    assert got.scored_predictions == expected.scored_predictions > 0
    assert got.prediction_mae_rad == expected.prediction_mae_rad
    assert got.hold_mae_rad == expected.hold_mae_rad
    assert [r["lag_s"] for r in got.robots.values()] == [r["lag_s"] for r in expected.robots.values()]
    assert [r["mode"] for r in got.robots.values()] == [r["mode"] for r in expected.robots.values()]


def test_report_reads_a_namespaced_run_as_the_root_one(tmp_path, root_numbers):
    bag = namespaced_bag(tmp_path / "bag", "/robot1")
    report = compute_report(read_run(bag))
    assert report.namespace == "/robot1"
    assert list(report.robots) == ["/robot1", "/robot1/uncompensated"]
    assert {r["mode"] for r in report.robots.values()} == {"guarded", "none"}
    same_report(report, root_numbers[0])


def test_latency_reads_a_namespaced_run_as_the_root_one(tmp_path, root_numbers):
    bag = namespaced_bag(tmp_path / "bag", "/robot1")
    report, expected = latency_report(bag), root_numbers[1]
    assert report.namespace == "/robot1" and report.latencies and set(report.latencies) == set(expected.latencies)
    for name, stats in expected.latencies.items():
        assert report.latencies[name] == stats, name
    assert [(c.published, c.recorded, c.consumed) for c in report.counts] == \
        [(c.published, c.recorded, c.consumed) for c in expected.counts]
    assert {c.topic for c in report.counts} == {"/robot1" + c.topic for c in expected.counts}


def test_a_bag_of_two_pipelines_is_read_one_pipeline_at_a_time(tmp_path, root_numbers):
    """Both pipelines' nodes report on the global /diagnostics: each report counts only its own."""
    bag = namespaced_bag(tmp_path / "bag", "/robot1", "/robot2",
                         extra={"/robot2": {"/angle_extractor": {"rejected.skeleton.layout": "7"}}})
    with pytest.raises(PipelineError, match="/robot1, /robot2: choose one with --namespace"):
        read_run(bag)
    with pytest.raises(PipelineError, match="no pipeline in namespace /robot3"):
        read_run(bag, "robot3")
    one, two = compute_report(read_run(bag, "robot1")), compute_report(read_run(bag, "/robot2/"))
    same_report(one, root_numbers[0])
    same_report(two, root_numbers[0])
    assert list(two.robots) == ["/robot2", "/robot2/uncompensated"]
    assert two.rejected.get("/robot2/angle_extractor:skeleton.layout") == 7
    assert not any(key.startswith("/robot2") for key in one.rejected)
    latency = latency_report(bag, "robot1")
    assert not any(c.concurrent for c in latency.counts)  # the other pipeline's nodes are not this one's
    assert [(c.published, c.consumed) for c in latency.counts] == \
        [(c.published, c.consumed) for c in root_numbers[1].counts]
    skeleton = next(c for c in latency_report(bag, "robot2").counts if c.topic == "/robot2/skeleton")
    assert skeleton.consumed == latency.counts[0].consumed + 7  # its extractor's own rejections
    assert len(read_video_run(bag, "robot1").robots) == 2


def test_the_commands_take_namespace_and_write_into_a_bare_bag_directory(tmp_path, capsys):
    parent = tmp_path / "recordings"
    bag = namespaced_bag(parent / "session1", "/robot1", "/robot2")
    assert cli_main(["report", str(bag)]) == 1
    assert "choose one with --namespace" in capsys.readouterr().err
    assert cli_main(["report", str(bag), "--namespace", "robot2"]) == 0
    assert "pipeline /robot2" in capsys.readouterr().out
    # a bare bag directory keeps its results: the parent may hold other bags, whose results would mix
    assert json.loads((bag / "report.json").read_text())["namespace"] == "/robot2"
    assert (bag / "report.png").is_file() and not (parent / "report.json").exists()
    assert cli_main(["latency", str(bag), "--namespace", "robot1"]) == 0
    assert json.loads((bag / "latency.json").read_text())["namespace"] == "/robot1"
    assert "/robot1/arm_angles" in capsys.readouterr().out
    assert bag_reader.bag_info(bag).topics["/robot1/arm_angles"][1] > 0  # still a bag with its results in it
    assert cli_main(["render", str(bag), "--namespace", "robot1", "--seconds", "2:2.5", "--fps", "2",
                     "--scale", "0.2", "--no-progress", "-o", str(tmp_path / "v.gif")]) == 0
    assert (tmp_path / "v.gif").stat().st_size > 0


def test_pipeline_namespaces_of_topics():
    topics = ["/robot1/arm_angles", "/robot1/uncompensated/joint_states", "/diagnostics", "/a/b/skeleton",
              "/humans/bodies/b1/joint_states", "/predictions"]
    assert namespaces.pipelines_in(topics) == ["", "/a/b", "/robot1"]
    assert namespaces.choose_pipeline(["/robot1/arm_angles", "/diagnostics"], None, "bag") == "/robot1"
    assert namespaces.choose_pipeline(["/diagnostics"], None, "bag") == ""
    for bad in ("2robots", "a//b", "a-b"):
        with pytest.raises(PipelineError, match="not a ROS namespace"):
            namespaces.normalise(bad)
    assert np.all([namespaces.within("/robot1/uncompensated", "/robot1"), not namespaces.within("/robot10", "/robot1"),
                   namespaces.within("/x", "")])


def test_the_report_of_a_bare_bag_directory_stays_in_it(tmp_path, capsys):
    parent = tmp_path / "recordings"
    bag = namespaced_bag(parent / "session1", "")  # a root-namespace bag, not in a run folder
    assert cli_main(["report", str(bag)]) == 0
    assert (bag / "report.json").is_file() and not (parent / "report.json").exists()


def test_replay_plan_renames_the_recorded_input_into_the_replays_namespace(tmp_path):
    bag = namespaced_bag(tmp_path / "bag", "/robot1", seconds=8)
    plan = replay_plan(str(bag), namespace="robot2")  # the default: the bag's skeleton topic
    assert (plan.input, plan.topics, plan.remaps) == ("skeleton", ("/robot1/skeleton",),
                                                      ("/robot1/skeleton:=/robot2/skeleton",))
    plan = replay_plan(str(bag), "/robot1/arm_angles", namespace="/robot1")
    assert (plan.input, plan.topics, plan.remaps) == ("arm_angles", ("/robot1/arm_angles",), ())
    with pytest.raises(PipelineError, match="topic named skeleton or arm_angles"):
        replay_plan(str(bag), "/robot1/joint_states")
    with pytest.raises(PipelineError, match="no messages on /robot2/skeleton"):
        replay_plan(str(bag), "/robot2/skeleton")
    with pytest.raises(PipelineError, match=r"record them with scripts/record\.sh --hri"):
        replay_plan(str(bag), hri=True)
    two = namespaced_bag(tmp_path / "two", "/robot1", "/robot2", seconds=8)
    with pytest.raises(PipelineError, match="2 skeleton topics"):
        replay_plan(str(two))


def test_replay_plan_of_the_hri_input_plays_what_this_machine_can_publish(tmp_path):
    js, point, ids = bag_messages.JOINT_STATE, "geometry_msgs/msg/PointStamped", "hri_msgs/msg/IdsList"
    recorded = {"/humans/bodies/b1/joint_states": (js, 5), "/humans/bodies/b1/position": (point, 5),
                "/humans/bodies/b2/joint_states": (js, 5), "/humans/bodies/tracked": (ids, 5),
                "/humans/bodies/b3/joint_states": (js, 0), "/arm_angles": (js, 5)}
    info = bag_reader.BagInfo(tmp_path, "mcap", 30, 0, 1, recorded)
    plan = hri_input(info, available=lambda msgtype: msgtype != ids)
    assert plan.topics == ("/humans/bodies/b1/joint_states", "/humans/bodies/b1/position",
                           "/humans/bodies/b2/joint_states") and plan.body == ""
    one = bag_reader.BagInfo(tmp_path, "mcap", 10, 0, 1, {k: v for k, v in recorded.items() if "b2" not in k})
    plan = hri_input(one, available=lambda msgtype: True)
    assert plan.topics == ("/humans/bodies/b1/joint_states",) and plan.body == "b1"  # followed at once
