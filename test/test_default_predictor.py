"""The default predictor (the gated experts) and its network alone behind one gate (gated_llm_gwr),
and the guarded compensator: behaviour and bands on the figures the README claims, at quick sizes."""

from __future__ import annotations

import numpy as np
import pytest
from fakes import damped_oscillation

from gwr_predictor.default_predictor import (
    Experts,
    LocalLinearParams,
    LocalLinearPredictor,
    RecognitionSwitch,
    make_default,
    make_gated_network,
)
from gwr_predictor.default_predictor.errors import DefaultPredictorError
from gwr_predictor.default_predictor.gate import GatedPredictor, GateParams
from gwr_predictor.evaluation.online import compare_online, run_sequence
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.predictors.baselines import HoldLast
from gwr_predictor.registry import DEFAULT_PREDICTOR, PRODUCT, load_predictor, make_predictor
from gwr_predictor.robot.closed_loop import run_closed_loop
from gwr_predictor.robot.compensator import DelayCompensator
from research.experiments import common
from research.experiments.delay import Oracle
from research.experiments.splits import make_splits


def make_gated_llm(params=None, gate=None):
    """The network behind one gate (`make_gated_network`), or the same composition with other settings."""
    if params is None and gate is None:
        return make_gated_network()
    lp = params or LocalLinearParams()
    return GatedPredictor(LocalLinearPredictor(lp, seed=0), gate or GateParams(horizon=lp.horizon, joints=lp.n_joints))


#: The predictors every promise of the default is checked on: the default, and its network alone behind a
#: gate; each with its ungated model (`_ratios_to_hold`).
MAKERS = {"gwr_experts": make_default, "gated_llm_gwr": make_gated_llm}
UNGATED = {"gwr_experts": "experts_ungated", "gated_llm_gwr": common.LLM}
each_default = pytest.mark.parametrize("name", list(MAKERS))


def _walk(n: int = 600, seed: int = 0) -> np.ndarray:
    """An unpredictable random walk (nothing repeats): hold-last is the best one can do."""
    return 0.3 + np.cumsum(np.random.default_rng(seed).normal(scale=0.03, size=(n, 8)), axis=0)


def _periodic(n: int = 600) -> np.ndarray:
    t = np.arange(n)[:, None] * 0.1
    return 0.5 * np.sin(2 * np.pi * 0.4 * t + np.arange(8)[None, :])


def test_the_default_is_registered_everywhere():
    assert DEFAULT_PREDICTOR == common.DEFAULT == "gwr_experts"
    model = make_predictor(DEFAULT_PREDICTOR)
    assert isinstance(model, RecognitionSwitch) and model.params.separate_gates
    assert [g.params.confidence for g in model.gates] == [0.5, 0.5]
    experts = model.experts
    assert isinstance(experts, Experts)
    assert set(experts.members) == {"network", "linear", "rls_ar", "memory", "long_memory"}
    assert all(isinstance(m, GatedPredictor) for m in experts.members.values())
    short, long = experts.members["memory"].model.params, experts.members["long_memory"].model.params
    assert (short.longest_lag, long.longest_lag) == (8, 16)
    assert isinstance(experts.learner, LocalLinearPredictor)
    network = make_predictor("gated_llm_gwr")
    assert isinstance(network, GatedPredictor) and isinstance(network.model, LocalLinearPredictor)


def _jumps(n: int = 800, seed: int = 0, chance: float = 0.05) -> np.ndarray:
    """The whole arm still, then a sudden jump to a random pose (on 5 % of the frames): nothing repeats,
    and a model that extrapolates the jumps it has seen is worse than holding still."""
    rng = np.random.default_rng(seed)
    moves = rng.random((n, 1)) < chance
    return 0.3 + np.cumsum(moves * rng.normal(scale=0.3, size=(n, 8)), axis=0)


