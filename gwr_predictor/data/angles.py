"""Skeleton (camera frame) -> the 8 Nao arm angles of `nao.ARM_JOINTS`, vectorised over frames.

Steps: (1) torso frame from the skeleton -- y (left) along right->left shoulder, z (up) from the
pelvis (mid-hips, or the torso joint when a hip is missing) to mid-shoulders made orthogonal to y,
x = y cross z (forward); (2) per arm, upper arm u and forearm f in that frame; (3) invert the
Nao chain Ry(pitch) Rz(roll) Rx(elbow yaw) Rz(elbow roll): pitch from u in the x-z plane, roll
from what is left of u, then f seen from the upper arm gives elbow roll (the bend, negative on the
left) and elbow yaw (the plane of the bend around the upper arm).

Singularities are resolved smoothly and statelessly, so a near-singular pose gives a stable value
instead of noise. In both cases a bias vector (`singular_bias`: half the width long at the
singularity, shrinking smoothly to exactly zero at the width) is added before the atan2, so the
angles are exact outside the two zones:
* pitch is undefined when the upper arm points straight sideways (|roll| = pi/2). The x-z vector
  is biased towards pitch 0 while cos(roll) < `PITCH_SINGULAR_WIDTH`; a lateral raise through the
  horizontal therefore sweeps pitch through 0 (arm beside-and-ahead), which is also how the Nao,
  whose roll stops at 76 deg, gets there. Roll is fitted to the biased pitch, which moves the
  upper-arm direction by at most 0.27 x PITCH_SINGULAR_WIDTH rad (5.3 deg). An arm pointing
  sideways and slightly *behind* the frontal plane still flips pitch near +-pi -- beyond the Nao's
  pitch range anyway.
* elbow yaw is undefined for a straight arm. The bend-plane vector is biased towards the
  hanging-arm yaw (-pi/2 left, +pi/2 right: forearm bending forward) while sin(bend) <
  `YAW_SINGULAR_WIDTH`; a straight arm gets exactly that yaw. The forearm direction moves by
  about bend x (yaw shift), a few degrees for the nearly straight arms the bias acts on.
Arms pointing straight up or down are regular in this chain. Yaw and roll are measured from the
unclipped shoulder, so a straight human arm stays a straight robot arm when the shoulder clips.

The Nao elbow sits 15 mm off the upper-arm axis and the hand 12 mm off the forearm axis; angles
are not corrected for that, so Nao forward kinematics reproduces the skeleton's upper arm and
forearm directions within about 8 and 6 degrees (plus clipping). Frames missing any needed joint
(or with degenerate geometry) become all-NaN rows: rows are either fully finite or fully NaN.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gwr_predictor.data.errors import DataError
from gwr_predictor.joints.skeleton import SKELETON_JOINTS
from gwr_predictor.robot.nao import ARM_JOINTS, clip_to_limits, limits_array

PITCH_SINGULAR_WIDTH = 0.35  # reach of the pitch bias in |(u_x, u_z)| = cos(roll): |roll| > 69.5 deg
YAW_SINGULAR_WIDTH = 0.7  # reach of the elbow-yaw bias in sin(elbow bend): bends < 44 deg
_MIN_LENGTH = 1e-3  # m: shorter segments are degenerate


def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / n, n[..., 0] > _MIN_LENGTH


def torso_frame(positions: np.ndarray, joint_names: Sequence[str] = SKELETON_JOINTS
                ) -> tuple[np.ndarray, np.ndarray]:
    """Rotations (..., 3, 3) camera -> torso (rows: forward, left, up) and a validity mask (...)."""
    pos = np.asarray(positions, dtype=np.float64)
    j = _indices(joint_names, ("left_shoulder", "right_shoulder", "left_hip", "right_hip", "torso"))
    ls, rs, lh, rh, torso = (pos[..., i, :] for i in j)
    hips_ok = np.all(np.isfinite(lh) & np.isfinite(rh), axis=-1, keepdims=True)
    pelvis = np.where(hips_ok, 0.5 * (lh + rh), torso)
    y, ok_y = _unit(ls - rs)
    up = 0.5 * (ls + rs) - pelvis
    z, ok_z = _unit(up - np.sum(up * y, axis=-1, keepdims=True) * y)
    x = np.cross(y, z)
    frame = np.stack([x, y, z], axis=-2)
    valid = ok_y & ok_z & np.all(np.isfinite(frame), axis=(-2, -1))
    return frame, valid


def _indices(joint_names: Sequence[str], wanted: Sequence[str]) -> list[int]:
    names = list(joint_names)
    missing = [w for w in wanted if w not in names]
    if missing:
        raise DataError(f"joint_names lacks {missing}; angle extraction needs {list(wanted)}")
    return [names.index(w) for w in wanted]


def singular_bias(s: np.ndarray, width: float) -> np.ndarray:
    """Bias length: width/2 at s = 0, fading smoothly (C1) to exactly 0 from s = width on."""
    r = np.clip(s / width, 0.0, 1.0)
    return 0.5 * width * (1.0 - r * r) ** 2


def arm_angles(u: np.ndarray, f: np.ndarray, side: str) -> np.ndarray:
    """Unclipped (..., 4) pitch, roll, elbow yaw, elbow roll from unit upper arm u and forearm f (torso frame)."""
    sign = -1.0 if side == "L" else 1.0  # sign of the elbow roll of a bent elbow
    c = np.hypot(u[..., 0], u[..., 2])
    pitch = np.arctan2(-u[..., 2], u[..., 0] + singular_bias(c, PITCH_SINGULAR_WIDTH))
    cp, sp = np.cos(pitch), np.sin(pitch)
    roll = np.arctan2(u[..., 1], cp * u[..., 0] - sp * u[..., 2])
    cr, sr = np.cos(roll), np.sin(roll)
    # Forearm in the elbow frame: Rz(-roll) Ry(-pitch) f.
    fx = cp * f[..., 0] - sp * f[..., 2]
    fz = sp * f[..., 0] + cp * f[..., 2]
    fy = f[..., 1]
    ex, ey = cr * fx + sr * fy, -sr * fx + cr * fy
    bend = np.arccos(np.clip(ex, -1.0, 1.0))
    s = np.hypot(ey, fz)
    yaw = np.arctan2(sign * (fz + singular_bias(s, YAW_SINGULAR_WIDTH)), sign * ey)
    return np.stack([pitch, roll, yaw, sign * bend], axis=-1)


def skeleton_to_angles(positions: np.ndarray, joint_names: Sequence[str] = SKELETON_JOINTS,
                       clip: bool = True) -> np.ndarray:
    """Positions (..., J, 3) in the camera frame -> (..., 8) angles in `ARM_JOINTS` order, radians.

    `clip=True` clips into the Nao joint limits; rows lacking a needed joint are all NaN.
    """
    pos = np.asarray(positions, dtype=np.float64)
    if pos.ndim < 2 or pos.shape[-1] != 3 or pos.shape[-2] != len(joint_names):
        raise DataError(f"positions must be (..., {len(joint_names)}, 3) for {len(joint_names)} "
                        f"joint names, got shape {pos.shape}")
    frame, valid = torso_frame(pos, joint_names)
    out = []
    for side, prefix in (("L", "left"), ("R", "right")):
        s, e, h = (pos[..., i, :] for i in _indices(joint_names, [f"{prefix}_{k}" for k in ("shoulder", "elbow",
                                                                                            "hand")]))
        u, ok_u = _unit(np.einsum("...ij,...j->...i", frame, e - s))
        f, ok_f = _unit(np.einsum("...ij,...j->...i", frame, h - e))
        valid = valid & ok_u & ok_f
        with np.errstate(invalid="ignore"):
            out.append(arm_angles(u, f, side))
    angles = np.concatenate(out, axis=-1)
    valid = valid & np.all(np.isfinite(angles), axis=-1)
    angles[~valid] = np.nan
    return clip_to_limits(angles) if clip else angles


def clip_fractions(raw_angles: np.ndarray, names: Sequence[str] = ARM_JOINTS) -> dict[str, float]:
    """Share of the finite rows of unclipped angles (..., 8) that lie outside each joint's limits."""
    raw = np.asarray(raw_angles, dtype=np.float64).reshape(-1, len(names))
    rows = raw[np.all(np.isfinite(raw), axis=1)]
    if not rows.size:
        return dict.fromkeys(names, 0.0)
    lo, hi = limits_array(tuple(names))
    share = np.mean((rows < lo) | (rows > hi), axis=0)
    return {n: float(v) for n, v in zip(names, share, strict=True)}
