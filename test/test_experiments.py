"""Every experiment runs at --quick size through the command line and writes what it promises;
splits are disjoint; `evaluate` ends with a JSON line."""

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from gwr_predictor.commands.cli import main
from gwr_predictor.default_predictor import LocalLinearParams
from gwr_predictor.evaluation.errors import EvaluationError
from gwr_predictor.evaluation.output import markdown_table, to_jsonable
from research.experiments import EXPERIMENTS, UnknownExperiment, load
from research.experiments.gate import DEFAULT as GATE_DEFAULT
from research.experiments.splits import SplitError, key, make_splits


def _seqs(patterns=("a", "b"), subjects=("s1", "s2", "s3"), reps=4):
    return [SimpleNamespace(pattern=p, subject=s, repetition=r, angles=np.zeros((5, 8)))
            for p in patterns for s in subjects for r in range(1, reps + 1)]


def test_splits_are_disjoint_and_cover_everything():
    seqs = _seqs()
    sp = make_splits(seqs, heldout_subjects=1, heldout_repetitions=1)
    sets = [set(map(key, part)) for _, part in sp.items()]
    assert all(a.isdisjoint(b) for i, a in enumerate(sets) for b in sets[i + 1:])
    assert set.union(*sets) == set(map(key, seqs))
    assert {s.subject for s in sp.heldout_subjects} == {"s3"}
    assert {s.subject for s in sp.train} == {"s1", "s2"}
    assert {s.repetition for s in sp.heldout_repetitions} == {4}
    assert sp.sizes() == {"train": 12, "heldout_repetitions": 4, "heldout_subjects": 8}
    named = make_splits(seqs, heldout_subjects=["s1"], heldout_repetitions=0)
    assert {s.subject for s in named.heldout_subjects} == {"s1"} and not named.heldout_repetitions


@pytest.mark.parametrize("kwargs", [{"heldout_subjects": 3}, {"heldout_repetitions": 4},
                                    {"heldout_subjects": ["s9"]}, {"heldout_subjects": ["s1", "s2", "s3"]}])
def test_impossible_splits_are_refused(kwargs):
    with pytest.raises(SplitError):
        make_splits(_seqs(), **kwargs)


def test_duplicate_demonstrations_are_refused():
    with pytest.raises(SplitError, match="share"):
        make_splits(_seqs() + _seqs()[:1])


def test_report_helpers():
    assert to_jsonable({"a": np.array([1.0, np.nan]), "b": (np.int64(2),)}) == {"a": [1.0, None], "b": [2]}
    with pytest.raises(EvaluationError):
        to_jsonable(object())
    assert markdown_table(["x", "y"], [[1, 0.12345]]).splitlines()[-1] == "| 1 | 0.123 |"
    with pytest.raises(UnknownExperiment):
        load("nope")


def _run(name, tmp_path, figures=True):
    out = tmp_path / name
    assert main(["experiment", name, "--quick", "--out", str(out), "--no-progress"]) == 0
    data = json.loads((out / "results.json").read_text())
    md = (out / "results.md").read_text()
    assert data["experiment"] == name and data["quick"] is True
    assert bool(data["figures"]) == figures and all((out / f).stat().st_size > 1000 for f in data["figures"])
    assert all(f in md for f in data["figures"]) and "|---" in md
    return data["results"], data["config"]


def test_every_experiment_has_a_quick_test():
    tested = {n[len("test_experiment_"):] for n in globals() if n.startswith("test_experiment_")}
    assert tested == set(EXPERIMENTS)


def test_experiment_compare(tmp_path):
    r, cfg = _run("compare", tmp_path)
    assert set(r["conditions"]) == {f"{s}/{m}" for s in ("train", "heldout_repetitions", "heldout_subjects")
                                    for m in ("frozen", "online")}
    for cond in r["conditions"].values():
        assert set(cond) == set(cfg["methods"])
        assert all(len(v["mae"]) == 6 and v["scored_frames"] > 0 for v in cond.values())
        # every method is scored on the same frames
        assert len({v["scored_frames"] for v in cond.values()}) == 1
    assert len(r["neurons"]["hierarchy"]) == 3
    # a new user's first pass over each pattern, from scratch: the default never far above holding still
    from research.experiments.common import DEFAULT, worst_ratio_to_hold

    assert set(r["from_scratch"]) == set(cfg["patterns"])
    assert all(worst_ratio_to_hold(stats, DEFAULT) <= 1.02 for stats in r["from_scratch"].values())


