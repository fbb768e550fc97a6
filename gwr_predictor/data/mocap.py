"""Motion-capture recordings in: one loader per format, one way onto the 15-joint skeleton stream.

A `MocapClip` is what every importer returns: joint positions (frames, joints, 3) in metres in the
recording's own world frame, the joint names of the file, the frame rate and where it came from.
`clip_to_skeleton` maps it onto the 15 `SKELETON_JOINTS` (`joint_maps`), turns its world frame into
the camera frame of `skeleton_files` (up axis -> y, the person's right -> x at the first frame, so
they face the sensor 2 m away) and resamples it to the 30 fps skeleton stream.

Formats, chosen by the suffix (`load_clip`): `.bvh` (`bvh`), `.amc` with its `.asf` (`asf_amc`),
`.npy` / `.npz` joint positions (`joint_positions`), `.pt` OMOMO-style torch files
(`torch_files`). `load_any_skeleton` also takes our own skeleton `.npz` / `.csv` files, so every
command and `skeleton_source` accept all of them.
"""

from __future__ import annotations

import warnings
import zipfile
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from gwr_predictor.data.asf_amc import load_amc
from gwr_predictor.data.bvh import load_bvh
from gwr_predictor.data.errors import DataError
from gwr_predictor.data.joint_maps import map_joints, resolve_map
from gwr_predictor.data.joint_positions import load_joint_positions
from gwr_predictor.data.mocap_clip import UNITS, ImportOptions, MocapClip, unit_scale
from gwr_predictor.data.skeleton_files import SkeletonSequence, check_positions, load_skeleton
from gwr_predictor.data.torch_files import load_torch_clip
from gwr_predictor.files import limits
from gwr_predictor.joints.skeleton import SKELETON_FPS, SKELETON_JOINTS

SUFFIXES = (".bvh", ".amc", ".npy", ".npz", ".pt")
#: A standing adult is about this tall; "auto" units pick the unit that brings the clip closest to it.
TYPICAL_HEIGHT_M = 1.6
CAMERA_DISTANCE_M = 2.0


# --- loading -----------------------------------------------------------------------------------

def load_clip(path: str | Path, options: ImportOptions | None = None) -> MocapClip:
    """Read a mocap recording chosen by suffix; units and fps from `options` override the file's."""
    options = options or ImportOptions()
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: no such file")
    suffix = path.suffix.lower()
    try:
        if suffix == ".bvh":
            clip = load_bvh(path)
        elif suffix in (".amc", ".asf"):
            clip = load_amc(path, options.asf)
        elif suffix in (".npy", ".npz"):
            check_numpy_file(path, DataError)
            clip = load_joint_positions(path, options)
        elif suffix == ".pt":
            clip = load_torch_clip(path, options)
        else:
            raise DataError(f"{path}: unknown mocap suffix {path.suffix!r}; use one of {', '.join(SUFFIXES)}")
    except DataError:
        raise
    except (ValueError, KeyError, IndexError, OSError, UnicodeDecodeError, zlib.error) as exc:
        raise DataError(f"{path}: cannot read it ({type(exc).__name__}: {str(exc)[:200]})") from exc
    if options.fps:
        clip.fps = float(options.fps)
    scale = unit_scale(options.units)
    if scale is not None:
        clip.positions = clip.positions * scale
        clip.scale_known = True
    elif not clip.scale_known:
        clip.positions = clip.positions * auto_scale(clip)
    return clip


def check_numpy_file(path: Path, error: type[DataError]) -> None:
    """A `.npy` or `.npz` within the recording limits, judged from its headers before numpy reads it."""
    if path.suffix.lower() == ".npy":
        limits.check_npy_file(path, error)
    else:
        limits.check_archive(path, limits.MAX_RECORDING_BYTES, "recording", error)


def auto_scale(clip: MocapClip) -> float:
    """Metres per unit among `UNITS` that makes the skeleton's extent closest to a person's height."""
    extent = _extent(clip.positions)
    if not np.isfinite(extent) or extent <= 0:
        raise DataError(f"{clip.source}: cannot guess the units of a skeleton without extent; give --units")
    scales = np.array(list(UNITS.values()))
    return float(scales[np.argmin(np.abs(np.log(extent * scales / TYPICAL_HEIGHT_M)))])


