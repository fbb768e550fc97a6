"""Hostile input, the smaller breaks: `report`/`render` on topics of another type, a body-tracking
MarkerArray with very many bodies, and `recover_bag` on a full disk."""

import errno
import io
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import storage_mcap

from gwr_predictor.commands.cli import main as cli_main
from gwr_predictor.data import k4abt
from gwr_predictor.data.demonstrator import default_subjects, demonstrate_one
from gwr_predictor.pipeline import bag_messages, bag_recovery, bag_writer, conventions
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.run_report import read_run
from gwr_predictor.robot.nao import ARM_JOINTS

T = bag_messages.TYPESTORE.types
DIAGNOSTICS = "diagnostic_msgs/msg/DiagnosticArray"
T0 = 1000.0
SECONDS = 3.0


# --- report / render on topics of another type ------------------------------------------------------


def person(t: float) -> np.ndarray:
    return 0.6 + 0.4 * np.sin(2 * np.pi * 0.4 * t + np.arange(8))


def diagnostics(stamp: float, name: str, values: dict[str, str]):
    status = T["diagnostic_msgs/msg/DiagnosticStatus"](
        level=0, name=name, message="", hardware_id="",
        values=[T["diagnostic_msgs/msg/KeyValue"](key=k, value=v) for k, v in values.items()])
    return T[DIAGNOSTICS](header=T["std_msgs/msg/Header"](stamp=bag_messages.time_msg(stamp), frame_id=""),
                          status=[status])


def impostor(msgtype: str, t: float):
    """A message of a type the topic does not have: a labelled array for a JointState topic and vice versa."""
    if msgtype == bag_messages.JOINT_STATE:
        return (bag_messages.FLOAT64_MULTIARRAY,
                bag_messages.multiarray_msg(conventions.pack_predictions(t, np.zeros((3, 8)))))
    return bag_messages.JOINT_STATE, bag_messages.joint_state_msg(ARM_JOINTS, np.zeros(8), t)


def run_bag(path: Path, wrong: tuple[str, ...] = (), diag_values: dict[str, str] | None = None) -> Path:
    """A small pipeline run (angles, predictions, skeleton, two robots, diagnostics); the topics in
    `wrong` carry messages of another type."""
    topics = {"/arm_angles": bag_messages.JOINT_STATE, "/predictions": bag_messages.FLOAT64_MULTIARRAY,
              "/skeleton": bag_messages.FLOAT64_MULTIARRAY, "/joint_states": bag_messages.JOINT_STATE,
              "/uncompensated/joint_states": bag_messages.JOINT_STATE, "/diagnostics": DIAGNOSTICS,
              "/uncompensated/diagnostics": DIAGNOSTICS, "/learner_status": DIAGNOSTICS}
    types = {topic: impostor(msgtype, 0.0)[0] if topic in wrong else msgtype for topic, msgtype in topics.items()}
    seq = demonstrate_one("wave_both", default_subjects(1)[0], 1, noise=False)

    def put(writer, topic: str, t: float, make) -> None:
        msg = impostor(topics[topic], t)[1] if topic in wrong else make()
        writer.write(topic, int(t * 1e9), msg)

    with bag_writer.BagWriter(path, types) as writer:
        for k in range(round(SECONDS * 10) + 1):
            t = T0 + 0.1 * k
            put(writer, "/arm_angles", t, lambda t=t: bag_messages.joint_state_msg(ARM_JOINTS, person(t), t))
            future = np.stack([person(t + 0.1 * j) for j in (1, 2, 3)])
            put(writer, "/predictions", t,
                lambda t=t, f=future: bag_messages.multiarray_msg(conventions.pack_predictions(t, f)))
        for k in range(round(SECONDS * 30) + 1):
            t = T0 + k / 30.0
            frame = seq.positions[k % len(seq.positions)]
            put(writer, "/skeleton", t,
                lambda t=t, f=frame: bag_messages.multiarray_msg(conventions.pack_skeleton(t, f)))
        for ns in ("", "/uncompensated"):
            for k in range(round(SECONDS * 50) + 1):
                t = T0 + 0.02 * k
                put(writer, f"{ns}/joint_states", t,
                    lambda t=t: bag_messages.joint_state_msg(ARM_JOINTS, person(t - 0.2), t))
            values = {"mode": "none" if ns else "fixed", **(diag_values or {})}
            put(writer, f"{ns}/diagnostics", T0 + 1,
                lambda ns=ns, v=values: diagnostics(T0 + 1, f"{ns}/delay_compensator", v))
        put(writer, "/learner_status", T0 + 1,
            lambda: diagnostics(T0 + 1, "arm_predictor", {conventions.NEURON_KEYS["gwr1"]: "12"}))
    return path


def one_line_error(err: str) -> str:
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.startswith("error:")]
    assert len(lines) == 1, err
    return lines[0]


def render(bag: Path, out: Path) -> int:
    return cli_main(["render", str(bag), "-o", str(out), "--seconds", "1:1.5", "--fps", "2", "--scale", "0.5",
                     "--no-progress"])


