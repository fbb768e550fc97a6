"""Streams where one real movement comes again and again, never twice alike: the repetition benchmark.

A segment (one movement, 1.5-4 s) is cut from a real recording's 30 fps skeleton and performed
`repetitions` times in one stream. Each performance is preceded by a pause in the movement's start pose
and followed by a smooth way back to it; it gets its own smooth monotone time warp (a speed that
changes slowly from one rate to another, both in 0.8-1.25x) and its own size (0.9-1.1x the angular
excursion from the start pose); tracker noise (1 cm per coordinate) is added to every skeleton frame.

Warp and noise act on the 30 fps skeleton, before the pipeline's own median of 3 and angle mapping:
interpolating at three times the learner's rate keeps the warp's resampling error small, the 10 fps
frames land on different instants of the motion in every performance (as with a real tracker), and
the noise reaches the angles the way a tracker's does (large where the arm is near a singular pose).
The size acts on the 10 fps angles, because scaling a skeleton changes no angle: what differs between
people doing one movement is how far each joint turns, a' = a0 + s (a - a0) about the start pose a0.
The tracker noise's effect on the angles (noisy minus clean extraction) is added after that scaling,
so the noise is not scaled with the motion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gwr_predictor.data.demonstrator import default_subjects, demonstrate_one
from gwr_predictor.data.extraction import extract_angles
from gwr_predictor.data.mocap import load_any_skeleton
from gwr_predictor.data.real_motion import fetch_clips
from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS
from gwr_predictor.robot.nao import clip_to_limits

#: phase labels of each frame
PAUSE, PERFORM, RETURN = 0, 1, 2
SKELETON_FPS = 30.0


class RepetitionError(GwrPredictorError, ValueError):
    """A segment or setting the stream builder cannot use; the message says which."""


@dataclass(frozen=True)
class Segment:
    """One movement inside a catalogue clip (`gwr_predictor.data.real_motion`), seconds from its start."""

    clip: str
    start_s: float
    end_s: float
    what: str = ""

    @property
    def name(self) -> str:
        return f"{self.clip}@{self.start_s:g}-{self.end_s:g}s"


@dataclass(frozen=True)
class StreamSettings:
    """How the performances of one stream vary (ranges are drawn uniformly; rates log-uniformly)."""

    repetitions: int = 8
    rate: tuple[float, float] = (0.8, 1.25)  # speed of the performance against the recording
    size: tuple[float, float] = (0.9, 1.1)  # angular excursion from the start pose
    pause_s: tuple[float, float] = (0.3, 1.5)  # start pose held before each performance
    noise_m: float = 0.01  # tracker noise, standard deviation per coordinate
    return_speed: float = 0.5  # m/s of the joint that moves most on the way back to the start pose
    min_return_s: float = 0.3
    fps: float = SKELETON_FPS

    def __post_init__(self) -> None:
        for name in ("rate", "size", "pause_s"):
            lo, hi = getattr(self, name)
            if not 0 < lo <= hi:
                raise RepetitionError(f"StreamSettings.{name} must be 0 < low <= high, got {(lo, hi)}")
        if self.repetitions < 1 or self.noise_m < 0 or self.return_speed <= 0 or self.fps <= 0:
            raise RepetitionError(f"StreamSettings out of range: {self}")


@dataclass(frozen=True)
class RepetitionStream:
    """A stream at 10 fps: angles (T, 8) clipped into the Nao limits and, per frame, the performance
    it belongs to (0-based: the pause before it, the performance, its way back) and its phase."""

    name: str
    angles: np.ndarray
    raw: np.ndarray  # unclipped
    repetition: np.ndarray  # (T,) int
    phase: np.ndarray  # (T,) PAUSE / PERFORM / RETURN
    rates: np.ndarray  # (reps, 2): speed at the start and at the end of each performance
    sizes: np.ndarray  # (reps,)
    pauses_s: np.ndarray  # (reps,)
    warps: tuple[np.ndarray, ...]  # per performance: recording time (s) of each 30 fps frame

    @property
    def seconds(self) -> float:
        return len(self.angles) / 10.0


def time_warp(duration_s: float, rates: tuple[float, float], fps: float) -> np.ndarray:
    """Recording time at each output frame of one performance: the speed goes smoothly (half a cosine)
    from rates[0] to rates[1] along the movement; strictly increasing from 0, ending at `duration_s`."""
    lo, hi = rates
    u, out = 0.0, [0.0]
    while u < duration_s:
        p = u / duration_s
        u += (lo + (hi - lo) * 0.5 * (1.0 - np.cos(np.pi * p))) / fps
        out.append(min(u, duration_s))
    return np.asarray(out)


def resample_at(positions: np.ndarray, fps: float, times: np.ndarray) -> np.ndarray:
    """Positions (N, J, 3) sampled at `fps` -> linearly interpolated at `times` (s)."""
    src = np.arange(positions.shape[0]) / fps
    flat = positions.reshape(positions.shape[0], -1)
    out = np.stack([np.interp(times, src, flat[:, c]) for c in range(flat.shape[1])], axis=1)
    return out.reshape(len(times), *positions.shape[1:])


def way_back(end: np.ndarray, start: np.ndarray, settings: StreamSettings, centre: int = 0) -> np.ndarray:
    """A minimum-jerk blend of every joint from `end` to `start` (frames in between, both excluded), as
    long as the joint that moves most relative to joint `centre` needs at `settings.return_speed` (a body
    that walked or climbed away comes back at no cost: its translation changes no arm angle)."""
    dist = float(np.max(np.linalg.norm((end - end[centre]) - (start - start[centre]), axis=-1)))
    n = max(1, round(max(settings.min_return_s, dist / settings.return_speed) * settings.fps))
    s = np.arange(1, n + 1) / (n + 1)
    w = (10 * s**3 - 15 * s**4 + 6 * s**5)[:, None, None]
    return end[None] + w * (start - end)[None]


def _log_uniform(rng: np.random.Generator, lo: float, hi: float, size: int | None = None) -> np.ndarray:
    return np.exp(rng.uniform(np.log(lo), np.log(hi), size))


def build_stream(segment: np.ndarray, rng: np.random.Generator, settings: StreamSettings | None = None,
                 name: str = "stream", joint_names: tuple[str, ...] = SKELETON_JOINTS) -> RepetitionStream:
    """`settings.repetitions` performances of `segment` (a fully tracked (N, J, 3) skeleton at settings.fps)."""
    st = settings or StreamSettings()
    seg = np.asarray(segment, dtype=float)
    if seg.ndim != 3 or seg.shape[0] < 3 or not np.isfinite(seg).all():
        raise RepetitionError(f"{name}: a segment must be a fully tracked (N >= 3, J, 3) skeleton, got "
                              f"shape {seg.shape}{'' if np.isfinite(seg).all() else ' with untracked frames'}")
    reps = st.repetitions
    centre = list(joint_names).index("torso") if "torso" in joint_names else 0
    rates = _log_uniform(rng, *st.rate, size=(reps, 2))
    sizes = rng.uniform(*st.size, size=reps)
    pauses = rng.uniform(*st.pause_s, size=reps)
    duration = (seg.shape[0] - 1) / st.fps
    parts, rep, phase, warps = [], [], [], []
    for k in range(reps):
        warp = time_warp(duration, (float(rates[k, 0]), float(rates[k, 1])), st.fps)
        moving = resample_at(seg, st.fps, warp)
        back = way_back(moving[-1], seg[0], st, centre)
        pause = np.repeat(seg[:1], max(1, round(pauses[k] * st.fps)), axis=0)
        for block, label in ((pause, PAUSE), (moving, PERFORM), (back, RETURN)):
            parts.append(block)
            rep.append(np.full(len(block), k))
            phase.append(np.full(len(block), label))
        warps.append(warp)
    clean = np.concatenate(parts)
    stamps = np.arange(len(clean)) / st.fps
    noisy = clean + rng.normal(scale=st.noise_m, size=clean.shape) if st.noise_m > 0 else clean
    a_clean = extract_angles(clean, stamps, joint_names).raw
    a_noisy = extract_angles(noisy, stamps, joint_names).raw
    start = extract_angles(np.repeat(seg[:1], 3, axis=0), np.arange(3) / st.fps, joint_names).raw[0]
    middle = np.arange(len(a_clean)) * 3 + 1  # the 30 fps frame at the middle of each median-of-3 group
    rep10, phase10 = np.concatenate(rep)[middle], np.concatenate(phase)[middle]
    noise = np.angle(np.exp(1j * (a_noisy - a_clean)))  # wrapped: a tracker's jitter, not a turn
    raw = start + sizes[rep10][:, None] * (a_clean - start) + noise
    return RepetitionStream(name, clip_to_limits(raw), raw, rep10, phase10, rates, sizes, pauses, tuple(warps))


def cut(positions: np.ndarray, start_s: float, end_s: float, fps: float = SKELETON_FPS,
        name: str = "segment") -> np.ndarray:
    """Frames [start_s, end_s] of a skeleton sampled at `fps` (s from its first frame)."""
    a, b = round(start_s * fps), round(end_s * fps) + 1
    if not 0 <= a < b <= len(positions):
        raise RepetitionError(f"{name}: {start_s:g}-{end_s:g} s is outside the recording "
                              f"({(len(positions) - 1) / fps:.1f} s)")
    return np.asarray(positions[a:b], dtype=float)


def load_segments(segments: tuple[Segment, ...]) -> list[tuple[Segment, np.ndarray]]:
    """Each segment's 30 fps skeleton from the real recordings (fetched into the cache on first use)."""

    clips = {c.name: c for c in fetch_clips(tuple(sorted({s.clip for s in segments})))}
    out = []
    for s in segments:
        seq = load_any_skeleton(clips[s.clip].path, clips[s.clip].options)
        if tuple(seq.joint_names) != SKELETON_JOINTS:
            raise RepetitionError(f"{s.name}: joints {seq.joint_names} are not the skeleton's")
        out.append((s, cut(seq.positions, s.start_s, s.end_s, name=s.name)))
    return out


