"""Videos of a run: frames drawn from a small bag written here, robots that move or stay put, the
ghost over an in-sync robot, clear errors, and MP4/GIF files through the command line."""

import numpy as np
import pytest
from PIL import Image

from gwr_predictor.commands.cli import main
from gwr_predictor.data.demonstrator import default_subjects, demonstrate_one
from gwr_predictor.pipeline import bag_messages, bag_writer, conventions
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.video import PERSON_ARM_RGB, PERSON_RGB, FrameRenderer, parse_span, read_video_run
from gwr_predictor.robot.errors import RobotError
from gwr_predictor.robot.nao import ARM_JOINTS
from gwr_predictor.robot.pybullet_nao import NaoSimulator

ARMS_DOWN = np.array([1.4, 0.15, -1.2, -0.4, 1.4, -0.15, 1.2, 0.4])
ARMS_UP = np.array([-1.2, 0.3, -1.0, -0.3, -1.2, -0.3, 1.0, 0.3])
T0 = 500.0
SECONDS = 3.0
LABEL_ROWS = 40  # the panel captions live above this row (scale 1)


def still(pose):
    return lambda t: pose


def swing(t):
    """Both arms from down (t = 0) to up (t = SECONDS), linearly."""
    w = np.clip(t / SECONDS, 0.0, 1.0)
    return (1.0 - w) * ARMS_DOWN + w * ARMS_UP


def write_bag(path, person=swing, robots=None, modes=None, skeleton=True):
    """A pipeline bag: the person's angles at 10 fps (and the demonstrator's skeleton at 30 fps),
    each robot's joint states at 50 Hz from `robots[ns](t)`, each compensator's mode."""
    robots = {"": swing, "/uncompensated": swing} if robots is None else robots
    modes = {"": "fixed", "/uncompensated": "none"} if modes is None else modes
    topics = {"/arm_angles": bag_messages.JOINT_STATE}
    if skeleton:
        topics["/skeleton"] = bag_messages.FLOAT64_MULTIARRAY
    for ns in robots:
        topics[f"{ns}/joint_states"] = bag_messages.JOINT_STATE
    for ns in modes:
        topics[f"{ns}/diagnostics"] = "diagnostic_msgs/msg/DiagnosticArray"
    seq = demonstrate_one("wave_both", default_subjects(1)[0], 1, noise=False)
    types = bag_messages.TYPESTORE.types
    with bag_writer.BagWriter(path, topics) as writer:
        for k in range(round(SECONDS * 10) + 1):
            t = 0.1 * k
            writer.write("/arm_angles", int((T0 + t) * 1e9),
                         bag_messages.joint_state_msg(ARM_JOINTS, person(t), T0 + t))
        if skeleton:
            for k in range(round(SECONDS * 30) + 1):
                t = k / 30.0
                frame = seq.positions[k % len(seq.positions)]
                writer.write("/skeleton", int((T0 + t) * 1e9),
                             bag_messages.multiarray_msg(conventions.pack_skeleton(T0 + t, frame)))
        for ns, fn in robots.items():
            for k in range(round(SECONDS * 50) + 1):
                t = 0.02 * k
                writer.write(f"{ns}/joint_states", int((T0 + t) * 1e9),
                             bag_messages.joint_state_msg(ARM_JOINTS, fn(t), T0 + t))
        for ns, mode in modes.items():
            status = types["diagnostic_msgs/msg/DiagnosticStatus"](
                level=0, name=f"{ns}/delay_compensator", message="", hardware_id="",
                values=[types["diagnostic_msgs/msg/KeyValue"](key="mode", value=mode)])
            header = types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=int(T0) + 1,
                                                                                            nanosec=0), frame_id="")
            writer.write(f"{ns}/diagnostics", int((T0 + 1) * 1e9),
                         types["diagnostic_msgs/msg/DiagnosticArray"](header=header, status=[status]))
    return path