def test_report_and_render_refuse_arm_angles_of_another_type_in_one_line(tmp_path, capsys):
    bag = run_bag(tmp_path / "bag", wrong=("/arm_angles",))
    with pytest.raises(PipelineError, match="/arm_angles"):
        read_run(bag)
    assert cli_main(["report", str(bag), "--out", str(tmp_path)]) == 1
    line = one_line_error(capsys.readouterr().err)
    assert "/arm_angles" in line and "expected sensor_msgs/msg/JointState" in line
    assert "std_msgs/msg/Float64MultiArray" in line
    assert render(bag, tmp_path / "v.gif") == 1
    assert "/arm_angles" in one_line_error(capsys.readouterr().err)
    assert not (tmp_path / "v.gif").exists()


def test_report_refuses_predictions_of_another_type_and_render_skips_them(tmp_path, capsys):
    bag = run_bag(tmp_path / "bag", wrong=("/predictions",))
    assert cli_main(["report", str(bag), "--out", str(tmp_path)]) == 1
    line = one_line_error(capsys.readouterr().err)
    assert "/predictions" in line and "expected std_msgs/msg/Float64MultiArray" in line
    assert "sensor_msgs/msg/JointState" in line
    assert render(bag, tmp_path / "v.gif") == 0  # a video does not need the predictions
    assert (tmp_path / "v.gif").is_file()


