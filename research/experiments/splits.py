"""Train / held-out splits of labelled demonstrations, so that quality is also measured on data
the model never trained on.

Three disjoint sets: `train` (the training subjects' first repetitions), `heldout_repetitions`
(the same subjects and patterns, later repetitions: new performances of known movements) and
`heldout_subjects` (people the model never saw). Sequences need `pattern`, `subject` and
`repetition` attributes (`datasets.AngleSequence`).
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from dataclasses import dataclass
from typing import Any

from gwr_predictor.errors import GwrPredictorError


class SplitError(GwrPredictorError, ValueError):
    """A split that would be empty or would leak data between sets."""


@dataclass(frozen=True)
class Splits:
    train: tuple[Any, ...]
    heldout_repetitions: tuple[Any, ...]
    heldout_subjects: tuple[Any, ...]

    def items(self) -> tuple[tuple[str, tuple[Any, ...]], ...]:
        return (("train", self.train), ("heldout_repetitions", self.heldout_repetitions),
                ("heldout_subjects", self.heldout_subjects))

    def sizes(self) -> dict[str, int]:
        return {name: len(seqs) for name, seqs in self.items()}


def key(seq: Any) -> tuple[Hashable, Hashable, int]:
    """(pattern, subject, repetition): what identifies one demonstration."""
    return (seq.pattern, seq.subject, int(seq.repetition))


def _ordered_unique(values: Sequence[Hashable]) -> list[Hashable]:
    return list(dict.fromkeys(values))


def make_splits(sequences: Sequence[Any], heldout_subjects: int | Sequence[Hashable] = 1,
                heldout_repetitions: int = 2) -> Splits:
    """Hold out the last `heldout_subjects` subjects (or the named ones) entirely, and the last
    `heldout_repetitions` repetitions of every remaining subject and pattern."""
    if not sequences:
        raise SplitError("no sequences to split")
    keys = [key(s) for s in sequences]
    if len(set(keys)) != len(keys):
        raise SplitError("two sequences share (pattern, subject, repetition): a split could leak")
    subjects = _ordered_unique([k[1] for k in keys])
    if isinstance(heldout_subjects, int):
        if not 0 <= heldout_subjects < len(subjects):
            raise SplitError(f"cannot hold out {heldout_subjects} of {len(subjects)} subjects")
        held_subj = set(subjects[len(subjects) - heldout_subjects:])
    else:
        held_subj = set(heldout_subjects)
        if unknown := held_subj - set(subjects):
            raise SplitError(f"unknown held-out subjects {sorted(map(str, unknown))}")
        if held_subj == set(subjects):
            raise SplitError("holding out every subject leaves nothing to train on")
    reps = sorted({k[2] for k in keys})
    if not 0 <= heldout_repetitions < len(reps):
        raise SplitError(f"cannot hold out {heldout_repetitions} of {len(reps)} repetitions")
    held_reps = set(reps[len(reps) - heldout_repetitions:])
    train, rep_out, subj_out = [], [], []
    for seq, (_, subject, rep) in zip(sequences, keys, strict=True):
        if subject in held_subj:
            subj_out.append(seq)
        elif rep in held_reps:
            rep_out.append(seq)
        else:
            train.append(seq)
    if not train:
        raise SplitError("the training split is empty")
    return Splits(tuple(train), tuple(rep_out), tuple(subj_out))
