"""Which joint of a recording is which of our 15 skeleton joints: presets detected from the names,
or a user mapping file.

Names are compared normalised (case, '_', '-', '.', spaces and a namespace such as `mixamorig:`
ignored). A position is where a bone *starts* (see `bvh`, `asf_amc`): the shoulder is the start of
the upper arm (`LeftArm`, `lhumerus`, `L_Shoulder`). Presets, tried in this order:

| preset | shoulder / elbow / hand (wrist) | hip / knee / foot (ankle) |
|---|---|---|
| `skeleton` (ours, OpenNI) | left_shoulder / left_elbow / left_hand | left_hip / left_knee / left_foot |
| `mixamo` (Mixamo, LAFAN, many BVH exports) | LeftArm / LeftForeArm / LeftHand | LeftUpLeg / LeftLeg / LeftFoot |
| `mocapbank` (anatomical names) | LeftShoulder / LeftElbow / LeftWrist | LeftHip / LeftKnee / LeftAnkle |
| `cmu` (ASF/AMC) | lhumerus / lradius / lwrist | lfemur / ltibia / lfoot |
| `smpl` (SMPL, SMPL-H, SMPL-X) | L_Shoulder / L_Elbow / L_Wrist | L_Hip / L_Knee / L_Ankle |

Shoulders, elbows, hands and hips are required (the arm angles need them); head, neck, torso,
knees and feet may be missing (NaN; a missing torso becomes the middle of hips and shoulders).

User mapping file (JSON, or YAML if PyYAML is installed): ``{"left_shoulder": "LArm", ...}``; a
value may be a joint index (for `.npy` files without names) or a list of candidate names. Keys
missing from the file fall back to the detected preset. Optional ``"joint_names": [...]`` names the
joints of an `.npy` file in order.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gwr_predictor.data.errors import DataError
from gwr_predictor.files.limits import MAX_SKELETON_BYTES
from gwr_predictor.files.user_files import read_text
from gwr_predictor.files.yaml_safe import load_yaml
from gwr_predictor.joints.skeleton import SKELETON_JOINTS

REQUIRED = ("left_shoulder", "left_elbow", "left_hand", "right_shoulder", "right_elbow", "right_hand",
            "left_hip", "right_hip")


def _sides(left: Mapping[str, Sequence[str]], centre: Mapping[str, Sequence[str]],
           right_of: dict[str, str]) -> dict[str, tuple[str, ...]]:
    out = {k: tuple(v) for k, v in centre.items()}
    for joint, names in left.items():
        out[f"left_{joint}"] = tuple(names)
        out[f"right_{joint}"] = tuple(_swap(n, right_of) for n in names)
    return out


def _swap(name: str, right_of: dict[str, str]) -> str:
    for a, b in right_of.items():
        if name.startswith(a):
            return b + name[len(a):]
    raise AssertionError(name)


PRESETS: dict[str, dict[str, tuple[str, ...]]] = {
    "skeleton": {j: (j,) for j in SKELETON_JOINTS},
    "mixamo": _sides({"shoulder": ["LeftArm"], "elbow": ["LeftForeArm"], "hand": ["LeftHand"],
                      "hip": ["LeftUpLeg"], "knee": ["LeftLeg"], "foot": ["LeftFoot"]},
                     {"head": ["Head"], "neck": ["Neck", "Neck1"], "torso": ["Spine1", "Spine", "Spine2"]},
                     {"Left": "Right"}),
    "mocapbank": _sides({"shoulder": ["LeftShoulder"], "elbow": ["LeftElbow"], "hand": ["LeftWrist", "LeftHand"],
                         "hip": ["LeftHip"], "knee": ["LeftKnee"], "foot": ["LeftAnkle", "LeftFoot"]},
                        {"head": ["Head"], "neck": ["Neck"], "torso": ["Chest", "Spine", "Torso"]},
                        {"Left": "Right"}),
    "cmu": _sides({"shoulder": ["lhumerus"], "elbow": ["lradius"], "hand": ["lwrist"],
                   "hip": ["lfemur"], "knee": ["ltibia"], "foot": ["lfoot"]},
                  {"head": ["head"], "neck": ["lowerneck", "upperneck"], "torso": ["upperback", "thorax"]},
                  {"l": "r"}),
    "smpl": _sides({"shoulder": ["L_Shoulder"], "elbow": ["L_Elbow"], "hand": ["L_Wrist"],
                    "hip": ["L_Hip"], "knee": ["L_Knee"], "foot": ["L_Ankle"]},
                   {"head": ["Head"], "neck": ["Neck"], "torso": ["Spine2", "Spine3", "Spine1"]},
                   {"L_": "R_"}),
}

#: SMPL-H joint order (52): the body of SMPL without its two hand joints, then 15 + 15 finger joints.
SMPL_BODY = ("Pelvis", "L_Hip", "R_Hip", "Spine1", "L_Knee", "R_Knee", "Spine2", "L_Ankle", "R_Ankle", "Spine3",
             "L_Foot", "R_Foot", "Neck", "L_Collar", "R_Collar", "Head", "L_Shoulder", "R_Shoulder", "L_Elbow",
             "R_Elbow", "L_Wrist", "R_Wrist")
_FINGERS = tuple(f"{f}{k}" for f in ("Index", "Middle", "Pinky", "Ring", "Thumb") for k in (1, 2, 3))
SMPLH_JOINTS = SMPL_BODY + tuple(f"L_{f}" for f in _FINGERS) + tuple(f"R_{f}" for f in _FINGERS)
SMPL_JOINTS = SMPL_BODY + ("L_Hand", "R_Hand")


def normalise(name: str) -> str:
    """Joint name for comparison: no namespace (`a:b`, `a|b`), no separators, lower case."""
    name = name.replace("|", ":").rsplit(":", 1)[-1]
    return "".join(ch for ch in name.lower() if ch not in "_-. ")


@dataclass(frozen=True)
class JointMap:
    """Our joint -> the index of the recording's joint (-1 = not in the recording)."""

    name: str
    indices: dict[str, int]