def _ratios_to_hold(x: np.ndarray, name: str) -> dict[str, np.ndarray]:
    """MAE / hold-last's MAE per step, one pass from scratch, of predictor `name` and of its ungated model."""
    from research.registry import RESEARCH  # the ungated models are research's

    params = common.make_params()
    res = compare_online({"hold": HoldLast(), "gated": MAKERS[name](),
                          "ungated": RESEARCH.make_predictor(UNGATED[name], params, 0)}, [x], progress=False)
    hold = np.array(res["hold"].stats.mae)
    return {m: np.array(res[m].stats.mae) / hold for m in ("gated", "ungated")}


@each_default
def test_never_worse_than_hold_where_nothing_repeats(name):
    """On a stream where the ungated model is clearly worse than holding still (measured 1.19 x at
    600 ms for the network, 1.29 x for the experts; on a plain random walk it is 1.00 x, so such a stream
    cannot tell a gate from none), the gated one stays within 1.02 x at every step."""
    ratio = _ratios_to_hold(_jumps(800), name)
    assert ratio["ungated"][-1] >= 1.10
    assert np.all(ratio["gated"] <= 1.02)


@each_default
def test_wins_where_motion_repeats_and_learns_from_nothing(name):
    res = compare_online({"hold": HoldLast(), "gated": MAKERS[name]()}, [_periodic(600)], progress=False)
    gated, hold = np.array(res["gated"].stats.mae), np.array(res["hold"].stats.mae)
    assert gated[-1] < 0.3 * hold[-1]  # one online pass from scratch on a sine


@each_default
def test_demonstrator_held_out_band(name):
    """Quick-size version of the README's claim: >= 10 % below hold-last at 600 ms on held-out
    repetitions and a held-out person, and never above 1.02 x hold-last at any step."""
    data = common.demo_data(("wave_one", "raise_front_both", "rotate_cw_both"), 3, 4, 0)
    splits = make_splits(data, 1, 1)
    models = {"hold": HoldLast(), "gated": MAKERS[name]()}
    rng = np.random.default_rng(0)
    for _ in range(3):
        compare_online(models, common.shuffled(splits.train, rng), progress=False)
    for seqs, learn in ((splits.heldout_repetitions, False), (splits.heldout_subjects, True)):
        res = compare_online(common.clone(models), seqs, learn=learn, progress=False)
        gated, hold = np.array(res["gated"].stats.mae), np.array(res["hold"].stats.mae)
        assert np.all(gated <= 1.02 * hold)
        assert gated[-1] <= 0.9 * hold[-1]
        assert res["gated"].stats.mse[-1] <= 0.9 * res["hold"].stats.mse[-1]


