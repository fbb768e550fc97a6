"""Record -> replay round trip: recorded /arm_angles replayed into a fresh learner with the same seed give
exactly the recorded predictions (the learner is deterministic and nothing is lost on the way)."""

import json
import signal

import numpy as np
import pytest
from rclpy.serialization import deserialize_message

from gwr_predictor.nodes import messages
from gwr_predictor.nodes.messages import JointState
from gwr_predictor.pipeline import bag_messages, bag_reader, bag_writer, conventions
from gwr_predictor.pipeline.bag_replay import parse_remaps, shift_stamp
from gwr_predictor.robot.nao import ARM_JOINTS

FAST = {"diagnostics_period_s": 0.5}


def recorded_predictions(bag) -> dict[float, np.ndarray]:
    out = {}
    for m in bag_reader.read_bag(bag, ["/predictions"]):
        stamp, names, preds = conventions.unpack_predictions(bag_messages.packed_array(m.msg))
        assert names == ARM_JOINTS
        out[stamp] = preds
    return out


@pytest.mark.ros
@pytest.mark.slow
def test_replayed_angles_reproduce_the_recorded_predictions_exactly(ros, tmp_path):
    probe = ros.probe
    diagnostics = probe.subscribe_diagnostics()
    learner_params = {**FAST, "seed": 3}
    recorder = ros.start("bag_recorder", label="recorder_live", params={
        **FAST, "path": str(tmp_path / "live"), "topics": ["skeleton", "arm_angles", "predictions"]})
    ros.wait_for_node(diagnostics, "/bag_recorder", timeout=60)
    live = [recorder, ros.start("arm_predictor", label="learner_live", params=learner_params),
            ros.start("angle_extractor", params=FAST)]
    for name in ("/arm_predictor", "/angle_extractor"):
        ros.wait_for_node(diagnostics, name, timeout=60)
    probe.wait_for_graph({"/arm_angles": ("angle_extractor", ["arm_predictor", "bag_recorder"]),
                          "/predictions": ("arm_predictor", ["bag_recorder"])})
    source = ros.start("skeleton_source", params={**FAST, "patterns": ["raise_lateral_one", "wave_both"], "subjects": 1,
                                                  "repetitions": 1, "loop": False, "pause_s": 0.7,
                                                  "wait_for_subscribers": 2})  # extractor and recorder
    assert source.wait(60) == 0, source.output()  # exits after its last sequence

    def counted(topic: str) -> int:
        return int(diagnostics.get("/bag_recorder", {}).get(f"recorded./{topic}", "0"))

    # a learner still working through its queue must not be stopped short of it (a loaded machine)
    probe.spin_until(lambda: counted("predictions") >= counted("arm_angles") > 60, 20,
                     lambda: f"a prediction recorded for every angle frame ({counted('predictions')} of "
                             f"{counted('arm_angles')})", live)
    probe.spin_for(1.0)
    for proc in reversed(live):
        code, killed = proc.stop(signal.SIGTERM)
        assert code == 0 and not killed, proc.output()
    recorded = recorded_predictions(tmp_path / "live")
    angles = bag_reader.bag_info(tmp_path / "live").topics["/arm_angles"][1]
    assert len(recorded) > 60 and angles == len(recorded)  # ~87 frames; the default predicts on every one

    diagnostics.clear()
    replay_recorder = ros.start("bag_recorder", label="recorder_replay", params={
        **FAST, "path": str(tmp_path / "replay"), "topics": ["predictions"]})
    learner = ros.start("arm_predictor", label="learner_replay", params=learner_params)
    # their 'ready' lines, not /diagnostics: a late final status of the live recorder could pass for one
    for proc in (replay_recorder, learner):
        ros.wait_for_log(proc, "]: ready", timeout=60)
    probe.wait_for_graph({"/predictions": ("arm_predictor", ["bag_recorder"])})
    code, output = ros.run("bag_player", timeout=60, params={
        **FAST, "bag": str(tmp_path / "live"), "topics": ["/arm_angles"], "rate": 4.0,
        "wait_for_subscribers": 1, "start_delay_s": 1.0})
    assert code == 0, output
    assert f"{angles} messages published" in output
    probe.spin_until(lambda: counted("predictions") >= len(recorded), 20, "every replayed prediction recorded",
                     [learner, replay_recorder])
    for proc in (learner, replay_recorder):
        code, killed = proc.stop()
        assert code == 0 and not killed, proc.output()
    replayed = recorded_predictions(tmp_path / "replay")
    assert sorted(replayed) == sorted(recorded)
    for stamp, preds in recorded.items():
        np.testing.assert_array_equal(replayed[stamp], preds)


