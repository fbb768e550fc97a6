"""BlendedPredictor: per-step inverse-MSE weights from already-scored predictions only."""

from __future__ import annotations

import copy
import re

import numpy as np
import pytest

from gwr_predictor.evaluation.online import Predictor, compare_online, train_online
from gwr_predictor.predictors.baselines import HoldLast
from research.blend import BlendedPredictor, BlendError, BlendParams, make_blend

H, J = 4, 3


class Noisy:
    """Predicts the last sample plus Gaussian noise at every step."""

    def __init__(self, sigma: float, seed: int = 0, horizon: int = H) -> None:
        self.sigma, self.horizon, self.rng = sigma, horizon, np.random.default_rng(seed)
        self.last = None

    def step(self, x, learn=True):
        if x is not None:
            self.last = np.asarray(x, float)
        if self.last is None:
            return None
        return self.last + self.sigma * self.rng.standard_normal((self.horizon, self.last.size))

    def reset_sequence(self):
        self.last = None


class Scripted:
    """Returns predetermined outputs: out[t] at the t-th step of a sequence (None where NaN); logs inputs."""

    def __init__(self, outputs: np.ndarray) -> None:
        self.outputs, self.t, self.seen = outputs, 0, []

    def step(self, x, learn=True):
        self.seen.append(None if x is None else np.array(x))
        out = self.outputs[self.t]
        self.t += 1
        return None if np.isnan(out).any() else out.copy()

    def reset_sequence(self):
        self.t = 0


def reference_mse(outputs: np.ndarray, frames: np.ndarray, upto: int, decay: float) -> np.ndarray:
    """Naive running MSE per step after frame `upto` of one sequence: the prediction made at s for step
    k counts iff s + k <= upto and frame s + k is observed; updates in target-frame order."""
    sse, w = np.zeros(H), np.zeros(H)
    for t in range(upto + 1):
        if np.isnan(frames[t]).any():
            continue
        for k in range(1, H + 1):
            s = t - k
            if s < 0 or np.isnan(outputs[s]).any():
                continue
            e = np.mean((outputs[s, k - 1] - frames[t]) ** 2)
            sse[k - 1] = decay * sse[k - 1] + e
            w[k - 1] = decay * w[k - 1] + 1
    with np.errstate(invalid="ignore"):
        return np.where(w > 0, sse / np.where(w > 0, w, 1), np.nan)


def test_params_validated():
    for bad in ({"decay": 0.0}, {"decay": 1.5}, {"floor": 0.0}, {"floor": np.inf}, {"horizon": 0},
                {"horizon": 2.5}):
        with pytest.raises(BlendError):
            BlendParams(**bad)
    with pytest.raises(BlendError):
        BlendedPredictor({})
    with pytest.raises(BlendError):
        make_blend("nope")
    assert isinstance(BlendedPredictor({"a": HoldLast(H, J)}, BlendParams(horizon=H)), Predictor)


def test_weights_go_to_the_member_with_lower_past_error():
    blend = BlendedPredictor({"hold": HoldLast(H, J), "noisy": Noisy(0.3)}, BlendParams(horizon=H))
    assert blend.step(None) is None  # nothing observed, nobody predicts
    x = np.array([0.5, -0.2, 1.0])
    first = blend.step(x)
    w0 = blend.weights()
    np.testing.assert_allclose(w0["hold"], 0.5)  # nothing scored yet: equal weights
    assert first.shape == (H, J)
    for _ in range(200):
        out = blend.step(x)
    w = blend.weights()
    assert (w["hold"] > 0.999).all() and (w["noisy"] < 1e-3).all()
    np.testing.assert_allclose(w["hold"] + w["noisy"], 1.0)
    np.testing.assert_allclose(out, np.tile(x, (H, 1)), atol=1e-3)
    mse = blend.running_mse()
    assert mse[0].max() == 0.0 and np.all(mse[1] > 0.05)
    err = blend.errors()
    assert set(err) >= {"running_mse", "scored", "weights"}
    assert err["scored"]["hold"] == [200, 199, 198, 197]  # predictions made at frames 1..200, step k targets +k


