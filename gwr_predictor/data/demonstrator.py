"""Synthetic demonstrator: OpenNI-style 15-joint skeletons of people doing the paper's 10 arm patterns.

The paper's recordings (3 people x 10 patterns x 10 repetitions, Asus Xtion at 30 fps) are not
public, so this module makes look-alikes. Each arm is a human arm model (shoulder ball joint +
elbow hinge, constant limb lengths) driven by smooth joint trajectories: minimum-jerk moves between
key poses plus enveloped oscillations for waving and circling. Subjects differ in body size,
speed, amplitude and style; repetitions vary in timing, amplitude, pose and phase; the tracker adds
white noise, slow jitter and occasional glitches of several centimetres.

Arm angles here are anatomical, for either arm (the right arm is the mirror image of the left):
plane of elevation (0 = frontal plane, pi/2 = straight ahead), elevation (0 = hanging), external
rotation of the upper arm, and elbow flexion (0 = straight). Body frame: x forward, y left, z up,
origin on the floor between the feet. Output positions are in the camera frame of
`skeleton_io.CAMERA_CONVENTION`: x towards the person's right (sensor's left), y up, z from the
sensor into the scene; the sensor is `CAMERA_HEIGHT` above the floor and the person faces it.
"One"-arm patterns move the right arm while the left hangs with small idle motion. "cw"/"ccw" is
the hand's sense of rotation as seen by the demonstrator looking ahead.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

from gwr_predictor.data.errors import DataError
from gwr_predictor.data.skeleton_files import CAMERA_CONVENTION, SkeletonSequence
from gwr_predictor.joints.skeleton import SKELETON_FPS, SKELETON_JOINTS
from gwr_predictor.robot.nao import rot_x, rot_y, rot_z

__all__ = ["CAMERA_HEIGHT", "HUMAN_RANGES", "PATTERNS", "ArmAngles", "DataError", "SkeletonSequence",
           "SubjectProfile", "Variation", "arm_points", "arm_trajectories", "default_subjects", "demonstrate",
           "demonstrate_one", "duration", "min_jerk"]

PATTERNS: tuple[str, ...] = (
    "raise_lateral_one", "raise_lateral_both", "raise_front_one", "raise_front_both",
    "wave_one", "wave_both", "rotate_cw_one", "rotate_cw_both", "rotate_ccw_one", "rotate_ccw_both",
)

#: Height of the depth sensor above the floor (m); it looks horizontally at the person.
CAMERA_HEIGHT = 1.0

#: Anatomical ranges (rad) every generated trajectory stays within (plane, elevation, rotation, flexion).
HUMAN_RANGES: dict[str, tuple[float, float]] = {
    "plane": (-0.6, 2.4), "elevation": (0.0, 3.0), "rotation": (-1.5, 1.6), "flexion": (0.0, 2.5),
}


class ArmAngles(NamedTuple):
    """Anatomical angle trajectories (T,) of one arm, radians (see the module docstring)."""

    plane: np.ndarray
    elevation: np.ndarray
    rotation: np.ndarray
    flexion: np.ndarray


# --- subjects ----------------------------------------------------------------------------------

_PROFILE_RANGES: dict[str, tuple[float, float, str]] = {
    "height": (1.3, 2.2, "m"), "shoulder_width": (0.25, 0.55, "m"), "upper_arm": (0.2, 0.42, "m"),
    "forearm": (0.18, 0.4, "m"), "speed": (0.5, 2.0, "x"), "amplitude": (0.6, 1.3, "x"),
    "plane_offset": (0.0, 0.8, "rad"), "elbow_bend": (0.05, 0.8, "rad"), "wave_hz": (0.5, 2.5, "Hz"),
    "circle_hz": (0.2, 1.2, "Hz"), "variability": (0.0, 3.0, "x"), "distance": (0.8, 3.5, "m"),
    "body_yaw": (-0.5, 0.5, "rad"), "noise_mm": (0.0, 30.0, "mm"),
}


@dataclass(frozen=True)
class SubjectProfile:
    """One simulated person: body size, tempo, amplitude and style (validated, hashable)."""

    name: str
    height: float = 1.75
    shoulder_width: float = 0.37  # between the two shoulder joints
    upper_arm: float = 0.31  # shoulder joint -> elbow joint
    forearm: float = 0.28  # elbow joint -> hand joint (palm centre)
    speed: float = 1.0  # tempo multiplier of every movement
    amplitude: float = 1.0  # extent multiplier of every movement
    plane_offset: float = 0.3  # lateral raises happen this far in front of the frontal plane
    elbow_bend: float = 0.3  # habitual elbow flexion in raises
    wave_hz: float = 1.2
    circle_hz: float = 0.6
    variability: float = 1.0  # scales repetition-to-repetition variation
    distance: float = 2.2  # from the sensor; the paper's sensor worked at 0.8-3.5 m
    body_yaw: float = 0.0  # how far the person turns away from facing the sensor
    noise_mm: float = 6.0  # tracker white-noise standard deviation

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name or not self.name.isidentifier():
            raise DataError(f"SubjectProfile.name must be a non-empty identifier, got {self.name!r}")
        for f in fields(self):
            if f.name == "name":
                continue
            lo, hi, unit = _PROFILE_RANGES[f.name]
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
                raise DataError(f"SubjectProfile.{f.name} must be in [{lo:g}, {hi:g}] {unit}, got {value!r}")


_DEFAULT_PROFILES = (  # one female and two male participants, like the paper
    SubjectProfile("s1", height=1.64, shoulder_width=0.33, upper_arm=0.28, forearm=0.26, speed=1.15,
                   amplitude=0.93, plane_offset=0.35, elbow_bend=0.3, wave_hz=1.4, circle_hz=0.7,
                   distance=2.0, body_yaw=0.06, noise_mm=5.0),
    SubjectProfile("s2", height=1.83, shoulder_width=0.40, upper_arm=0.33, forearm=0.30, speed=0.9,
                   amplitude=1.05, plane_offset=0.22, elbow_bend=0.2, wave_hz=1.1, circle_hz=0.55,
                   distance=2.4, body_yaw=-0.08, noise_mm=6.0),
    SubjectProfile("s3", height=1.76, shoulder_width=0.37, upper_arm=0.31, forearm=0.28, speed=1.0,
                   amplitude=0.98, plane_offset=0.5, elbow_bend=0.4, wave_hz=1.25, circle_hz=0.62,
                   distance=2.2, body_yaw=0.0, noise_mm=7.0),
)


def default_subjects(n: int = 3, seed: int = 0) -> list[SubjectProfile]:
    """`n` subjects: the three fixed profiles s1-s3 first, then random ones drawn from `seed`."""
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise DataError(f"number of subjects must be an integer >= 1, got {n!r}")
    out = list(_DEFAULT_PROFILES[:n])
    for i in range(len(out), n):
        r = np.random.default_rng([seed, i])
        height = r.uniform(1.55, 1.95)
        out.append(SubjectProfile(
            f"s{i + 1}", height=height, shoulder_width=0.21 * height * r.uniform(0.92, 1.08),
            upper_arm=0.178 * height * r.uniform(0.95, 1.05), forearm=0.16 * height * r.uniform(0.95, 1.05),
            speed=r.uniform(0.8, 1.3), amplitude=r.uniform(0.85, 1.1), plane_offset=r.uniform(0.15, 0.6),
            elbow_bend=r.uniform(0.15, 0.5), wave_hz=r.uniform(0.9, 1.6), circle_hz=r.uniform(0.45, 0.8),
            distance=r.uniform(1.6, 3.0), body_yaw=r.uniform(-0.12, 0.12), noise_mm=r.uniform(4.0, 9.0)))
    return out


# --- smooth building blocks ---------------------------------------------------------------------

def min_jerk(s: np.ndarray) -> np.ndarray:
    """Minimum-jerk profile 0 -> 1 for s in [0, 1] (clamped outside): zero velocity and acceleration at ends."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))