def test_experiment_horizon(tmp_path):
    r, cfg = _run("horizon", tmp_path)
    ev = r["evaluation"]["heldout_repetitions"]
    assert {"hierarchy_recursive", "hierarchy_vector", "hold"} <= set(ev)
    assert all(len(ev[m]["mae"]) == cfg["max_horizon"] for m in ev)
    hold = np.array(ev["hold"]["mae"])
    assert hold[-1] > hold[0]  # holding still gets worse further ahead


def test_experiment_unseen(tmp_path):
    r, cfg = _run("unseen", tmp_path)
    run = r["runs"][0]
    for m in cfg["methods"]:
        v = run["methods"][m]
        assert len(v["error"]) == cfg["presentations"] * run["frames_per_presentation"]
        assert {"slope", "intercept"} == set(v["trend"])
        assert len(v["mae_per_presentation"]) == cfg["presentations"]
    assert run["methods"]["hold"]["settling_frame"] == 0  # a method that does not learn has nothing to settle


def test_experiment_dataloss(tmp_path):
    r, cfg = _run("dataloss", tmp_path)
    levels = r["levels"]
    assert [lv["loss"] for lv in levels] == cfg["losses"]
    for lv in levels:
        assert abs(lv["kept_fraction"] - (1 - lv["loss"])) < 0.15
        assert {"online", "clean", "heldout", "coverage"} <= set(lv)
    assert levels[0]["coverage"]["hierarchy"] > levels[-1]["coverage"]["hierarchy"]


def test_experiment_incremental(tmp_path):
    r, cfg = _run("incremental", tmp_path)
    epochs = len(cfg["patterns"]) * cfg["epochs_per_pattern"]
    assert np.array(r["neurons_mean"]).shape == (epochs, 3)
    assert len(r["cpe_mean"]) == len(r["pe_mean"]) == len(r["evaluated_at"]) == epochs // cfg["eval_every"]
    assert len(r["late_growth_share"]) == 3
    f = r["forgetting"]  # each pattern scored on its own after every block: first and last entries
    assert set(f["just_learned"]) == set(f["after_all"]) == set(cfg["patterns"])
    last = r["runs"][0]["order"][-1]
    assert f["just_learned"][last] == f["after_all"][last]  # the last pattern has only one block
    assert f["max_rise"] >= f["mean_rise"]
    together = r["runs"][0]["together"]  # the reference: a fresh model trained on all patterns at once
    assert set(together["per_pattern_mse"]) == set(f["together"]) == set(cfg["patterns"])
    lost = np.mean([f["after_all"][p] - f["together"][p] for p in cfg["patterns"]])
    assert f["mean_forgotten"] == pytest.approx(lost)
    assert 0 < together["cpe"] < 1 and together["neurons"][-1] > 2
    # the reference curve: fresh models trained on the first k patterns at once, and on all of them
    curve = r["together_curve"]
    assert [c["patterns"] for c in curve] == [*cfg["together_at"], len(cfg["patterns"])]
    assert curve[-1]["together"] == f["cpe_together"]
    for c in curve:  # the sequential C.P.E. at the end of block k, from the same table
        assert c["sequential"] == r["cpe_mean"][r["evaluated_at"].index(c["patterns"] * cfg["epochs_per_pattern"])]
        assert 0 < c["together"] < 1
    # the first reference, recomputed: a fresh model on the order's first k patterns, scored on those only
    from research.experiments import common, incremental
    config = incremental.QUICK
    groups = common.by_pattern(common.demo_data(config.patterns, config.subjects, config.repetitions, 0))
    k, order = cfg["together_at"][0], r["runs"][0]["order"]
    scored = [s for p in order[:k] for s in groups[p] if s.repetition <= config.eval_repetitions]
    ref = incremental.trained_together(config, common.make_params(config.overrides), order[:k], groups, scored,
                                       0, False)
    assert r["runs"][0]["together_curve"][0] == [k, pytest.approx(ref["cpe"])]
    assert ref["cpe"] != pytest.approx(together["cpe"])  # a prefix reference differs from the full one


