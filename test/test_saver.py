"""Checkpoints written off the learner's path (`learning/saver.py`): a snapshot between two frames, the
write on a thread of its own, only the newest snapshot written, failures reported to the learner."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from gwr_predictor.learning import saver as saver_module
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.saver import CheckpointSaver
from gwr_predictor.registry import load_predictor, make_predictor


def _stream(n: int) -> np.ndarray:
    t = np.arange(n)[:, None] * 0.1
    return 0.4 * np.sin(t + np.arange(8))


@pytest.fixture
def held_writes(monkeypatch):
    """Writes that wait until the test lets them go (the disk of a slow robot computer)."""
    release, started = threading.Event(), threading.Event()
    real = saver_module.write_checkpoint

    def slow(*args, **kwargs):
        started.set()
        assert release.wait(30)
        real(*args, **kwargs)

    monkeypatch.setattr(saver_module, "write_checkpoint", slow)
    return release, started


def test_frames_go_on_while_a_save_is_written_and_the_file_holds_the_snapshot(tmp_path, held_writes):
    release, started = held_writes
    model = make_predictor("gated_llm_gwr")
    frames = _stream(300)
    for x in frames[:100]:
        model.step(x)
    saver = CheckpointSaver(tmp_path / "model.npz")
    saver.submit(model)
    assert started.wait(10)
    for x in frames[100:]:  # learning and predicting while the write is held
        assert model.step(x) is not None
    assert saver.busy() and not (tmp_path / "model.npz").exists()
    release.set()
    assert saver.wait(30)
    [result] = saver.results()
    assert result.error is None and result.bytes == (tmp_path / "model.npz").stat().st_size
    saved = load_predictor("gated_llm_gwr", tmp_path / "model.npz")
    assert saved.model.frames_seen == 100  # the state when it was snapshot, not later
    assert saver.close(10)


def test_only_the_newest_waiting_snapshot_is_written(tmp_path, held_writes):
    release, started = held_writes
    model = make_predictor("gated_llm_gwr")
    saver = CheckpointSaver(tmp_path / "model.npz")
    frames = _stream(60)
    for i, x in enumerate(frames):
        model.step(x)
        if i in (9, 19, 29, 39):
            saver.submit(model)
            if i == 9:
                assert started.wait(10)  # the first is being written; the next ones wait, newest winning
    release.set()
    assert saver.close(30)
    assert saver.superseded == 2 and len(saver.results()) == 2
    assert load_predictor("gated_llm_gwr", tmp_path / "model.npz").model.frames_seen == 40


def test_a_failed_write_is_reported_to_the_learner_and_a_closed_saver_refuses(tmp_path):
    model = make_predictor("gated_llm_gwr")
    model.step(_stream(1)[0])
    saver = CheckpointSaver(tmp_path / "no_such_folder" / "model.npz")
    saver.submit(model)
    assert saver.close(30)
    [result] = saver.results()
    assert isinstance(result.error, LearningError) and "no_such_folder" in str(result.error)
    with pytest.raises(LearningError, match="closed"):
        saver.submit(model)
