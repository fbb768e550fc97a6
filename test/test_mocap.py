"""Mocap importers: BVH forward kinematics against hand computations, ASF/AMC, joint-position arrays,
torch files without torch, joint maps, the camera frame and resampling; files written by the tests."""

from __future__ import annotations

import json
import pickle
import sys
import types
import zipfile

import numpy as np
import pytest
from mocap_files import MIXAMO_NAMES, as_zup_millimetres, person, write_bvh

from gwr_predictor.data.angles import skeleton_to_angles
from gwr_predictor.data.asf_amc import load_amc
from gwr_predictor.data.bvh import load_bvh
from gwr_predictor.data.errors import DataError
from gwr_predictor.data.joint_maps import detect_preset, resolve_map
from gwr_predictor.data.mocap import load_any_skeleton, load_clip, resample
from gwr_predictor.data.mocap_clip import ImportOptions
from gwr_predictor.data.smoothing import median_of_3
from gwr_predictor.data.torch_files import load_tensor
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS

TWO_JOINTS = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Arm
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 0 5
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.008333333
1 2 3 90 0 0 0 0 0
1 2 3 0 90 0 0 0 90
"""


def test_bvh_forward_kinematics_matches_a_hand_computation(tmp_path):
    path = tmp_path / "two.bvh"
    path.write_text(TWO_JOINTS)
    clip = load_bvh(path)
    assert clip.joint_names == ("Hips", "Arm", "Arm_end")
    assert clip.fps == pytest.approx(120.0, rel=1e-6)
    # frame 0: root at (1,2,3) turned 90 deg about z: the arm's (0,10,0) points to -x
    np.testing.assert_allclose(clip.positions[0], [[1, 2, 3], [-9, 2, 3], [-9, 2, 8]], atol=1e-9)
    # frame 1: root 90 deg about x (y -> z), arm 90 deg about y: its end (0,0,5) -> (5,0,0) -> (5,0,0)
    np.testing.assert_allclose(clip.positions[1], [[1, 2, 3], [1, 2, 13], [6, 2, 13]], atol=1e-9)


def test_bvh_rotation_order_follows_the_channel_list(tmp_path):
    zx = TWO_JOINTS.replace("Frames: 2", "Frames: 1").rsplit("1 2 3 90", 1)[0] + "0 0 0 0 0 0 90 90 0\n"
    xz = zx.replace("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 3 Xrotation Zrotation Yrotation")
    (tmp_path / "zx.bvh").write_text(zx)
    (tmp_path / "xz.bvh").write_text(xz)
    end_zx = load_bvh(tmp_path / "zx.bvh").positions[0, 2]
    end_xz = load_bvh(tmp_path / "xz.bvh").positions[0, 2]
    # Rz(90) Rx(90) (0,0,5) = Rz(90) (0,-5,0) = (5,0,0); Rx(90) Rz(90) (0,0,5) = Rx(90) (0,0,5) = (0,-5,0)
    np.testing.assert_allclose(end_zx - [0, 10, 0], [5, 0, 0], atol=1e-9)
    np.testing.assert_allclose(end_xz - [0, 10, 0], [0, -5, 0], atol=1e-9)


@pytest.mark.parametrize("text, needle", [
    (TWO_JOINTS.replace("MOTION", "MOTON"), "no MOTION"),
    (TWO_JOINTS.replace("Frames: 2", "Frames: 5"), "truncated"),
    (TWO_JOINTS.replace("1 2 3 0 90 0 0 0 90", "1 2 3 0 90 0 0 0"), "motion frame 1: 8 values"),
    (TWO_JOINTS.replace("Zrotation Xrotation Yrotation\n    End", "Zrotation Xrotation Qrotation\n    End"),
     "unknown channels ['Qrotation'] in joint Arm"),
    (TWO_JOINTS.replace("    }\n  }\n}", "    }\n  }\n"), "not closed"),
    (TWO_JOINTS.replace("OFFSET 0 10 0", "OFFSET 0 ten 0"), "OFFSET needs 3 numbers"),
])
def test_bad_bvh_files_say_what_is_wrong(tmp_path, text, needle):
    path = tmp_path / "bad.bvh"
    path.write_text(text)
    with pytest.raises(DataError, match=r"bad\.bvh") as err:
        load_clip(path)
    assert needle in str(err.value)


def test_bvh_person_becomes_a_camera_frame_skeleton_at_30_fps(tmp_path):
    path = write_bvh(tmp_path / "swing.bvh", frames=240, fps=120.0)
    seq = load_any_skeleton(path)
    assert seq.joint_names == SKELETON_JOINTS and seq.metadata["joint_map"] == "mixamo"
    assert seq.fps == pytest.approx(30.0) and seq.positions.shape[0] == 60  # 2 s at 30 fps
    j = {n: seq.positions[0, i] for i, n in enumerate(SKELETON_JOINTS)}
    # centimetres detected: the head joint 1.47 m above the ankles; the person faces the sensor 2 m away
    assert j["head"][1] - j["left_foot"][1] == pytest.approx(1.47, abs=0.01)
    assert j["left_shoulder"][0] < 0 < j["right_shoulder"][0]  # the person's left is the camera's -x
    assert j["left_hand"][0] < j["left_shoulder"][0]  # the left arm is raised sideways, to the person's left
    assert 0.5 * (j["left_hip"][2] + j["right_hip"][2]) == pytest.approx(2.0)
    # Y-up BVH, LeftArm = the shoulder joint: upper arm 28 cm
    upper = np.linalg.norm(seq.positions[:, 4] - seq.positions[:, 3], axis=1)
    np.testing.assert_allclose(upper, 0.28, atol=1e-3)


def test_zup_millimetre_arrays_give_the_same_arm_angles_as_the_camera_frame(tmp_path):
    """A Z-up, millimetre, 120 fps copy of a demonstrator person, under Mixamo names, through a
    joint map that only names the joints: the arm angles match the original's."""
    fast = person(fps=120.0, noise=False)
    names = [MIXAMO_NAMES[j] for j in SKELETON_JOINTS]
    np.save(tmp_path / "person.npy", as_zup_millimetres(fast))
    (tmp_path / "map.json").write_text(json.dumps({"joint_names": names}))
    opts = ImportOptions(fps=120.0, joint_map=tmp_path / "map.json")
    seq = load_any_skeleton(tmp_path / "person.npy", opts)
    assert seq.metadata["joint_map"].startswith("mixamo")
    assert np.nanmean(seq.joint("head")[:, 1] - seq.joint("torso")[:, 1]) > 0.2  # Z up became y up
    ref = person(fps=30.0, noise=False)
    n = min(len(ref.timestamps), len(seq.timestamps))
    got = skeleton_to_angles(median_of_3(seq.positions[:n], seq.timestamps[:n])[0])
    want = skeleton_to_angles(median_of_3(ref.positions[:n], ref.timestamps[:n])[0])
    ok = np.isfinite(got).all(axis=1) & np.isfinite(want).all(axis=1)
    assert ok.mean() > 0.9
    assert np.median(np.abs(got[ok] - want[ok])) < 0.02


