"""Synthetic arm demonstrations for the bench and the soak run, without the demonstrator.

Ten smooth periodic patterns of the 8 Nao arm angles (lateral/front raises, waves, circles, one or
both arms) around a neutral pose, done by simulated people who differ in amplitude, tempo and
posture, plus per-frame tracker noise; cheap to make in any length, so speed figures do not depend
on the skeleton -> angles pipeline.
"""

from __future__ import annotations

import math

import numpy as np

from gwr_predictor.robot.nao import ARM_JOINTS, clip_to_limits

# Neutral pose (arms hanging, elbows slightly bent) in ARM_JOINTS order.
_NEUTRAL = np.array([1.4, 0.15, -1.2, -0.4, 1.4, -0.15, 1.2, 0.4])
_MIRROR = np.array([1.0, -1.0, -1.0, -1.0])  # left -> right sign of pitch, roll, yaw, elbow roll


def _arm(pitch: np.ndarray, roll: np.ndarray, yaw: np.ndarray, elbow: np.ndarray) -> np.ndarray:
    """Left-arm angles (T, 4) as offsets from the neutral pose."""
    return np.stack([pitch, roll, yaw, elbow], axis=1)


def _pattern(kind: int, phase: np.ndarray) -> np.ndarray:
    """Offsets (T, 8) from the neutral pose of one of 10 arm patterns, phase in [0, 1)."""
    up = 0.5 - 0.5 * np.cos(2 * np.pi * phase)  # 0 -> 1 -> 0
    c, s = np.cos(2 * np.pi * phase), np.sin(2 * np.pi * phase)
    z = np.zeros_like(phase)
    lateral = _arm(-0.3 * up, 1.1 * up, 0.4 * up, 0.3 * up)
    front = _arm(-1.5 * up, 0.1 * up, 0.6 * up, 0.2 * up)
    wave = _arm(-1.6 * up, 0.3 * up, 1.0 * up, 0.25 * up * (1 - np.cos(6 * np.pi * phase)))
    circle = _arm(-0.9 + 0.5 * c, 0.5 + 0.35 * s, 0.8 + 0.2 * s, 0.2 + 0.1 * c)
    circle_ccw = _arm(-0.9 + 0.5 * c, 0.5 - 0.35 * s, 0.8 - 0.2 * s, 0.2 + 0.1 * c)
    rest = _arm(z, z, z, z)
    left, right = {
        0: (lateral, lateral), 1: (lateral, rest), 2: (front, front), 3: (rest, front),
        4: (wave, wave), 5: (rest, wave), 6: (circle, circle), 7: (circle_ccw, circle_ccw),
        8: (circle, rest), 9: (rest, circle_ccw),
    }[kind]
    return np.concatenate([left, right * _MIRROR], axis=1)


def synthetic_demonstrations(seed: int = 0, patterns: int = 10, subjects: int = 3,
                             repeats: int = 10) -> list[tuple[int, np.ndarray]]:
    """(pattern, frames (T, 8) radians at 10 fps) for every demonstration: each pattern done
    `repeats` times by each of `subjects` people who differ in amplitude, tempo and posture,
    plus per-frame tracker noise."""
    rng = np.random.default_rng(seed)
    demos = []
    for kind in range(patterns):
        for _ in range(subjects):
            gain, tempo, posture = rng.uniform(0.85, 1.15), rng.uniform(0.8, 1.25), rng.normal(0, 0.05, 8)
            for _ in range(repeats):
                frames = max(8, round(30 / tempo * rng.uniform(0.9, 1.1)))
                phase = np.arange(frames) / frames
                warp = phase + 0.03 * np.sin(2 * np.pi * phase) * rng.normal()
                angles = _NEUTRAL + posture + gain * _pattern(kind, warp) + rng.normal(0, 0.02, (frames, 8))
                demos.append((kind, clip_to_limits(angles, ARM_JOINTS)))
    return demos


def synthetic_arm_stream(n_frames: int, seed: int = 0) -> np.ndarray:
    """(n_frames, 8) radians: the demonstrations of all patterns, concatenated and repeated."""
    demos = np.concatenate([d for _, d in synthetic_demonstrations(seed)])
    reps = math.ceil(n_frames / len(demos))
    return np.tile(demos, (reps, 1))[:n_frames]