def panels(frame, renderer):
    """The frame's panels (below the caption rows), left to right."""
    w, h = renderer.panel_w, renderer.panel_h
    return [frame[LABEL_ROWS:h, k * w:(k + 1) * w] for k in range(frame.shape[1] // w)]


def robot_pixels(renderer, image):
    """Where a robot render differs from the empty scene: the robot itself."""
    return np.any(np.abs(image.astype(int) - renderer.empty_scene.astype(int)) > 12, axis=2)


def test_frames_are_not_blank_and_show_person_robots_and_captions(tmp_path):
    run = read_video_run(write_bag(tmp_path / "bag"))
    assert list(run.robots) == ["", "/uncompensated"] and run.modes == {"": "fixed", "/uncompensated": "none"}
    assert run.skeleton.shape[1:] == (15, 3)
    with FrameRenderer(run, 0.0, SECONDS) as r:
        frame = r.frame(1.5)
        assert frame.shape == (r.height, r.width, 3) == (288, 960, 3)
        person, comp, uncomp = panels(frame, r)
        for panel in (person, comp, uncomp):
            _, counts = np.unique(panel.reshape(-1, 3), axis=0, return_counts=True)
            assert counts.size >= 4 and counts.max() < 0.8 * counts.sum()  # no colour fills the panel
        assert np.all(person == PERSON_RGB, axis=2).sum() > 200  # the stick figure's body
        assert np.all(person == PERSON_ARM_RGB, axis=2).sum() > 100  # and its arms
        for panel in (comp, uncomp):
            assert robot_pixels(r, np.vstack([r.empty_scene[:LABEL_ROWS], panel])).sum() > 3000
        caption = frame[r.panel_h:]
        assert (caption.max(axis=2) < 60).sum() > 200  # text


def test_robot_pixels_move_when_its_angles_move_and_stay_put_when_not(tmp_path):
    bag = write_bag(tmp_path / "bag", person=still(ARMS_DOWN), robots={"": swing, "/uncompensated": still(ARMS_DOWN)})
    with FrameRenderer(read_video_run(bag), 0.0, SECONDS) as r:
        a, b = r.frame(0.5), r.frame(2.5)
    _, moving_a, still_a = panels(a, r)
    _, moving_b, still_b = panels(b, r)
    assert np.any(moving_a != moving_b, axis=2).sum() > 1500
    np.testing.assert_array_equal(still_a, still_b)


def test_ghost_covers_an_in_sync_robot_and_trails_a_lagging_one(tmp_path):
    run = read_video_run(write_bag(tmp_path / "bag"))
    with FrameRenderer(run, 0.0, SECONDS) as r:
        for pose in (ARMS_DOWN, ARMS_UP, 0.5 * (ARMS_DOWN + ARMS_UP)):
            ghost = r.ghost_mask(pose)
            assert ghost.sum() > 300
            in_sync = (ghost & robot_pixels(r, r.robot_image(pose))).sum() / ghost.sum()
            assert in_sync > 0.9, in_sync
        ghost = r.ghost_mask(ARMS_UP)
        off = (ghost & robot_pixels(r, r.robot_image(ARMS_DOWN))).sum() / ghost.sum()
        assert off < 0.5, off
        # drawn into a frame: the ghost of a robot in sync changes only pixels of the robot itself
        image = r.robot_image(ARMS_UP)
        changed = np.any(r.draw_ghost(image, ARMS_UP) != image, axis=2)
        assert changed.sum() > 300 and (changed & robot_pixels(r, image)).sum() / changed.sum() > 0.85


def test_the_captions_follow_the_lag(tmp_path):
    """A robot 0.4 s late is measured 0.4 s late by the windowed lag of the captions."""
    def person(t):
        return ARMS_DOWN + 0.4 * np.sin(2 * np.pi * 0.5 * t)

    bag = write_bag(tmp_path / "bag", person=person, robots={"": lambda t: person(t - 0.4)}, modes={"": "fixed"},
                    skeleton=False)
    run = read_video_run(bag)
    with FrameRenderer(run, 0.0, SECONDS) as r:
        m = r.metrics[""]
        frame = r.frame(2.0)
    assert m.lag[-1] == pytest.approx(0.4, abs=0.03)
    assert frame.shape[1] == 2 * r.panel_w  # the person (as arm angles, no skeleton) and one robot


def test_a_bag_without_robot_topics_is_a_clear_error(tmp_path, capsys):
    bag = write_bag(tmp_path / "bag", robots={}, modes={})
    with pytest.raises(PipelineError, match=r"bag: no robot in the bag \(no <namespace>/joint_states.*arm_angles"):
        read_video_run(bag)
    assert main(["render", str(bag), "-o", str(tmp_path / "v.gif"), "--no-progress"]) == 1
    assert "no robot in the bag" in capsys.readouterr().err
    assert not (tmp_path / "v.gif").exists()


def test_span_parsing():
    assert parse_span(None, 60.0) == (0.0, 60.0)
    assert parse_span("-20:", 60.0) == (40.0, 60.0)
    assert parse_span("10:30", 60.0) == (10.0, 30.0)
    assert parse_span(":-5", 60.0) == (0.0, 55.0)
    for bad in ("5", "a:b", "30:10", "70:80"):
        with pytest.raises(PipelineError, match="--seconds"):
            parse_span(bad, 60.0)


def test_render_command_writes_an_mp4_and_a_gif(tmp_path, capsys):
    import imageio_ffmpeg

    bag = write_bag(tmp_path / "run" / "bag")
    assert main(["render", str(tmp_path / "run"), "--seconds", "1:2", "--scale", "0.5", "--no-progress"]) == 0
    mp4 = tmp_path / "run" / "video.mp4"
    assert "written" in capsys.readouterr().out and mp4.is_file()
    reader = imageio_ffmpeg.read_frames(str(mp4))
    meta = next(reader)
    assert tuple(meta["size"]) == (480, 160) and sum(1 for _ in reader) == 30
    gif = tmp_path / "v.gif"
    assert main(["render", str(bag), "-o", str(gif), "--seconds=-1:", "--fps", "10", "--scale", "0.5",
                 "--no-progress"]) == 0
    with Image.open(gif) as im:
        assert im.size == (480, 160) and im.n_frames == 10
    gif15 = tmp_path / "v15.gif"  # 15 fps: delays of 60 and 70 ms that add up to real time
    assert main(["render", str(bag), "-o", str(gif15), "--seconds", "0:2", "--scale", "0.5", "--no-progress"]) == 0
    with Image.open(gif15) as im:
        delays = []
        for k in range(im.n_frames):
            im.seek(k)
            delays.append(im.info["duration"])
    assert len(delays) == 30 and sum(delays) == 2000 and set(delays) == {60, 70}
    assert not list(tmp_path.rglob("*.part.*"))


def test_gui_without_a_display_is_refused_with_the_reason(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    with pytest.raises(RobotError, match="DISPLAY is not set"):
        NaoSimulator(gui=True)


@pytest.mark.ros
def test_nao_sim_with_gui_but_no_display_warns_and_runs_headless(ros):
    from gwr_predictor.nodes import messages

    ros.env.pop("DISPLAY", None)
    states = ros.probe.subscribe(f"/{conventions.TOPIC_ROBOT_STATE}", messages.JointState)
    proc = ros.start("nao_sim", params={"gui": True})
    ros.wait_for_log(proc, "ready")
    assert "parameter 'gui': gui=True needs a display, but DISPLAY is not set" in proc.output()
    assert "running headless instead" in proc.output()
    ros.probe.spin_until(lambda: len(states) >= 5, 30, "joint_states from the headless nao_sim", [proc])
