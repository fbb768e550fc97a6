"""gwr_hierarchy with predictor:=blend_hierarchy_rls: predictions flow, the status carries neuron counts
and blend weights, and SIGTERM leaves a checkpoint that loads as a blend (and not as a hierarchy)."""

import signal

import numpy as np
import pytest

from gwr_predictor.learning.checkpoint import CheckpointError
from gwr_predictor.learning.hierarchy import Hierarchy
from gwr_predictor.nodes import messages
from gwr_predictor.nodes.messages import DiagnosticArray, Float64MultiArray, JointState
from gwr_predictor.pipeline.conventions import NEURON_KEYS
from gwr_predictor.predictors.blend import BlendedPredictor
from gwr_predictor.robot.nao import ARM_JOINTS

POSE = np.array([1.2, 0.2, -1.0, -0.5, 1.2, -0.2, 1.0, 0.5])  # inside every joint limit
FRAMES = 60


@pytest.mark.ros
def test_blend_predictor_runs_publishes_and_checkpoints(ros, tmp_path):
    checkpoint = tmp_path / "blend.npz"
    probe = ros.probe
    diagnostics = probe.subscribe_diagnostics()
    preds = probe.subscribe("/predictions", Float64MultiArray)
    status = probe.subscribe("/learner_status", DiagnosticArray)
    learner = ros.start("gwr_hierarchy", params={"predictor": "blend_hierarchy_rls", "checkpoint": str(checkpoint),
                                                 "checkpoint_interval_s": 0.0, "status_period_s": 0.3,
                                                 "diagnostics_period_s": 0.5})
    ros.wait_for_node(diagnostics, "/gwr_hierarchy", timeout=60)
    pub = probe.publisher("/arm_angles", JointState)
    probe.wait_for_subscribers(pub)
    for i in range(FRAMES):  # 10 fps stamps, published without real-time pacing
        values = POSE + 0.15 * np.sin(0.3 * i + np.arange(8))
        pub.publish(messages.joint_state(100.0 + 0.1 * i, ARM_JOINTS, values))
        probe.spin_for(0.01)
    probe.spin_until(lambda: int(diagnostics["/gwr_hierarchy"].get("frames.learned", "0")) >= FRAMES, 20,
                     "every frame learned", [learner])
    probe.spin_until(lambda: len(preds) >= FRAMES - 10, 10, "predictions", [learner])
    stamp, names, p = messages.read_predictions(preds[-1])
    assert names == ARM_JOINTS and p.shape == (6, 8) and np.isfinite(p).all()
    assert abs(stamp - (100.0 + 0.1 * (FRAMES - 1))) < 1e-6
    probe.spin_until(lambda: len(status) >= 2, 10, "learner status", [learner])
    values = next(iter(messages.read_diagnostics(status[-1]).values()))
    assert all(int(values[key]) >= 2 for key in NEURON_KEYS.values())
    weights = [float(values[f"blend_weight_{m}_h6"]) for m in ("hierarchy", "rls")]
    assert min(weights) >= 0 and abs(sum(weights) - 1.0) < 1e-3

    learner.send_signal(signal.SIGTERM)
    assert learner.wait(30) == 0, learner.output()
    blend = BlendedPredictor.load(checkpoint)
    assert blend.names == ("hierarchy", "rls")
    assert blend.members["hierarchy"].frames_seen == FRAMES
    assert blend.members["rls"].updates_ > 0
    with pytest.raises(CheckpointError, match="holds a 'BlendedPredictor'"):
        Hierarchy.load(checkpoint)

    # the same checkpoint with the default predictor: refused, not moved aside
    code, out = ros.run("gwr_hierarchy", timeout=30, params={"checkpoint": str(checkpoint)}, label="wrong_kind")
    assert code == 1, out
    assert "does not fit parameter predictor='gated_llm_gwr'" in out
    assert checkpoint.exists() and not list(tmp_path.glob("blend.npz.corrupt-*"))
