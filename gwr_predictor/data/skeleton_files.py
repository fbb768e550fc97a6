"""Skeleton sequences and their files (NPZ and CSV), read with checks that say exactly what is wrong.

Camera frame (`CAMERA_CONVENTION`, OpenNI style, right-handed, metres): origin at the depth
sensor, x horizontal towards the person's right (the sensor's left), y up, z from the sensor
into the scene; a person facing the sensor 2 m away stands near z = 2. NaN positions mean "joint
not tracked in that frame" and are allowed everywhere; infinities are not.

NPZ (``np.savez_compressed``, read with ``allow_pickle=False``):

    positions    float64 (T, J, 3), metres, camera frame
    joint_names  str (J,), must contain the 15 `SKELETON_JOINTS` (any order; extras are dropped)
    timestamps   float64 (T,), seconds, finite and strictly increasing (or give `fps` instead)
    fps          float scalar, optional; used only when `timestamps` is absent
    convention   str scalar, must be `CAMERA_CONVENTION`
    pattern, subject  str scalars, optional ("" = unknown); repetition int scalar (-1 = unknown)

CSV: optional ``# key: value`` lines (convention, pattern, subject, repetition), then a header
``time,head_x,head_y,head_z,...`` and one row per frame; ``nan`` or an empty cell is a NaN.
"""

from __future__ import annotations

import csv
import io
import zipfile
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gwr_predictor.data.errors import DataError
from gwr_predictor.files.limits import (
    MAX_CSV_BYTES,
    MAX_FRAMES,
    MAX_JOINTS,
    MAX_RECORDING_BYTES,
    check_archive,
    check_count,
    check_file_size,
)
from gwr_predictor.files.user_files import output_file
from gwr_predictor.joints.skeleton import SKELETON_JOINTS

CAMERA_CONVENTION = "openni-rh"
CAMERA_CONVENTION_TEXT = ("metres; x towards the person's right (sensor's left), y up, "
                          "z from the sensor into the scene; right-handed")
FORMAT_VERSION = 1
#: A person tracked by a depth sensor is within a few metres: larger magnitudes mean millimetres.
MAX_PLAUSIBLE_METRES = 20.0
AXES = ("x", "y", "z")


@dataclass
class SkeletonSequence:
    """Positions (T, J, 3) in metres in the camera frame, with per-frame timestamps and labels."""

    positions: np.ndarray
    timestamps: np.ndarray
    joint_names: tuple[str, ...] = SKELETON_JOINTS
    pattern: str | None = None
    subject: str | None = None
    repetition: int | None = None
    convention: str = CAMERA_CONVENTION
    metadata: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.positions = np.asarray(self.positions, dtype=np.float64)
        self.timestamps = np.asarray(self.timestamps, dtype=np.float64)
        self.joint_names = tuple(self.joint_names)
        p = self.positions
        if p.ndim != 3 or p.shape[2] != 3 or p.shape[1] != len(self.joint_names):
            raise DataError(f"positions must be (T, {len(self.joint_names)}, 3), got {p.shape}")
        if self.timestamps.shape != (p.shape[0],):
            raise DataError(f"timestamps must be ({p.shape[0]},), got {self.timestamps.shape}")

    @property
    def name(self) -> str:
        """File stem such as ``wave_both_s1_r03`` (unknown parts are left out)."""
        parts = [self.pattern or "skeleton"]
        if self.subject:
            parts.append(self.subject)
        if self.repetition is not None:
            parts.append(f"r{self.repetition:02d}")
        return "_".join(parts)

    @property
    def fps(self) -> float:
        """Median frame rate (NaN with fewer than two frames)."""
        if self.timestamps.size < 2:
            return float("nan")
        return float(1.0 / np.median(np.diff(self.timestamps)))

    def joint(self, name: str) -> np.ndarray:
        """Trajectory (T, 3) of one joint."""
        return self.positions[:, self.joint_names.index(name)]


# --- writing -----------------------------------------------------------------------------------