def test_optional_topics_of_another_type_are_skipped_with_a_warning(tmp_path, capsys):
    wrong = ("/uncompensated/joint_states", "/uncompensated/diagnostics", "/learner_status", "/skeleton")
    bag = run_bag(tmp_path / "bag", wrong=wrong)
    run = read_run(bag)
    assert list(run.robots) == [""] and run.modes == {"": "fixed"} and run.learner == {}
    assert cli_main(["report", str(bag), "--out", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err and (tmp_path / "report.json").is_file()
    warnings = [line for line in captured.err.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 3, captured.err
    assert any("/uncompensated/joint_states" in w and "expected sensor_msgs/msg/JointState" in w
               and "std_msgs/msg/Float64MultiArray" in w for w in warnings)
    assert render(bag, tmp_path / "v.gif") == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err and (tmp_path / "v.gif").is_file()
    assert any("/skeleton" in line and "expected std_msgs/msg/Float64MultiArray" in line
               for line in err.splitlines() if line.startswith("warning:"))


def test_counters_that_are_not_numbers_are_skipped_with_a_warning(tmp_path, capsys):
    bag = run_bag(tmp_path / "bag", diag_values={"rejected.layout": "lots", "rejected.stamp": "nan"})
    assert cli_main(["report", str(bag), "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err and "'lots'" in err
    assert read_run(bag).rejected == {}


# --- body tracking: many bodies in one MarkerArray ---------------------------------------------------


def reference_nearest(ids: np.ndarray, xyz: np.ndarray) -> k4abt.TrackedBody | None:
    """The definition, body by body: later markers of a (body, joint) win; nearest pelvis, else mean."""
    bodies: dict[int, np.ndarray] = {}
    unknown = 0
    for marker_id, p in zip(ids.tolist(), xyz, strict=True):
        b, j = divmod(marker_id, k4abt.ID_STRIDE)
        if j >= k4abt.N_JOINTS:
            unknown += 1
            continue
        bodies.setdefault(b, np.full((k4abt.N_JOINTS, 3), np.nan))[j] = p
    if not bodies:
        return None
    best = min(bodies, key=lambda b: (k4abt.body_distance(bodies[b]), b))
    return k4abt.TrackedBody(best, k4abt.to_skeleton(bodies[best]), len(bodies), unknown)


def random_markers(rng: np.random.Generator, n: int, n_bodies: int) -> tuple[np.ndarray, np.ndarray]:
    body = rng.integers(0, n_bodies, n)
    joint = rng.integers(0, k4abt.ID_STRIDE, n)  # about 2/3 unknown joint indices; duplicates likely
    joint[: n // 2] = rng.integers(0, k4abt.N_JOINTS, n // 2)
    xyz = rng.normal(size=(n, 3)) * 2.0 + [0.0, 0.0, 3.0]
    xyz[rng.random(n) < 0.1] = np.nan  # untracked joints
    return body * k4abt.ID_STRIDE + joint, xyz


def assert_same(got: k4abt.TrackedBody | None, want: k4abt.TrackedBody | None) -> None:
    assert (got is None) == (want is None)
    if want is not None:
        assert (got.body_id, got.n_bodies, got.unknown_markers) == (want.body_id, want.n_bodies, want.unknown_markers)
        np.testing.assert_array_equal(got.positions, want.positions)


def test_nearest_body_agrees_with_the_body_by_body_definition():
    rng = np.random.default_rng(7)
    for n, n_bodies in [(0, 1), (1, 1), (5, 2), (40, 3), (300, 10), (2000, 400)]:
        for _ in range(5):
            ids, xyz = random_markers(rng, n, n_bodies)
            assert_same(k4abt.nearest_body(ids, xyz), reference_nearest(ids, xyz))


class CountingNumpy:
    """numpy, counting every function call made through it."""

    def __init__(self) -> None:
        self.calls = 0

    def __getattr__(self, name: str):
        attr = getattr(np, name)
        if not callable(attr) or isinstance(attr, type):
            return attr

        def counted(*args, **kwargs):
            self.calls += 1
            return attr(*args, **kwargs)

        return counted


def test_nearest_body_does_a_fixed_number_of_array_operations_whatever_the_number_of_bodies(monkeypatch):
    """Per-body work over the whole message was what made 60k markers take seconds: the number of
    numpy calls must not grow with the number of bodies (each call is one pass over the markers)."""
    calls = {}
    for n_bodies in (2, 50, 2000):
        ids = np.arange(n_bodies * 3) // 3 * k4abt.ID_STRIDE + np.arange(n_bodies * 3) % 3
        xyz = np.random.default_rng(n_bodies).normal(size=(ids.size, 3)) + [0.0, 0.0, 3.0]
        counter = CountingNumpy()
        monkeypatch.setattr(k4abt, "np", counter)
        tracked = k4abt.nearest_body(ids, xyz)
        monkeypatch.setattr(k4abt, "np", np)
        assert tracked.n_bodies == n_bodies
        calls[n_bodies] = counter.calls
    assert calls[2] == calls[50] == calls[2000], calls


def test_sixty_thousand_bodies_in_one_message_give_the_nearest_one():
    n = 60_000
    ids = np.arange(n, dtype=np.int64) * k4abt.ID_STRIDE + k4abt.K4ABT_JOINTS.index("PELVIS")
    xyz = np.random.default_rng(3).uniform(2.0, 5.0, size=(n, 3))
    xyz[41_234] = [0.0, 0.1, 0.9]
    tracked = k4abt.nearest_body(ids, xyz)
    assert tracked.body_id == 41_234 and tracked.n_bodies == n and tracked.unknown_markers == 0
    assert_same(tracked, reference_nearest(ids, xyz))


# --- recover_bag on a full disk ----------------------------------------------------------------------


def crashed_bag(path: Path) -> Path:
    """A bag whose recorder died after flushing 20 messages (no summary, no metadata.yaml)."""
    writer = bag_writer.BagWriter(path, {"/arm_angles": bag_messages.JOINT_STATE}, flush_every=5)
    writer.open()
    for k in range(20):
        writer.write("/arm_angles", int((T0 + k) * 1e9), bag_messages.joint_state_msg(ARM_JOINTS, np.zeros(8), T0 + k))
    writer._writer.storage.bio.close()
    return path


def disk_full(*args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device")


def write_record_to_a_full_disk(bio, op, record):
    """rosbags' MCAP record write: in-memory chunks work, the file write finds the disk full."""
    if not isinstance(bio, io.BytesIO):
        disk_full()
    return ORIGINAL_WRITE_RECORD(bio, op, record)


ORIGINAL_WRITE_RECORD = storage_mcap.write_record


@pytest.mark.parametrize("target, name, replacement", [
    (storage_mcap, "write_record", write_record_to_a_full_disk),
    (Path, "mkdir", disk_full),
])
def test_recover_bag_on_a_full_disk_is_one_bag_error_and_leaves_the_bag_as_it_was(tmp_path, monkeypatch, target,
                                                                                   name, replacement):
    bag = crashed_bag(tmp_path / "bag")
    before = sorted(p.name for p in bag.iterdir())
    monkeypatch.setattr(target, name, replacement)
    with pytest.raises(PipelineError) as caught:
        bag_recovery.recover_bag(bag)
    message = str(caught.value)
    assert "\n" not in message and message.startswith(str(bag)) and "No space left on device" in message
    assert "unchanged" in message
    monkeypatch.undo()
    assert sorted(p.name for p in bag.iterdir()) == before and sorted(p.name for p in tmp_path.iterdir()) == ["bag"]
    assert bag_recovery.recover_bag(bag).message_count == 20  # once there is space again


def test_recover_bag_that_cannot_move_the_result_into_place_says_where_it_is(tmp_path, monkeypatch):
    bag = crashed_bag(tmp_path / "bag")
    before = sorted(p.name for p in bag.iterdir())
    real_rename = Path.rename

    def rename(self, target):
        if self.parent.name == "bag" and self.parent != bag and Path(target).suffix == ".mcap":
            disk_full()  # moving the recovered .mcap in from the staging folder
        return real_rename(self, target)

    monkeypatch.setattr(Path, "rename", rename)
    with pytest.raises(PipelineError) as caught:
        bag_recovery.recover_bag(bag)
    message = str(caught.value)
    assert "\n" not in message and "No space left on device" in message
    kept = tmp_path / ".bag.recovering" / "bag"
    assert str(kept) in message and (kept / "metadata.yaml").is_file()
    assert "the bag is unchanged" in message and sorted(p.name for p in bag.iterdir()) == before
