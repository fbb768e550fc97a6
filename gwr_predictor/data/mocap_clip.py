"""What every mocap importer returns (`MocapClip`) and how the user says to read a recording
(`ImportOptions`: units, up axis, frame rate, joint map), apart from the importers themselves so that
each reader (`bvh`, `asf_amc`, `joint_positions`, `torch_files`) and `mocap`, which chooses among them,
import it without importing one another.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gwr_predictor.data.errors import DataError

#: Length units by name -> metres per unit. "auto" picks one from the skeleton's size.
UNITS: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001, "inch": 0.0254, "dm": 0.1}
UP_AXES = ("auto", "x", "y", "z", "-x", "-y", "-z")


@dataclass(frozen=True)
class ImportOptions:
    """How to read a recording: units, up axis, frame rate, joint mapping, ASF skeleton.

    `units` is a name of `UNITS`, "auto" or a number (metres per file unit); `fps` 0 means "from the
    file" (required for `.npy` without a rate); `joint_map` a user mapping file (see `joint_maps`).
    """

    units: str = "auto"
    up: str = "auto"
    fps: float = 0.0
    joint_map: str | Path | None = None
    asf: str | Path | None = None
    joint_names: tuple[str, ...] | None = None  # names for an .npy without them (else from the map)

    def __post_init__(self) -> None:
        if self.up not in UP_AXES:
            raise DataError(f"up axis {self.up!r} is not one of {', '.join(UP_AXES)}")
        if not (np.isfinite(self.fps) and self.fps >= 0):
            raise DataError(f"fps must be a positive number (0 = from the file), got {self.fps}")
        unit_scale(self.units)


def unit_scale(units: str | float) -> float | None:
    """Metres per file unit for a unit name or number; None for "auto"."""
    if isinstance(units, (int, float)):
        value = float(units)
    elif units == "auto":
        return None
    elif units in UNITS:
        return UNITS[units]
    else:
        try:
            value = float(units)
        except ValueError:
            raise DataError(f"units {units!r}: use auto, {', '.join(UNITS)} or metres per unit as a number") from None
    if not (np.isfinite(value) and value > 0):
        raise DataError(f"units must be positive metres per unit, got {units!r}")
    return value


@dataclass
class MocapClip:
    """Joint positions of one recording in its own world frame (metres once `scale` is applied)."""

    positions: np.ndarray  # (T, J, 3), file units times `scale`
    joint_names: tuple[str, ...]
    fps: float
    source: str
    up: str = "auto"  # the file's up axis when the format says it ("y" for BVH by convention)
    scale_known: bool = False  # the format fixed the units (ASF header, metres by definition)
    metadata: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.positions = np.asarray(self.positions, dtype=np.float64)
        self.joint_names = tuple(str(n) for n in self.joint_names)
        p = self.positions
        if p.ndim != 3 or p.shape[2] != 3 or p.shape[1] != len(self.joint_names):
            raise DataError(f"{self.source}: positions must be (frames, {len(self.joint_names)}, 3), got {p.shape}")
        if p.shape[0] < 1:
            raise DataError(f"{self.source}: no frames")
        if p.shape[1] < 1:
            raise DataError(f"{self.source}: no joints")
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise DataError(f"{self.source}: frame rate must be positive, got {self.fps} (give --fps)")
        if np.isinf(p).any():
            raise DataError(f"{self.source}: infinite joint positions")

    @property
    def duration_s(self) -> float:
        return (self.positions.shape[0] - 1) / self.fps
