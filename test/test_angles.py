"""Angle extraction: known poses, exact inversion of the Nao chain, singularities, missing joints,
forward kinematics against the demonstrator, the angle CSV files, plots and the `angles` command."""

import argparse

import numpy as np
import pytest

from gwr_predictor.commands import angles as angles_cmd
from gwr_predictor.data.angle_files import load_angles_csv, save_angles_csv
from gwr_predictor.data.angles import PITCH_SINGULAR_WIDTH, arm_angles, clip_fractions, skeleton_to_angles, torso_frame
from gwr_predictor.data.demonstrator import PATTERNS, default_subjects, demonstrate, demonstrate_one
from gwr_predictor.data.errors import DataError
from gwr_predictor.data.skeleton_files import save_skeleton
from gwr_predictor.data.smoothing import median_of_3
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.plotting import plot_angle_series
from gwr_predictor.robot.nao import (
    ARM_JOINTS,
    ELBOW_OFFSET,
    HAND_OFFSET,
    WRIST_OFFSET,
    forward_kinematics,
    rot_x,
    rot_y,
    rot_z,
)

J = {name: i for i, name in enumerate(SKELETON_JOINTS)}
BODY_TO_CAMERA = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])
DOWN, UP, FORWARD, LEFT, RIGHT = (np.array(v, float) for v in
                                  ([0, 0, -1], [0, 0, 1], [1, 0, 0], [0, 1, 0], [0, -1, 0]))
HALF_PI = np.pi / 2


def skeleton(lu, lf, ru, rf, yaw=0.0, tilt=0.0):
    """Camera-frame skeleton (..., 15, 3) of a person whose arm segments point along the given
    torso-frame directions, turned by `yaw` and leaning by `tilt` relative to the sensor."""
    lu, lf, ru, rf = (np.asarray(v, float) for v in (lu, lf, ru, rf))
    shape = np.broadcast_shapes(lu.shape, lf.shape, ru.shape, rf.shape)
    body = np.zeros(shape[:-1] + (15, 3))
    fixed = {"head": (0, 0, 1.65), "neck": (0, 0, 1.45), "torso": (0, 0, 1.2), "left_shoulder": (0, 0.18, 1.45),
             "right_shoulder": (0, -0.18, 1.45), "left_hip": (0, 0.1, 0.95), "right_hip": (0, -0.1, 0.95),
             "left_knee": (0, 0.1, 0.5), "right_knee": (0, -0.1, 0.5), "left_foot": (0, 0.1, 0.05),
             "right_foot": (0, -0.1, 0.05)}
    for name, p in fixed.items():
        body[..., J[name], :] = p
    for side, u, f in (("left", lu, lf), ("right", ru, rf)):
        u = u / np.linalg.norm(u, axis=-1, keepdims=True)
        f = f / np.linalg.norm(f, axis=-1, keepdims=True)
        body[..., J[f"{side}_elbow"], :] = body[..., J[f"{side}_shoulder"], :] + 0.3 * u
        body[..., J[f"{side}_hand"], :] = body[..., J[f"{side}_elbow"], :] + 0.27 * f
    rot = rot_y(np.asarray(yaw)) @ BODY_TO_CAMERA @ rot_y(np.asarray(tilt))
    return body @ rot.T + np.array([0.1, -1.0, 2.2])


ORIENTATIONS = [(0.0, 0.0), (0.5, 0.0), (-0.3, 0.15)]


