"""Skeleton files: NPZ and CSV round trips, and clear errors for every kind of broken file."""

import argparse

import numpy as np
import pytest

from gwr_predictor.commands import demonstrate as demonstrate_cmd
from gwr_predictor.data.demonstrator import default_subjects, demonstrate_one
from gwr_predictor.data.errors import DataError
from gwr_predictor.data.skeleton_files import SkeletonSequence, load_skeleton, save_skeleton
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS


@pytest.fixture(scope="module")
def seq() -> SkeletonSequence:
    s = demonstrate_one("wave_one", default_subjects(1)[0], repetition=2, seed=3)
    s.positions[5, 2] = np.nan  # an untracked joint survives the round trip
    return s


def _npz(path, **arrays):
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    return path


def _valid_arrays(n=4):
    pos = np.zeros((n, 15, 3))
    pos[..., 2] = 2.0
    return {"positions": pos, "joint_names": np.array(SKELETON_JOINTS), "timestamps": np.arange(n) / 30.0}


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_round_trip_keeps_positions_stamps_nans_and_labels(tmp_path, seq, suffix):
    path = save_skeleton(tmp_path / f"x{suffix}", seq)
    back = load_skeleton(path)
    tol = 0 if suffix == ".npz" else 1e-6  # CSV keeps micrometres
    np.testing.assert_allclose(back.positions, seq.positions, atol=tol)
    np.testing.assert_allclose(back.timestamps, seq.timestamps, atol=tol)
    assert np.isnan(back.positions[5, 2]).all()
    assert (back.pattern, back.subject, back.repetition) == ("wave_one", "s1", 2)
    assert back.joint_names == SKELETON_JOINTS and back.convention == seq.convention


def test_joints_are_reordered_and_extra_joints_dropped(tmp_path):
    arrays = _valid_arrays()
    order = list(reversed(SKELETON_JOINTS)) + ["left_wrist"]
    pos = np.concatenate([arrays["positions"], np.zeros((4, 1, 3))], axis=1)
    pos[:, 0] = [0.1, 0.2, 2.3]  # 'right_foot' in this file's order
    arrays.update(positions=pos, joint_names=np.array(order))
    back = load_skeleton(_npz(tmp_path / "r.npz", **arrays))
    assert back.positions.shape == (4, 15, 3)
    np.testing.assert_array_equal(back.joint("right_foot"), np.tile([0.1, 0.2, 2.3], (4, 1)))
    assert back.pattern is None and back.repetition is None


def test_fps_can_replace_timestamps(tmp_path):
    arrays = _valid_arrays(6)
    del arrays["timestamps"]
    back = load_skeleton(_npz(tmp_path / "f.npz", fps=np.array(30.0), **arrays))
    np.testing.assert_allclose(back.timestamps, np.arange(6) / 30.0)
    assert back.fps == pytest.approx(30.0)


@pytest.mark.parametrize(("change", "message"), [
    ({"positions": np.zeros((4, 15))}, r"'positions' must be \(frames, joints, 3\)"),
    ({"positions": np.zeros((4, 14, 3))}, "14 joints in positions"),
    ({"joint_names": np.array(list(SKELETON_JOINTS[:-1]) + ["tail"])}, r"lacks \['right_foot'\]"),
    ({"timestamps": np.array([0.0, 0.1, 0.1, 0.2])}, "not strictly increasing at frame 2"),
    ({"timestamps": np.array([0.0, np.nan, 0.2, 0.3])}, r"timestamps\[1\] is nan"),
    ({"timestamps": np.arange(3.0)}, r"must have shape \(4,\)"),
    ({"convention": np.array("kinect-lh")}, "convention 'kinect-lh' is not supported"),
    ({"positions": np.full((4, 15, 3), "a")}, "must be numeric"),
])
def test_malformed_npz_fields_are_named(tmp_path, change, message):
    arrays = {**_valid_arrays(), **change}
    path = _npz(tmp_path / "bad.npz", **arrays)
    with pytest.raises(DataError, match=message) as err:
        load_skeleton(path)
    assert str(path) in str(err.value)