def synthetic_segments(patterns: tuple[str, ...] = ("wave_one", "raise_front_both")
                       ) -> list[tuple[Segment, np.ndarray]]:
    """Stand-ins made without any download: one clean demonstrator repetition per pattern."""

    subject = default_subjects(1)[0]
    out = []
    for p in patterns:
        seq = demonstrate_one(p, subject, 1, noise=False)
        out.append((Segment(f"synthetic_{p}", 0.0, float(seq.timestamps[-1]), f"demonstrator {p}"),
                    np.asarray(seq.positions, dtype=float)))
    return out


def make_streams(segments: list[tuple[Segment, np.ndarray]], seeds: tuple[int, ...],
                 settings: StreamSettings | None = None, by_cut: bool | None = None) -> list[RepetitionStream]:
    """One stream per (segment, seed), segment-major; each seeded by (seed, segment index). A stream is
    named by its clip, or by its cut (`by_cut`; by default where two segments share a clip)."""
    clips = [s.clip for s, _ in segments]

    def name(s: Segment) -> str:
        return s.name if (clips.count(s.clip) > 1 if by_cut is None else by_cut) else s.clip

    return [build_stream(seg, np.random.default_rng([seed, i]), settings, name=f"{name(s)} s{seed}")
            for i, (s, seg) in enumerate(segments) for seed in seeds]
