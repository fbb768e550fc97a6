"""Torch `.pt` tensors read without torch and without running code from the file.

A `.pt` file (torch >= 1.6) is a zip: `<name>/data.pkl` pickles the tensor structure and refers to
raw storages `<name>/data/<key>`. Unpickling arbitrary data can run arbitrary code, so the
unpickler here resolves only the handful of globals a plain tensor needs (`_rebuild_tensor_v2`,
the typed storages, `OrderedDict`) and refuses everything else, naming it. Tensors come back as
numpy arrays.

OMOMO / InterMimic files (as in `holosoma-retargeting`'s demo data): a (frames, 591) tensor whose
columns 162:318 are 52 SMPL-H joint positions (metres, Z up, 30 fps) in `INTERMIMIC_JOINTS` order.
"""

from __future__ import annotations

import pickle
import struct
import zipfile
import zlib
from collections import OrderedDict
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.data.errors import DataError
from gwr_predictor.data.mocap_clip import ImportOptions, MocapClip
from gwr_predictor.files.limits import MAX_RECORDING_BYTES, MAX_VALUES, check_archive, check_count

STORAGE_DTYPES = {"FloatStorage": np.float32, "DoubleStorage": np.float64, "HalfStorage": np.float16,
                  "LongStorage": np.int64, "IntStorage": np.int32, "ShortStorage": np.int16,
                  "CharStorage": np.int8, "ByteStorage": np.uint8, "BoolStorage": np.bool_}
OMOMO_COLUMNS = slice(162, 162 + 52 * 3)
OMOMO_WIDTH = 591
OMOMO_FPS = 30.0
#: Joint order of the InterMimic/OMOMO SMPL-H positions (body, then 15 finger joints per hand).
INTERMIMIC_JOINTS = (
    "Pelvis", "L_Hip", "L_Knee", "L_Ankle", "L_Toe", "R_Hip", "R_Knee", "R_Ankle", "R_Toe", "Torso", "Spine",
    "Chest", "Neck", "Head", "L_Thorax", "L_Shoulder", "L_Elbow", "L_Wrist",
    *(f"L_{f}{k}" for f in ("Index", "Middle", "Pinky", "Ring", "Thumb") for k in (1, 2, 3)),
    "R_Thorax", "R_Shoulder", "R_Elbow", "R_Wrist",
    *(f"R_{f}{k}" for f in ("Index", "Middle", "Pinky", "Ring", "Thumb") for k in (1, 2, 3)),
)


class _Storage:
    def __init__(self, name: str) -> None:
        self.name = name


def _ints(value: Any, what: str) -> tuple[int, ...]:
    if not isinstance(value, tuple) or not all(isinstance(v, int) and not isinstance(v, bool) for v in value):
        raise DataError(f"tensor {what} must be a tuple of integers, got {str(value)[:60]}")
    return value


def _rebuild_tensor(storage: np.ndarray, offset: int, size: tuple[int, ...], stride: tuple[int, ...],
                    *_: Any) -> np.ndarray:
    """The tensor as numpy, after checking that its shape, strides and offset stay inside its
    storage and that its element count (strides may repeat values) is within `MAX_VALUES`."""
    if not isinstance(storage, np.ndarray) or not isinstance(offset, int):
        raise DataError("tensor without a storage or an integer offset")
    size, stride = _ints(size, "size"), _ints(stride, "stride")
    if len(size) != len(stride) or offset < 0 or any(s < 0 for s in size) or any(st < 0 for st in stride):
        raise DataError(f"tensor of size {size}, stride {stride}, offset {offset} reaches outside its storage")
    check_count("tensor", int(np.prod(size, dtype=object)), MAX_VALUES, "tensor elements", DataError)
    need = offset + sum((s - 1) * st for s, st in zip(size, stride, strict=True)) + 1 if all(size) else 0
    if need > storage.size:
        raise DataError(f"tensor of size {size} at offset {offset} does not fit its storage of {storage.size}")
    return np.lib.stride_tricks.as_strided(storage[offset:], shape=size,
                                           strides=tuple(st * storage.itemsize for st in stride)).copy()