def test_millimetres_are_refused_with_the_fix(tmp_path):
    arrays = _valid_arrays()
    arrays["positions"] = arrays["positions"] * 1000.0
    with pytest.raises(DataError, match=r"looks like millimetres.*divide by 1000"):
        load_skeleton(_npz(tmp_path / "mm.npz", **arrays))


def test_infinite_position_is_refused_with_frame_and_joint(tmp_path):
    arrays = _valid_arrays()
    arrays["positions"][2, SKELETON_JOINTS.index("left_hand"), 1] = np.inf
    with pytest.raises(DataError, match=r"positions\[2\] left_hand_y is infinite"):
        load_skeleton(_npz(tmp_path / "inf.npz", **arrays))


def test_missing_arrays_are_named(tmp_path):
    arrays = _valid_arrays()
    del arrays["joint_names"]
    with pytest.raises(DataError, match="missing array 'joint_names'"):
        load_skeleton(_npz(tmp_path / "m.npz", **arrays))
    arrays = _valid_arrays()
    del arrays["timestamps"]
    with pytest.raises(DataError, match="needs 'timestamps'"):
        load_skeleton(_npz(tmp_path / "t.npz", **arrays))


def test_truncated_and_garbage_files_get_clear_errors(tmp_path, seq):
    good = save_skeleton(tmp_path / "good.npz", seq).read_bytes()
    (tmp_path / "cut.npz").write_bytes(good[: len(good) // 2])
    (tmp_path / "junk.npz").write_bytes(b"\x00\xff definitely not a zip" * 10)
    for name in ("cut.npz", "junk.npz"):
        with pytest.raises(DataError, match="not a readable NPZ archive"):
            load_skeleton(tmp_path / name)
    (tmp_path / "junk.csv").write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(DataError, match="not a text CSV"):
        load_skeleton(tmp_path / "junk.csv")


def test_csv_errors_name_line_and_column(tmp_path, seq):
    path = save_skeleton(tmp_path / "s.csv", seq)
    lines = path.read_text().splitlines()
    first_data = next(i for i, line in enumerate(lines) if line[0].isdigit())
    cells = lines[first_data + 1].split(",")
    cells[4] = "oops"
    broken = [*lines[: first_data + 1], ",".join(cells), *lines[first_data + 2:]]
    path.write_text("\n".join(broken) + "\n")
    with pytest.raises(DataError, match=rf"line {first_data + 2}, column 'neck_x': not a number"):
        load_skeleton(path)
    path.write_text("\n".join([*lines[: first_data + 1], "0.5,1.0"]) + "\n")
    with pytest.raises(DataError, match=rf"line {first_data + 2}: 2 columns, header has 46"):
        load_skeleton(path)
    path.write_text("time,head_x,head_y\n")
    with pytest.raises(DataError, match="2 position columns is not a multiple of 3"):
        load_skeleton(path)
    path.write_text("# pattern: x\n")
    with pytest.raises(DataError, match="no header line"):
        load_skeleton(path)


def test_unknown_suffix_and_missing_file(tmp_path, seq):
    with pytest.raises(DataError, match=r"use \.npz or \.csv"):
        save_skeleton(tmp_path / "x.json", seq)
    with pytest.raises(DataError, match="no such file"):
        load_skeleton(tmp_path / "absent.npz")


@pytest.mark.parametrize("fmt", ["npz", "csv"])
def test_demonstrate_command_writes_one_named_file_per_sequence(tmp_path, fmt):
    parser = argparse.ArgumentParser()
    demonstrate_cmd.configure(parser)
    args = parser.parse_args(["--out", str(tmp_path), "--patterns", "wave_both", "rotate_cw_one",
                              "--subjects", "2", "--repetitions", "2", "--format", fmt, "--quiet"])
    assert demonstrate_cmd.run(args) == 0
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == sorted(f"{p}_s{s}_r0{r}.{fmt}" for p in ("wave_both", "rotate_cw_one")
                           for s in (1, 2) for r in (1, 2))
    back = load_skeleton(tmp_path / f"wave_both_s2_r02.{fmt}")
    assert (back.pattern, back.subject, back.repetition) == ("wave_both", "s2", 2)