def test_experiment_threshold(tmp_path):
    r, cfg = _run("threshold", tmp_path)
    pts = r["points"]
    assert [p["a_t"] for p in pts] == cfg["thresholds"]
    lower = {tuple(p["neurons"][:2]) for p in pts}
    assert lower == {tuple(r["lower_layers"])}  # GWR1/GWR2 stayed frozen
    assert pts[-1]["neurons"][2] > pts[0]["neurons"][2]  # a higher a_T grows a larger P-GWR


def _delay_with_written_clips(tmp_path, monkeypatch):
    from mocap_files import fake_recording_cache

    from gwr_predictor.data import real_motion

    monkeypatch.setenv("GWR_REAL_DATA", str(fake_recording_cache(tmp_path / "cache")))
    monkeypatch.setattr(real_motion.subprocess, "run", lambda *a, **k: pytest.fail("pip must not run"))
    return _run("delay", tmp_path)


def _guarded_over_none(r, cfg) -> dict[tuple[str, float], float]:
    real = r["real"]
    out = {}
    for clip in real["clips"]:
        for delay in cfg["delays"]:
            mae = {x["rule"]: x["mae"] for x in real["runs"] if x["clip"] == clip and x["delay_s"] == delay}
            out[clip, delay] = mae["guarded_true"] / mae["none"]
    return out


def test_experiment_delay(tmp_path, monkeypatch):
    """The demonstrator's closed loop, and the real clips' (from a written recording cache): on every
    clip and delay the guarded robot tracks the person about as well as the uncompensated one or better.
    Tolerance 1 %: the written climb_0 is a 12-s noise-free wave learned from scratch (5.3 s and 16
    compensated frames scored), where one lead of 1-3 frames that beat holding on the frames before costs
    about 1 %. Its 200 ms case is the tightest: 1.0099 x (round 12, with the long snippet memory; rounds
    9-11 1.044 x, a strict xfail until then; round 8, lending no trust at the onset, 1.031 x; round 6's
    5-frame memory key 1.012 x; without the recognition switch 1.000 x). Kneel gains ~40 %."""
    r, cfg = _delay_with_written_clips(tmp_path, monkeypatch)
    runs = r["runs"]
    assert len(runs) == len(cfg["delays"]) * len(cfg["rules"]) * len(cfg["predictors"])
    for x in runs:
        if x["rule"] == "none":  # uncompensated: the robot lags by the delay plus its motor latency
            assert x["lag_s"] == pytest.approx(x["delay_s"] + 0.035, abs=0.06)
    none = {x["delay_s"]: x["mae"] for x in runs if x["rule"] == "none"}
    for x in r["oracle"]:  # a perfect predictor leaves only the motors' lag: far below uncompensated
        assert x["mae"] < 0.5 * none[x["delay_s"]] and x["lag_s"] < 0.1
    real = r["real"]
    assert real["clips"] == list(cfg["real_clips"]) and real["predictor"] == "gwr_experts"
    assert len(real["runs"]) == len(real["clips"]) * len(cfg["delays"]) * len(cfg["real_rules"])
    ratios = _guarded_over_none(r, cfg)
    assert ("climb_0", 0.2) in ratios and all(ratio <= 1.01 for ratio in ratios.values()), ratios


def test_experiment_scale(tmp_path):
    r, cfg = _run("scale", tmp_path)
    pts = r["points"]
    assert [[p["input_scale"], p["normalise_distance"]] for p in pts] == cfg["variants"]
    coarse, fine = (sum(p["neurons"]["hierarchy"]) for p in pts)
    assert fine > coarse  # a larger scale makes the same a_T insert at a smaller distance