@pytest.mark.parametrize(("yaw", "tilt"), ORIENTATIONS)
def test_known_poses_give_known_angles_on_both_sides(yaw, tilt):
    def angles(lu, lf, ru, rf, clip=True):
        return skeleton_to_angles(skeleton(lu, lf, ru, rf, yaw, tilt), clip=clip)

    hanging = angles(DOWN, DOWN, DOWN, DOWN)
    np.testing.assert_allclose(hanging[[0, 1, 4, 5]], [HALF_PI, 0, HALF_PI, 0], atol=1e-9)
    np.testing.assert_allclose(hanging[[3, 7]], [-0.0349066, 0.0349066])  # straight elbows, clipped
    np.testing.assert_allclose(hanging[[2, 6]], [-HALF_PI, HALF_PI], atol=1e-9)  # documented straight-arm yaw
    forward = angles(FORWARD, FORWARD, FORWARD, FORWARD)
    np.testing.assert_allclose(forward[[0, 1, 4, 5]], 0.0, atol=1e-9)
    up = angles(UP, UP, UP, UP)
    np.testing.assert_allclose(up[[0, 4]], -HALF_PI, atol=1e-9)
    lateral = angles(LEFT, LEFT, RIGHT, RIGHT)
    np.testing.assert_allclose(lateral[[1, 5]], [1.32645, -1.32645])  # clipped to the limits
    np.testing.assert_allclose(angles(LEFT, LEFT, RIGHT, RIGHT, clip=False)[[1, 5]], [HALF_PI, -HALF_PI],
                               atol=1e-9)
    bent = angles(DOWN, FORWARD, DOWN, FORWARD)  # elbows at 90 degrees, forearms forward
    np.testing.assert_allclose(bent[[3, 7]], [-1.54462, 1.54462])
    np.testing.assert_allclose(angles(DOWN, FORWARD, DOWN, FORWARD, clip=False)[[3, 7]], [-HALF_PI, HALF_PI],
                               atol=1e-9)
    np.testing.assert_allclose(bent[[2, 6]], [-HALF_PI, HALF_PI], atol=1e-9)
    hands_up = angles(FORWARD, UP, FORWARD, UP)  # upper arms forward, forearms vertical
    np.testing.assert_allclose(hands_up[[0, 1, 2, 4, 5, 6]], [0, 0, -HALF_PI, 0, 0, HALF_PI], atol=1e-9)
    inward = angles(FORWARD, RIGHT, FORWARD, LEFT, clip=False)  # forearms folded in front of the chest
    np.testing.assert_allclose(inward[[2, 3, 6, 7]], [0.0, -HALF_PI, 0.0, HALF_PI], atol=1e-9)


