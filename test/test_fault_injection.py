"""Fault injection on the running pipeline: every node is killed with SIGKILL (a crash: no signal
handler, no final hook) and started again, in turn, while a tracker with one-second dropouts feeds
it. After each restart messages flow downstream again; the learner resumes from its periodic
checkpoint (losing at most one interval); the recorder's bag from before its crash is recovered and
the new one reads back whole."""

import signal

import numpy as np
import pytest

from gwr_predictor.default_predictor.gate import inner_model
from gwr_predictor.nodes import messages
from gwr_predictor.nodes.messages import DiagnosticArray, Float64MultiArray, JointState
from gwr_predictor.pipeline import bag_messages, bag_reader, bag_recovery
from gwr_predictor.pipeline.conventions import NEURON_KEYS
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.registry import DEFAULT_PREDICTOR, load_predictor

FAST = {"diagnostics_period_s": 0.5}
CHECKPOINT_INTERVAL_S = 2.0
STREAMS = ("skeleton", "arm_angles", "predictions", "joint_commands", "joint_states")
FLOW = 4  # messages that must arrive from a restarted node (or downstream of it)


def learner_values(msg) -> dict[str, str]:
    return next(iter(messages.read_diagnostics(msg).values()))


def layer_neurons(values: dict[str, str]) -> tuple[int, ...]:
    """Neurons of the layers the learner reports (the default predictor: its P-GWR only)."""
    return tuple(int(values[NEURON_KEYS[layer]]) for layer in ("gwr1", "gwr2", "pgwr") if NEURON_KEYS[layer] in values)