def test_experiment_ablation(tmp_path):
    r, cfg = _run("ablation", tmp_path, figures=False)
    worst = r["worst_ratio_to_hold"]
    assert set(worst) == set(cfg["base"]["methods"])
    # the gate keeps the default and the paper's hierarchy within 2 % of hold-last at every step
    for m in ("gated_llm_gwr", "gated_hierarchy"):
        assert max(worst[m].values()) <= 1.02, worst[m]


def test_experiment_tune(tmp_path):
    r, cfg = _run("tune", tmp_path, figures=False)
    for method, n in (("gated_llm_gwr", len(cfg["rates"]) * len(cfg["insertion_scales"]) * len(cfg["neighbour_rates"])),
                      ("rls_ar", len(cfg["orders"]) * len(cfg["forgettings"])),
                      ("linear", len(cfg["linear_orders"]) * len(cfg["linear_deltas"]))):
        res = r["methods"][method]
        assert len(res["grid"]) == n
        best = min(g["heldout_repetitions"]["mae"] for g in res["grid"])
        tie = {"gated_llm_gwr": cfg["tie"], "linear": cfg["linear_tie"]}.get(method, 0.0)  # held-out repetitions only
        assert best <= res["chosen_scores"]["heldout_repetitions"]["mae"] <= best * (1 + tie)
    stage = r["methods"]["gated_llm_gwr:recruitment"]  # at the chosen point, each recruit_surprise
    assert stage["at"] == r["methods"]["gated_llm_gwr"]["chosen"]
    assert [g["settings"]["recruit_surprise"] for g in stage["grid"]] == list(cfg["recruit_surprises"])
    surprise = LocalLinearParams().recruit_surprise
    default = next(g for g in stage["grid"] if g["settings"]["recruit_surprise"] == surprise)
    for split in ("heldout_repetitions", "heldout_subjects"):  # the first stage ran with the library default
        assert default[split] == r["methods"]["gated_llm_gwr"]["chosen_scores"][split]
    maes = {g["settings"]["recruit_surprise"]: g["heldout_repetitions"]["mae"] for g in stage["grid"]}
    eager = [v for v in maes if v > 0 and maes[v] <= min(maes.values()) * (1 + cfg["tie"])]
    assert stage["chosen"]["recruit_surprise"] == (min(eager) if eager else 0.0)


def test_tune_reads_only_the_demonstrators_tuning_recordings(monkeypatch):
    """Settings are chosen on demonstrator recordings no reported figure uses, whatever `--seed` is."""
    from research.experiments import common, tune

    seeds = []

    def demo_data(patterns, subjects, repetitions, seed):
        seeds.append(seed)
        raise RuntimeError("stop here")

    monkeypatch.setattr(common, "demo_data", demo_data)
    for seed in (0, 1, 2):
        with pytest.raises(RuntimeError, match="stop here"):
            tune.measure(tune.QUICK, seed, progress=False)
    assert seeds == [tune.TUNING_DATA_SEED] * 3
    assert tune.TUNING_DATA_SEED not in (0, 1, 2)  # the seeds of the reported demonstrator results


def test_tune_choice_breaks_near_ties_towards_the_finer_insertion_threshold():
    from research.experiments.tune import choose

    rows = [{"settings": {"insertion_scale": i, "rate": r}, "heldout_repetitions": {"mae": m}}
            for i, r, m in ((1.5, 0.1, 0.1278), (1.0, 0.1, 0.1281), (1.0, 0.2, 0.1284), (0.5, 0.1, 0.1300))]
    assert choose(rows, 0.0)["settings"] == {"insertion_scale": 1.5, "rate": 0.1}  # plain lowest MAE
    assert choose(rows, 0.005)["settings"] == {"insertion_scale": 1.0, "rate": 0.1}  # 0.5 is 1.7 % off: out
    assert choose(rows, 0.02)["settings"] == {"insertion_scale": 0.5, "rate": 0.1}