@pytest.mark.ros
def test_recorder_with_an_unwritable_path_stops_with_a_clear_message(ros, tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    code, output = ros.run("bag_recorder", params={"path": str(blocker / "bag")})
    assert code == 1
    assert f"{blocker / 'bag'}: cannot create bag" in output


@pytest.mark.ros
def test_recorder_refuses_to_overwrite_an_existing_bag(ros, tmp_path):
    (tmp_path / "bag").mkdir()
    code, output = ros.run("bag_recorder", params={"path": str(tmp_path / "bag")})
    assert code == 1 and "exists already" in output


def test_player_remaps_are_parsed_and_checked():
    assert parse_remaps(["skeleton:=replayed/skeleton", "/a:=/b"]) == {"/skeleton": "/replayed/skeleton", "/a": "/b"}
    with pytest.raises(ValueError, match="'skeleton' must look like 'from:=to'"):
        parse_remaps(["skeleton"])


def test_restamping_moves_header_and_array_stamps_only():
    # bytes as on the wire
    state = bag_messages.serialize(bag_messages.joint_state_msg(ARM_JOINTS, np.arange(8.0), 10.25))
    shifted = shift_stamp(state, bag_messages.JOINT_STATE, 100.5)
    assert len(shifted) == len(state)  # exact CDR size: a recorder can store it again
    moved = deserialize_message(shifted, JointState)
    assert messages.read_joint_state(moved)[0] == pytest.approx(110.75)
    np.testing.assert_array_equal(moved.position, np.arange(8.0))
    preds = bag_messages.serialize(bag_messages.multiarray_msg(conventions.pack_predictions(10.25, np.ones((6, 8)))))
    moved = deserialize_message(shift_stamp(preds, bag_messages.FLOAT64_MULTIARRAY, -10.0), messages.Float64MultiArray)
    stamp, _, values = messages.read_predictions(moved)
    assert stamp == pytest.approx(0.25)
    np.testing.assert_array_equal(values, np.ones((6, 8)))
    a_second_later = shift_stamp(preds, bag_messages.FLOAT64_MULTIARRAY, 1.0)
    assert bag_messages.deserialize(a_second_later, bag_messages.FLOAT64_MULTIARRAY).data[0] == 11.25


def write_synthetic_run(path, lag_s: float, mode: str = "none", interval_half: float = 0.0):
    """A bag as the pipeline would record it: a person moving sinusoidally (10 fps), perfect
    predictions, and a robot (50 Hz) that follows the person `lag_s` late; with `interval_half` > 0 also
    an 80 % interval that many rad either side of a prediction, centred on it at even frames (the truth
    inside) and twice that above it at odd ones (the truth below it)."""
    topics = {"/arm_angles": bag_messages.JOINT_STATE, "/predictions": bag_messages.FLOAT64_MULTIARRAY,
              "/joint_states": bag_messages.JOINT_STATE, "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray"}
    if interval_half:
        topics["/prediction_interval"] = bag_messages.FLOAT64_MULTIARRAY

    def person(t):
        return 0.8 + 0.5 * np.sin(2 * np.pi * 0.4 * np.asarray(t)[..., None] + np.arange(8))

    t0 = 1000.0
    with bag_writer.BagWriter(path, topics) as writer:
        for k in range(300):  # 30 s at 10 fps
            t = t0 + 0.1 * k
            writer.write("/arm_angles", int(t * 1e9), bag_messages.joint_state_msg(ARM_JOINTS, person(t), t))
            future = person(t + 0.1 * np.arange(1, 7))
            writer.write("/predictions", int(t * 1e9),
                         bag_messages.multiarray_msg(conventions.pack_predictions(t, future)))
            if interval_half:
                centre = future + (k % 2) * 2 * interval_half
                writer.write("/prediction_interval", int(t * 1e9),
                             bag_messages.multiarray_msg(conventions.pack_interval(
                                 t, centre - interval_half, centre + interval_half, 0.8)))
        for k in range(1500):  # 30 s at 50 Hz
            t = t0 + 0.02 * k
            writer.write("/joint_states", int(t * 1e9), bag_messages.joint_state_msg(ARM_JOINTS, person(t - lag_s), t))
        types = bag_messages.TYPESTORE.types
        status = types["diagnostic_msgs/msg/DiagnosticStatus"](
            level=0, name="/delay_compensator", message="", hardware_id="",
            values=[types["diagnostic_msgs/msg/KeyValue"](key="mode", value=mode)])
        header = types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=1030, nanosec=0),
                                              frame_id="")
        writer.write("/diagnostics", int(1030e9), types["diagnostic_msgs/msg/DiagnosticArray"](header=header,
                                                                                                status=[status]))