def _extent(positions: np.ndarray) -> float:
    """Median over frames of the largest bounding-box side of the skeleton."""
    p = positions[:: max(1, positions.shape[0] // 50)]
    with np.errstate(invalid="ignore"), _quiet_nan():
        side = np.nanmax(p, axis=1) - np.nanmin(p, axis=1)
        return float(np.nanmedian(np.nanmax(side, axis=1)))


@contextmanager
def _quiet_nan() -> Iterator[None]:
    """Silence numpy's all-NaN slice warnings: untracked joints are expected, NaN is the answer."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        yield


def is_mocap_file(path: str | Path) -> bool:
    """True for files `load_clip` reads rather than our own skeleton format. An `.npz` is ours when
    it has a `convention` or `timestamps` field or names all 15 skeleton joints (already camera frame)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        try:
            check_numpy_file(path, DataError)
            with np.load(path, allow_pickle=False) as npz:
                if "convention" in npz.files or "timestamps" in npz.files:
                    return False
                names = npz["joint_names"] if "joint_names" in npz.files else np.array([])
                if names.size > limits.MAX_JOINTS:
                    return False
                return not set(SKELETON_JOINTS) <= {str(n) for n in np.atleast_1d(names)}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error, NotImplementedError, RuntimeError):
            return False  # unreadable or over the limits: the skeleton reader says why
    return suffix in SUFFIXES or suffix == ".asf"


def load_any_skeleton(path: str | Path, options: ImportOptions | None = None) -> SkeletonSequence:
    """A skeleton sequence from our .npz/.csv files or any mocap file (mapped, camera frame, 30 fps)."""
    if is_mocap_file(path):
        options = options or ImportOptions()
        return clip_to_skeleton(load_clip(path, options), options)
    return load_skeleton(path)


# --- onto the skeleton stream ------------------------------------------------------------------

def clip_to_skeleton(clip: MocapClip, options: ImportOptions | None = None,
                     fps: float = SKELETON_FPS) -> SkeletonSequence:
    """Map `clip` onto the 15 skeleton joints, into the camera frame, resampled to `fps`."""
    options = options or ImportOptions()
    joint_map = resolve_map(clip.joint_names, options.joint_map, source=clip.source)
    mapped = map_joints(clip.positions, clip.joint_names, joint_map, source=clip.source)
    up = options.up if options.up != "auto" else clip.up
    limits.check_resampled(clip.source, clip.duration_s, fps, DataError)
    camera = to_camera_frame(mapped, up, source=clip.source)
    t = np.arange(camera.shape[0]) / clip.fps
    positions, stamps = resample(camera, t, fps)
    seq = SkeletonSequence(positions=positions, timestamps=stamps, joint_names=SKELETON_JOINTS,
                           pattern=Path(clip.source).stem, metadata={**clip.metadata, "source": clip.source,
                                                                      "joint_map": joint_map.name})
    check_positions(clip.source, seq.positions)
    return seq


def _joint(positions: np.ndarray, name: str) -> np.ndarray:
    return positions[:, SKELETON_JOINTS.index(name)]


def detect_up(positions: np.ndarray, source: str = "clip") -> str:
    """The axis (with sign) along which the shoulders sit above the hips over the first 5 % of the
    clip (recordings start upright far more often than they stay upright: a crawl would fool a
    whole-clip mean)."""
    pelvis = 0.5 * (_joint(positions, "left_hip") + _joint(positions, "right_hip"))
    chest = 0.5 * (_joint(positions, "left_shoulder") + _joint(positions, "right_shoulder"))
    trunk = chest - pelvis
    tracked = np.flatnonzero(np.all(np.isfinite(trunk), axis=1))
    first = tracked[: max(1, len(tracked) // 20)]
    with _quiet_nan():
        v = np.nanmedian(trunk[first], axis=0) if first.size else np.full(3, np.nan)
    if not np.all(np.isfinite(v)) or np.linalg.norm(v) < 1e-6:
        raise DataError(f"{source}: cannot find the up axis (hips and shoulders never tracked); give --up")
    axis = int(np.argmax(np.abs(v)))
    return ("-" if v[axis] < 0 else "") + "xyz"[axis]


def up_rotation(up: str) -> np.ndarray:
    """A proper rotation (det +1) taking the `up` axis of a right-handed frame to +y."""
    sign = -1.0 if up.startswith("-") else 1.0
    axis = "xyz".index(up[-1])
    e = np.zeros(3)
    e[axis] = sign
    target = np.array([0.0, 1.0, 0.0])
    if np.allclose(e, target):
        return np.eye(3)
    if np.allclose(e, -target):
        return np.diag([1.0, -1.0, -1.0])  # half turn about x
    k = np.cross(e, target)  # rotation axis, |k| = 1 for orthogonal unit vectors
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + kx + kx @ kx  # Rodrigues with sin = 1, cos = 0


def to_camera_frame(positions: np.ndarray, up: str = "auto", source: str = "clip") -> np.ndarray:
    """World positions (T, 15, 3) -> camera frame: up -> y, person's right -> x at the first
    tracked frame (so they face the sensor), pelvis 2 m in front of it. Rotations only: a
    right-handed recording stays right-handed."""
    up = detect_up(positions, source) if up == "auto" else up
    p = positions @ up_rotation(up).T
    right = _joint(p, "right_shoulder") - _joint(p, "left_shoulder")
    ok = np.flatnonzero(np.all(np.isfinite(right), axis=1) & (np.hypot(right[:, 0], right[:, 2]) > 1e-3))
    if not ok.size:
        raise DataError(f"{source}: the shoulders are never tracked, cannot orient the person")
    r = right[ok[0]]
    yaw = np.arctan2(r[2], r[0])  # rotate about y by +yaw: r -> +x
    c, s = np.cos(yaw), np.sin(yaw)
    rot_y = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    p = p @ rot_y.T
    pelvis = 0.5 * (_joint(p, "left_hip") + _joint(p, "right_hip"))[ok[0]]
    if not np.all(np.isfinite(pelvis)):
        pelvis = _joint(p, "torso")[ok[0]]
    shift = np.array([-pelvis[0], 0.0, CAMERA_DISTANCE_M - pelvis[2]]) if np.all(np.isfinite(pelvis)) else 0.0
    return p + shift


def _box_filter(flat: np.ndarray, width: int) -> np.ndarray:
    """Centred moving average of each column (edges padded with the end values) by running sums, so
    its cost does not grow with `width`; a window holding a NaN is NaN, as with a convolution."""
    pad = np.pad(flat, ((width // 2, width - 1 - width // 2), (0, 0)), mode="edge")
    nan = np.isnan(pad)
    sums = np.zeros((pad.shape[0] + 1, pad.shape[1]))
    np.cumsum(np.where(nan, 0.0, pad), axis=0, out=sums[1:])
    counts = np.concatenate([np.zeros((1, pad.shape[1]), int), np.cumsum(nan, axis=0)])
    out = (sums[width:] - sums[:-width]) / width
    out[counts[width:] - counts[:-width] > 0] = np.nan
    return out


def resample(positions: np.ndarray, t: np.ndarray, fps: float = SKELETON_FPS) -> tuple[np.ndarray, np.ndarray]:
    """Positions (T, ...) at stamps t -> the same motion at `fps` (linear; box filter first when
    downsampling, so a 120 fps clip is not aliased). A NaN next to a new frame makes it NaN."""
    positions = np.asarray(positions, dtype=np.float64)
    if positions.shape[0] < 2:
        return positions.copy(), np.asarray(t, dtype=np.float64)[:1] * 0.0
    src_fps = 1.0 / float(np.median(np.diff(t)))
    flat = positions.reshape(positions.shape[0], -1)
    ratio = src_fps / fps
    if ratio > 1.5:
        # odd: a centred window does not delay the motion; never wider than the clip
        width = 2 * int(min(ratio, flat.shape[0]) // 2) + 1
        flat = _box_filter(flat, width)
    new_t = np.arange(0.0, t[-1] - t[0] + 1e-3 / fps, 1.0 / fps)  # tolerance: frame times in files are rounded
    pos = new_t * src_fps
    lo = np.clip(np.floor(pos).astype(int), 0, flat.shape[0] - 1)
    hi = np.clip(lo + 1, 0, flat.shape[0] - 1)
    w = (pos - lo)[:, None]
    out = (1 - w) * flat[lo] + w * flat[hi]
    out[np.isnan(flat[lo]) | (np.isnan(flat[hi]) & (w > 1e-9))] = np.nan
    return out.reshape(len(new_t), *positions.shape[1:]), new_t