def test_tune_breaks_the_linear_models_near_ties_towards_a_prior_variance_of_one():
    from research.experiments.tune import _prior_near_one, choose

    rows = [{"settings": {"order": 12, "delta": d}, "heldout_repetitions": {"mae": m}}
            for d, m in ((0.1, 0.171285), (1.0, 0.171308), (10.0, 0.171321), (0.01, 0.1712))]
    assert choose(rows, 0.0)["settings"]["delta"] == 0.01
    assert choose(rows, 0.0001, _prior_near_one)["settings"]["delta"] == 0.01  # 0.01 % of 0.1712: only itself
    assert choose(rows, 0.001, _prior_near_one)["settings"]["delta"] == 1.0


def test_tune_recruitment_stage_takes_the_most_eager_recruitment_within_the_tie():
    from research.experiments.tune import _most_eager_recruitment, choose

    rows = [{"settings": {"recruit_surprise": v}, "heldout_repetitions": {"mae": m}}
            for v, m in ((0.0, 0.1280), (6.0, 0.1300), (9.0, 0.1283), (12.0, 0.1279), (16.0, 0.1280))]
    assert choose(rows, 0.0, _most_eager_recruitment)["settings"] == {"recruit_surprise": 12.0}
    assert choose(rows, 0.005, _most_eager_recruitment)["settings"] == {"recruit_surprise": 9.0}  # 6 is 1.6 % off
    assert choose(rows[:1] + rows[1:2], 0.005, _most_eager_recruitment)["settings"] == {"recruit_surprise": 0.0}


def test_experiment_real(tmp_path, monkeypatch):
    """On a written recording cache: every clip one pass from scratch, the climbing takes left out in
    turn, with the k-NN reference; nothing is downloaded."""
    from mocap_files import fake_recording_cache

    from gwr_predictor.data import real_motion

    monkeypatch.setenv("GWR_REAL_DATA", str(fake_recording_cache(tmp_path / "cache")))
    monkeypatch.setattr(real_motion.subprocess, "run", lambda *a, **k: pytest.fail("pip must not run"))
    r, cfg = _run("real", tmp_path)
    assert [c["name"] for c in r["clips"]] == list(cfg["clips"])
    assert r["default_method"] in r["one_pass"]["pooled"]
    for per in r["one_pass"]["per_clip"].values():
        assert len({v["scored_frames"] for v in per.values()}) == 1  # every method on the same frames
    loo = r["leave_one_take_out"]
    assert sorted(loo["per_take"]) == ["climb_0", "climb_1", "climb_4"]
    assert set(loo["pooled"]) == {*cfg["methods"], r["default_method"], "knn"}  # the default is always scored
    # the takes are the same motion: the other takes hold this one's future (2 of the 5 neighbours are
    # exact copies), so k-NN beats holding by far
    assert loo["pooled"]["knn"]["mae"][-1] < 0.5 * loo["pooled"]["hold"]["mae"][-1]
    hold = loo["pooled"]["hold"]["mae"]
    assert hold[-1] > hold[0]


def test_experiment_repeats(tmp_path):
    """Demonstrator stand-ins (no download); the full checks are in test_repeats.py."""
    r, cfg = _run("repeats", tmp_path)
    assert r["default_method"] in r["pooled"] and len(r["learning_curve"]["hold"]) == cfg["repetitions"]


def test_experiment_calibration(tmp_path):
    """Demonstrator splits and repeated demonstrator stand-ins (no download): every method that states an
    interval is scored per condition and step, near the stated share; the compensator option is measured."""
    r, cfg = _run("calibration", tmp_path)
    assert r["nominal"] == 0.8 and set(r["methods"]) == {*cfg["methods"], r["default_method"]}
    for split in ("heldout_repetitions", "heldout_subjects"):
        for learn in ("frozen", "online"):
            per = r["demonstrator"][f"{split}/{learn}"]
            assert set(per) == set(r["methods"])
            assert all(abs(c - 0.8) < 0.1 for s in per.values() for c in s["coverage"])
    per_performance = r["repeated"]["per_performance"][r["default_method"]]
    assert len(per_performance) == cfg["performances"] and all(s["n"][-1] > 0 for s in per_performance)
    loop = r["repeated"]["closed_loop"]
    assert {x["spread_shrink"] for x in loop} == {0.0, *cfg["shrinks"]}