def test_npz_positions_with_names_and_rate_and_a_user_map_by_index(tmp_path):
    seq = person(fps=60.0)
    odd = [f"J{i}" for i in range(len(SKELETON_JOINTS))]
    np.savez(tmp_path / "a.npz", joints=seq.positions, names=np.array(odd), mocap_framerate=np.array(60.0))
    with pytest.raises(DataError, match=r"fit no preset.*lacks left_shoulder") as err:
        load_any_skeleton(tmp_path / "a.npz")
    assert "--joint-map" in str(err.value) and "a.npz" in str(err.value)
    (tmp_path / "map.json").write_text(json.dumps({j: i for i, j in enumerate(SKELETON_JOINTS)}))
    out = load_any_skeleton(tmp_path / "a.npz", ImportOptions(joint_map=tmp_path / "map.json", up="y", units="m"))
    assert out.fps == pytest.approx(30.0)
    (tmp_path / "bad.json").write_text(json.dumps({"left_elbow": "NoSuchJoint"}))
    with pytest.raises(DataError, match="maps left_elbow to 'NoSuchJoint', which the recording lacks"):
        load_any_skeleton(tmp_path / "a.npz", ImportOptions(joint_map=tmp_path / "bad.json"))
    (tmp_path / "keys.json").write_text(json.dumps({"left_wrist": "J5"}))
    with pytest.raises(DataError, match=r"keys \['left_wrist'\] are not skeleton joints"):
        load_any_skeleton(tmp_path / "a.npz", ImportOptions(joint_map=tmp_path / "keys.json"))


