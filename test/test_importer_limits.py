"""Every mocap importer checks what a file declares (size, joints, nesting, frames, frame time,
values, zip members, tensor strides) before allocating it, and refuses a hostile file with the
package's one-line error naming the file and the limit; the files are crafted here, each small."""

from __future__ import annotations

import pickle
import time
import zipfile

import numpy as np
import pytest
from mocap_files import write_bvh

from gwr_predictor.data.asf_amc import load_amc
from gwr_predictor.data.bvh import load_bvh
from gwr_predictor.data.errors import DataError
from gwr_predictor.data.mocap import load_any_skeleton, load_clip
from gwr_predictor.data.skeleton_files import load_skeleton
from gwr_predictor.data.torch_files import load_tensor
from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.files import limits


def _ops(value: object) -> bytes:
    """Pickle opcodes pushing `value` (ints, strings, tuples of them), without PROTO and STOP."""
    return pickle.dumps(value, protocol=2)[2:-1]


def pt_bytes(size: tuple[int, ...], stride: tuple[int, ...], offset: int = 0, numel: int = 1) -> bytes:
    """The data.pkl of a `.pt` holding one float tensor rebuilt from storage '0' (what torch writes)."""
    storage = b"(" + _ops("storage") + b"ctorch\nFloatStorage\n" + _ops("0") + _ops("cpu") + _ops(numel) + b"tQ"
    return (b"\x80\x02ctorch._utils\n_rebuild_tensor_v2\n(" + storage + _ops(offset) + _ops(size) + _ops(stride)
            + b"\x89ccollections\nOrderedDict\n)RtR.")


def write_pt(path, size, stride, offset=0, values=None):
    values = np.zeros(1, np.float32) if values is None else values
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("t/data.pkl", pt_bytes(size, stride, offset, values.size))
        z.writestr("t/byteorder", "little")
        z.writestr("t/data/0", values.astype("<f4").tobytes())
    return path


def bvh_text(joints: int, frames: int, depth_first: bool = False, frame_time: float = 0.0333) -> str:
    """A root with one channel and `joints` channel-less children (nested if `depth_first`)."""
    lines = ["HIERARCHY", "ROOT r", "{", "OFFSET 0 0 0", "CHANNELS 1 Xrotation"]
    for k in range(joints):
        lines += [f"JOINT j{k}", "{", "OFFSET 0 1 0", "CHANNELS 0"] + ([] if depth_first else ["}"])
    lines += ["}"] * (joints if depth_first else 0) + ["}", "MOTION", f"Frames: {frames}",
                                                        f"Frame Time: {frame_time}"]
    return "\n".join(lines + ["0"] * frames) + "\n"


def test_a_pt_tensor_repeating_one_value_by_a_zero_stride_is_refused(tmp_path):
    path = write_pt(tmp_path / "zero.pt", (1 << 26,), (0,))  # 514 bytes, 256 MB once materialised
    assert path.stat().st_size < 1000
    with pytest.raises(DataError, match=r"zero\.pt.*limit"):
        load_tensor(path)


@pytest.mark.parametrize("offset, stride", [(-4, (1,)), (0, (-1,))])
def test_a_pt_tensor_reaching_outside_its_storage_is_refused(tmp_path, offset, stride):
    path = write_pt(tmp_path / "out.pt", (4,), stride, offset, np.arange(4, dtype=np.float32))
    with pytest.raises(DataError, match=r"out\.pt.*storage"):
        load_tensor(path)


def test_a_bvh_with_a_huge_frame_time_is_refused_before_resampling(tmp_path):
    path = write_bvh(tmp_path / "slow.bvh", frames=2, fps=30.0)
    path.write_text(path.read_text().replace("Frame Time: 0.03333333", "Frame Time: 1e9"))
    assert path.stat().st_size < 8000
    with pytest.raises(DataError, match=r"slow\.bvh.*limit"):
        load_any_skeleton(path)


def test_a_small_bvh_declaring_thousands_of_joints_and_frames_is_refused(tmp_path):
    path = tmp_path / "wide.bvh"
    path.write_text(bvh_text(2000, 5000))
    assert path.stat().st_size < 100_000
    with pytest.raises(DataError, match=r"wide\.bvh.*joints exceed the limit"):
        load_bvh(path)


def test_deeply_nested_bvh_joints_are_refused_quickly(tmp_path):
    path = tmp_path / "deep.bvh"
    path.write_text(bvh_text(50_000, 2, depth_first=True))
    start = time.process_time()
    with pytest.raises(DataError, match=r"deep\.bvh.*(nesting|joints).*limit"):
        load_bvh(path)
    assert time.process_time() - start < 2.0


