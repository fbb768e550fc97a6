"""The synthetic demonstrator: reproducible, humanly plausible, 10 distinct patterns, and the
10 fps angle data set the learner consumes."""

import dataclasses

import numpy as np
import pytest

from gwr_predictor.data.angles import skeleton_to_angles, torso_frame
from gwr_predictor.data.datasets import AngleSequence, demo_angle_sequences
from gwr_predictor.data.demonstrator import (
    HUMAN_RANGES,
    PATTERNS,
    SubjectProfile,
    arm_trajectories,
    default_subjects,
    demonstrate,
    demonstrate_one,
    duration,
)
from gwr_predictor.data.errors import DataError
from gwr_predictor.data.smoothing import median_of_3
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS
from gwr_predictor.robot.nao import ARM_JOINTS, VELOCITY_LIMITS

J = {name: i for i, name in enumerate(SKELETON_JOINTS)}
SUBJECTS = default_subjects(3)


def test_there_are_exactly_the_papers_ten_patterns():
    assert len(PATTERNS) == len(set(PATTERNS)) == 10
    for kind in ("raise_lateral", "raise_front", "wave", "rotate_cw", "rotate_ccw"):
        assert {f"{kind}_one", f"{kind}_both"} <= set(PATTERNS)


def test_same_seed_reproduces_and_other_seeds_or_repetitions_differ():
    a = demonstrate_one("wave_both", SUBJECTS[0], 3, seed=11)
    b = demonstrate_one("wave_both", SUBJECTS[0], 3, seed=11)
    np.testing.assert_array_equal(a.positions, b.positions)
    for other in (demonstrate_one("wave_both", SUBJECTS[0], 3, seed=12),
                  demonstrate_one("wave_both", SUBJECTS[0], 4, seed=11)):
        n = min(len(a.timestamps), len(other.timestamps))
        assert np.abs(a.positions[:n] - other.positions[:n]).max() > 0.02


def test_default_subjects_are_three_fixed_people_and_more_can_be_drawn():
    assert [s.name for s in SUBJECTS] == ["s1", "s2", "s3"]
    assert default_subjects(3, seed=5) == SUBJECTS  # the seed only affects extra subjects
    five = default_subjects(5, seed=1)
    assert five[:3] == SUBJECTS and len({s.name for s in five}) == 5
    assert five[3:] == default_subjects(5, seed=1)[3:] != default_subjects(5, seed=2)[3:]
    assert len({(s.height, s.speed, s.amplitude) for s in five}) == 5  # they differ in body and style


@pytest.mark.parametrize(("field", "value"), [("upper_arm", 0.9), ("speed", 0.0), ("noise_mm", -1.0),
                                              ("distance", 5.0), ("amplitude", "big")])
def test_subject_profile_names_the_bad_field_and_its_range(field, value):
    with pytest.raises(DataError, match=rf"SubjectProfile\.{field} must be in \[.*\]"):
        dataclasses.replace(SUBJECTS[0], **{field: value})


def test_bad_pattern_and_counts_are_refused():
    with pytest.raises(DataError, match="unknown pattern 'jump'"):
        demonstrate(["jump"], repetitions=1)
    with pytest.raises(DataError, match="repetitions"):
        demonstrate(repetitions=0)
    with pytest.raises(DataError, match="subjects"):
        default_subjects(0)


def test_demonstrate_nests_patterns_subjects_repetitions():
    seqs = demonstrate(["raise_front_one", "wave_both"], subjects=2, repetitions=2, seed=1)
    assert [(s.pattern, s.subject, s.repetition) for s in seqs] == [
        (p, s, r) for p in ("raise_front_one", "wave_both") for s in ("s1", "s2") for r in (1, 2)]
    assert all(s.positions.shape[1:] == (15, 3) and s.joint_names == SKELETON_JOINTS for s in seqs)


@pytest.fixture(scope="module")
def clean():
    return demonstrate(repetitions=2, noise=False)


@pytest.fixture(scope="module")
def noisy():
    return demonstrate(repetitions=2)


def test_repetitions_last_a_few_seconds_at_30_fps_with_rest_at_both_ends(clean):
    for seq in clean:
        assert 3.0 <= seq.timestamps[-1] <= 8.0
        assert seq.fps == pytest.approx(30.0)
        frame, _ = torso_frame(seq.positions[[0, -1]])
        for side in ("left", "right"):
            hand = seq.joint(f"{side}_hand")[[0, -1]] - seq.joint(f"{side}_shoulder")[[0, -1]]
            down = -np.einsum("tij,tj->ti", frame, hand)[:, 2] / np.linalg.norm(hand, axis=1)
            assert (down > 0.9).all(), seq.name  # hands hang below the shoulders


