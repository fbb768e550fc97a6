"""Joint-position arrays (`.npy` / `.npz` of shape (frames, joints, 3)) as shipped by many data sets
and retargeting tools.

`.npz`: the positions are the array named `positions`, `joints`, `joint_positions` or
`global_joint_positions` (or the only 3-D array), the names `joint_names` (or `names`), the rate
`fps`, `framerate` or `mocap_framerate`. `.npy`: the array only, so the names come from
`ImportOptions.joint_names`, the joint-map file's `joint_names` list, or the map's indices, and the
rate from `--fps`. Both are read with `allow_pickle=False`: a data file never runs code.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from gwr_predictor.data.errors import DataError
from gwr_predictor.data.joint_maps import read_map_file
from gwr_predictor.data.mocap_clip import ImportOptions, MocapClip
from gwr_predictor.files.limits import MAX_JOINTS, check_count, check_shape

POSITION_KEYS = ("positions", "joints", "joint_positions", "global_joint_positions")
NAME_KEYS = ("joint_names", "names")
FPS_KEYS = ("fps", "framerate", "mocap_framerate", "frame_rate")


def _names_from_options(path: Path, options: ImportOptions, n: int) -> tuple[str, ...]:
    names = options.joint_names
    if names is None and options.joint_map:
        listed = read_map_file(options.joint_map).get("joint_names")
        if listed is not None:
            names = tuple(str(x) for x in listed)
    if names is None:
        return tuple(f"joint{i}" for i in range(n))  # only a map with indices can use these
    if len(names) != n:
        raise DataError(f"{path}: {len(names)} joint names given for {n} joints in the array")
    return tuple(names)


def load_joint_positions(path: str | Path, options: ImportOptions | None = None) -> MocapClip:
    """A (frames, joints, 3) array file as a `MocapClip` (units and up axis decided later)."""
    path = Path(path)
    options = options or ImportOptions()
    fps = float(options.fps)
    names: tuple[str, ...] | None = None
    try:
        if path.suffix.lower() == ".npy":
            arr = np.load(path, allow_pickle=False)
        else:
            with np.load(path, allow_pickle=False) as npz:
                data = {k: npz[k] for k in npz.files}
            key = next((k for k in POSITION_KEYS if k in data), None)
            if key is None:
                three = [k for k, v in data.items() if v.ndim == 3 and v.shape[-1] == 3]
                if len(three) != 1:
                    raise DataError(f"{path}: no positions array (looked for {', '.join(POSITION_KEYS)}; "
                                    f"has {sorted(data)})")
                key = three[0]
            arr = data[key]
            name_key = next((k for k in NAME_KEYS if k in data), None)
            if name_key is not None:
                check_count(path, np.size(data[name_key]), MAX_JOINTS, "joint names", DataError)
                names = tuple(str(x) for x in np.atleast_1d(data[name_key]))
            fps_key = next((k for k in FPS_KEYS if k in data), None)
            if not fps and fps_key is not None:
                fps = float(np.asarray(data[fps_key]).reshape(-1)[0])
    except (zipfile.BadZipFile, EOFError, OSError) as exc:
        raise DataError(f"{path}: not a readable numpy file ({exc})") from None
    except ValueError as exc:  # object arrays need pickle: refused
        raise DataError(f"{path}: cannot read it without unpickling ({exc})") from None
    if not np.issubdtype(arr.dtype, np.number):
        raise DataError(f"{path}: positions must be numeric, got dtype {arr.dtype}")
    if arr.ndim == 2 and arr.shape[1] % 3 == 0:
        arr = arr.reshape(arr.shape[0], -1, 3)
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise DataError(f"{path}: positions must be (frames, joints, 3), got shape {arr.shape}")
    check_shape(path, arr.shape[0], arr.shape[1], DataError)
    if names is None:
        names = _names_from_options(path, options, arr.shape[1])
    elif len(names) != arr.shape[1]:
        raise DataError(f"{path}: {len(names)} joint_names for {arr.shape[1]} joints")
    if not fps:
        raise DataError(f"{path}: the file does not say its frame rate; give --fps")
    return MocapClip(arr.astype(np.float64), names, fps, str(path), metadata={"format": path.suffix.lower()[1:]})