def test_a_text_recording_over_the_limit_is_refused_before_reading(tmp_path):
    path = tmp_path / "huge.bvh"
    with path.open("wb") as fh:  # sparse: no disk space used
        fh.write(bvh_text(1, 1).encode())
        fh.truncate(limits.MAX_TEXT_BYTES + 1)
    with pytest.raises(DataError, match=r"huge\.bvh.*too large.*limit"):
        load_clip(path)


def _npz_bomb(path, inflated: int) -> None:
    """A positions `.npz` of zeros that deflates about 1000:1, written without holding it in memory."""
    frames = inflated // (20 * 3 * 8)
    header = {"descr": "<f8", "fortran_order": False, "shape": (frames, 20, 3)}
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        with z.open("positions.npy", "w", force_zip64=True) as fh:
            np.lib.format.write_array_header_1_0(fh, header)
            chunk = bytes(1 << 20)
            for _ in range(frames * 480 // len(chunk)):
                fh.write(chunk)
            fh.write(bytes(frames * 480 % len(chunk)))
        z.writestr("fps.npy", b"")


def test_an_npz_zip_bomb_is_refused_by_load_any_skeleton_as_by_load_skeleton(tmp_path):
    path = tmp_path / "bomb.npz"
    _npz_bomb(path, limits.MAX_RECORDING_BYTES + (8 << 20))
    assert path.stat().st_size < 1 << 20
    with pytest.raises(DataError, match=r"bomb\.npz.*limit"):
        load_skeleton(path)
    with pytest.raises(DataError, match=r"bomb\.npz.*limit"):
        load_any_skeleton(path)


@pytest.mark.parametrize("suffix", [".npy", ".npz"])
def test_a_numpy_header_declaring_more_than_the_file_holds_is_refused(tmp_path, suffix):
    npy = tmp_path / "lie.npy"
    with npy.open("wb") as fh:
        np.lib.format.write_array_header_1_0(fh, {"descr": "<f8", "fortran_order": False,
                                                  "shape": (10**6, 1000, 3)})
        fh.write(bytes(64))
    path = npy
    if suffix == ".npz":
        path = tmp_path / "lie.npz"
        with zipfile.ZipFile(path, "w") as z:
            z.write(npy, "positions.npy")
    with pytest.raises(DataError, match=r"lie\.np[yz].*limit"):
        load_clip(path)


def test_an_asf_bone_with_two_parents_is_refused(tmp_path):
    bones = "\n".join(f"begin\nname b{i}\ndirection 0 1 0\nlength 1\naxis 0 0 0 XYZ\ndof rx\nend" for i in range(4))
    (tmp_path / "d.asf").write_text(f":units\nlength 1\n:root\norder TX TY TZ RX RY RZ\n:bonedata\n{bones}\n"
                                    ":hierarchy\nbegin\nroot b0\nb0 b1 b2\nb1 b3\nb2 b3\nend\n")
    (tmp_path / "d.amc").write_text("1\nroot 0 0 0 0 0 0\n")
    with pytest.raises(DataError, match=r"d\.asf.*'b3'.*two parents"):
        load_amc(tmp_path / "d.amc")


def test_every_limit_error_is_the_packages_one_line_error(tmp_path):
    path = tmp_path / "wide.bvh"
    path.write_text(bvh_text(1000, 2))
    with pytest.raises(GwrPredictorError) as err:
        load_bvh(path)
    assert "\n" not in str(err.value) and str(path) in str(err.value)


def test_the_angles_command_reports_a_hostile_file_in_one_line(tmp_path, capsys):
    from gwr_predictor.commands.cli import main

    path = write_bvh(tmp_path / "slow.bvh", frames=2, fps=30.0)
    path.write_text(path.read_text().replace("Frame Time: 0.03333333", "Frame Time: 1e9"))
    assert main(["angles", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "slow.bvh" in err and "limit" in err


@pytest.mark.ros
def test_skeleton_source_stops_cleanly_on_a_hostile_file(ros, tmp_path):
    path = write_bvh(tmp_path / "slow.bvh", frames=2, fps=30.0)
    path.write_text(path.read_text().replace("Frame Time: 0.03333333", "Frame Time: 1e9"))
    code, out = ros.run("skeleton_source", params={"source": "file", "file": str(path)}, timeout=60)
    assert code == 1 and "slow.bvh" in out and "limit" in out
    assert "Traceback" not in out and "MemoryError" not in out