def test_camera_frame_convention_person_faces_the_sensor(clean):
    for seq in clean[:: len(clean) // 7]:
        p = seq.positions
        # x towards the person's right, y up, z away from the sensor.
        assert (p[:, J["right_shoulder"], 0] > p[:, J["left_shoulder"], 0]).all()
        assert (p[:, J["head"], 1] > p[:, J["left_foot"], 1] + 1.2).all()
        assert (np.abs(p[:, J["torso"], 1]) < 0.6).all()  # sensor 1 m up, torso near that height
        assert (1.5 < p[:, J["torso"], 2]).all() and (p[:, J["torso"], 2] < 3.0).all()
        # facing the sensor: the shoulder line is across the view, not along it
        across = p[:, J["right_shoulder"]] - p[:, J["left_shoulder"]]
        assert (np.abs(across[:, 0]) > 2.0 * np.abs(across[:, 2])).all()


def test_limb_lengths_are_constant_exactly_without_noise_and_within_noise_with_it(clean, noisy):
    for seqs, tol in ((clean, 1e-9), (noisy, 0.02)):
        for seq in seqs:
            for side in ("left", "right"):
                s, e, h = (seq.joint(f"{side}_{k}") for k in ("shoulder", "elbow", "hand"))
                for a, b in ((s, e), (e, h)):
                    length = np.linalg.norm(b - a, axis=1)
                    assert np.median(np.abs(length - np.median(length))) < tol, seq.name


def test_arm_trajectories_stay_within_human_ranges():
    rng = np.random.default_rng(0)
    for subject in default_subjects(6, seed=3):
        for pattern in PATTERNS:
            for _ in range(3):
                total, var = duration(pattern, subject, rng)
                t = np.arange(0.0, total, 1 / 30)
                for arm in arm_trajectories(pattern, subject, t, rng, var):
                    for name, values in arm._asdict().items():
                        lo, hi = HUMAN_RANGES[name]
                        assert lo <= values.min() and values.max() <= hi, (pattern, subject.name, name)


def _angle_steps(seqs) -> np.ndarray:
    """|angle change| per second between consecutive 10 fps frames, relative to the Nao limit."""
    limits = np.array([VELOCITY_LIMITS[n] for n in ARM_JOINTS])
    out = []
    for seq in seqs:
        pos, t = median_of_3(seq.positions, seq.timestamps)
        out.append(np.abs(np.diff(skeleton_to_angles(pos), axis=0)) / np.diff(t)[:, None] / limits)
    return np.concatenate(out)


def test_movements_are_smooth_within_nao_velocity_limits(clean):
    assert _angle_steps(clean).max() < 0.8


def test_tracker_noise_rarely_pushes_angle_steps_past_the_velocity_limits(noisy):
    steps = _angle_steps(noisy)
    assert np.mean(steps > 1.0) < 0.002  # a few glitches of several cm survive the median


def test_one_arm_patterns_move_the_right_arm_while_the_left_hangs(clean):
    for seq in clean:
        pos, _ = median_of_3(seq.positions, seq.timestamps)
        spread = np.ptp(skeleton_to_angles(pos), axis=0)
        left, right = spread[:4].max(), spread[4:].max()
        if seq.pattern.endswith("_one"):
            assert left < 0.35 < 0.9 < right, seq.name
        else:
            assert min(left, right) > 0.9, seq.name


def _hand_circle_sense(seq, side: str) -> float:
    """Signed area of the hand path seen by the person looking ahead (right = -y, up = z): < 0 is cw."""
    frame, _ = torso_frame(seq.positions)
    hand = np.einsum("tij,tj->ti", frame, seq.joint(f"{side}_hand") - seq.joint(f"{side}_shoulder"))
    x, y = -hand[:, 1], hand[:, 2]
    return 0.5 * float(np.sum(x[:-1] * y[1:] - x[1:] * y[:-1]))


def test_rotations_circle_the_hands_in_the_named_sense(clean):
    for seq in clean:
        if not seq.pattern.startswith("rotate"):
            continue
        sides = ("left", "right") if seq.pattern.endswith("both") else ("right",)
        for side in sides:
            area = _hand_circle_sense(seq, side)
            assert abs(area) > 0.01, seq.name  # at least a few 100 cm^2 per repetition
            assert (area < 0) == ("_cw_" in seq.pattern), (seq.name, side, area)


def _features(seq: AngleSequence, tau: float = 0.3) -> np.ndarray:
    """Poses with their velocity (x tau): telling cw from ccw needs the direction of travel."""
    return np.hstack([seq.angles, tau * np.gradient(seq.angles, seq.t, axis=0)])


def _chamfer(a: np.ndarray, b: np.ndarray) -> float:
    d = np.linalg.norm(a[:, None] - b[None], axis=-1)
    return 0.5 * (d.min(axis=1).mean() + d.min(axis=0).mean())


def test_patterns_are_distinct_beyond_repetition_variation():
    """Timing varies between repetitions, so trajectories are compared as sets of (pose, velocity):
    every repetition's nearest other repetition of the same person is of the same pattern."""
    data = demo_angle_sequences(repetitions=4)
    for subject in ("s1", "s2", "s3"):
        seqs = [s for s in data if s.subject == subject]
        feats = [_features(s) for s in seqs]
        dist = np.array([[_chamfer(a, b) for b in feats] for a in feats])
        np.fill_diagonal(dist, np.inf)
        labels = np.array([s.pattern for s in seqs])
        assert (labels[dist.argmin(axis=1)] == labels).all(), subject


def test_demo_angle_sequences_are_10fps_cached_and_read_only():
    data = demo_angle_sequences(["wave_one", "rotate_cw_both"], subjects=2, repetitions=2, seed=4)
    assert demo_angle_sequences(("wave_one", "rotate_cw_both"), subjects=2, repetitions=2, seed=4) is data
    assert [(s.pattern, s.subject, s.repetition) for s in data][:3] == [
        ("wave_one", "s1", 1), ("wave_one", "s1", 2), ("wave_one", "s2", 1)]
    for seq in data:
        assert seq.angles.shape == (len(seq.t), 8) and np.isfinite(seq.angles).all()
        np.testing.assert_allclose(np.diff(seq.t), 0.1, atol=1e-9)
        with pytest.raises(ValueError, match="read-only"):
            seq.angles[0, 0] = 1.0
    one = demo_angle_sequences("wave_one", subjects=[SubjectProfile("alice")], repetitions=1)
    assert len(one) == 1 and one[0].name == "wave_one_alice_r01"