def test_mse_uses_only_frames_already_observed():
    """The running MSE after frame t equals a naive count over targets <= t, for random scripted
    outputs and frames with gaps; outputs up to t do not depend on frames after t."""
    rng = np.random.default_rng(1)
    t_len, decay = 40, 0.9
    frames = rng.standard_normal((t_len, J))
    frames[[7, 8, 20]] = np.nan  # missing samples
    outputs = rng.standard_normal((t_len, H, J))
    outputs[[0, 13, 14]] = np.nan  # the member did not predict there
    other = np.zeros((t_len, H, J))
    blend = BlendedPredictor({"a": Scripted(outputs), "b": Scripted(other)}, BlendParams(decay, horizon=H))
    blend.reset_sequence()
    history = []
    for t in range(t_len):
        history.append(blend.step(None if np.isnan(frames[t]).any() else frames[t]))
        np.testing.assert_allclose(blend.running_mse()[0], reference_mse(outputs, frames, t, decay), rtol=1e-12)
        np.testing.assert_allclose(blend.running_mse()[1], reference_mse(other, frames, t, decay), rtol=1e-12)
    # the member received the missing samples as None
    assert blend.members["a"].seen[7] is None and blend.members["a"].seen[6] is not None
    # changing the future leaves the past outputs alone
    changed = frames.copy()
    changed[25:] += 10.0
    blend2 = BlendedPredictor({"a": Scripted(outputs), "b": Scripted(other)}, BlendParams(decay, horizon=H))
    for t in range(t_len):
        out = blend2.step(None if np.isnan(changed[t]).any() else changed[t])
        if t < 25:
            np.testing.assert_array_equal(out, history[t])
        elif t > 25:
            assert not np.allclose(out, history[t])


def test_members_returning_none_are_left_out():
    rng = np.random.default_rng(2)
    outputs = rng.standard_normal((10, H, J))
    outputs[3:6] = np.nan
    const = np.full((10, H, J), 7.0)
    blend = BlendedPredictor({"a": Scripted(outputs), "b": Scripted(const)}, BlendParams(horizon=H))
    for t in range(10):
        out = blend.step(rng.standard_normal(J))
        if 3 <= t < 6:
            np.testing.assert_array_equal(out, const[t])  # only b predicted
        else:
            assert not np.allclose(out, const[t])
    nobody = BlendedPredictor({"a": Scripted(np.full((3, H, J), np.nan))}, BlendParams(horizon=H))
    assert all(nobody.step(np.zeros(J)) is None for _ in range(3))


