"""BVH (Biovision hierarchy) files -> joint positions by our own forward kinematics.

Why our own: the maintained PyPI parsers (bvh, bvhio, bvhsdk, pybvh) either stop at the channel
values or pull in large dependencies; forward kinematics is 30 lines of vectorised numpy here.

Conventions (the de-facto BVH standard): a joint's rotation channels, in the order listed, multiply
as R = R_1 @ R_2 @ R_3 (e.g. `Zrotation Xrotation Yrotation` -> Rz Rx Ry), angles in degrees; a
joint's global rotation is its parent's times its own; its position is the parent's position plus
the parent's global rotation times its local translation, which is the OFFSET, or the position
channels when the joint has them (they replace the OFFSET). `End Site`s are kept as joints named
`<parent>_end`. Units are whatever the file used (see `mocap.ImportOptions.units`); Y is up unless
told otherwise. Positions of a joint are where its bone starts: `LeftArm` is the shoulder.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gwr_predictor.data.mocap import MocapClip, MocapError

_AXIS = {"x": 0, "y": 1, "z": 2}


@dataclass
class BvhJoint:
    name: str
    parent: int  # -1 for a root
    offset: np.ndarray
    channels: tuple[str, ...]
    first_channel: int  # column of its first channel in the motion table


def rotation_matrices(angles_deg: np.ndarray, axes: str) -> np.ndarray:
    """(T, k) angles in degrees about `axes` (e.g. "zxy") -> (T, 3, 3) R = R_axes[0] @ R_axes[1] @ ..."""
    t = angles_deg.shape[0]
    out = np.broadcast_to(np.eye(3), (t, 3, 3)).copy()
    rad = np.deg2rad(angles_deg)
    for k, axis in enumerate(axes):
        c, s = np.cos(rad[:, k]), np.sin(rad[:, k])
        r = np.zeros((t, 3, 3))
        i = _AXIS[axis]
        j, m = [a for a in range(3) if a != i]
        r[:, i, i] = 1.0
        r[:, j, j] = c
        r[:, m, m] = c
        sign = -1.0 if i == 1 else 1.0  # y: [[c, 0, s], [0, 1, 0], [-s, 0, c]]
        r[:, j, m] = -s * sign
        r[:, m, j] = s * sign
        out = out @ r
    return out


def parse_bvh(path: Path) -> tuple[list[BvhJoint], np.ndarray, float]:
    """Joints, motion table (frames, channels) and frame time in seconds; errors name file and line."""
    tokens: list[tuple[int, str]] = []
    text = path.read_text(errors="replace")
    head, sep, motion = text.partition("MOTION")
    if not sep:
        raise MocapError(f"{path}: no MOTION section (not a BVH file?)")
    for n, line in enumerate(head.splitlines(), 1):
        tokens.extend((n, tok) for tok in line.split())
    if not tokens or tokens[0][1] != "HIERARCHY":
        raise MocapError(f"{path}: must start with HIERARCHY")
    joints: list[BvhJoint] = []
    stack: list[int] = []
    n_channels = 0
    i = 1
    pending: tuple[str, int] | None = None  # name, parent of the joint whose '{' comes next

    def expect(k: int) -> tuple[int, str]:
        if k >= len(tokens):
            raise MocapError(f"{path}: hierarchy ends early (unbalanced braces?)")
        return tokens[k]

    while i < len(tokens):
        line, tok = tokens[i]
        if tok in ("ROOT", "JOINT"):
            _, name = expect(i + 1)
            pending = (name, stack[-1] if stack else -1)
            if tok == "JOINT" and not stack:
                raise MocapError(f"{path}: line {line}: JOINT {name} outside a ROOT")
            i += 2
        elif tok == "End":
            parent = stack[-1] if stack else -1
            if parent < 0:
                raise MocapError(f"{path}: line {line}: End Site outside a joint")
            pending = (f"{joints[parent].name}_end", parent)
            i += 2
        elif tok == "{":
            if pending is None:
                raise MocapError(f"{path}: line {line}: '{{' without a joint")
            joints.append(BvhJoint(pending[0], pending[1], np.zeros(3), (), n_channels))
            stack.append(len(joints) - 1)
            pending = None
            i += 1
        elif tok == "}":
            if not stack:
                raise MocapError(f"{path}: line {line}: unbalanced '}}'")
            stack.pop()
            i += 1
        elif tok == "OFFSET":
            vals = [expect(i + k)[1] for k in (1, 2, 3)]
            try:
                joints[stack[-1]].offset = np.array([float(v) for v in vals])
            except (ValueError, IndexError):
                raise MocapError(f"{path}: line {line}: OFFSET needs 3 numbers, got {vals}") from None
            i += 4
        elif tok == "CHANNELS":
            try:
                k = int(expect(i + 1)[1])
            except ValueError:
                raise MocapError(f"{path}: line {line}: CHANNELS needs a count") from None
            names = tuple(expect(i + 2 + c)[1] for c in range(k))
            bad = [c for c in names if c.lower() not in {f"{a}{kind}" for a in "xyz" for kind in ("position",
                                                                                                  "rotation")}]
            if bad or not stack:
                raise MocapError(f"{path}: line {line}: unknown channels {bad} in joint "
                                 f"{joints[stack[-1]].name if stack else '?'}")
            j = joints[stack[-1]]
            j.channels, j.first_channel = names, n_channels
            n_channels += k
            i += 2 + k
        else:
            raise MocapError(f"{path}: line {line}: unexpected {tok!r} in HIERARCHY")
    if stack:
        raise MocapError(f"{path}: hierarchy not closed (missing '}}' for {joints[stack[-1]].name})")
    if not joints:
        raise MocapError(f"{path}: no joints in HIERARCHY")
    return joints, *_parse_motion(path, motion, n_channels)


def _parse_motion(path: Path, motion: str, n_channels: int) -> tuple[np.ndarray, float]:
    lines = [ln.strip() for ln in motion.splitlines() if ln.strip()]
    frames = time = None
    body = 0
    while body < len(lines) and ":" in lines[body]:
        key, _, value = lines[body].partition(":")
        key = key.strip().lower()
        try:
            if key == "frames":
                frames = int(value)
            elif key == "frame time":
                time = float(value)
            else:
                break
        except ValueError:
            raise MocapError(f"{path}: MOTION header {lines[body]!r} needs a number") from None
        body += 1
    if frames is None or time is None:
        raise MocapError(f"{path}: MOTION needs 'Frames:' and 'Frame Time:' lines")
    if not time > 0:
        raise MocapError(f"{path}: Frame Time must be positive, got {time}")
    if frames < 1:
        raise MocapError(f"{path}: no motion frames (Frames: {frames})")
    rows = lines[body:]
    if len(rows) < frames:
        raise MocapError(f"{path}: header says {frames} frames, file has {len(rows)} (truncated?)")
    try:
        table = np.array([r.split() for r in rows[:frames]], dtype=np.float64)
    except ValueError:
        for n, r in enumerate(rows[:frames]):
            vals = r.split()
            if len(vals) != n_channels:
                raise MocapError(f"{path}: motion frame {n}: {len(vals)} values, hierarchy has {n_channels} "
                                 "channels") from None
        raise MocapError(f"{path}: motion data has a value that is not a number") from None
    if table.ndim != 2 or table.shape[1] != n_channels:
        raise MocapError(f"{path}: motion rows have {table.shape[-1] if table.ndim == 2 else '?'} values, "
                         f"hierarchy has {n_channels} channels")
    if not np.all(np.isfinite(table)):
        raise MocapError(f"{path}: motion data has NaN or infinite values")
    return table, time


def forward_kinematics(joints: list[BvhJoint], motion: np.ndarray) -> np.ndarray:
    """Global joint positions (frames, joints, 3) in file units."""
    t = motion.shape[0]
    rot = np.zeros((len(joints), t, 3, 3))
    pos = np.zeros((len(joints), t, 3))
    for k, j in enumerate(joints):
        cols = {c.lower(): j.first_channel + n for n, c in enumerate(j.channels)}
        local = np.broadcast_to(j.offset, (t, 3)).copy()
        if any(c.endswith("position") for c in cols):
            for a in "xyz":
                if f"{a}position" in cols:
                    local[:, _AXIS[a]] = motion[:, cols[f"{a}position"]]
        order = "".join(c[0] for c in (ch.lower() for ch in j.channels) if c.endswith("rotation"))
        r_local = rotation_matrices(motion[:, [cols[f"{a}rotation"] for a in order]], order)
        if j.parent < 0:
            rot[k], pos[k] = r_local, local
        else:
            rot[k] = rot[j.parent] @ r_local
            pos[k] = pos[j.parent] + np.einsum("tij,tj->ti", rot[j.parent], local)
    return pos.transpose(1, 0, 2)


def load_bvh(path: str | Path) -> MocapClip:
    """A BVH file as a `MocapClip` (file units, Y up, the file's frame rate)."""
    path = Path(path)
    joints, motion, frame_time = parse_bvh(path)
    names = [j.name for j in joints]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise MocapError(f"{path}: duplicate joint names {dup}")
    return MocapClip(forward_kinematics(joints, motion), tuple(names), 1.0 / frame_time, str(path), up="y",
                     metadata={"format": "bvh"})