def save_skeleton(path: str | Path, seq: SkeletonSequence) -> Path:
    """Write `seq` as NPZ or CSV, chosen by the suffix of `path`."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        _save_npz(path, seq)
    elif suffix == ".csv":
        _save_csv(path, seq)
    else:
        raise DataError(f"{path}: unknown skeleton file suffix {path.suffix!r}; use .npz or .csv")
    return path


def _save_npz(path: Path, seq: SkeletonSequence) -> None:
    with output_file(path, "skeleton file", DataError) as fh:
        np.savez_compressed(
            fh, positions=seq.positions, joint_names=np.array(seq.joint_names, dtype=str),
            timestamps=seq.timestamps, convention=np.array(seq.convention),
            pattern=np.array(seq.pattern or ""), subject=np.array(seq.subject or ""),
            repetition=np.array(-1 if seq.repetition is None else int(seq.repetition)),
            format_version=np.array(FORMAT_VERSION))


def _save_csv(path: Path, seq: SkeletonSequence) -> None:
    header = ["time"] + [f"{j}_{a}" for j in seq.joint_names for a in AXES]
    table = np.column_stack([seq.timestamps, seq.positions.reshape(len(seq.timestamps), -1)])
    meta = {"convention": seq.convention, "pattern": seq.pattern or "", "subject": seq.subject or "",
            "repetition": "" if seq.repetition is None else str(seq.repetition)}
    with output_file(path, "skeleton file", DataError, text=True) as fh:
        for key, value in meta.items():
            fh.write(f"# {key}: {value}\n")
        fh.write(",".join(header) + "\n")
        np.savetxt(fh, table, delimiter=",", fmt="%.6f")


# --- reading -----------------------------------------------------------------------------------

def load_skeleton(path: str | Path) -> SkeletonSequence:
    """Read an NPZ or CSV skeleton file, validated and reordered to `SKELETON_JOINTS`."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix == ".npz":
        raw = _read_npz(path)
    elif suffix == ".csv":
        raw = _read_csv(path)
    else:
        raise DataError(f"{path}: unknown skeleton file suffix {path.suffix!r}; use .npz or .csv")
    return _validated(path, **raw)


def _read_npz(path: Path) -> dict:
    check_archive(path, MAX_RECORDING_BYTES, "skeleton recording", DataError)
    try:
        with np.load(path, allow_pickle=False) as npz:
            data = {k: npz[k] for k in npz.files}
    except (zipfile.BadZipFile, OSError, EOFError, ValueError, zlib.error, NotImplementedError, RuntimeError) as exc:
        raise DataError(f"{path}: not a readable NPZ archive (truncated or not NPZ?): {exc}") from exc
    for key in ("positions", "joint_names"):
        if key not in data:
            raise DataError(f"{path}: missing array {key!r} (has {sorted(data)})")
    if "timestamps" in data:
        stamps = data["timestamps"]
    elif "fps" in data:
        fps = _scalar(path, data, "fps", float)
        if not np.isfinite(fps) or fps <= 0:
            raise DataError(f"{path}: field 'fps' must be a positive number, got {fps}")
        stamps = np.arange(np.shape(data["positions"])[0]) / fps
    else:
        raise DataError(f"{path}: needs 'timestamps' (T,) or a scalar 'fps'")
    if not np.issubdtype(data["positions"].dtype, np.number):
        raise DataError(f"{path}: field 'positions' must be numeric, got dtype {data['positions'].dtype}")
    if not np.issubdtype(np.asarray(stamps).dtype, np.number):
        raise DataError(f"{path}: field 'timestamps' must be numeric, got dtype {stamps.dtype}")
    rep = _scalar(path, data, "repetition", int) if "repetition" in data else -1
    check_count(path, np.size(data["joint_names"]), MAX_JOINTS, "joint names", DataError)
    return {"positions": data["positions"].astype(np.float64), "timestamps": np.asarray(stamps, np.float64),
            "joint_names": [str(n) for n in np.atleast_1d(data["joint_names"])],
            "convention": _scalar(path, data, "convention", str) if "convention" in data else None,
            "pattern": _scalar(path, data, "pattern", str) if "pattern" in data else "",
            "subject": _scalar(path, data, "subject", str) if "subject" in data else "",
            "repetition": rep}


def _scalar(path: Path, data: dict, key: str, kind: type):
    arr = np.asarray(data[key])
    if arr.shape != ():
        raise DataError(f"{path}: field {key!r} must be a scalar, got shape {arr.shape}")
    try:
        return kind(arr.item())
    except (TypeError, ValueError) as exc:
        raise DataError(f"{path}: field {key!r} must be {kind.__name__}, got {arr.item()!r}") from exc


def _read_csv(path: Path) -> dict:
    check_file_size(path, MAX_CSV_BYTES, "skeleton CSV", DataError)
    try:
        text = path.read_text()
    except UnicodeDecodeError as exc:
        raise DataError(f"{path}: not a text CSV file ({exc})") from exc
    lines = text.splitlines()
    meta: dict[str, str] = {}
    n_comment = 0
    for line in lines:
        if not line.startswith("#"):
            break
        key, _, value = line[1:].partition(":")
        meta[key.strip()] = value.strip()
        n_comment += 1
    rows = list(csv.reader(io.StringIO("\n".join(lines[n_comment:]))))
    if not rows:
        raise DataError(f"{path}: no header line (expected 'time,head_x,head_y,head_z,...')")
    header = [h.strip() for h in rows[0]]
    names = _csv_joint_names(path, header)
    check_count(path, len(rows) - 1, MAX_FRAMES, "frames", DataError)
    table, _ = parse_float_table(path, rows[1:], len(header), first_line=n_comment + 2,
                                 error=DataError, header=header)
    rep_text = meta.get("repetition", "")
    try:
        rep = int(rep_text) if rep_text else -1
    except ValueError as exc:
        raise DataError(f"{path}: '# repetition:' must be an integer, got {rep_text!r}") from exc
    return {"positions": table[:, 1:].reshape(len(table), len(names), 3), "timestamps": table[:, 0],
            "joint_names": names, "convention": meta.get("convention"), "pattern": meta.get("pattern", ""),
            "subject": meta.get("subject", ""), "repetition": rep}


