"""BVH (Biovision hierarchy) files -> joint positions by our own forward kinematics.

Why our own: the maintained PyPI parsers (bvh, bvhio, bvhsdk, pybvh) either stop at the channel
values or pull in large dependencies; forward kinematics is 30 lines of vectorised numpy here.

Conventions (the de-facto BVH standard): a joint's rotation channels, in the order listed, multiply
as R = R_1 @ R_2 @ R_3 (e.g. `Zrotation Xrotation Yrotation` -> Rz Rx Ry), angles in degrees; a
joint's global rotation is its parent's times its own; its position is the parent's position plus
the parent's global rotation times its local translation, which is the OFFSET, or the position
channels when the joint has them (they replace the OFFSET). `End Site`s are kept as joints named
`<parent>_end`. Units are whatever the file used (see `mocap_clip.ImportOptions.units`); Y is up unless
told otherwise. Positions of a joint are where its bone starts: `LeftArm` is the shoulder.
"""

from __future__ import annotations

import itertools
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gwr_predictor.data.errors import DataError
from gwr_predictor.data.mocap_clip import MocapClip
from gwr_predictor.files.limits import (
    MAX_DEPTH,
    MAX_JOINTS,
    MAX_TEXT_BYTES,
    MAX_VALUES,
    check_count,
    check_file_size,
    check_shape,
    frame_chunks,
)

_AXIS = {"x": 0, "y": 1, "z": 2}
_CHANNELS = frozenset(f"{a}{kind}" for a in "xyz" for kind in ("position", "rotation"))
#: Motion lines parsed per numpy call: the text of a few thousand frames at a time.
_ROWS_PER_CHUNK = 4096


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
    """Joints, motion table (frames, channels) and frame time in seconds; errors name file and line.

    The file is streamed line by line and every declared size (file, joints, nesting, channels,
    frames x channels) is checked against `files.limits` before the motion table is allocated."""
    check_file_size(path, MAX_TEXT_BYTES, "BVH file", DataError)
    with path.open(errors="replace") as fh:
        lines = enumerate(fh, 1)
        joints, n_channels = _parse_hierarchy(path, _tokens(lines))
        table, time = _parse_motion(path, lines, n_channels, len(joints))
    return joints, table, time


def _tokens(lines: Iterator[tuple[int, str]]) -> Iterator[tuple[int, str]]:
    for n, line in lines:
        for tok in line.split():
            yield n, tok


