"""Small mocap files the tests write: BVH, ASF/AMC and joint-position arrays of a moving person."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gwr_predictor.data.demonstrator import default_subjects, demonstrate_one
from gwr_predictor.data.skeleton_files import SkeletonSequence
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS

#: Our skeleton joint -> a Mixamo name, for arrays written in a "recording's" naming.
MIXAMO_NAMES = {"head": "Head", "neck": "Neck", "torso": "Spine1", "left_shoulder": "LeftArm",
                "left_elbow": "LeftForeArm", "left_hand": "LeftHand", "right_shoulder": "RightArm",
                "right_elbow": "RightForeArm", "right_hand": "RightHand", "left_hip": "LeftUpLeg",
                "left_knee": "LeftLeg", "left_foot": "LeftFoot", "right_hip": "RightUpLeg", "right_knee": "RightLeg",
                "right_foot": "RightFoot"}

#: Camera frame (x = person's right, y up, person facing -z) -> a Z-up world in which the person
#: faces +y: a quarter turn about x (a proper rotation, det +1).
CAMERA_TO_ZUP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def person(pattern: str = "wave_both", fps: float = 30.0, repetition: int = 1, noise: bool = True
           ) -> SkeletonSequence:
    return demonstrate_one(pattern, default_subjects(1)[0], repetition, fps=fps, noise=noise)


def as_zup_millimetres(seq: SkeletonSequence) -> np.ndarray:
    """The demonstrator's camera-frame positions as a Z-up mocap world in millimetres."""
    return 1000.0 * seq.positions @ CAMERA_TO_ZUP.T


def write_bvh(path: Path, frames: int = 240, fps: float = 120.0, swing_deg: float = 40.0, phase: float = 0.0) -> Path:
    """A Mixamo-named BVH (cm, Y up, facing +z) whose left arm swings forward and back."""
    t = np.arange(frames) / fps
    swing = swing_deg * np.sin(2 * np.pi * 0.5 * t + phase)
    joints = [  # name, parent, offset (cm)
        ("Hips", None, (0, 0, 0)), ("Spine", "Hips", (0, 10, 0)), ("Spine1", "Spine", (0, 15, 0)),
        ("Neck", "Spine1", (0, 25, 0)), ("Head", "Neck", (0, 10, 0)),
        ("LeftShoulder", "Spine1", (5, 22, 0)), ("LeftArm", "LeftShoulder", (12, 0, 0)),
        ("LeftForeArm", "LeftArm", (0, -28, 0)), ("LeftHand", "LeftForeArm", (0, -25, 0)),
        ("RightShoulder", "Spine1", (-5, 22, 0)), ("RightArm", "RightShoulder", (-12, 0, 0)),
        ("RightForeArm", "RightArm", (0, -28, 0)), ("RightHand", "RightForeArm", (0, -25, 0)),
        ("LeftUpLeg", "Hips", (9, -5, 0)), ("LeftLeg", "LeftUpLeg", (0, -42, 0)), ("LeftFoot", "LeftLeg", (0, -40, 0)),
        ("RightUpLeg", "Hips", (-9, -5, 0)), ("RightLeg", "RightUpLeg", (0, -42, 0)),
        ("RightFoot", "RightLeg", (0, -40, 0)),
    ]
    children: dict[str | None, list[str]] = {}
    for name, parent, _ in joints:
        children.setdefault(parent, []).append(name)
    offsets = {n: o for n, _, o in joints}
    lines = ["HIERARCHY"]
    order: list[str] = []

    def emit(name: str, depth: int) -> None:
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if depth == 0 else 'JOINT'} {name}")
        lines.append(pad + "{")
        lines.append(f"{pad}  OFFSET {' '.join(f'{v:.4f}' for v in offsets[name])}")
        channels = "6 Xposition Yposition Zposition" if depth == 0 else "3"
        lines.append(f"{pad}  CHANNELS {channels} Zrotation Xrotation Yrotation")
        order.append(name)
        kids = children.get(name, [])
        for kid in kids:
            emit(kid, depth + 1)
        if not kids:
            lines.extend([f"{pad}  End Site", pad + "  {", f"{pad}    OFFSET 0.0 -5.0 0.0", pad + "  }"])
        lines.append(pad + "}")

    emit("Hips", 0)
    lines += ["MOTION", f"Frames: {frames}", f"Frame Time: {1.0 / fps:.8f}"]
    for k in range(frames):
        values = []
        for name in order:
            rot = [0.0, 0.0, 0.0]  # Z X Y
            if name == "LeftArm":
                rot = [60.0, swing[k], 0.0]  # hanging arm raised 60 deg sideways, swinging about x
            elif name == "RightArm":
                rot = [-60.0, 0.0, 0.0]
            elif name == "LeftForeArm":
                rot = [0.0, 30.0 + 0.5 * swing[k], 0.0]
            if name == "Hips":
                values += [0.0, 95.0, 0.0]
            values += rot
        lines.append(" ".join(f"{v:.5f}" for v in values))
    path.write_text("\n".join(lines) + "\n")
    return path


def fake_recording_cache(root: Path, seconds: float = 12.0) -> Path:
    """A `real_motion` cache whose package archives hold small written recordings instead of the real
    ones (climbing takes = the same demonstrator motion, a BVH), so `experiment real` runs without pip."""
    import io
    import tarfile
    import zipfile

    downloads = root / "downloads"
    downloads.mkdir(parents=True, exist_ok=True)
    names = [MIXAMO_NAMES[j] for j in SKELETON_JOINTS]
    frames = {0: "f900-3700", 1: "f0-2422", 2: "f100-3110", 3: "f200-2600", 4: "f0-2303"}
    take = person("wave_both", fps=120.0, noise=False)
    keep = take.timestamps <= seconds
    with zipfile.ZipFile(downloads / "holosoma_retargeting-0.1.0-py3-none-any.whl", "w") as z:
        z.writestr("holosoma_retargeting/config_types/data_type.py", f"MOCAP_DEMO_JOINTS = {names!r}\n")
        for i, f in frames.items():
            buf = io.BytesIO()
            np.save(buf, (as_zup_millimetres(take)[keep] / 1000).astype(np.float32))
            z.writestr(f"holosoma_retargeting/demo_data/climb/mocap_climb_seq_{i}/mocap_climb_seq_{i}_joint_positions_"
                       f"{f}.npy", buf.getvalue())
    bvh = write_bvh(root / "kneel.bvh", frames=int(30 * seconds), fps=30.0).read_bytes()
    with tarfile.open(downloads / "bvhtoolbox-0.1.3.tar.gz", "w:gz") as t:
        info = tarfile.TarInfo("bvhtoolbox-0.1.3/tests/example_files/test_mocapbank.bvh")
        info.size = len(bvh)
        t.addfile(info, io.BytesIO(bvh))
    return root