def test_npy_without_a_rate_or_with_the_wrong_shape_is_refused(tmp_path):
    np.save(tmp_path / "p.npy", np.zeros((10, 15, 3)))
    with pytest.raises(DataError, match="give --fps"):
        load_clip(tmp_path / "p.npy")
    np.save(tmp_path / "q.npy", np.zeros((10, 15, 4)))
    with pytest.raises(DataError, match=r"\(frames, joints, 3\), got shape \(10, 15, 4\)"):
        load_clip(tmp_path / "q.npy", ImportOptions(fps=30))
    np.save(tmp_path / "o.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(DataError, match="without unpickling"):
        load_clip(tmp_path / "o.npy", ImportOptions(fps=30))


@pytest.mark.parametrize("names, preset", [
    (["mixamorig:Hips", "mixamorig:LeftArm", "mixamorig:LeftForeArm", "mixamorig:LeftHand", "mixamorig:RightArm",
      "mixamorig:RightForeArm", "mixamorig:RightHand", "mixamorig:LeftUpLeg", "mixamorig:RightUpLeg",
      "mixamorig:LeftShoulder"], "mixamo"),
    (["LeftShoulder", "LeftElbow", "LeftWrist", "RightShoulder", "RightElbow", "RightWrist", "LeftHip", "RightHip"],
     "mocapbank"),
    (["root", "lhumerus", "lradius", "lwrist", "rhumerus", "rradius", "rwrist", "lfemur", "rfemur"], "cmu"),
    (["Pelvis", "L_Shoulder", "L_Elbow", "L_Wrist", "R_Shoulder", "R_Elbow", "R_Wrist", "L_Hip", "R_Hip"], "smpl"),
    (list(SKELETON_JOINTS), "skeleton"),
    (["Hips", "LeftArm", "LeftForeArm"], None),
])
def test_presets_are_detected_from_the_names(names, preset):
    assert detect_preset(names) == preset


def test_a_recording_that_misses_one_arm_joint_names_it(tmp_path):
    text = write_bvh(tmp_path / "a.bvh", frames=3, fps=30.0).read_text().replace("LeftForeArm", "LeftFore")
    (tmp_path / "b.bvh").write_text(text)
    with pytest.raises(DataError, match=r"b\.bvh: joint names fit no preset; the closest, mixamo, lacks "
                                         r"left_elbow \(LeftForeArm\); give a joint-map file"):
        load_any_skeleton(tmp_path / "b.bvh")


def test_mixamo_shoulder_is_the_upper_arm_not_the_clavicle():
    names = ["LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand", "RightShoulder", "RightArm", "RightForeArm",
             "RightHand", "LeftUpLeg", "RightUpLeg"]
    m = resolve_map(names)
    assert names[m.indices["left_shoulder"]] == "LeftArm" and names[m.indices["right_elbow"]] == "RightForeArm"
    assert m.indices["head"] == -1


ASF = """# test skeleton
:version 1.10
:name test
:units
  mass 1.0
  length 0.45
  angle deg
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name upper
     direction 1 0 0
     length 10
     axis 0 0 90  XYZ
    dof rx
    limits (-180.0 180.0)
  end
  begin
     id 2
     name lower
     direction 0 -1 0
     length 4
     axis 0 0 0  XYZ
  end
:hierarchy
  begin
    root upper
    upper lower
  end
"""
AMC = """:FULLY-SPECIFIED
:DEGREES
1
root 1 2 3 0 0 0
upper 0
2
root 1 2 3 0 0 0
upper 90
"""


def test_asf_amc_forward_kinematics_matches_a_hand_computation(tmp_path):
    (tmp_path / "walk.asf").write_text(ASF)
    (tmp_path / "walk.amc").write_text(AMC)
    clip = load_amc(tmp_path / "walk.amc")
    s = 0.0254 / 0.45  # metres per ASF unit: 1/0.45 inch
    names = list(clip.joint_names)
    p = {n: clip.positions[:, names.index(n)] for n in ("root", "upper", "upper_end", "lower_end")}
    np.testing.assert_allclose(p["root"], [[s, 2 * s, 3 * s]] * 2, atol=1e-12)
    np.testing.assert_allclose(p["upper"], p["root"], atol=1e-12)  # a bone starts where its parent ends
    np.testing.assert_allclose(p["upper_end"][0] - p["root"][0], [10 * s, 0, 0], atol=1e-12)  # rest pose
    # 90 deg about the bone's local x, whose axis is turned 90 deg about z: C Rx(90) C^-1 = Ry(90)
    np.testing.assert_allclose(p["upper_end"][1] - p["root"][1], [0, 0, -10 * s], atol=1e-12)
    np.testing.assert_allclose(p["lower_end"][1] - p["upper_end"][1], [0, -4 * s, 0], atol=1e-12)
    assert clip.fps == 120.0 and clip.scale_known


def test_amc_errors_name_the_file_and_the_bone(tmp_path):
    (tmp_path / "walk.amc").write_text(AMC)
    with pytest.raises(DataError, match=r"no skeleton walk\.asf beside it.*--asf"):
        load_clip(tmp_path / "walk.amc")
    (tmp_path / "skel.asf").write_text(ASF)
    (tmp_path / "other.asf").write_text(ASF)
    clip = load_clip(tmp_path / "walk.amc", ImportOptions(asf=tmp_path / "skel.asf"))
    assert clip.positions.shape[0] == 2
    (tmp_path / "bad.amc").write_text(AMC.replace("upper 90", "upper 90 12"))
    with pytest.raises(DataError, match="frame 2, bone 'upper': 2 values, the ASF gives it 1 dof"):
        load_clip(tmp_path / "bad.amc", ImportOptions(asf=tmp_path / "skel.asf"))
    (tmp_path / "ghost.amc").write_text(AMC.replace("upper 90", "upper 90\nghost 1"))
    with pytest.raises(DataError, match=r"bones \['ghost'\] are not in the ASF"):
        load_clip(tmp_path / "ghost.amc", ImportOptions(asf=tmp_path / "skel.asf"))


def _fake_torch(monkeypatch: pytest.MonkeyPatch) -> tuple[type, object]:
    """Stand-in `torch` modules so that pickle writes the globals a real .pt file holds."""
    torch = types.ModuleType("torch")
    utils = types.ModuleType("torch._utils")

    class FloatStorage:
        pass

    def _rebuild_tensor_v2(*args: object) -> None:
        return None

    FloatStorage.__module__, FloatStorage.__qualname__ = "torch", "FloatStorage"
    _rebuild_tensor_v2.__module__, _rebuild_tensor_v2.__qualname__ = "torch._utils", "_rebuild_tensor_v2"
    torch.FloatStorage, utils._rebuild_tensor_v2, torch._utils = FloatStorage, _rebuild_tensor_v2, utils
    monkeypatch.setitem(sys.modules, "torch", torch)
    monkeypatch.setitem(sys.modules, "torch._utils", utils)
    return FloatStorage, _rebuild_tensor_v2


def _write_pt(path, values: np.ndarray, payload: bytes | None = None) -> None:
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("clip/data.pkl", payload)
        z.writestr("clip/byteorder", "little")
        z.writestr("clip/data/0", values.astype("<f4").tobytes())


def test_torch_files_are_read_without_torch_and_never_run_code(tmp_path, monkeypatch):
    storage_type, rebuild = _fake_torch(monkeypatch)
    values = np.arange(2 * 591, dtype=np.float32)

    class Tensor:
        def __reduce__(self):
            from collections import OrderedDict

            return rebuild, (Storage(), 0, (2, 591), (591, 1), False, OrderedDict())

    class Storage:
        pass

    class Pickler(pickle.Pickler):
        def persistent_id(self, obj):
            return ("storage", storage_type, "0", "cpu", values.size) if isinstance(obj, Storage) else None

    import io

    buf = io.BytesIO()
    Pickler(buf, protocol=2).dump(Tensor())
    _write_pt(tmp_path / "clip.pt", values, buf.getvalue())
    monkeypatch.delitem(sys.modules, "torch")
    monkeypatch.delitem(sys.modules, "torch._utils")
    arr = load_tensor(tmp_path / "clip.pt")
    np.testing.assert_array_equal(arr, values.reshape(2, 591))
    clip = load_clip(tmp_path / "clip.pt", ImportOptions(units="m"))  # the OMOMO layout: columns 162:318
    assert clip.joint_names[15] == "L_Shoulder" and clip.fps == 30.0
    np.testing.assert_array_equal(clip.positions[1, 0], values[591 + 162: 591 + 165])
    evil = b"\x80\x02cos\nsystem\nX\x04\x00\x00\x00trueq\x00\x85R."
    _write_pt(tmp_path / "evil.pt", values, evil)
    with pytest.raises(DataError, match=r"refuses to load os\.system"):
        load_tensor(tmp_path / "evil.pt")


def test_resampling_keeps_the_motion_and_marks_gaps():
    t = np.arange(0, 2.0, 1 / 120)
    x = np.sin(2 * np.pi * 0.5 * t)[:, None]
    out, stamps = resample(x, t, 30.0)
    assert stamps[1] == pytest.approx(1 / 30) and len(stamps) == 60
    np.testing.assert_allclose(out[1:-1, 0], np.sin(2 * np.pi * 0.5 * stamps[1:-1]), atol=0.01)  # ends: padding
    x[100:110] = np.nan
    out, stamps = resample(x, t, 30.0)
    gap = np.isnan(out[:, 0])
    assert gap.any() and not gap[:20].any() and not gap[-20:].any()


def test_our_npz_files_are_not_taken_for_mocap_positions(tmp_path):
    from gwr_predictor.data.mocap import is_mocap_file
    from gwr_predictor.data.skeleton_files import save_skeleton

    seq = person()
    ours = save_skeleton(tmp_path / "ours.npz", seq)
    np.savez(tmp_path / "bare.npz", positions=seq.positions, joint_names=np.array(SKELETON_JOINTS),
             fps=np.array(30.0))  # our format without the optional fields: already camera frame
    np.savez(tmp_path / "theirs.npz", positions=seq.positions, joint_names=np.array(list(MIXAMO_NAMES.values())),
             fps=np.array(30.0))
    assert not is_mocap_file(ours) and not is_mocap_file(tmp_path / "bare.npz")
    assert is_mocap_file(tmp_path / "theirs.npz")
    np.testing.assert_array_equal(load_any_skeleton(tmp_path / "bare.npz").positions, seq.positions)


def test_angles_command_reads_a_bvh(tmp_path, capsys):
    from gwr_predictor.commands.cli import main

    bvh = write_bvh(tmp_path / "swing.bvh", frames=90, fps=30.0)
    assert main(["angles", str(bvh), "-o", str(tmp_path / "a.csv")]) == 0
    assert "30 frames (0 missing)" in capsys.readouterr().err
    assert main(["angles", str(bvh), "--units", "furlong"]) == 2
    assert "units 'furlong'" in capsys.readouterr().err