def test_experiment_gate(tmp_path):
    """Every variant replays the same recorded model outputs: the ungated replay is the model itself,
    and the default gate stays within the band on every pattern learned from scratch."""
    r, cfg = _run("gate", tmp_path, figures=False)
    assert set(r["ratio_to_hold"]) == set(cfg["variants"])
    default = r["ratio_to_hold"][GATE_DEFAULT]
    assert all(max(v["mae"]) <= 1.02 for name, v in default.items() if "from scratch" in name)
    ungated = r["ratio_to_hold"]["ungated model"]
    assert ungated.keys() == default.keys() and any(ungated[n] != default[n] for n in ungated)


def test_evaluate_prints_a_json_last_line(tmp_path, capsys):
    from gwr_predictor.data.angle_files import save_angles_csv
    from gwr_predictor.data.datasets import demo_angle_sequences

    files = []
    for s in demo_angle_sequences(["wave_one"], 1, 2):
        files.append(str(save_angles_csv(tmp_path / f"{s.name}.csv", s.t, s.angles)))
    assert main(["evaluate", *files, "--passes", "2", "--horizon", "4", "--no-progress"]) == 0
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert {"horizon", "mae_rad", "frames", "neurons"} <= set(last)
    assert last["horizon"] == 4
    assert set(last["mae_rad"]) == {"hold", "const_velocity", "rls_ar", "hierarchy", "gwr_experts"}
    assert last["default_method"] == "gwr_experts"
    assert all(len(v) == 4 for v in last["mae_rad"].values())
    assert last["frames"] == 2 * sum(len(s) for s in demo_angle_sequences(["wave_one"], 1, 2))
    assert len(last["neurons"]["hierarchy"]) == 3
    # the methods that state an interval: its share, and per step how often it held the truth and how wide it was
    assert last["interval_nominal"] == 0.8
    assert set(last["interval_coverage"]) == set(last["interval_width_rad"]) == {"hold", "rls_ar", "gwr_experts"}
    for m in last["interval_coverage"]:
        assert len(last["interval_coverage"][m]) == len(last["interval_width_rad"][m]) == 4
        assert all(0.6 < c < 0.95 for c in last["interval_coverage"][m])  # about the stated share, two short passes
        width = last["interval_width_rad"][m]
        assert 0.0 < width[0] and all(np.diff(width) > 0)  # wider the further ahead


def test_evaluate_predicts_as_far_as_it_scores(tmp_path, capsys):
    """--horizon builds every model for that many frames (600 ms at 30 fps is 18), not only the scoring."""
    from gwr_predictor.data.angle_files import save_angles_csv
    from gwr_predictor.data.datasets import demo_angle_sequences

    s = demo_angle_sequences(["wave_one"], 1, 1)[0]
    csv = str(save_angles_csv(tmp_path / "wave.csv", s.t, s.angles))
    assert main(["evaluate", csv, "--horizon", "18", "--methods", "hold,rls_ar", "--no-progress"]) == 0
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert last["horizon"] == 18 and set(last["mae_rad"]) == {"hold", "rls_ar", "gwr_experts"}
    assert all(len(v) == 18 for v in last["mae_rad"].values())
    assert main(["evaluate", csv, "--horizon", "18", "--param", "horizon=12", "--no-progress"]) == 2
    assert "--horizon 18 and --param horizon=12 disagree" in capsys.readouterr().err


def test_evaluate_reports_an_unreadable_file(tmp_path, capsys):
    bad = Path(tmp_path / "bad.csv")
    bad.write_text("hello,world\n1,2\n")
    assert main(["evaluate", str(bad), "--no-progress"]) == 2
    assert "bad.csv" in capsys.readouterr().err