def test_report_measures_a_known_lag_and_perfect_predictions(tmp_path):
    from gwr_predictor.pipeline.run_report import compute_report, plot_run, read_run

    write_synthetic_run(tmp_path / "bag", lag_s=0.5)
    run = read_run(tmp_path / "bag")
    report = compute_report(run)
    assert report.horizon == 6 and report.scored_predictions == 300 - 6
    assert report.prediction_mae_rad == pytest.approx(0.0, abs=1e-9)
    assert report.hold_mae_rad > 0.3  # the person moves: holding the last frame is worse
    robot = report.robots[""]
    assert robot["mode"] == "none"
    assert robot["lag_s"] == pytest.approx(0.5, abs=0.01)
    assert robot["tracking_mae_rad"] > 0.2
    assert report.message_counts["/joint_states"] == 1500
    assert plot_run(run, tmp_path / "plot.png").stat().st_size > 10_000
    assert json.loads(report.to_json())["robots"][""]["lag_s"] == pytest.approx(0.5, abs=0.01)


def test_report_scores_the_stated_interval_and_the_plot_shades_it(tmp_path, monkeypatch):
    from gwr_predictor.pipeline import plotting
    from gwr_predictor.pipeline.run_report import compute_report, plot_run, read_run

    write_synthetic_run(tmp_path / "bag", lag_s=0.5, interval_half=0.05)
    run = read_run(tmp_path / "bag")
    report = compute_report(run)
    assert report.interval_nominal == 0.8
    np.testing.assert_allclose(report.interval_coverage_per_step, 0.5, atol=0.01)  # every other frame inside
    np.testing.assert_allclose(report.interval_width_per_step_rad, 0.1)
    assert any("stated 80 % interval" in line and "50.0 %" in line for line in report.summary_lines())
    drawn = {}
    monkeypatch.setattr(plotting, "plot_angle_series", lambda path, series, **kw: drawn.update(kw, series=series))
    plot_run(run, tmp_path / "plot.png")
    ((label, (of, t, lower, upper)),) = drawn["bands"].items()
    assert "80 % interval" in label and of in drawn["series"] and of.startswith("prediction +600 ms")
    np.testing.assert_allclose(t, drawn["series"][of][0])  # at the times the prediction is for
    np.testing.assert_allclose(upper - lower, 0.1, atol=1e-9)


def test_a_band_is_drawn_around_its_series(tmp_path):
    from PIL import Image

    from gwr_predictor.pipeline.plotting import plot_angle_series

    t = np.linspace(0.0, 5.0, 50)
    values = np.sin(t)[:, None] + np.arange(8)
    series = {"prediction": (t, values)}
    plain = plot_angle_series(tmp_path / "plain.png", series)
    banded = plot_angle_series(tmp_path / "banded.png", series,
                               bands={"its interval": ("prediction", t, values - 0.3, values + 0.3)})
    with Image.open(plain) as a, Image.open(banded) as b:
        differ = np.abs(np.asarray(a.convert("L"), float) - np.asarray(b.convert("L"), float)) > 10
    assert differ.mean() > 0.02  # a visible shaded area, not a legend entry alone


def test_report_command_writes_json_and_plot_next_to_the_bag(tmp_path, capsys):
    from gwr_predictor.commands.cli import main

    write_synthetic_run(tmp_path / "run" / "bag", lag_s=0.3, mode="fixed")
    assert main(["report", str(tmp_path / "run")]) == 0
    printed = capsys.readouterr().out
    assert "robot / (compensator mode fixed): lags the person by 0.30" in printed
    saved = json.loads((tmp_path / "run" / "report.json").read_text())
    assert saved["scored_predictions"] == 294 and saved["prediction_mae_rad"] == pytest.approx(0.0, abs=1e-9)
    assert (tmp_path / "run" / "report.png").stat().st_size > 10_000
    assert main(["report", str(tmp_path / "missing")]) == 1