class _Hierarchy:
    """The HIERARCHY section as it is read: joints so far, the open ones, the next joint's name."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.joints: list[BvhJoint] = []
        self.stack: list[int] = []
        self.n_channels = 0
        self.pending: tuple[str, int] | None = None  # name, parent of the joint whose '{' comes next

    def open(self, line: int) -> None:
        if self.pending is None:
            raise DataError(f"{self.path}: line {line}: '{{' without a joint")
        check_count(self.path, len(self.joints) + 1, MAX_JOINTS, "joints", DataError)
        check_count(self.path, len(self.stack) + 1, MAX_DEPTH, "levels of joint nesting", DataError)
        self.joints.append(BvhJoint(self.pending[0], self.pending[1], np.zeros(3), (), self.n_channels))
        self.stack.append(len(self.joints) - 1)
        self.pending = None

    def channels(self, line: int, names: tuple[str, ...]) -> None:
        bad = [c for c in names if c.lower() not in _CHANNELS]
        if bad or not self.stack:
            raise DataError(f"{self.path}: line {line}: unknown channels {bad} in joint "
                            f"{self.joints[self.stack[-1]].name if self.stack else '?'}")
        j = self.joints[self.stack[-1]]
        j.channels, j.first_channel = names, self.n_channels
        self.n_channels += len(names)


def _parse_hierarchy(path: Path, tokens: Iterator[tuple[int, str]]) -> tuple[list[BvhJoint], int]:
    """Reads tokens up to and including MOTION; refuses more than `MAX_JOINTS` or `MAX_DEPTH` as it goes."""
    def take() -> tuple[int, str]:
        tok = next(tokens, None)
        if tok is None:
            raise DataError(f"{path}: hierarchy ends early (unbalanced braces?; no MOTION section?)")
        return tok

    first = next(tokens, (0, ""))
    if first[1] != "HIERARCHY":
        raise DataError(f"{path}: must start with HIERARCHY")
    h = _Hierarchy(path)
    while True:
        line, tok = take()
        if tok == "MOTION":
            break
        if not h.stack and h.joints and tok != "ROOT":
            raise DataError(f"{path}: line {line}: expected MOTION after the hierarchy, got {tok[:30]!r} "
                            "(no MOTION section?)")
        if tok in ("ROOT", "JOINT"):
            _, name = take()
            if tok == "JOINT" and not h.stack:
                raise DataError(f"{path}: line {line}: JOINT {name} outside a ROOT")
            h.pending = (name, h.stack[-1] if h.stack else -1)
        elif tok == "End":
            take()
            if not h.stack:
                raise DataError(f"{path}: line {line}: End Site outside a joint")
            h.pending = (f"{h.joints[h.stack[-1]].name}_end", h.stack[-1])
        elif tok == "{":
            h.open(line)
        elif tok == "}":
            if not h.stack:
                raise DataError(f"{path}: line {line}: unbalanced '}}'")
            h.stack.pop()
        elif tok == "OFFSET":
            vals = [take()[1] for _ in range(3)]
            try:
                h.joints[h.stack[-1]].offset = np.array([float(v) for v in vals])
            except (ValueError, IndexError):
                raise DataError(f"{path}: line {line}: OFFSET needs 3 numbers, got {vals}") from None
        elif tok == "CHANNELS":
            try:
                k = int(take()[1])
            except ValueError:
                raise DataError(f"{path}: line {line}: CHANNELS needs a count") from None
            if not 0 <= k <= len(_CHANNELS):
                raise DataError(f"{path}: line {line}: CHANNELS {k}: a joint has 0 to {len(_CHANNELS)} channels")
            h.channels(line, tuple(take()[1] for _ in range(k)))
        else:
            raise DataError(f"{path}: line {line}: unexpected {tok[:30]!r} in HIERARCHY")
    if h.stack:
        raise DataError(f"{path}: hierarchy not closed (missing '}}' for {h.joints[h.stack[-1]].name})")
    if not h.joints:
        raise DataError(f"{path}: no joints in HIERARCHY")
    return h.joints, h.n_channels


def _motion_header(path: Path, lines: Iterator[tuple[int, str]]) -> tuple[int, float, str | None]:
    """Frames and frame time, and the first line after them (None at the end of the file)."""
    frames = time = None
    for _, raw in lines:
        line = raw.strip()
        if not line:
            continue
        key, colon, value = line.partition(":")
        key = key.strip().lower()
        if not colon or key not in ("frames", "frame time"):
            break
        try:
            if key == "frames":
                frames = int(value)
            else:
                time = float(value)
        except ValueError:
            raise DataError(f"{path}: MOTION header {line[:60]!r} needs a number") from None
    else:
        line = None
    if frames is None or time is None:
        raise DataError(f"{path}: MOTION needs 'Frames:' and 'Frame Time:' lines")
    return frames, time, line


def _parse_motion(path: Path, lines: Iterator[tuple[int, str]], n_channels: int,
                  n_joints: int) -> tuple[np.ndarray, float]:
    frames, time, first = _motion_header(path, lines)
    if not time > 0:
        raise DataError(f"{path}: Frame Time must be positive, got {time}")
    if frames < 1:
        raise DataError(f"{path}: no motion frames (Frames: {frames})")
    check_shape(path, frames, n_joints, DataError)
    check_count(path, frames * n_channels, MAX_VALUES, "motion values (frames x channels)", DataError)
    table = np.empty((frames, n_channels))
    rows = itertools.chain([] if first is None else [first], (ln.strip() for _, ln in lines))
    done = 0
    while done < frames:
        chunk = list(itertools.islice((r for r in rows if r), min(_ROWS_PER_CHUNK, frames - done)))
        if not chunk:
            raise DataError(f"{path}: header says {frames} frames, file has {done} (truncated?)")
        table[done:done + len(chunk)] = _rows(path, chunk, done, n_channels)
        done += len(chunk)
    if not np.all(np.isfinite(table)):
        raise DataError(f"{path}: motion data has NaN or infinite values")
    return table, time


def _rows(path: Path, chunk: list[str], first: int, n_channels: int) -> np.ndarray:
    """Motion lines -> (len(chunk), n_channels) floats; errors name the frame."""
    cells = [r.split() for r in chunk]
    for n, vals in enumerate(cells):
        if len(vals) != n_channels:
            raise DataError(f"{path}: motion frame {first + n}: {len(vals)} values, hierarchy has {n_channels} "
                            "channels")
    try:
        return np.array(cells, dtype=np.float64).reshape(len(chunk), n_channels)
    except ValueError:
        raise DataError(f"{path}: motion data has a value that is not a number") from None


def forward_kinematics(joints: list[BvhJoint], motion: np.ndarray) -> np.ndarray:
    """Global joint positions (frames, joints, 3) in file units, a few frames at a time so that the
    rotations of every joint are never held for the whole clip."""
    out = np.empty((motion.shape[0], len(joints), 3))
    for frames in frame_chunks(motion.shape[0], 12 * len(joints)):
        out[frames] = _forward_kinematics(joints, motion[frames])
    return out


def _forward_kinematics(joints: list[BvhJoint], motion: np.ndarray) -> np.ndarray:
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
    dup = sorted(n for n, count in Counter(names).items() if count > 1)
    if dup:
        raise DataError(f"{path}: duplicate joint names {dup}")
    return MocapClip(forward_kinematics(joints, motion), tuple(names), 1.0 / frame_time, str(path), up="y",
                     metadata={"format": "bvh"})