def test_blend_of_identical_members_is_the_member():
    rng = np.random.default_rng(3)
    seq = np.cumsum(0.05 * rng.standard_normal((60, J)), axis=0)
    seq[[10, 11, 30]] = np.nan
    ref = HoldLast(H, J)
    blend = BlendedPredictor({"a": HoldLast(H, J), "b": HoldLast(H, J)}, BlendParams(horizon=H))
    for t, x in enumerate(seq):
        if t == 40:
            ref.reset_sequence()
            blend.reset_sequence()
        x = None if np.isnan(x).any() else x
        np.testing.assert_allclose(blend.step(x), ref.step(x), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(blend.weights()["a"], 0.5)


def test_reset_drops_pending_predictions():
    """A prediction made in one sequence is never scored against a frame of the next one."""
    outputs = np.zeros((10, H, J))
    blend = BlendedPredictor({"a": Scripted(outputs)}, BlendParams(decay=1.0, horizon=H))
    for _ in range(5):
        blend.step(np.zeros(J))
    before = blend.running_mse().copy()
    count = blend.errors()["scored"]["a"]
    assert np.all(before == 0) and count == [4, 3, 2, 1]
    blend.reset_sequence()
    blend.step(np.ones(J))  # would score error 1 at every step if the pending ring survived
    np.testing.assert_array_equal(blend.running_mse(), before)
    assert blend.errors()["scored"]["a"] == count
    blend.step(np.ones(J))  # now the prediction (0) made at the new sequence's first frame is scored
    assert blend.running_mse()[0, 0] == pytest.approx(1 / 5) and blend.errors()["scored"]["a"][0] == 5


def test_frozen_scoring_is_optional_and_predict_needs_members_with_predict():
    frozen = BlendedPredictor({"a": HoldLast(H, J), "b": Noisy(0.3)}, BlendParams(horizon=H, adapt_frozen=False))
    for _ in range(10):
        frozen.step(np.ones(J), learn=False)
    assert np.isnan(frozen.running_mse()).all()
    with pytest.raises(BlendError):
        frozen.predict()


def test_make_blend_on_demonstrator_subset():
    """Trained on the first sequences, the blend's 6-step MSE on the last ones (still learning) is no
    worse than the worse member's and close to or below the better member's."""
    from gwr_predictor.data.datasets import demo_angle_sequences

    seqs = demo_angle_sequences(patterns=("wave_one", "raise_front_both", "rotate_cw_one"), subjects=2,
                                repetitions=3)
    train, test = seqs[:-4], seqs[-4:]
    for kind in ("blend_hierarchy_rls", "blend_flat_rls"):
        blend = make_blend(kind, seed=0)
        assert blend.horizon == 6
        train_online(blend, train, passes=2, progress=False)
        members = copy.deepcopy(blend.members)  # independent copies: they learn exactly as the blend's own
        assert len(blend.neuron_counts) == (3 if kind == "blend_hierarchy_rls" else 1)
        res = compare_online({"blend": blend, **members}, test, progress=False)
        mse = {m: r.stats.mse[-1] for m, r in res.items()}
        worse = max(mse[m] for m in members)
        better = min(mse[m] for m in members)
        assert mse["blend"] <= worse, (kind, mse)
        assert mse["blend"] <= better * 1.1, (kind, mse)
        assert res["blend"].scored_frames > 100
        assert set(blend.errors()["members"]) == {{"blend_hierarchy_rls": "hierarchy", "blend_flat_rls": "flat"}[kind]}
        np.testing.assert_allclose(sum(blend.weights().values()), 1.0)
        p = blend.predict()
        assert p is not None and p.shape == (6, 8)


def _arm_frames(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = 0.1 * np.arange(n)
    return 0.3 * np.sin(t[:, None] * np.arange(1, 9) * 0.5) + 0.01 * rng.standard_normal((n, 8))


@pytest.mark.parametrize("kind", ["blend_hierarchy_rls", "blend_flat_rls"])
def test_blend_saved_mid_stream_continues_bit_for_bit(tmp_path, kind):
    frames = _arm_frames(160)
    frames[50] = np.nan  # a missing sample before the save, one right after it
    frames[91] = np.nan
    a = make_blend(kind, seed=3)
    for x in frames[:90]:
        a.step(x)
    path = tmp_path / "blend.npz"
    a.save(path)
    b = BlendedPredictor.load(path)
    assert b.names == a.names and b.params == a.params and b.neuron_counts == a.neuron_counts
    np.testing.assert_array_equal(b.running_mse(), a.running_mse())
    for t, x in enumerate(frames[90:]):
        if t == 40:
            a.reset_sequence(), b.reset_sequence()
        pa, pb = a.step(x), b.step(x)
        assert (pa is None) == (pb is None)
        if pa is not None:
            np.testing.assert_array_equal(pa, pb)
    np.testing.assert_array_equal(b.running_mse(), a.running_mse())
    np.testing.assert_array_equal(b.predict(), a.predict())
    np.testing.assert_array_equal(b.weight_matrix(), a.weight_matrix())
    np.testing.assert_array_equal(b._count, a._count)


def test_fresh_blend_round_trips_before_any_frame(tmp_path):
    a = make_blend("blend_hierarchy_rls", seed=1, blend=BlendParams(decay=0.95, floor=1e-5, adapt_frozen=False))
    a.save(tmp_path / "b.npz")
    b = BlendedPredictor.load(tmp_path / "b.npz")
    assert b.params == a.params and b._pending is None
    for x in _arm_frames(20):
        pa, pb = a.step(x), b.step(x)
        assert (pa is None) == (pb is None)
        if pa is not None:
            np.testing.assert_array_equal(pa, pb)


def test_checkpoint_kind_mismatch_names_the_file_and_the_kind(tmp_path):
    from gwr_predictor.learning.errors import LearningError
    from gwr_predictor.learning.hierarchy import FlatPredictor, Hierarchy

    blend_path, plain_path = tmp_path / "blend.npz", tmp_path / "plain.npz"
    make_blend("blend_hierarchy_rls").save(blend_path)
    Hierarchy().save(plain_path)
    expected = f"{plain_path}: holds a 'Hierarchy', expected a 'BlendedPredictor'"
    with pytest.raises(LearningError, match=re.escape(expected)):
        BlendedPredictor.load(plain_path)
    for cls in (Hierarchy, FlatPredictor):
        expected = f"{blend_path}: holds a 'BlendedPredictor', expected a '{cls.kind}'"
        with pytest.raises(LearningError, match=re.escape(expected)):
            cls.load(blend_path)


def test_blend_with_unsaveable_members_refuses_to_save(tmp_path):
    from gwr_predictor.learning.errors import LearningError

    blend = BlendedPredictor({"hold": HoldLast(H, J)}, BlendParams(horizon=H))
    with pytest.raises(LearningError, match=r"member 'hold' .*cannot be saved"):
        blend.save(tmp_path / "x.npz")
    assert not (tmp_path / "x.npz").exists()


@pytest.mark.parametrize("name", ["hierarchy", "gated_llm_gwr", "gwr_experts"])
def test_every_learner_says_its_horizon_and_keeps_it_through_a_checkpoint(name, tmp_path):
    """The learner node publishes as many steps as the model predicts, which a loaded checkpoint decides."""
    from gwr_predictor.learning.protocol import Learner
    from gwr_predictor.registry import learner_names, load_predictor, make_predictor

    assert name in learner_names()
    model = make_predictor(name, {"horizon": 4, "n_joints": 8})
    assert isinstance(model, Learner) and model.horizon == 4
    for x in np.random.default_rng(0).normal(0.0, 0.1, (30, 8)):
        out = model.step(x)
    assert out.shape == (4, 8)
    model.save(tmp_path / "m.npz")
    assert load_predictor(name, tmp_path / "m.npz").horizon == 4


def test_make_predictor_names_the_hierarchy_and_both_blends():
    from gwr_predictor import registry as product
    from gwr_predictor.learning.hierarchy import FlatPredictor, Hierarchy
    from gwr_predictor.predictors.errors import PredictorError
    from research.blend import gwr_member
    from research.registry import RESEARCH

    assert isinstance(RESEARCH.make_predictor("hierarchy"), Hierarchy)
    assert isinstance(gwr_member(RESEARCH.make_predictor("blend_hierarchy_rls")), Hierarchy)
    assert isinstance(gwr_member(RESEARCH.make_predictor("blend_flat_rls")), FlatPredictor)
    # research names are in research's registry, beside the product's; the product's, which the node and
    # pretrain offer, knows none of them
    assert {"blend_flat_rls", "llm_gwr", "gated_hierarchy"} <= set(RESEARCH.names())
    assert set(product.names()) <= set(RESEARCH.names()) and not {"blend_flat_rls", "llm_gwr"} & set(product.names())
    assert set(product.learner_names()) == {"hierarchy", "gated_llm_gwr", "gwr_experts"}
    with pytest.raises(PredictorError, match="unknown predictor 'nope'"):
        RESEARCH.make_predictor("nope")
    with pytest.raises(PredictorError, match="unknown predictor 'llm_gwr'"):
        product.make_predictor("llm_gwr")


def test_load_predictor_refuses_a_blend_of_other_members(tmp_path):
    from gwr_predictor.learning.errors import LearningError
    from research.registry import RESEARCH

    path = tmp_path / "flat.npz"
    RESEARCH.make_predictor("blend_flat_rls").save(path)
    assert tuple(RESEARCH.load_predictor("blend_flat_rls", path).names) == ("flat", "rls")
    with pytest.raises(LearningError, match=r"holds a blend of \['flat', 'rls'\], expected one of "
                                              r"\['hierarchy', 'rls'\]") as other:
        RESEARCH.load_predictor("blend_hierarchy_rls", path)
    assert other.value.kind_mismatch and other.value.expected == "blend_hierarchy_rls"
    assert tuple(other.value.found) == ("flat", "rls")
    with pytest.raises(LearningError, match="expected a 'Hierarchy'") as other:
        RESEARCH.load_predictor("hierarchy", path)
    assert other.value.kind_mismatch and (other.value.found, other.value.expected) == ("BlendedPredictor", "Hierarchy")


def test_registered_predictor_is_available_to_evaluate_by_name(tmp_path, capsys):
    import json

    from gwr_predictor import registry
    from gwr_predictor.commands.cli import main
    from gwr_predictor.errors import GwrPredictorError

    class Zero:
        """Predicts the origin: worse than hold-last on any motion away from it."""

        def __init__(self, horizon: int, joints: int = 8) -> None:
            self.out = np.zeros((horizon, joints))

        def step(self, x, learn=True):
            return self.out

        def reset_sequence(self):
            pass

    name = "zero_test_only"
    registry.register(name, lambda params, seed: Zero(params.horizon), "predicts zeros")
    try:
        with pytest.raises(GwrPredictorError, match="already registered"):
            registry.register(name, lambda params, seed: Zero(params.horizon))
        assert name in registry.names() and name not in registry.learner_names()
        frames = 0.5 + _arm_frames(60)
        csv = tmp_path / "angles.csv"
        from gwr_predictor.robot.nao import ARM_JOINTS

        csv.write_text("time," + ",".join(ARM_JOINTS) + "\n" + "\n".join(
            f"{0.1 * t:.1f}," + ",".join(f"{v:.5f}" for v in row) for t, row in enumerate(frames)) + "\n")
        assert main(["evaluate", str(csv), "--methods", f"hold,{name}", "--no-progress"]) == 0
        out = capsys.readouterr().out
        assert "| predicts zeros |" in out
        mae = json.loads(out.strip().splitlines()[-1])["mae_rad"]
        assert mae[name][0] > mae["hold"][0]
    finally:
        registry.PRODUCT.unregister(name)