def _chain(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Upper-arm and forearm axes of the Nao chain (no link offsets) for arm angles (..., 4)."""
    rs = rot_y(q[..., 0]) @ rot_z(q[..., 1])
    re = rs @ rot_x(q[..., 2]) @ rot_z(q[..., 3])
    return rs[..., :, 0], re[..., :, 0]


@pytest.mark.parametrize(("yaw", "tilt"), ORIENTATIONS)
def test_extraction_inverts_the_nao_chain_away_from_singularities(yaw, tilt):
    rng = np.random.default_rng(7)
    n = 2000
    q = np.column_stack([rng.uniform(-2.0, 2.0, n), rng.uniform(-1.1, 1.1, n), rng.uniform(-2.0, 2.0, n),
                         -rng.uniform(0.8, 1.5, n), rng.uniform(-2.0, 2.0, n), rng.uniform(-1.1, 1.1, n),
                         rng.uniform(-2.0, 2.0, n), rng.uniform(0.8, 1.5, n)])
    lu, lf = _chain(q[:, :4])
    ru, rf = _chain(q[:, 4:])
    got = skeleton_to_angles(skeleton(lu, lf, ru, rf, yaw, tilt), clip=False)
    # |roll| <= 1.1 and bends >= 0.8 rad are outside both singular zones: exact.
    np.testing.assert_allclose(got, q, atol=1e-9)


def test_straight_arm_yaw_is_stable_under_noise_instead_of_random():
    rng = np.random.default_rng(1)
    n = 500
    f = FORWARD + rng.normal(0.0, 0.02, (n, 3))  # about 1 degree of tracker noise on a straight arm
    got = skeleton_to_angles(skeleton(FORWARD, f, FORWARD, f))
    assert np.ptp(got[:, 2]) < 0.5 and np.ptp(got[:, 6]) < 0.5
    raw_yaw = np.arctan2(-f[:, 2], -f[:, 1])  # the unregularised bend-plane angle spans the circle
    assert np.ptp(raw_yaw) > 5.0


def test_lateral_raise_through_the_horizontal_sweeps_pitch_smoothly():
    elev = np.linspace(0.1, 2.6, 400)  # left arm rises sideways, 6 degrees in front of the frontal plane
    u = np.column_stack([0.1 * np.sin(elev), np.sin(elev), -np.cos(elev)])
    a = skeleton_to_angles(skeleton(u, u, DOWN, DOWN), clip=False)
    assert np.max(np.abs(np.diff(a[:, 0]))) < 0.1  # no jump where pitch is ill-conditioned
    assert a[0, 0] == pytest.approx(HALF_PI, abs=0.2) and a[-1, 0] < -1.0
    lu, _ = _chain(a[:, :4])
    err = np.degrees(np.arccos(np.clip(np.sum(lu * (u / np.linalg.norm(u, axis=1)[:, None]), 1), -1, 1)))
    # The price of the regularisation: the bias moves the upper arm by at most 0.27 x its width (rad).
    assert 0.5 < err.max() < np.degrees(0.27 * PITCH_SINGULAR_WIDTH)


def test_missing_or_degenerate_joints_give_all_nan_rows_only_there():
    good = skeleton(DOWN, FORWARD, LEFT, UP)
    frames = np.stack([good] * 6)
    frames[1, J["left_hand"], 0] = np.nan
    frames[2, J["right_shoulder"]] = np.inf
    frames[3, J["left_hip"]] = np.nan  # falls back to the torso joint: still valid
    frames[4, J["right_elbow"]] = frames[4, J["right_shoulder"]]  # zero-length upper arm
    frames[5, J["left_hip"]] = np.nan
    frames[5, J["torso"]] = np.nan  # no way to find "up"
    got = skeleton_to_angles(frames)
    assert np.isnan(got[[1, 2, 4, 5]]).all()
    np.testing.assert_allclose(got[3], got[0], atol=0.05)
    assert np.isfinite(got[[0, 3]]).all()


def test_any_batch_shape_and_a_single_frame_work():
    one = skeleton(DOWN, FORWARD, FORWARD, UP)
    batch = np.broadcast_to(one, (2, 3, 15, 3))
    assert skeleton_to_angles(one).shape == (8,)
    np.testing.assert_allclose(skeleton_to_angles(batch), np.broadcast_to(skeleton_to_angles(one), (2, 3, 8)))


def test_bad_shapes_and_missing_joint_names_are_refused():
    with pytest.raises(DataError, match=r"\(\.\.\., 15, 3\)"):
        skeleton_to_angles(np.zeros((4, 15, 2)))
    names = [*SKELETON_JOINTS[:-1], "tail"]
    skeleton_to_angles(np.zeros((15, 3)), joint_names=names)  # right_foot is not needed
    names = ["hand" if n == "left_hand" else n for n in SKELETON_JOINTS]
    with pytest.raises(DataError, match="left_hand"):
        skeleton_to_angles(np.zeros((15, 3)), joint_names=names)


def test_torso_frame_is_a_rotation():
    frames, valid = torso_frame(skeleton(DOWN, DOWN, DOWN, DOWN, yaw=0.7, tilt=0.2))
    np.testing.assert_allclose(frames @ frames.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(frames) == pytest.approx(1.0) and valid


# Nao link offsets: the elbow sits 15 mm beside the upper-arm axis (8.1 deg) and the hand 12 mm
# below the forearm axis (6.2 deg); the extraction does not correct for them.
ELBOW_OFFSET_DEG = np.degrees(np.arctan2(ELBOW_OFFSET[1], ELBOW_OFFSET[0]))
HAND_OFFSET_DEG = np.degrees(np.arctan2(-HAND_OFFSET[2], WRIST_OFFSET[0] + HAND_OFFSET[0]))


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    cos = np.sum(a * b, -1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


@pytest.fixture(scope="module")
def clean_demos():
    return {p: [median_of_3(s.positions, s.timestamps)[0] for s in demonstrate([p], repetitions=2, noise=False)]
            for p in PATTERNS}


@pytest.mark.parametrize("pattern", PATTERNS)
def test_nao_forward_kinematics_reproduces_the_arm_directions_of_every_pattern(clean_demos, pattern):
    """Tolerances, clean motion (tracker noise is tested separately):
    upper arm: 8.1 deg Nao elbow offset + 5.3 deg at most from the pitch regularisation near the
    lateral singularity (0.27 x PITCH_SINGULAR_WIDTH) + a little for the roll limit (76 deg);
    forearm: 6.2 deg Nao hand offset + 11 deg elbow-yaw regularisation on nearly straight elbows
    (bend below about 0.4 rad, error about bend x yaw shift)."""
    for pos in clean_demos[pattern]:
        angles = skeleton_to_angles(pos)
        assert np.isfinite(angles).all()
        frame, _ = torso_frame(pos)
        fk = forward_kinematics(angles)
        for side, prefix in (("L", "left"), ("R", "right")):
            s, e, h = (pos[:, J[f"{prefix}_{k}"]] for k in ("shoulder", "elbow", "hand"))
            u = np.einsum("tij,tj->ti", frame, e - s)
            f = np.einsum("tij,tj->ti", frame, h - e)
            pts = fk[side]
            assert _angle_deg(pts.elbow - pts.shoulder, u).max() < ELBOW_OFFSET_DEG + 6.0
            assert _angle_deg(pts.hand - pts.elbow, f).max() < HAND_OFFSET_DEG + 11.0


def test_tracker_noise_keeps_forward_kinematics_close_for_most_frames():
    errors = []
    for seq in demonstrate(repetitions=1):
        pos, _ = median_of_3(seq.positions, seq.timestamps)
        frame, _ = torso_frame(pos)
        fk = forward_kinematics(skeleton_to_angles(pos))
        for side, prefix in (("L", "left"), ("R", "right")):
            e, h = (pos[:, J[f"{prefix}_{k}"]] for k in ("elbow", "hand"))
            errors.append(_angle_deg(fk[side].hand - fk[side].elbow, np.einsum("tij,tj->ti", frame, h - e)))
    # Noise of a few mm on 27 cm forearms, glitches of several cm: a tail, but a short one.
    assert np.percentile(np.concatenate(errors), 95) < HAND_OFFSET_DEG + 11.0


def test_clip_fractions_count_rows_beyond_the_limits():
    raw = np.zeros((4, 8))
    raw[:, 3], raw[:, 7] = -0.5, 0.5
    raw[0, 1] = 1.5  # beyond LShoulderRoll's 1.326
    raw[1, 1] = np.nan  # missing rows do not count
    raw[1, :] = np.nan
    got = clip_fractions(raw)
    assert got["LShoulderRoll"] == pytest.approx(1 / 3)
    assert sum(got.values()) == pytest.approx(1 / 3)


def test_arm_angles_mirror_between_sides():
    rng = np.random.default_rng(3)
    u = rng.normal(size=(50, 3))
    f = rng.normal(size=(50, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    f /= np.linalg.norm(f, axis=1)[:, None]
    mirror = np.array([1.0, -1.0, 1.0])
    left = arm_angles(u, f, "L")
    right = arm_angles(u * mirror, f * mirror, "R")
    np.testing.assert_allclose(right, left * np.array([1.0, -1.0, -1.0, -1.0]), atol=1e-12)


# --- angle CSV files ------------------------------------------------------------------------------

def test_angle_csv_round_trip_keeps_nan_rows(tmp_path):
    t = np.arange(5) / 10.0
    a = np.random.default_rng(0).uniform(-1, 1, (5, 8))
    a[2] = np.nan
    path = save_angles_csv(tmp_path / "a.csv", t, a)
    assert path.read_text().splitlines()[0] == "time," + ",".join(ARM_JOINTS)
    assert "nan" in path.read_text().splitlines()[3]
    t2, a2, names = load_angles_csv(path)
    np.testing.assert_allclose(t2, t, atol=1e-6)
    np.testing.assert_allclose(a2, a, atol=1e-6)
    assert names == ARM_JOINTS


@pytest.mark.parametrize(("text", "message"), [
    ("", "empty file"),
    ("t,LShoulderPitch\n0,0\n", "first header column must be 'time'"),
    ("time,LShoulderPitch,Knee\n0,0,0\n", r"unknown joint columns \['Knee'\]"),
    ("time,LShoulderPitch\n0,0\n0.1,abc\n", "line 3, column 'LShoulderPitch': not a number"),
    ("time,LShoulderPitch\n0,0\n0.1,0.2,0.3\n", "line 3: 3 columns"),
    ("time,LShoulderPitch\n0,0\n0,0.1\n", "line 3: time 0.0 does not increase"),
    ("time,LShoulderPitch\n0,0\nnan,0.1\n", "line 3: time must be finite"),
    ("time,LShoulderPitch\n0,45\n0.1,90\n", "looks like degrees"),
])
def test_malformed_angle_csv_is_explained(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(DataError, match=message):
        load_angles_csv(path)


def test_empty_cells_read_as_nan(tmp_path):
    path = tmp_path / "e.csv"
    path.write_text("time,LShoulderPitch,RShoulderPitch\n0,,0.5\n\n0.1,0.2,0.3\n")
    _t, a, names = load_angles_csv(path)
    assert np.isnan(a[0, 0]) and a[1, 1] == pytest.approx(0.3) and names == ("LShoulderPitch", "RShoulderPitch")


# --- plots and the command ------------------------------------------------------------------------

def test_plot_writes_a_png_with_all_series(tmp_path):
    t = np.arange(30) / 10.0
    a = np.sin(t)[:, None] * np.ones(8)
    a[5] = np.nan
    path = plot_angle_series(tmp_path / "p.png", {"person": (t, a), "prediction": (t + 0.6, a)},
                             title="x", marks={"rep 2": 1.5})
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000
    with pytest.raises(PipelineError, match="series 'bad'"):
        plot_angle_series(tmp_path / "q.png", {"bad": (t, a[:, :7])})


def test_angles_command_writes_csv_and_plot_from_a_skeleton_file(tmp_path, capsys):
    seq = demonstrate_one("rotate_ccw_both", default_subjects(1)[0], 1)
    skel = save_skeleton(tmp_path / f"{seq.name}.npz", seq)
    parser = argparse.ArgumentParser()
    angles_cmd.configure(parser)
    args = parser.parse_args([str(skel), "-o", str(tmp_path / "a.csv"), "--plot", str(tmp_path / "a.png")])
    assert angles_cmd.run(args) == 0
    t, a, _names = load_angles_csv(tmp_path / "a.csv")
    pos, stamps = median_of_3(seq.positions, seq.timestamps)
    np.testing.assert_allclose(t, stamps, atol=1e-6)
    np.testing.assert_allclose(a, skeleton_to_angles(pos), atol=1e-6)
    assert (tmp_path / "a.png").stat().st_size > 10_000
    assert "frames (0 missing)" in capsys.readouterr().err


def test_angles_command_reports_a_bad_file(tmp_path, capsys):
    (tmp_path / "x.npz").write_bytes(b"garbage")
    parser = argparse.ArgumentParser()
    angles_cmd.configure(parser)
    assert angles_cmd.run(parser.parse_args([str(tmp_path / "x.npz")])) == 2
    assert "not a readable NPZ archive" in capsys.readouterr().err
