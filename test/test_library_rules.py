"""Rules that used to live in the nodes, now library code the nodes call: the parameter spec, the gap
rule, skeleton reordering, the corrupt-checkpoint policy, the sine delay, the robot-state timeout and
the one skeleton -> median -> angles -> clip path."""

import warnings

import numpy as np
import pytest

from gwr_predictor.data.datasets import demo_angle_sequences
from gwr_predictor.data.demonstrator import default_subjects, demonstrate_one
from gwr_predictor.data.extraction import extract_angles, frame_angles
from gwr_predictor.learning.checkpoint import set_aside
from gwr_predictor.learning.params import hierarchy_parameter_specs
from gwr_predictor.parameters.spec import ParameterError, ParamSpec
from gwr_predictor.pipeline.conventions import ARM_JOINTS, SKELETON_JOINTS, split_stamp, stamp_seconds
from gwr_predictor.pipeline.input_rules import ArmAnglesCheck, RejectionCounter, SkeletonReorder, missing_frames
from gwr_predictor.robot.compensator import DelayCompensator, recent_state
from gwr_predictor.robot.delayed_arm import sine_delay
from gwr_predictor.robot.nao import clip_to_limits


class _Log:
    def warning(self, text):
        pass

    info = warning


def test_param_spec_checks_type_range_and_choices_and_says_what_is_allowed():
    spec = ParamSpec("rate", 1.0, "speed", 0.0, 10.0, lo_open=True)
    assert spec.check(2) == 2.0 and isinstance(spec.check(2), float)
    assert (spec.lo, spec.hi, spec.read_only, spec.kind) == (0.0, 10.0, True, "double")
    with pytest.raises(ParameterError, match=r"'rate' = 0.0 is outside the allowed range \(0.0, 10.0\]"):
        spec.check(0.0)
    with pytest.raises(ParameterError, match=r"Owner.rate must be in \(0.0, 10.0\], got 11"):
        spec.check(11, owner="Owner")
    with pytest.raises(ParameterError, match="must be a number"):
        spec.check("fast")
    assert ParamSpec("gain", 0.5, "live", 0.0, 1.0, live=True).read_only is False
    mode = ParamSpec("mode", "a", "m", choices=("a", "b"))
    with pytest.raises(ParameterError, match="must be one of 'a', 'b'"):
        mode.check("c")


def test_hierarchy_specs_are_the_ones_the_dataclasses_check():
    specs = {s.name: s for s in hierarchy_parameter_specs()}
    assert specs["gwr1.activation_threshold"].lo_open and specs["gwr1.activation_threshold"].hi_open
    assert specs["pgwr.max_neurons"].check(0) == 0  # 0 stands for unlimited
    with pytest.raises(ParameterError):
        specs["pgwr.max_neurons"].check(1)
    assert specs["gwr2.max_edge_age"].default == 200


def test_gap_rule_counts_missing_frames_or_ends_the_sequence():
    assert missing_frames(0.1, 0.1, 0.5) == 0
    assert missing_frames(0.31, 0.1, 0.5) == 2
    assert missing_frames(0.05, 0.1, 0.5) == 0
    assert missing_frames(0.6, 0.1, 0.5) is None


def test_skeleton_reorder_drops_unknown_and_fills_missing_with_nan():
    counters = RejectionCounter(_Log())
    reorder = SkeletonReorder(counters)
    names = ("extra", *reversed(SKELETON_JOINTS[1:]))
    positions = np.arange(len(names) * 3, dtype=float).reshape(-1, 3)
    out = reorder(names, positions)
    assert np.isnan(out[0]).all()
    np.testing.assert_array_equal(out[1], positions[-1])
    assert counters.get("skeleton.unknown_joints_ignored") == 1
    assert counters.get("skeleton.missing_joints_filled_nan") == 1


def test_corrupt_checkpoint_is_moved_aside_not_lost(tmp_path):
    path = tmp_path / "model.npz"
    path.write_bytes(b"not a zip")
    aside = set_aside(path, when="x")
    assert not path.exists() and aside.name == "model.npz.corrupt-x" and aside.read_bytes() == b"not a zip"


def test_sine_delay_and_robot_state_timeout():
    assert sine_delay(5.0, 0.6, 0.0, 20.0) == 0.6
    assert sine_delay(5.0, 0.6, 0.2, 20.0) == pytest.approx(0.8)
    assert sine_delay(15.0, 0.1, 0.5, 20.0) == 0.0
    state = np.zeros(8)
    assert recent_state(state, 1.0, 1.4, 0.5) is state
    assert recent_state(state, 1.0, 1.6, 0.5) is None
    comp = DelayCompensator(stale_after_s=0.5)
    assert comp.stale(10.6, 10.0) and not comp.stale(10.4, 10.0) and comp.stale(10.0, None)


def test_stamp_conversion_round_trips_and_carries_nanoseconds():
    assert split_stamp(1.9999999999) == (2, 0)
    sec, nanosec = split_stamp(12.25)
    assert (sec, nanosec) == (12, 250_000_000)

    class T:
        pass

    t = T()
    t.sec, t.nanosec = sec, nanosec
    assert stamp_seconds(t) == 12.25
    with pytest.raises(ValueError):
        split_stamp(-1.0)


def test_one_extraction_path_clips_once_and_the_dataset_uses_it():
    subject = default_subjects(1)[0]
    seq = demonstrate_one("wave_one", subject, 1)
    ext = extract_angles(seq.positions, seq.timestamps)
    assert len(ext.t) == len(seq.timestamps) // 3
    np.testing.assert_array_equal(ext.angles, clip_to_limits(ext.raw))
    data = demo_angle_sequences("wave_one", [subject], repetitions=1)[0]
    np.testing.assert_array_equal(data.angles, ext.angles)
    clipped, raw = frame_angles(seq.positions[1])
    np.testing.assert_array_equal(clipped, clip_to_limits(raw))


def test_arm_angles_check_rejects_huge_and_non_finite_angles_without_numeric_warnings():
    counters = RejectionCounter(_Log())
    check = ArmAnglesCheck(counters, "arm_angles", check_stamps=False)
    angles = np.zeros(len(ARM_JOINTS))
    angles[:2] = [1e308, np.nan]  # the rejection's message once overflowed while rounding 1e308
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert check.accept(1.0, ARM_JOINTS, angles) is None
    assert counters.get("rejected.arm_angles.non_finite") == 1


def test_arm_angles_check_without_a_limit_rule_passes_commands_on_unclipped():
    """nao_sim's commands: the robot's input clips them (once), so the check neither rejects nor clips."""
    counters = RejectionCounter(_Log())
    check = ArmAnglesCheck(counters, "joint_commands", limit_margin=None, check_stamps=False)
    wild = np.full(len(ARM_JOINTS), 5.0)
    _, angles = check.accept(1.0, ARM_JOINTS, wild)
    np.testing.assert_array_equal(angles, wild)
    assert counters.snapshot() == {}
    assert check.accept(2.0, ARM_JOINTS, np.full(len(ARM_JOINTS), np.nan)) is None  # the other rules stay
    assert counters.get("rejected.joint_commands.non_finite") == 1
