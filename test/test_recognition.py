"""The recognition switch: the default trusts its experts ungated where the snippet memory knows the motion."""

from __future__ import annotations

import numpy as np
import pytest

from gwr_predictor.default_predictor import (
    DefaultPredictor,
    Experts,
    GatedPredictor,
    MemoryParams,
    RecognitionSwitch,
    TrajectoryMemory,
    make_default,
)
from gwr_predictor.default_predictor.errors import DefaultPredictorError
from gwr_predictor.learning.checkpoint import read_checkpoint, write_checkpoint
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.registry import DEFAULT_PREDICTOR, load_predictor

NOISE = 0.002  # rad: a person never repeats a pose to the bit
#: One last gate over both weightings (before round 6), which has no ungated weighting's gate to lend to.
ONE_GATE = {"recognition.separate_gates": False, "recognition.onset_trust": 0.0}


def _performance(speed: float, n: int = 45) -> np.ndarray:
    """One out-and-back reach of every joint, `speed` times as fast as at 1.0, then still."""
    t = np.arange(n) * 0.1 * speed
    phase = np.clip(t / 3.0, 0.0, 1.0)
    return 0.2 + 0.6 * np.sin(np.pi * phase)[:, None] * np.linspace(0.5, 1.0, 8)[None, :]


def _repeated(speeds: tuple[float, ...] = (1.0, 0.9, 1.1, 1.0), seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The reach performed at each speed, with tracker noise; and each frame's performance index."""
    parts = [_performance(s) for s in speeds]
    index = np.concatenate([np.full(len(p), i) for i, p in enumerate(parts)])
    x = np.concatenate(parts)
    return x + np.random.default_rng(seed).normal(scale=NOISE, size=x.shape), index


def _abs_errors_600(model, x: np.ndarray) -> np.ndarray:
    """|error| at the last step, mean over joints, per frame (NaN where nothing is scored)."""
    out = np.full(len(x), np.nan)
    for t, f in enumerate(x):
        pred = model.step(f)
        if pred is not None and t + 6 < len(x):
            out[t] = np.abs(pred[-1] - x[t + 6]).mean()
    return out


def test_the_memory_knows_motion_it_has_seen_and_not_a_pose_it_has_not():
    memory = TrajectoryMemory(MemoryParams())
    x, _ = _repeated()
    assert memory.familiarity is None  # nothing read yet
    seen = []
    for f in x:
        memory.step(f)
        seen.append(memory.familiarity)
    second = [f for f, i in zip(seen, _repeated()[1], strict=True) if i == 1 and f is not None]
    assert np.median(second) < 1.0  # within one motion scale of a stored key
    memory.step(x[-1] + 1.0)  # a jump to a pose it has never seen
    assert memory.familiarity > 10.0
    memory.step(None)
    assert memory.familiarity is None and memory.travel is None


def test_the_memory_says_how_far_the_pose_has_travelled():
    """Over the key's longest lag, in motion scales: near 0 in a pause however well the pose is known."""
    memory = TrajectoryMemory(MemoryParams())
    x, _ = _repeated()
    frames = np.concatenate([x, np.repeat(x[-1:], 20, axis=0)])
    travel = []
    for t, f in enumerate(frames):
        memory.step(f)
        travel.append(memory.travel)
        if memory.travel is not None:  # the change over 8 frames, in units of the motion scale
            expected = np.linalg.norm(f - frames[t - 8]) / max(memory.motion_rms, memory.params.noise_floor)
            assert memory.travel == pytest.approx(expected)
    assert travel[0] is None  # nothing read yet
    reaching = [t for t in travel[len(x) - 160:len(x) - 150] if t is not None]
    assert reaching and min(reaching) > 3.0 and travel[-1] < 1.0
    assert memory.familiarity is not None and memory.familiarity < 1.0  # the pose is known all the same


def test_a_movement_seen_once_is_trusted_on_its_second_performance():
    """The gates remember that every expert was wrong on the first performance; the switch trusts them
    where the memory recognises the motion, so the second performance is anticipated."""
    x, index = _repeated()
    switched = make_default()
    errors = _abs_errors_600(switched, x)
    gated = _abs_errors_600(make_default(settings={"recognition.radius": 0.0}), x)
    hold = np.array([np.abs(x[t] - x[t + 6]).mean() if t + 6 < len(x) else np.nan for t in range(len(x))])
    second = index == 1  # measured: 0.071 rad, the gated experts 0.092, holding the pose 0.122
    assert np.nanmean(errors[second]) < 0.85 * np.nanmean(gated[second])
    assert np.nanmean(errors[second]) < 0.65 * np.nanmean(hold[second])
    first = index == 0  # nothing to recognise yet: the gated experts, which hold the pose
    np.testing.assert_array_equal(errors[first], gated[first])
    assert switched.recognised > 0


def test_without_recognition_the_switch_is_the_gated_experts():
    x, _ = _repeated()
    off = make_default(settings={"recognition.radius": 0.0})
    experts = GatedPredictor(make_default().experts, off.gate.params)
    for f in x:
        np.testing.assert_array_equal(off.step(f), experts.step(f))
    assert off.recognised == 0


def test_the_switch_needs_gated_members_and_a_memory():
    made = make_default()
    members = dict(made.experts.members)
    with pytest.raises(DefaultPredictorError, match="memory"):
        RecognitionSwitch(Experts({n: m for n, m in members.items() if n != "memory"}))
    members["memory"] = members["memory"].model
    with pytest.raises(DefaultPredictorError, match="not gated"):
        RecognitionSwitch(Experts(members))


def test_each_weighting_is_judged_by_its_own_record():
    """One last gate over both weightings judged the ungated one, on the second performance, by the gated
    one's record from the first, where it had mostly held the pose; a gate per weighting does not
    (measured at a one-standard-error bound: 0.074 rad against 0.082 with one gate; holding 0.122; with
    the memory's key over lags up to 4, before round 7: 0.062 against 0.072)."""
    x, index = _repeated()
    second = index == 1
    one = {"gate.confidence": 1.0}
    separate = _abs_errors_600(make_default(settings={**one, "recognition.onset_trust": 0.0}), x)
    single = _abs_errors_600(make_default(settings={**one, **ONE_GATE}), x)
    assert np.nanmean(separate[second]) < 0.95 * np.nanmean(single[second])
    first = index == 0  # nothing recognised yet: the gated weighting's gate alone, the same either way
    np.testing.assert_array_equal(separate[first], single[first])


def test_the_defaults_loader_refuses_other_models(tmp_path):
    """Another predictor's checkpoint is a kind mismatch (the node tells the user to fix `predictor`)."""
    from gwr_predictor.learning.hierarchy import Hierarchy
    from gwr_predictor.registry import make_predictor

    make_predictor("gated_llm_gwr").save(tmp_path / "network.npz")
    Hierarchy().save(tmp_path / "hierarchy.npz")
    for name, found in (("network.npz", "GatedPredictor"), ("hierarchy.npz", "Hierarchy")):
        with pytest.raises(LearningError) as refused:
            load_predictor(DEFAULT_PREDICTOR, tmp_path / name)
        assert refused.value.kind_mismatch and refused.value.found == found


def test_a_copy_of_the_default_predicts_on_its_own():
    """The evaluation copies trained models (`copy.deepcopy`): the copy's last gates must view the copy's
    weightings, not the original's, so the two predict alike on the same frames and apart on others."""
    import copy

    x, _ = _repeated()
    made = make_default()
    for f in x[:100]:
        made.step(f)
    twin = copy.deepcopy(made)
    for f in x[100:]:
        np.testing.assert_array_equal(made.step(f), twin.step(f))
    other = copy.deepcopy(made)
    for f in x[:60][::-1]:  # the original steps on alone: the copy must not see it
        made.step(f)
    fresh = copy.deepcopy(other)
    for f in x[100:130]:
        np.testing.assert_array_equal(other.step(f), fresh.step(f))


def _paused(pause: int = 12, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """`_repeated`'s reaches, each after a pause in the start pose: what a person does between two."""
    parts, index = [], []
    for i, speed in enumerate((1.0, 0.9, 1.1, 1.0)):
        reach = _performance(speed)
        parts += [np.repeat(reach[:1], pause, axis=0), reach]
        index += [np.full(pause + len(reach), i)]
    x = np.concatenate(parts)
    return x + np.random.default_rng(seed).normal(scale=NOISE, size=x.shape), np.concatenate(index)


def test_onset_trust_anticipates_a_recognised_movement_after_a_pause():
    """In the pause the ungated weighting predicts the reach to begin and it does not, so step 6's record
    is against it when the reach comes; step 1's record follows the reach a frame later. Borrowing it
    over the onset anticipates the second performance (measured, all of step 1's trust: 0.062 rad against
    0.067 lending none)."""
    x, index = _paused()
    borrowed = _abs_errors_600(make_default(settings={"recognition.onset_trust": 1.0}), x)
    own = _abs_errors_600(make_default(settings={"recognition.onset_trust": 0.0}), x)
    second = index == 1
    assert np.nanmean(borrowed[second]) < 0.95 * np.nanmean(own[second])
    first = index == 0  # nothing recognised yet: the gated weighting, the same either way
    np.testing.assert_array_equal(borrowed[first], own[first])


def test_onset_trust_lends_step_1_only_before_a_step_has_scores_of_the_movement():
    """Outside a recognised movement every step borrows; in one, step k only over its first k frames."""
    x, _ = _paused()
    made = make_default(settings={"recognition.onset_trust": 0.5})
    gate = made.ungated_gate
    lent: dict[int, np.ndarray | None] = {}
    for f in x:
        made.step(f)
        lent.setdefault(made.onset, gate.borrow)
        if gate.borrow is not None:
            alpha = gate.alpha()
            assert (alpha[gate.borrow > 0] >= 0.5 * alpha[0] - 1e-12).all()
    np.testing.assert_array_equal(lent[0], np.full(6, 0.5))
    np.testing.assert_array_equal(lent[3], [0.0, 0.0, 0.5, 0.5, 0.5, 0.5])
    assert max(lent) > 6 and lent[7] is None
    off = make_default(settings={"recognition.onset_trust": 0.0})
    for f in x:
        off.step(f)
        assert off.ungated_gate.borrow is None
    with pytest.raises(DefaultPredictorError, match="separate_gates false, set onset_trust 0"):
        make_default(settings={"recognition.separate_gates": False})


def test_the_onset_count_survives_a_checkpoint(tmp_path):
    x, _ = _paused()
    made = make_default(settings={"recognition.onset_trust": 0.5})
    cut = next(t for t in range(len(x)) if made.step(x[t]) is not None and made.onset == 3)
    made.save(tmp_path / "now.npz")
    loaded = load_predictor(DEFAULT_PREDICTOR, tmp_path / "now.npz")
    assert loaded.onset == 3
    for f in x[cut + 1:]:
        np.testing.assert_array_equal(loaded.step(f), made.step(f))


def test_the_ungated_record_kept_on_recognised_movement_anticipates_the_later_performances():
    """Every member is new to the first performance, and its errors there say little about it once the
    movement is known; weighed at 0.1, they leave the record to the recognised performances (measured,
    third and fourth performances at decay 0.995: 0.045 / 0.013 rad against 0.062 / 0.039 with every
    prediction alike)."""
    x, index = _repeated()
    kept = _abs_errors_600(make_default(settings={"recognition.outside_weight": 0.1}), x)
    alike = _abs_errors_600(make_default(settings={"recognition.outside_weight": 1.0}), x)
    later = index >= 2
    assert np.nanmean(kept[later]) < 0.8 * np.nanmean(alike[later])
    first = index == 0  # nothing recognised yet: the gated weighting, the same either way
    np.testing.assert_array_equal(kept[first], alike[first])


def test_the_ungated_weighting_hears_its_members_at_its_own_power():
    """The recognised movements' record weighs the members more evenly than the gated weighting's (power 3
    against 4); 0 takes the experts' power."""
    x, _ = _repeated()
    made, same = make_default(), make_default(settings={"recognition.power": 0.0})
    assert made.ungated.params.power == 3.0 and same.ungated.params.power == made.experts.params.power == 4.0
    for f in x[:120]:
        made.step(f)
        same.step(f)
    mse = made.ungated.running_mse()
    np.testing.assert_allclose(made.ungated.weights(), (1 / mse**3) / (1 / mse**3).sum(axis=0))
    assert not np.allclose(made.ungated.weights(), same.ungated.weights())


def test_the_record_weights_survive_a_checkpoint_and_bad_ones_are_refused(tmp_path):
    x, _ = _repeated()
    made = make_default()
    cut = next(t for t in range(len(x)) if made.step(x[t]) is not None and made.ungated.record_weight.min() < 1.0
               and made.recognised)
    made.save(tmp_path / "now.npz")
    loaded = load_predictor(DEFAULT_PREDICTOR, tmp_path / "now.npz")
    np.testing.assert_array_equal(loaded.ungated.record_weight, made.ungated.record_weight)
    for f in x[cut + 1:]:
        np.testing.assert_array_equal(loaded.step(f), made.step(f))
    header, arrays = read_checkpoint(tmp_path / "now.npz", DefaultPredictor.kind)
    header["ungated"]["record_weight"] = [0.5, "x", 1, 1, 1, 1]
    write_checkpoint(tmp_path / "bad.npz", DefaultPredictor.kind, header, arrays)
    with pytest.raises(LearningError, match="record_weight"):
        load_predictor(DEFAULT_PREDICTOR, tmp_path / "bad.npz")


@pytest.mark.parametrize("part", [("onset",), ("spread",), ("experts", "record_weight"), ("ungated", "record_weight")],
                         ids=".".join)
def test_a_checkpoint_of_the_default_without_part_of_its_state_is_refused(tmp_path, part):
    """A checkpoint of this format holds the whole default: one that lacks a part of it is refused, naming
    the file, never loaded with that part fresh or guessed."""
    made = make_default()
    for f in _repeated()[0][:40]:
        made.step(f)
    made.save(tmp_path / "now.npz")
    header, arrays = read_checkpoint(tmp_path / "now.npz", DefaultPredictor.kind)
    *path, name = part
    holder = header
    for step in path:
        holder = holder[step]
    del holder[name]
    write_checkpoint(tmp_path / "cut.npz", DefaultPredictor.kind, header, arrays)
    with pytest.raises(LearningError, match=r"cut\.npz") as refused:
        load_predictor(DEFAULT_PREDICTOR, tmp_path / "cut.npz")
    assert not refused.value.kind_mismatch
