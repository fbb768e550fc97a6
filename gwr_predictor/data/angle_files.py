"""Angle CSV files: a ``time`` column (s) and one column per joint (rad), one row per frame.

Missing frames are written as rows of ``nan``; reading accepts ``nan`` or empty cells. The joint
columns must be known robot joints (`nao.JOINT_LIMITS`); values beyond 2*pi look like degrees and
are refused with a hint, as are non-finite or decreasing times.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path
from typing import IO

import numpy as np

from gwr_predictor.data.errors import DataError
from gwr_predictor.data.skeleton_files import parse_float_table
from gwr_predictor.files.limits import MAX_CSV_BYTES, check_file_size
from gwr_predictor.files.user_files import output_file
from gwr_predictor.robot.nao import ARM_JOINTS, JOINT_LIMITS


def save_angles_csv(path: str | Path, t: np.ndarray, angles: np.ndarray,
                    names: Sequence[str] = ARM_JOINTS) -> Path:
    """Write stamps (T,) and angles (T, len(names)) as CSV; NaN is written as ``nan``."""
    path = Path(path)
    with output_file(path, "angle file", DataError, text=True) as fh:
        write_angles_csv(fh, t, angles, names, where=str(path))
    return path


def write_angles_csv(fh: IO[str], t: np.ndarray, angles: np.ndarray, names: Sequence[str] = ARM_JOINTS,
                     where: str = "<stream>") -> None:
    """`save_angles_csv` into an open text stream (e.g. stdout)."""
    t = np.asarray(t, dtype=np.float64)
    angles = np.asarray(angles, dtype=np.float64)
    if t.ndim != 1 or angles.shape != (t.shape[0], len(names)):
        raise DataError(f"{where}: angles must be ({t.shape[0]}, {len(names)}) for t {t.shape}, "
                        f"got {angles.shape}")
    fh.write(",".join(["time", *names]) + "\n")
    np.savetxt(fh, np.column_stack([t, angles]), delimiter=",", fmt="%.6f")


def load_angles_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Read (t (T,), angles (T, J), joint names) from an angle CSV, validated."""
    path = Path(path)
    if path.is_file():
        check_file_size(path, MAX_CSV_BYTES, "angle CSV", DataError)
    try:
        with path.open(newline="") as fh:
            rows = list(csv.reader(fh))
    except FileNotFoundError as exc:
        raise DataError(f"{path}: no such file") from exc
    except (UnicodeDecodeError, csv.Error) as exc:
        raise DataError(f"{path}: not a text CSV file ({exc})") from exc
    if not rows:
        raise DataError(f"{path}: empty file (expected a header 'time,{','.join(ARM_JOINTS[:2])},...')")
    header = [h.strip() for h in rows[0]]
    if header[0] != "time":
        raise DataError(f"{path}: first header column must be 'time', got {header[0]!r}")
    names = tuple(header[1:])
    unknown = [n for n in names if n not in JOINT_LIMITS]
    if not names or unknown:
        raise DataError(f"{path}: unknown joint columns {unknown or '(none)'}; expected names such as "
                        f"{', '.join(ARM_JOINTS)}")
    if len(set(names)) != len(names):
        raise DataError(f"{path}: duplicate joint columns in the header")
    table, lines = parse_float_table(path, rows[1:], len(header), first_line=2, error=DataError,
                                     header=header)
    t, angles = table[:, 0], table[:, 1:]
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise DataError(f"{path}: line {lines[bad[0]]}: time must be finite, got {t[bad[0]]}")
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        raise DataError(f"{path}: line {lines[back[0] + 1]}: time {t[back[0] + 1]} does not increase "
                        f"(previous {t[back[0]]})")
    big = np.abs(angles[np.isfinite(angles)])
    if big.size and big.max() > 2 * math.pi:
        raise DataError(f"{path}: angles reach {big.max():.1f}, which looks like degrees; "
                        "angles must be radians (multiply by pi/180)")
    return t, angles, names