def _csv_joint_names(path: Path, header: list[str]) -> list[str]:
    if not header or header[0] != "time":
        raise DataError(f"{path}: first header column must be 'time', got {header[:1]}")
    cols = header[1:]
    check_count(path, len(cols) // 3, MAX_JOINTS, "joints", DataError)
    if len(cols) % 3:
        raise DataError(f"{path}: {len(cols)} position columns is not a multiple of 3 (x, y, z per joint)")
    names = []
    for i in range(0, len(cols), 3):
        stem = cols[i][:-2]
        expected = [f"{stem}_{a}" for a in AXES]
        if cols[i:i + 3] != expected:
            raise DataError(f"{path}: header columns {i + 2}-{i + 4} must be {expected}, got {cols[i:i + 3]}")
        names.append(stem)
    return names


def parse_float_table(path: Path, rows: Sequence[Sequence[str]], width: int, first_line: int,
                      error: type[ValueError], header: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """CSV cells -> ((N, width) floats, file line number of each row); blank lines are skipped.

    '' and 'nan' are NaN; errors name the line and the column.
    """
    kept = [(first_line + i, [c.strip() or "nan" for c in row])
            for i, row in enumerate(rows) if any(c.strip() for c in row)]
    lines = np.array([n for n, _ in kept], dtype=int)
    for n, row in kept:
        if len(row) != width:
            raise error(f"{path}: line {n}: {len(row)} columns, header has {width}")
    try:
        return np.array([r for _, r in kept], dtype=np.float64).reshape(len(kept), width), lines
    except ValueError:
        for n, row in kept:
            for j, cell in enumerate(row):
                try:
                    float(cell)
                except ValueError:
                    raise error(f"{path}: line {n}, column {header[j]!r}: not a number: {cell[:30]!r}") from None
        raise


def _validated(path: Path, positions: np.ndarray, timestamps: np.ndarray, joint_names: list[str],
               convention: str | None, pattern: str, subject: str, repetition: int) -> SkeletonSequence:
    if positions.ndim != 3 or positions.shape[2] != 3:
        raise DataError(f"{path}: field 'positions' must be (frames, joints, 3), got shape {positions.shape}")
    if len(joint_names) != positions.shape[1]:
        raise DataError(f"{path}: {len(joint_names)} joint_names for {positions.shape[1]} joints in positions")
    missing = [j for j in SKELETON_JOINTS if j not in joint_names]
    if missing:
        raise DataError(f"{path}: joint_names lacks {missing} (needs the 15 OpenNI joints {SKELETON_JOINTS})")
    if len(set(joint_names)) != len(joint_names):
        raise DataError(f"{path}: duplicate names in joint_names")
    if convention is not None and convention != CAMERA_CONVENTION:
        raise DataError(f"{path}: convention {convention!r} is not supported; expected {CAMERA_CONVENTION!r} "
                        f"({CAMERA_CONVENTION_TEXT}); convert the positions first (e.g. negate x)")
    check_timestamps(path, timestamps, positions.shape[0])
    positions = positions[:, [joint_names.index(j) for j in SKELETON_JOINTS]]
    check_positions(path, positions)
    return SkeletonSequence(positions=positions, timestamps=timestamps, joint_names=SKELETON_JOINTS,
                            pattern=pattern or None, subject=subject or None,
                            repetition=None if repetition < 0 else repetition)


def check_timestamps(path: str | Path, timestamps: np.ndarray, n_frames: int) -> None:
    """Timestamps must be (n_frames,), finite and strictly increasing."""
    if timestamps.shape != (n_frames,):
        raise DataError(f"{path}: field 'timestamps' must have shape ({n_frames},), got {timestamps.shape}")
    bad = np.flatnonzero(~np.isfinite(timestamps))
    if bad.size:
        raise DataError(f"{path}: timestamps[{bad[0]}] is {timestamps[bad[0]]} (must be finite)")
    back = np.flatnonzero(np.diff(timestamps) <= 0)
    if back.size:
        i = back[0] + 1
        raise DataError(f"{path}: timestamps not strictly increasing at frame {i}: "
                        f"{timestamps[i - 1]} then {timestamps[i]}")


def check_positions(path: str | Path, positions: np.ndarray) -> None:
    """Positions may be NaN (not tracked) but not infinite, and must look like metres."""
    inf = np.argwhere(np.isinf(positions))
    if inf.size:
        f, j, a = inf[0]
        raise DataError(f"{path}: positions[{f}] {SKELETON_JOINTS[j]}_{AXES[a]} is infinite "
                        "(use NaN for an untracked joint)")
    finite = np.abs(positions[np.isfinite(positions)])
    if finite.size and finite.max() > MAX_PLAUSIBLE_METRES:
        raise DataError(f"{path}: positions reach {finite.max():.1f}, which looks like millimetres; "
                        f"positions must be metres (divide by 1000)")