class _RestrictedUnpickler(pickle.Unpickler):
    def __init__(self, fh: Any, archive: zipfile.ZipFile, prefix: str, path: Path) -> None:
        super().__init__(fh)
        self.archive, self.prefix, self.path = archive, prefix, path

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) == ("torch._utils", "_rebuild_tensor_v2"):
            return _rebuild_tensor
        if module == "torch" and name in STORAGE_DTYPES:
            return _Storage(name)
        if (module, name) == ("collections", "OrderedDict"):
            return OrderedDict
        raise DataError(f"{self.path}: refuses to load {module}.{name} (only plain tensors are read; "
                        "a .pt file can carry code)")

    def persistent_load(self, pid: Any) -> np.ndarray:
        if not (isinstance(pid, tuple) and len(pid) == 5 and pid[0] == "storage" and isinstance(pid[1], _Storage)):
            raise DataError(f"{self.path}: unexpected persistent id {str(pid)[:60]}")
        _, kind, key, _location, numel = pid
        try:
            raw = self.archive.read(f"{self.prefix}data/{key}")
        except (KeyError, TypeError):
            raise DataError(f"{self.path}: storage {key!r} missing from the archive") from None
        arr = np.frombuffer(raw, dtype=np.dtype(STORAGE_DTYPES[kind.name]).newbyteorder("<"))
        if not isinstance(numel, int) or arr.size < numel:
            raise DataError(f"{self.path}: storage {key!r} has {arr.size} values, expected {numel}")
        return arr


def load_tensor(path: str | Path) -> Any:
    """The object saved in a torch zip file, tensors as numpy arrays; refuses anything but tensors."""
    path = Path(path)
    check_archive(path, MAX_RECORDING_BYTES, "torch file", DataError)
    try:
        with zipfile.ZipFile(path) as archive:
            pkl = [n for n in archive.namelist() if n.endswith("data.pkl")]
            if len(pkl) != 1:
                raise DataError(f"{path}: not a torch zip file (no single data.pkl; legacy .pt files are not read)")
            prefix = pkl[0][: -len("data.pkl")]
            order = archive.read(f"{prefix}byteorder").decode(errors="replace").strip() \
                if f"{prefix}byteorder" in archive.namelist() else "little"
            if order != "little":
                raise DataError(f"{path}: byte order {order!r} is not supported")
            with archive.open(pkl[0]) as fh:
                return _RestrictedUnpickler(fh, archive, prefix, path).load()
    except DataError as exc:
        raise DataError(str(exc) if str(exc).startswith(str(path)) else f"{path}: {exc}") from None
    except (zipfile.BadZipFile, zlib.error, NotImplementedError, RuntimeError):
        raise DataError(f"{path}: not a torch zip file (legacy or corrupt .pt)") from None
    except (pickle.UnpicklingError, EOFError, TypeError, AttributeError, ValueError, KeyError, IndexError,
            OverflowError, UnicodeDecodeError, struct.error) as exc:
        raise DataError(f"{path}: unreadable pickle in the .pt file ({type(exc).__name__}: {exc})"[:300]) from None


def load_torch_clip(path: str | Path, options: ImportOptions | None = None) -> MocapClip:
    """Joint positions from a `.pt` tensor: OMOMO layout (frames, 591), or (frames, joints, 3)."""
    path = Path(path)
    options = options or ImportOptions()
    arr = load_tensor(path)
    if not isinstance(arr, np.ndarray):
        raise DataError(f"{path}: holds a {type(arr).__name__}, expected one tensor")
    names = options.joint_names
    fps = options.fps
    if arr.ndim == 2 and arr.shape[1] == OMOMO_WIDTH:
        arr = arr[:, OMOMO_COLUMNS].reshape(arr.shape[0], 52, 3)
        names = names or INTERMIMIC_JOINTS
        fps = fps or OMOMO_FPS
        layout = "omomo"
    elif arr.ndim == 3 and arr.shape[2] == 3:
        layout = "positions"
    else:
        raise DataError(f"{path}: tensor of shape {arr.shape} is neither (frames, {OMOMO_WIDTH}) OMOMO data nor "
                        "(frames, joints, 3) positions")
    if names is None:
        names = tuple(f"joint{i}" for i in range(arr.shape[1]))
    if len(names) != arr.shape[1]:
        raise DataError(f"{path}: {len(names)} joint names for {arr.shape[1]} joints")
    if not fps:
        raise DataError(f"{path}: the file does not say its frame rate; give --fps")
    return MocapClip(arr.astype(np.float64), tuple(names), float(fps), str(path),
                     metadata={"format": "pt", "layout": layout})