def _match(names: Sequence[str], candidates: Sequence[str | int]) -> int:
    norm = [normalise(n) for n in names]
    for c in candidates:
        if isinstance(c, (int, np.integer)):
            return int(c)
        key = normalise(str(c))
        if key in norm:
            return norm.index(key)
    return -1


def preset_map(names: Sequence[str], preset: str) -> JointMap:
    return JointMap(preset, {j: _match(names, PRESETS[preset].get(j, ())) for j in SKELETON_JOINTS})


def detect_preset(names: Sequence[str]) -> str | None:
    """The first preset that finds every required joint among `names`, or None."""
    for preset in PRESETS:
        m = preset_map(names, preset)
        if all(m.indices[j] >= 0 for j in REQUIRED):
            return preset
    return None


def read_map_file(path: str | Path) -> dict:
    """The user mapping file as a dict (JSON, or YAML when the suffix says so)."""
    path = Path(path)
    if path.suffix.lower() in (".yaml", ".yml"):
        data = load_yaml(path, MAX_SKELETON_BYTES, "joint-map file", DataError)
    else:
        text = read_text(path, MAX_SKELETON_BYTES, "joint-map file", DataError)
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise DataError(f"{path}: not a readable joint-map file ({exc})") from None
    if not isinstance(data, dict):
        raise DataError(f"{path}: a joint map is a mapping {{our joint: recording joint}}, got {type(data).__name__}")
    return data


def resolve_map(names: Sequence[str], map_file: str | Path | None = None, source: str = "clip") -> JointMap:
    """The joint map for a recording with these joint `names`; errors name what is missing."""
    user = read_map_file(map_file) if map_file else {}
    user = {k: v for k, v in user.items() if k != "joint_names"}
    unknown = [k for k in user if k not in SKELETON_JOINTS]
    if unknown:
        raise DataError(f"{map_file}: keys {unknown} are not skeleton joints; use {', '.join(SKELETON_JOINTS)}")
    preset = detect_preset(names)
    base = preset_map(names, preset) if preset else JointMap("none", dict.fromkeys(SKELETON_JOINTS, -1))
    indices = dict(base.indices)
    for joint, value in user.items():
        candidates = value if isinstance(value, list) else [value]
        idx = _match(names, candidates)
        if idx < 0 or idx >= len(names):
            raise DataError(f"{source}: joint map {map_file} maps {joint} to {value!r}, which the recording "
                            f"lacks (it has {len(names)} joints: {', '.join(list(names)[:12])}...)")
        indices[joint] = idx
    missing = [j for j in REQUIRED if indices[j] < 0]
    if missing and not preset and not user:  # name the closest preset and exactly what it lacks
        closest = max(PRESETS, key=lambda p: sum(i >= 0 for i in preset_map(names, p).indices.values()))
        found = preset_map(names, closest).indices
        lacks = [f"{j} ({'/'.join(PRESETS[closest][j])})" for j in REQUIRED if found[j] < 0]
        raise DataError(f"{source}: joint names fit no preset; the closest, {closest}, lacks {', '.join(lacks)}; "
                        "give a joint-map file (--joint-map)")
    if missing:
        hint = (f"no preset ({', '.join(PRESETS)}) fits its names" if not preset else f"preset {preset}")
        raise DataError(f"{source}: cannot find {', '.join(missing)} ({hint}; joints: "
                        f"{', '.join(list(names)[:20])}{'...' if len(names) > 20 else ''}); "
                        "give a joint-map file (--joint-map)")
    name = preset or "none"
    if map_file and user:  # user mappings come only from a map file
        name = f"{preset}+{Path(map_file).name}" if preset else Path(map_file).name
    return JointMap(name, indices)


def map_joints(positions: np.ndarray, names: Sequence[str], joint_map: JointMap, source: str = "clip") -> np.ndarray:
    """(T, J, 3) recording positions -> (T, 15, 3) in `SKELETON_JOINTS` order (NaN = not in the recording)."""
    t = positions.shape[0]
    out = np.full((t, len(SKELETON_JOINTS), 3), np.nan)
    for k, joint in enumerate(SKELETON_JOINTS):
        idx = joint_map.indices[joint]
        if idx >= 0:
            out[:, k] = positions[:, idx]
    torso = SKELETON_JOINTS.index("torso")
    if joint_map.indices["torso"] < 0:
        j = {n: positions[:, joint_map.indices[n]] for n in ("left_hip", "right_hip", "left_shoulder",
                                                             "right_shoulder")}
        out[:, torso] = 0.25 * (j["left_hip"] + j["right_hip"] + j["left_shoulder"] + j["right_shoulder"])
    return out