def _keyframes(times: np.ndarray, poses: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Minimum-jerk interpolation (T, D) through key poses (K, D) at increasing `times` (K,)."""
    k = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2)
    s = (t - times[k]) / (times[k + 1] - times[k])
    return poses[k] + (poses[k + 1] - poses[k]) * min_jerk(s)[:, None]


def _envelope(t: np.ndarray, start: float, end: float, ramp: float) -> np.ndarray:
    """Smooth trapezoid: 0 before `start`, 1 between the ramps, 0 after `end`."""
    return min_jerk((t - start) / ramp) * min_jerk((end - t) / ramp)


# --- patterns ----------------------------------------------------------------------------------

_REST = np.array([0.3, 0.12, -0.2, 0.2])  # plane, elevation, rotation, flexion of a hanging arm
_CIRCLE_ELEVATION = 1.15  # hand circles are centred at about chest height


@dataclass(frozen=True)
class Variation:
    """Per-repetition draws shared by both arms (so a 'both' pattern stays coordinated)."""

    durations: np.ndarray  # rest0, move-in, main, move-out, rest1 (s)
    amplitude: float
    pose_offset: np.ndarray  # (4,)
    phase: float
    freq: float  # multiplier
    left_lag: float  # s the left arm trails the right in 'both' patterns (people are not symmetric)
    left_gain: float  # amplitude of the left arm relative to the right


def _draw_variation(pattern: str, subject: SubjectProfile, rng: np.random.Generator) -> Variation:
    v = subject.variability
    tempo = 1.0 / subject.speed
    if pattern.startswith("raise"):
        main = 0.5  # hold at the top
        move = 1.3 * tempo
    elif pattern.startswith("wave"):
        main = 3.5 / subject.wave_hz  # three and a half waves
        move = 0.9 * tempo
    else:
        main = 2.0 / subject.circle_hz  # two circles
        move = 0.9 * tempo
    base = np.array([rng.uniform(0.4, 0.8), move, main, move, rng.uniform(0.4, 0.8)])
    return Variation(durations=base * np.exp(rng.normal(0.0, 0.08 * v, 5)),
                     amplitude=float(np.clip(1.0 + rng.normal(0.0, 0.05 * v), 0.8, 1.2)),
                     pose_offset=rng.normal(0.0, 0.04 * v, 4), phase=float(rng.uniform(-0.4, 0.4) * v),
                     freq=float(np.exp(rng.normal(0.0, 0.06 * v))), left_lag=float(rng.normal(0.0, 0.04 * v)),
                     left_gain=float(np.clip(1.0 + rng.normal(0.0, 0.03 * v), 0.9, 1.1)))


def _main_pose(pattern: str, subject: SubjectProfile, amp: float) -> np.ndarray:
    """The pose the active arm moves to (and oscillates around)."""
    a = subject.amplitude * amp
    if pattern.startswith("raise_lateral"):
        return np.array([subject.plane_offset, 1.42 * a, -0.2, subject.elbow_bend])
    if pattern.startswith("raise_front"):
        return np.array([1.42, 1.45 * a, 0.0, subject.elbow_bend])
    if pattern.startswith("wave"):
        return np.array([0.5, 1.4 * min(a, 1.1), 0.75, 1.2])  # forearm about vertical
    return np.array([1.3, _CIRCLE_ELEVATION, 0.0, 0.45 + 0.5 * subject.elbow_bend])


def _oscillation(pattern: str, subject: SubjectProfile, var: Variation, amp: float, sense: float,
                 t: np.ndarray, start: float, end: float) -> np.ndarray:
    """Enveloped waving / circling offsets (T, 4) added to the main pose; zero for raises."""
    out = np.zeros((t.size, 4))
    if pattern.startswith("raise"):
        return out
    env = _envelope(t, start, end, ramp=0.3)
    a = subject.amplitude * amp
    if pattern.startswith("wave"):
        ph = 2 * np.pi * subject.wave_hz * var.freq * (t - start) + var.phase
        out[:, 3] = 0.3 * a * np.sin(ph)  # forearm swings side to side
        out[:, 2] = 0.08 * a * np.cos(ph)  # with a little upper-arm rotation
    else:
        ph = 2 * np.pi * subject.circle_hz * var.freq * (t - start) + var.phase
        radius = 0.32 * a
        out[:, 1] = radius * np.cos(ph)  # hand high at phase 0 ...
        out[:, 0] = sense * radius * np.sin(ph) / math.sin(_CIRCLE_ELEVATION)  # ... then right for cw
        out[:, 3] = 0.1 * a * np.sin(ph)
    return out * env[:, None]


def _active_arm(pattern: str, subject: SubjectProfile, var: Variation, t: np.ndarray, gain: float,
                sense: float) -> np.ndarray:
    d = np.cumsum(var.durations)
    amp = var.amplitude * gain
    main = _main_pose(pattern, subject, amp) + var.pose_offset
    rest = _REST + 0.3 * var.pose_offset
    times = np.array([0.0, d[0], d[1], d[2], d[3], d[4] + 1.0])
    poses = np.stack([rest, rest, main, main, rest, rest])
    path = _keyframes(times, poses, t)
    # Waving / circling fades in and out while the arm is half-way up, not at rest.
    start, end = d[0] + 0.5 * var.durations[1], d[2] + 0.5 * var.durations[3]
    return path + _oscillation(pattern, subject, var, amp, sense, t, start, end)


def _idle_arm(t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A hanging arm that sways a little, as a relaxed person's does."""
    f = rng.uniform(0.15, 0.35, 4)
    ph = rng.uniform(0.0, 2 * np.pi, 4)
    amp = np.array([0.05, 0.03, 0.05, 0.06])
    return _REST + amp * np.sin(2 * np.pi * f * t[:, None] + ph)


def arm_trajectories(pattern: str, subject: SubjectProfile, t: np.ndarray, rng: np.random.Generator,
                     variation: Variation | None = None) -> tuple[ArmAngles, ArmAngles]:
    """Anatomical (left, right) arm angles at times `t` for one repetition of `pattern`."""
    _check_pattern(pattern)
    var = variation or _draw_variation(pattern, subject, rng)
    # +1 circles the left hand clockwise; the right arm is its mirror image, so it needs -1 for that.
    sense = 1.0 if "_cw_" in pattern else -1.0
    right = _active_arm(pattern, subject, var, t, 1.0, -sense)
    if pattern.endswith("_both"):
        left = _active_arm(pattern, subject, var, t - var.left_lag, var.left_gain, sense)
    else:
        left = _idle_arm(t, rng)
    return ArmAngles(*left.T), ArmAngles(*right.T)


def duration(pattern: str, subject: SubjectProfile, rng: np.random.Generator) -> tuple[float, Variation]:
    """Length (s) of one repetition and the variation that produced it."""
    var = _draw_variation(pattern, subject, rng)
    return float(var.durations.sum()), var


# --- kinematics ----------------------------------------------------------------------------------

def arm_points(shoulder: np.ndarray, angles: ArmAngles, upper_arm: float, forearm: float,
               side: str) -> tuple[np.ndarray, np.ndarray]:
    """Elbow and hand (T, 3) in the body frame from the shoulder (T, 3) and anatomical angles.

    Shoulder orientation Rz(-plane) Rx(elevation) Rz(plane + rotation): the upper arm hangs along
    -z at rest and the elbow bends the forearm forwards; the right arm mirrors y.
    """
    q = rot_z(-angles.plane) @ rot_x(angles.elevation) @ rot_z(angles.plane + angles.rotation)
    beta = angles.flexion
    upper_local = np.array([0.0, 0.0, -1.0])
    fore_local = np.stack([np.sin(beta), np.zeros_like(beta), -np.cos(beta)], axis=-1)
    u = q @ upper_local
    f = np.einsum("tij,tj->ti", q, fore_local)
    if side == "R":
        u = u * np.array([1.0, -1.0, 1.0])
        f = f * np.array([1.0, -1.0, 1.0])
    elbow = shoulder + upper_arm * u
    return elbow, elbow + forearm * f


def _body_points(subject: SubjectProfile, n: int) -> np.ndarray:
    """Static body joints (n, 15, 3) in the body frame; the arms are filled in later."""
    h, w = subject.height, subject.shoulder_width / 2
    hip, knee, foot = 0.065 * h, 0.06 * h, 0.065 * h
    table = {
        "head": (0.02, 0.0, 0.925 * h), "neck": (0.0, 0.0, 0.82 * h), "torso": (0.0, 0.0, 0.675 * h),
        "left_shoulder": (0.0, w, 0.815 * h), "right_shoulder": (0.0, -w, 0.815 * h),
        "left_hip": (0.0, hip, 0.53 * h), "right_hip": (0.0, -hip, 0.53 * h),
        "left_knee": (0.01, knee, 0.285 * h), "right_knee": (0.01, -knee, 0.285 * h),
        "left_foot": (0.03, foot, 0.04 * h), "right_foot": (0.03, -foot, 0.04 * h),
    }
    base = np.array([table.get(j, (0.0, 0.0, 0.0)) for j in SKELETON_JOINTS])
    return np.broadcast_to(base, (n, len(SKELETON_JOINTS), 3)).copy()


def _shrug(elevation: np.ndarray) -> np.ndarray:
    """Shoulder girdle lift (m) when the arm rises above about 70 degrees."""
    return 0.025 * min_jerk((elevation - 1.2) / 1.2)


def _sway(t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Slow whole-body lean and turn (T, 3, 3) about the feet: a standing person is never still."""
    f = rng.uniform(0.1, 0.3, 3)
    ph = rng.uniform(0.0, 2 * np.pi, 3)
    a = np.array([0.008, 0.008, 0.02]) * np.sin(2 * np.pi * f * t[:, None] + ph)
    return rot_z(a[:, 2]) @ rot_y(a[:, 1]) @ rot_x(a[:, 0])


_BODY_TO_CAMERA = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])


def _to_camera(points: np.ndarray, subject: SubjectProfile, lateral: float) -> np.ndarray:
    """Body frame -> camera frame: person facing the sensor `distance` away, turned by `body_yaw`."""
    rot = rot_y(np.asarray(subject.body_yaw)) @ _BODY_TO_CAMERA
    offset = np.array([lateral, -CAMERA_HEIGHT, subject.distance])
    return points @ rot.T + offset


def _tracker_noise(shape: tuple[int, ...], subject: SubjectProfile, rng: np.random.Generator) -> np.ndarray:
    """White noise + slow jitter + rare glitches (m): depth (z) and the distal arm joints are noisier."""
    n, j, _ = shape
    sigma = subject.noise_mm / 1000.0
    scale = np.ones((j, 3)) * np.array([1.0, 1.0, 1.5])
    distal = [SKELETON_JOINTS.index(k) for k in ("left_elbow", "left_hand", "right_elbow", "right_hand")]
    scale[distal] *= 1.3
    white = rng.normal(0.0, sigma, shape)
    k = 9  # slow jitter: box-filtered noise, about 0.3 s correlation at 30 fps
    raw = rng.normal(0.0, 0.5 * sigma * math.sqrt(k), (n + k, j, 3))
    c = np.cumsum(raw, axis=0)
    slow = (c[k:] - c[:-k]) / k
    glitch_at = rng.random((n, j)) < 0.003
    jump = rng.normal(0.0, 0.04, shape) * glitch_at[..., None]
    lasting = np.roll(jump, 1, axis=0) * (rng.random((n, j, 1)) < 0.5)
    lasting[0] = 0.0
    return (white + slow) * scale + jump + lasting


# --- public generators ---------------------------------------------------------------------------

def _check_pattern(pattern: str) -> None:
    if pattern not in PATTERNS:
        raise DataError(f"unknown pattern {pattern!r}; choose from {', '.join(PATTERNS)}")


def demonstrate_one(pattern: str, subject: SubjectProfile, repetition: int, seed: int = 0,
                    fps: float = SKELETON_FPS, noise: bool = True) -> SkeletonSequence:
    """One repetition (a few seconds, rest poses at both ends) as a camera-frame skeleton sequence.

    Deterministic in (pattern, subject, repetition, seed); `noise=False` gives the clean motion.
    """
    _check_pattern(pattern)
    if not isinstance(subject, SubjectProfile):
        raise DataError(f"subject must be a SubjectProfile, got {type(subject).__name__}")
    if not (isinstance(fps, (int, float)) and 1.0 <= fps <= 1000.0):
        raise DataError(f"fps must be in [1, 1000], got {fps!r}")
    key = [seed, PATTERNS.index(pattern), int.from_bytes(subject.name.encode()[:8], "little"), repetition]
    rng = np.random.default_rng(key)
    total, var = duration(pattern, subject, rng)
    t = np.arange(math.ceil(total * fps)) / fps
    left, right = arm_trajectories(pattern, subject, t, rng, var)

    pts = _body_points(subject, t.size)
    idx = {j: SKELETON_JOINTS.index(j) for j in SKELETON_JOINTS}
    for side, angles in (("L", left), ("R", right)):
        prefix = "left" if side == "L" else "right"
        pts[:, idx[f"{prefix}_shoulder"], 2] += _shrug(angles.elevation)
        elbow, hand = arm_points(pts[:, idx[f"{prefix}_shoulder"]], angles, subject.upper_arm,
                                 subject.forearm, side)
        pts[:, idx[f"{prefix}_elbow"]] = elbow
        pts[:, idx[f"{prefix}_hand"]] = hand
    pts = np.einsum("tij,tkj->tki", _sway(t, rng), pts)
    cam = _to_camera(pts, subject, lateral=float(rng.normal(0.0, 0.1)))
    if noise:
        cam = cam + _tracker_noise(cam.shape, subject, rng)
    return SkeletonSequence(positions=cam, timestamps=t, joint_names=SKELETON_JOINTS, pattern=pattern,
                            subject=subject.name, repetition=repetition, convention=CAMERA_CONVENTION)


def demonstrate(patterns: Sequence[str] | None = None, subjects: int | Sequence[SubjectProfile] | None = None,
                repetitions: int = 10, seed: int = 0, fps: float = SKELETON_FPS,
                noise: bool = True) -> list[SkeletonSequence]:
    """Every (pattern, subject, repetition) in that nesting order; repetitions are numbered from 1."""
    patterns = PATTERNS if patterns is None else tuple(patterns)
    for p in patterns:
        _check_pattern(p)
    if subjects is None or isinstance(subjects, int):
        subjects = default_subjects(3 if subjects is None else subjects, seed=seed)
    if isinstance(repetitions, bool) or not isinstance(repetitions, int) or repetitions < 1:
        raise DataError(f"repetitions must be an integer >= 1, got {repetitions!r}")
    return [demonstrate_one(p, s, r, seed=seed, fps=fps, noise=noise)
            for p in patterns for s in subjects for r in range(1, repetitions + 1)]
