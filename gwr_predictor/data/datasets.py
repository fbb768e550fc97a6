"""The demonstrator's data as the learner sees it: 10 fps Nao angle sequences, memoised.

demonstrator (30 fps skeletons) -> `extraction.extract_angles` (median of 3, 10 fps, angles clipped to
the Nao limits). Experiments ask for the same data many times, so results are cached per argument set;
the cached arrays are read-only, so no caller can change what the next one gets.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from gwr_predictor.data.demonstrator import PATTERNS, SubjectProfile, default_subjects, demonstrate_one
from gwr_predictor.data.errors import DataError
from gwr_predictor.data.extraction import extract_angles


@dataclass(frozen=True)
class AngleSequence:
    """One demonstration: stamps t (T,) in s and angles (T, 8) in `nao.ARM_JOINTS` order, rad."""

    t: np.ndarray
    angles: np.ndarray
    pattern: str
    subject: str
    repetition: int

    @property
    def name(self) -> str:
        return f"{self.pattern}_{self.subject}_r{self.repetition:02d}"

    def __len__(self) -> int:
        return len(self.t)


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


def demo_angle_sequences(patterns: Sequence[str] | str | None = None,
                         subjects: int | Sequence[SubjectProfile] | None = None,
                         repetitions: int = 10, seed: int = 0) -> tuple[AngleSequence, ...]:
    """Angle sequences of every (pattern, subject, repetition), in that nesting order, cached.

    `patterns` is one name, several, or None for all 10; `subjects` a count (default 3) or profiles.
    """
    if isinstance(repetitions, bool) or not isinstance(repetitions, int) or repetitions < 1:
        raise DataError(f"repetitions must be an integer >= 1, got {repetitions!r}")
    pats = PATTERNS if patterns is None else (patterns,) if isinstance(patterns, str) else tuple(patterns)
    subs = tuple(default_subjects(3 if subjects is None else subjects, seed=seed)
                 if subjects is None or isinstance(subjects, int) else subjects)
    return _cached(pats, subs, repetitions, seed)


@lru_cache(maxsize=64)
def _cached(patterns: tuple[str, ...], subjects: tuple[SubjectProfile, ...], repetitions: int,
            seed: int) -> tuple[AngleSequence, ...]:
    out = []
    for p in patterns:
        for s in subjects:
            for r in range(1, repetitions + 1):
                seq = demonstrate_one(p, s, r, seed=seed)
                ext = extract_angles(seq.positions, seq.timestamps)
                out.append(AngleSequence(_readonly(ext.t), _readonly(ext.angles), p, s.name, r))
    return tuple(out)