@pytest.mark.ros
@pytest.mark.slow
def test_each_node_killed_and_restarted_the_pipeline_recovers_and_keeps_what_it_learned(ros, tmp_path):
    probe = ros.probe
    diagnostics = probe.subscribe_diagnostics()  # the latest status per node
    all_diagnostics = probe.subscribe("/diagnostics", DiagnosticArray)  # every status, deep queue
    got = {topic: probe.subscribe(f"/{topic}", msg_type) for topic, msg_type in (
        ("skeleton", Float64MultiArray), ("arm_angles", JointState), ("predictions", Float64MultiArray),
        ("joint_commands", JointState), ("joint_states", JointState), ("learner_status", DiagnosticArray))}
    checkpoint = tmp_path / "model.npz"
    params = {
        "bag_recorder": {**FAST, "path": str(tmp_path / "bag1"), "flush_period_s": 0.5},
        "nao_sim": {**FAST, "backend": "kinematic"},
        "delay_compensator": FAST,
        "arm_predictor": {**FAST, "checkpoint": str(checkpoint), "checkpoint_interval_s": CHECKPOINT_INTERVAL_S,
                          "status_period_s": 0.25},
        "angle_extractor": FAST,
        # the tracker loses 30 % of the frames in 1 s chunks: dropouts of seconds all along
        "skeleton_source": {**FAST, "patterns": ["wave_both", "raise_front_both"], "loop": True, "pause_s": 0.7,
                            "drop_fraction": 0.3, "drop_chunk_s": 1.0, "seed": 3, "wait_for_subscribers": 3},
    }
    procs = {name: ros.start(name, params=p) for name, p in params.items()}
    everyone = list(procs.values())
    probe.spin_until(lambda: len(got["predictions"]) >= 10, 60, "the pipeline to predict", everyone)

    def restart(name: str, downstream: tuple[str, ...]) -> None:
        """SIGKILL `name`, let in-flight messages drain, start it again; the topics must flow again."""
        ros.kill(procs[name])
        probe.spin_for(0.3)
        before = {topic: len(got[topic]) for topic in downstream}
        procs[name] = ros.restart(procs[name], f"{name}_restarted")
        everyone.append(procs[name])
        ros.wait_for_log(procs[name], "]: ready")
        for topic in downstream:
            # on a timeout, the restarted node's latest counters say which of its inputs stopped
            probe.spin_until(lambda topic=topic: len(got[topic]) >= before[topic] + FLOW, 30,
                             lambda topic=topic: f"/{topic} to flow again after {name} restarted (received "
                             f"{len(got[topic]) - before[topic]}); its latest diagnostics: "
                             f"{diagnostics.get('/' + name)}", everyone)

    restart("skeleton_source", ("skeleton", "arm_angles", "predictions"))
    restart("angle_extractor", ("arm_angles", "predictions"))

    # --- the learner: crash, resume from the last periodic checkpoint --------------------------------
    probe.spin_until(lambda: checkpoint.exists(), 30, "the first periodic checkpoint", everyone)
    # a learner status at least one interval (+ margin) before the crash: the checkpoint has at least that
    statuses = got["learner_status"]
    probe.spin_for(CHECKPOINT_INTERVAL_S + 1.0)
    frames_well_before = int(learner_values(statuses[-1])["frames"])
    probe.spin_for(CHECKPOINT_INTERVAL_S + 1.0)
    frames_at_kill = int(learner_values(statuses[-1])["frames"])
    ros.kill(procs["arm_predictor"])
    saved = load_predictor(DEFAULT_PREDICTOR, checkpoint)  # a SIGKILL never leaves a half-written checkpoint
    saved_frames = inner_model(saved).frames_seen
    assert frames_well_before <= saved_frames <= frames_at_kill + 10
    n_status = len(statuses)
    restart("arm_predictor", ("predictions", "learner_status"))
    log = procs["arm_predictor"].output()
    assert (f"loaded {checkpoint} ({DEFAULT_PREDICTOR}): {saved_frames} frames seen, "
            f"neurons {saved.neuron_counts}") in log
    after = learner_values(statuses[n_status])
    assert int(after["frames"]) >= saved_frames
    assert all(a >= b for a, b in zip(layer_neurons(after), saved.neuron_counts, strict=True)), \
        (layer_neurons(after), saved.neuron_counts)

    restart("delay_compensator", ("joint_commands",))
    restart("nao_sim", ("joint_states",))

    # --- the recorder: its bag up to the last flush is recovered, a new one starts --------------------
    on_disk = int(diagnostics["/bag_recorder"]["messages.on_disk"])
    assert on_disk > 0
    ros.kill(procs["bag_recorder"])
    with pytest.raises(PipelineError, match="recover_bag"):
        bag_reader.bag_info(tmp_path / "bag1")
    recovered = bag_recovery.recover_bag(tmp_path / "bag1")
    assert recovered.message_count >= on_disk
    assert all(recovered.topics[f"/{t}"][1] > 0 for t in ("skeleton", "arm_angles", "predictions", "joint_states"))
    n_diag = len(all_diagnostics)
    procs["bag_recorder"] = ros.start("bag_recorder", params={**params["bag_recorder"], "path": str(tmp_path / "bag2")},
                                      label="bag_recorder_restarted")
    everyone.append(procs["bag_recorder"])
    ros.wait_for_log(procs["bag_recorder"], "]: ready")

    def new_recorder_records_every_stream() -> bool:
        statuses = [messages.read_diagnostics(m).get("/bag_recorder", {}) for m in all_diagnostics[n_diag:]]
        return any(all(int(v.get(f"recorded./{t}", "0")) >= FLOW for t in STREAMS) for v in statuses)

    def recorded_so_far() -> str:
        latest = {}
        for m in all_diagnostics[n_diag:]:
            latest.update(messages.read_diagnostics(m).get("/bag_recorder", {}))
        return ("the restarted recorder to record every stream; recorded so far: "
                + ", ".join(f"{t} {latest.get(f'recorded./{t}', '0')}" for t in STREAMS))

    probe.spin_until(new_recorder_records_every_stream, 30, recorded_so_far, everyone)

    # --- learning went on through the dropouts and the crashes -----------------------------------
    source = diagnostics["/skeleton_source"]
    assert int(source["frames.dropped_by_fault_injection"]) > 0
    learned_before_stop = int(diagnostics["/arm_predictor"]["frames.learned"])
    assert learned_before_stop > 0
    for name in ("skeleton_source", "angle_extractor", "arm_predictor", "delay_compensator", "nao_sim",
                 "bag_recorder"):
        code, killed = procs[name].stop(signal.SIGINT)
        assert code == 0 and not killed, procs[name].output()[-2000:]
    final = inner_model(load_predictor(DEFAULT_PREDICTOR, checkpoint))
    assert final.frames_seen >= saved_frames + learned_before_stop
    info = bag_reader.bag_info(tmp_path / "bag2")  # closed properly: no recovery needed
    assert all(info.topics[f"/{t}"][1] >= FLOW for t in STREAMS), info.topics
    stamps = [m.msg.header.stamp for m in bag_reader.read_bag(tmp_path / "bag2", ["/arm_angles"])]
    assert np.all(np.diff([bag_messages.stamp_seconds(s) for s in stamps]) > 0)