def test_neurons_level_off_while_a_pattern_repeats():
    seq = common.demo_data(("wave_one",), 1, 3, 0)
    model = LocalLinearPredictor()
    counts = []
    for _ in range(30):
        compare_online({"m": model}, seq, progress=False)
        counts.append(model.neuron_counts[0])
    early, late = counts[9] - counts[0], counts[-1] - counts[19]
    assert counts[0] > 2 and late <= max(2, early // 4)


def test_the_insertion_threshold_follows_the_data_scale():
    """The same motion in degrees instead of radians grows about the same network."""
    x = _periodic(400)
    a, b = LocalLinearPredictor(), LocalLinearPredictor(LocalLinearParams(noise_floor=0.01 * 57.3))
    for f in x:
        a.step(f)
        b.step(f * 57.3)
    assert abs(a.neuron_counts[0] - b.neuron_counts[0]) <= max(3, 0.2 * a.neuron_counts[0])


def _oscillation(n: int = 300, seed: int = 1) -> np.ndarray:
    """A linear system, seen once."""
    return damped_oscillation(n, seed, damping=0.995, stiffness=0.05, noise=0.005)


def test_the_global_read_out_carries_what_the_network_has_barely_seen():
    """One pass over a short linear motion: a few dozen neurons with a handful of pairs each, while the
    global read-out fits every pair; mixed by least squares, the prediction beats the local read-outs
    alone, and the mix leans on the global one."""
    x = _oscillation()
    both, local = LocalLinearPredictor(), LocalLinearPredictor(LocalLinearParams(global_order=0))
    res = compare_online({"both": both, "local": local}, [x], progress=False)
    assert res["both"].stats.mse[-1] < 0.8 * res["local"].stats.mse[-1]
    weights = both.mix_weights()
    assert weights.shape == (6, 2) and np.all(weights[:, 1] > weights[:, 0])
    assert local.mix_weights() is None and "mix_weights" not in local.errors()
    assert set(both.errors()["mix_weights"]) == {"local", "global"}


def test_global_read_out_settings_are_checked():
    with pytest.raises(DefaultPredictorError, match="global_order 5 exceeds"):
        LocalLinearParams(global_order=5)
    with pytest.raises(DefaultPredictorError, match="mix_ridge"):
        LocalLinearParams(mix_ridge=0.0)


def _peeks(make, n: int = 200, at: int = 120) -> bool:
    """Whether a predictor built by `make(sequence)` and fed `sequence` by the evaluation loop predicts
    anything differently before frame `at` when only the frames from `at` on differ."""
    x = _periodic(n)
    y = x.copy()
    y[at:] += 1.0  # a different future, handed to the loop (and to `make`) in full
    before = [run_sequence(make(seq), seq, 6)[0][:at] for seq in (x, y)]
    return not np.array_equal(*before, equal_nan=True)


@each_default
def test_no_peeking(name):
    assert _peeks(lambda seq: Oracle(seq, 6))  # a fake that reads the future it holds is caught
    assert not _peeks(lambda seq: MAKERS[name]())


@each_default
def test_gaps_fall_back_to_hold_and_recover(name):
    model = MAKERS[name]()
    x = _periodic(100)
    for f in x[:50]:
        model.step(f)
    out = model.step(None)
    assert out.shape == (6, 8) and np.isfinite(out).all()
    out = model.step(x[51])
    assert out.shape == (6, 8) and np.isfinite(out).all()
    if name == "gated_llm_gwr":  # the network's window is refilling: the newest pose is held
        np.testing.assert_allclose(out, np.repeat(x[51][None], 6, axis=0))
    for f in x[52:]:  # the experts whose windows span the gap wait; the others carry on
        out = model.step(f)
    assert np.abs(out - x[-1]).max() < 1.0


@pytest.mark.parametrize("name", PRODUCT.names())
def test_a_frame_no_pose_can_be_is_a_missing_sample(name):
    """A driver's garbage (1e100 rad, or 1e20) overflowed the running statistics: the default then
    predicted NaN for good, or crashed, and 1e20 shut its gates for hours. Such a frame is now a missing
    sample, exactly: every predictor answers as if None had come."""
    x = _periodic(300)
    garbage = {120: np.full(8, 1e100), 140: np.r_[1e20, np.zeros(7)], 141: np.full(8, -1e300), 200: np.full(8, 101.0)}
    outputs = []
    for frames in ({t: f for t, f in garbage.items()}, {t: None for t in garbage}):
        model = make_predictor(name)
        outputs.append([model.step(frames.get(t, x[t])) for t in range(len(x))])
    for with_garbage, with_none in zip(*outputs, strict=True):
        assert (with_garbage is None) == (with_none is None)
        if with_none is not None:
            np.testing.assert_array_equal(with_garbage, with_none)
    assert np.isfinite(outputs[0][-1]).all()
    assert np.abs(outputs[0][-1] - x[-1]).max() < 1.0


@each_default
def test_checkpoint_continues_bit_for_bit(tmp_path, name):
    model = MAKERS[name]()
    x = _periodic(300)
    for f in x[:200]:
        model.step(f)
    path = tmp_path / "m.npz"
    model.save(path)
    again = load_predictor(name, path)
    for f in x[200:]:
        np.testing.assert_array_equal(model.step(f), again.step(f))
    assert again.neuron_counts == model.neuron_counts


class _Oracle(Oracle):
    """Knows the sequence: predicts the true future until `fails_at`, then the opposite movement."""

    def __init__(self, x: np.ndarray, fails_at: int, h: int = 6) -> None:
        super().__init__(x, h)
        self.fails_at = fails_at

    def step(self, obs, learn=True):
        future = super().step(obs, learn)
        return future if self.t < self.fails_at else 2 * self.angles[self.t] - future


def _alphas(gate: GatedPredictor, x: np.ndarray) -> np.ndarray:
    out = []
    for f in x:
        gate.step(f)
        out.append(gate.alpha().mean())
    return np.array(out)


def test_the_short_memory_shuts_a_failing_model_out_within_a_few_frames():
    """A model that was right for 300 frames and then goes wrong: the long memory alone keeps
    trusting it for dozens of frames; the short memory's cap shuts it out within 10."""
    x = _periodic(400)
    with_fast = _alphas(GatedPredictor(_Oracle(x, 300)), x)
    long_only = _alphas(GatedPredictor(_Oracle(x, 300), GateParams(fast_decay=0.0)), x)
    assert with_fast[290] > 0.9 and long_only[290] > 0.9  # both trust a model that is right
    assert with_fast[300 + 6 + 10] < 0.05  # its wrong predictions are scored from frame 301 on
    assert long_only[300 + 6 + 10] > 0.5
    res = compare_online({"hold": HoldLast(), "gated": GatedPredictor(_Oracle(x, 0))}, [x], progress=False)
    assert np.all(np.array(res["gated"].stats.mae) <= 1.02 * np.array(res["hold"].stats.mae))


def test_a_long_memory_that_warms_up_trusts_a_model_that_has_just_learned():
    """A model wrong for its first 60 frames (still learning), right from then on: a long memory of
    ~200 frames keeps its early errors for over 100 frames; one that starts at ~20 frames and lengthens
    (`warmup`) trusts it within ~40, and has the long memory once it has seen `warmup` frames."""

    class Learner(Oracle):
        def step(self, obs, learn=True):
            future = super().step(obs, learn)
            return future if self.t >= 60 else 2 * self.angles[self.t] - future

    x = _periodic(600)
    long = GateParams(decay=0.995, fast_decay=0.0)
    warming = GateParams(decay=0.995, warmup=400, warmup_decay=0.95, fast_decay=0.0)
    plain = _alphas(GatedPredictor(Learner(x, 6), long), x)
    gate = GatedPredictor(Learner(x, 6), warming)
    warm = _alphas(gate, x)
    assert warm[:60].max() == 0.0  # the wrong start is not trusted either way
    assert warm[100] > 0.5 and plain[100] < 0.1  # measured 0.59 against 0.0
    assert warm[150] > 0.9 and plain[150] < 0.5  # 0.94 against 0.35
    assert gate._decays[0].item() == 0.995


def test_the_short_memory_judges_by_the_freshest_record():
    """A model wrong for 4 frames (a change of movement it did not foresee), right before and after:
    judged by its 1-step predictions, the short memory shrinks during the failure and trusts the model
    again right after it; judged step by step, it learns of the failure up to 6 frames late and
    shrinks the good predictions that follow."""

    class Blip(Oracle):
        def step(self, obs, learn=True):
            future = super().step(obs, learn)
            return 2 * self.angles[self.t] - future if 300 <= self.t < 304 else future

    x = _periodic(400)
    sure = {"fast_confidence": 0.5}  # a bound on the short memory too, so both react as fast as they can
    fresh = _alphas(GatedPredictor(Blip(x, 6), GateParams(**sure)), x)
    per_step = _alphas(GatedPredictor(Blip(x, 6), GateParams(fast_step=0, **sure)), x)
    assert fresh[302:306].mean() < per_step[302:306].mean() - 0.2
    assert fresh[308:313].mean() > per_step[308:313].mean() + 0.05
    with pytest.raises(DefaultPredictorError, match="fast_step"):
        GateParams(fast_step=7)


def test_the_confidence_bound_ignores_luck():
    """A model whose steps are noise unrelated to the motion: the plain least-squares gate lets
    chance correlations through; the lower confidence bound keeps alpha at 0 nearly always."""

    class Noise:
        rng = np.random.default_rng(1)

        def step(self, obs, learn=True):
            return None if obs is None else obs + self.rng.normal(scale=0.05, size=(6, 8))

        def reset_sequence(self):
            pass

    x = _walk(600)
    bounded = _alphas(GatedPredictor(Noise(), GateParams(fast_decay=0.0)), x)[50:]
    plain = _alphas(GatedPredictor(Noise(), GateParams(confidence=0.0, fast_decay=0.0)), x)[50:]
    assert np.mean(bounded > 0) < 0.1 < np.mean(plain > 0)


def test_bad_checkpoint_and_bad_output_are_named(tmp_path):
    path = tmp_path / "m.npz"
    make_gated_llm().save(path)
    from gwr_predictor.learning.checkpoint import read_checkpoint, write_checkpoint

    header, arrays = read_checkpoint(path, "GatedPredictor", [])
    arrays["model.matrices"] = np.zeros((1, 2, 3))
    write_checkpoint(path, "GatedPredictor", {k: v for k, v in header.items()
                                              if k not in ("magic", "kind", "format_version")}, arrays)
    with pytest.raises(LearningError, match="local models"):
        GatedPredictor.load(path)

    class Bad:
        def step(self, x, learn=True):
            return np.zeros((2, 8))

        def reset_sequence(self):
            pass

    with pytest.raises(DefaultPredictorError, match="shape"):
        GatedPredictor(Bad(), GateParams()).step(np.zeros(8))


class _Wrong:
    """A predictor that is confidently wrong: it predicts the opposite of the motion."""

    def __init__(self) -> None:
        self.last = None

    def step(self, x, learn=True):
        prev, self.last = self.last, x
        if prev is None:
            return None
        v = x - prev
        return x[None, :] - 3 * np.arange(1, 7)[:, None] * v[None, :]

    def reset_sequence(self) -> None:
        self.last = None


def test_guarded_compensation_cannot_hurt():
    person = _periodic(300)
    none = run_closed_loop(person, _Wrong(), delay_s=0.6, compensation="none").errors(skip_s=2.0)["mae"]
    fixed = run_closed_loop(person, _Wrong(), delay_s=0.6, compensation="fixed").errors(skip_s=2.0)["mae"]
    guarded = run_closed_loop(person, _Wrong(), delay_s=0.6, compensation="guarded").errors(skip_s=2.0)["mae"]
    assert fixed > 1.5 * none  # the wrong predictor hurts when executed blindly
    assert guarded <= 1.02 * none


def test_guarded_uses_the_full_lead_of_a_good_predictor():
    person = _periodic(300)

    res = run_closed_loop(person, Oracle(person, 6), delay_s=0.6, compensation="guarded")
    assert np.median(res.steps_used[50:]) == 6
    comp = DelayCompensator("guarded")
    model, hold = comp.guard_mse
    assert model.size == hold.size == 0  # nothing scored before the first command


def _steady(n: int = 400, seed: int = 0) -> np.ndarray:
    """A slow drift under sensor noise: little to predict beyond the newest pose."""
    t = np.arange(n)[:, None] * 0.1
    return 0.3 + 0.02 * t + np.random.default_rng(seed).normal(scale=0.02, size=(n, 8))


@pytest.mark.parametrize("person", [_walk(400, 0), _walk(400, 1), _walk(400, 2), _steady()],
                         ids=["walk0", "walk1", "walk2", "steady"])
def test_guarded_default_is_not_above_uncompensated_where_there_is_little_to_predict(person):
    """The default predictor from scratch at a 600 ms delay. Tolerance 0.1 %: the guard commands the
    observation, the uncompensated command, until a lead has beaten holding still by its margin on
    enough frames, so only such leads can cost anything (measured: at most 1.00006 x; the guard
    without margin and evidence, guard_margin 1 and one scored frame, reached 1.0014 and 1.0040 x
    on walk1 and walk2)."""
    none, guarded = (run_closed_loop(person, make_gated_llm(), delay_s=0.6, compensation=m).errors(skip_s=2.0)["mae"]
                     for m in ("none", "guarded"))
    assert guarded <= 1.001 * none


def test_guarded_default_tracks_well_below_uncompensated_on_the_demonstrator():
    """Quick-size closed loop of `experiment delay` (3 patterns, pretrained twice, a held-out person,
    600 ms): this size measured -38 % (0.149 vs 0.239 rad)."""
    from research.experiments import delay

    cfg = delay.Config(delays=(0.6,), rules=("none", "guarded_true"), predictors=(common.DEFAULT,),
                       patterns=("wave_one", "raise_front_both", "rotate_cw_both"), subjects=3, repetitions=3,
                       heldout_repetitions=1, pretrain_epochs=2, real=False)
    mae = {x["rule"]: x["mae"] for x in delay.measure(cfg, 0, False)["runs"]}
    assert mae["guarded_true"] <= 0.8 * mae["none"]


def _data_loss(name: str) -> tuple[dict, dict]:
    """Held-out MSE per method after 6 epochs over 2 repetitions, loss-free and with 30 % of the
    training frames lost in 1 s chunks."""
    from research.experiments import dataloss

    cfg = dataloss.Config(losses=(0.0, 0.3), patterns=("wave_one", "raise_front_both"), subjects=2,
                          train_repetitions=2, epochs=6, methods=("hold", name))
    data = common.demo_data(cfg.patterns, cfg.subjects, cfg.train_repetitions + cfg.test_repetitions, 0)
    clean, lossy = (dataloss.one_level(cfg, loss, data, 0, False)["heldout"] for loss in cfg.losses)
    return clean, lossy


@each_default
def test_data_loss_does_not_hurt_what_is_learned(name):
    """30 % of the training frames lost in 1 s chunks: the error on complete unseen repetitions stays
    within 10 % of the loss-free one. Measured: gated_llm_gwr 0.96 x; gwr_experts 1.09 x (0.0360 -> 0.0392
    rad^2; round 11's default 1.09 x as well, round 10's 1.08 x, round 9's 1.03 x, rounds 8 and 7 1.02 x,
    round 6's, with the 5-frame memory key, 1.11 x). The full `experiment dataloss` stays flat: 0.0400 -> 0.0359."""
    clean, lossy = _data_loss(name)
    assert lossy[name]["mse"][-1] <= 1.10 * clean[name]["mse"][-1]


@each_default
def test_a_few_repetitions_learned_halve_the_error_of_holding_on_new_ones(name):
    """Measured: gwr_experts 0.39 x, gated_llm_gwr 0.40 x (gwr_experts was 0.55 x while the memory recalled
    replayed recordings from their copies)."""
    clean, _ = _data_loss(name)
    assert clean[name]["mse"][-1] <= 0.5 * clean["hold"]["mse"][-1]


@pytest.mark.parametrize("cls, field, value", [
    (LocalLinearParams, "order", 0), (LocalLinearParams, "motion_decay", 1.0),
    (LocalLinearParams, "noise_floor", 0.0), (LocalLinearParams, "rate", 2.0),
    (GateParams, "decay", 0.0), (GateParams, "prior", float("nan")), (GateParams, "horizon", 0),
])
def test_settings_out_of_range_are_refused_with_the_field_and_the_allowed_range(cls, field, value):
    with pytest.raises(DefaultPredictorError, match=rf"{cls.__name__}\.{field} must be"):
        cls(**{field: value})


@pytest.mark.parametrize("gate", [GateParams(), GateParams(per_joint=True, fast_decay=0.0),
                                  GateParams(warmup=300, warmup_decay=0.9)])
def test_a_gated_model_loaded_mid_stream_continues_bit_for_bit(tmp_path, gate):
    """The gate's statistics, pending predictions and last pose, and its model, survive a save."""
    x = _periodic(400) + 0.1 * _walk(400)
    x[150] = np.nan
    model = make_gated_llm(gate=gate)
    for f in x[:200]:
        model.step(f)
    model.save(tmp_path / "m.npz")
    twin = GatedPredictor.load(tmp_path / "m.npz")
    assert model.alpha().max() > 0.1  # the gate has something to lose
    np.testing.assert_array_equal(model.alpha(), twin.alpha())
    for t, f in enumerate(x[200:]):
        if t == 100:
            model.reset_sequence()
            twin.reset_sequence()
        a, b = model.step(f), twin.step(f)
        assert (a is None and b is None) or np.array_equal(a, b)
    np.testing.assert_array_equal(model.alpha(), twin.alpha())
