"""arm_predictor: learns the person's arm movements online and predicts the next `horizon` frames.

Every accepted JointState of the arm angles is one step of the chosen predictor (learn, then predict,
as in the paper: training never stops). Each step publishes P(t+1..t+h) on `predictions` (stamped t)
and the h-step prediction as a JointState on `predicted_angles` (stamped t + h * frame period);
for standard tools also as a `trajectory_msgs/JointTrajectory` on `predicted_trajectory` (stamped t,
points at t+1..t+h) and the predicted arm at t+h as a MarkerArray on `predicted_arm_markers`
(frame `torso`, over the robot model, stamped with the node clock when published). A predictor that
states an interval with every prediction (the default) publishes it first, on `prediction_interval`
(stamped t like the predictions it belongs to, its share in the layout), and with the standard outputs
its bounds as two more JointTrajectory messages beside `predicted_trajectory`:
`predicted_trajectory_lower` and `predicted_trajectory_upper` (same stamp, same point times).
Missing frames inside a sequence are fed as missing samples, a gap longer than `max_gap_s` ends
the sequence. The model is loaded from `checkpoint` at start and saved there atomically every
`checkpoint_interval_s` and at shutdown; an unreadable checkpoint is moved aside, never overwritten.
A periodic save copies the model between two frames and writes the copy on a thread of its own
(`learning/saver.py`), so no frame waits for the disk; the final save at shutdown waits for it.
The node locks its checkpoint (`.<name>.lock` beside it) while it runs: a second learner on the same
file refuses to start instead of overwriting the first one's learning.

`predictor` picks the model: `gwr_experts` (the default: the local-linear P-GWR, two snippet memories
and two linear models, each behind a confidence gate, weighted per horizon step by their recent errors,
see gwr_predictor/default_predictor/; its status carries each expert's weight at the last step,
`expert_weight_<expert>_h6`, the network's read-out mix, `mix_weight_local_h6` /
`mix_weight_global_h6`, and the snippets each memory holds, `snippets_<memory>`, and has replaced
at its capacity, `snippets_replaced_<memory>`), `gated_llm_gwr` (that network alone behind one
gate) or `hierarchy` (the paper). The node declares the chosen predictor's own settings and no other's, named
`<predictor>.<setting>` (`gwr_experts.memory.k`, `hierarchy.gwr1.eps_b`): one params file can hold a
section for each (config/arm_predictor.yaml does), the others' are ignored without a warning.
A checkpoint of another kind than `predictor` stops the node (it is neither used nor moved aside).

The executable `gwr_hierarchy` (the node's old name) starts the same node named `gwr_hierarchy`, with a
deprecation warning; it goes in the next release. Either name warns about a params file whose
section names only the other one, which rcl would skip without a word.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import rclpy

from gwr_predictor import registry
from gwr_predictor.default_predictor import DefaultPredictor
from gwr_predictor.default_predictor.gate import GatedPredictor, inner_model
from gwr_predictor.learning.blas import blas_threads
from gwr_predictor.learning.checkpoint import (
    CheckpointLock,
    check_checkpoint_place,
    remove_stale_temp_files,
    set_aside,
)
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.hierarchy import Hierarchy
from gwr_predictor.learning.params import HIERARCHY_SPECS, HierarchyParams
from gwr_predictor.learning.protocol import Spreading
from gwr_predictor.learning.saver import CheckpointSaver
from gwr_predictor.parameters.spec import ParameterError, ParamSpec
from gwr_predictor.pipeline import conventions, params_file
from gwr_predictor.pipeline.input_rules import missing_frames
from gwr_predictor.pipeline.markers import ROBOT_FRAME, arm_figure
from gwr_predictor.pipeline.trajectory import prediction_trajectory
from gwr_predictor.registry import DEFAULT_PREDICTOR, learner_names, load_predictor, make_predictor
from gwr_predictor.robot.nao import ARM_JOINTS

from . import messages, standard_messages
from .exits import NodeFatalError
from .pipeline_node import PipelineNode
from .qos import status_qos, stream_qos
from .runner import run_node

PARAMS = (
    ParamSpec("predictor", DEFAULT_PREDICTOR, "model: 'gwr_experts' (default: the local-linear P-GWR, two "
              "snippet memories and two linear models, each gated unless the memory recognises the motion, weighted by "
              "recent error), 'gated_llm_gwr' (the network alone, gated) or 'hierarchy' (GWR1 -> GWR2 -> P-GWR, "
              "the paper); the node declares the chosen one's settings as '<predictor>.<name>'",
              choices=learner_names()),
    dataclasses.replace(HIERARCHY_SPECS["horizon"], description="frames predicted ahead (6 at 10 fps = 600 ms)"),
    ParamSpec("seed", 0, "seed of the networks' initial random neurons", 0, 2**31 - 1),
    ParamSpec("learn", True, "learn from every frame (false: predict with the networks as they are)", live=True),
    ParamSpec("frame_period_s", 1.0 / conventions.ANGLE_FPS, "spacing of the angle frames (s)", 0.001, 10.0),
    ParamSpec("max_gap_s", conventions.MAX_GAP_S, "a stamp gap larger than this ends the sequence", 0.0, 3600.0),
    ParamSpec("checkpoint", "", "model file: loaded at start if it exists, saved periodically and at shutdown; "
          "empty: none"),
    ParamSpec("checkpoint_interval_s", 60.0, "save the checkpoint this often (s); 0: only at shutdown", 0.0, 86400.0,
              live=True),
    ParamSpec("standard_outputs", True, "also publish predicted_trajectory (JointTrajectory) and "
              "predicted_arm_markers (MarkerArray) for viewers and controllers"),
    ParamSpec("status_period_s", 1.0, "period of the learner status (neurons, errors) (s)", 0.05, 3600.0),
)


#: How long the final save waits for a background write still in progress (a stuck disk must not stop shutdown).
SAVE_WAIT_S = 60.0


def predictor_specs(name: str) -> tuple[ParamSpec, ...]:
    """The settings of product predictor `name` as this node declares them: '<name>.<setting>'."""
    return tuple(dataclasses.replace(s, name=f"{name}.{s.name}") for s in registry.entry(name).settings())


class ArmPredictorNode(PipelineNode):
    NODE_NAME = conventions.LEARNER_NODE
    #: The learner's other name: a params file with a section for it only is warned about at start.
    OTHER_NAME = conventions.DEPRECATED_LEARNER_NODE

    def __init__(self) -> None:
        super().__init__(self.NODE_NAME, PARAMS)
        p = self.params
        #: The chosen predictor's settings (its own names) plus the node's horizon and the arm's joints.
        self.settings = registry.settings_from_parameters(p["predictor"], p, len(ARM_JOINTS))
        self.checkpoint = Path(p["checkpoint"]) if p["checkpoint"] else None
        self.checkpoint_lock = self.claim_checkpoint(self.checkpoint) if self.checkpoint is not None else None
        try:
            self.model = self.load_or_create(self.settings)
        except BaseException:
            self.release_checkpoint()
            raise
        self.gwr = inner_model(self.model)  # the GWR learner (behind the gate, if any)
        self.horizon = self.model.horizon
        self.angles = self.arm_check("arm_angles")
        self.step_times: list[float] = []
        self.step_max = 0.0
        self.pred_pub = self.create_publisher(messages.Float64MultiArray, conventions.TOPIC_PREDICTIONS, stream_qos())
        self.pred_angles_pub = self.create_publisher(messages.JointState, conventions.TOPIC_PREDICTED_ANGLES,
                                                     stream_qos())
        self.interval_pubs = self.make_interval_publishers() if isinstance(self.model, Spreading) else None
        if p["standard_outputs"]:
            self.trajectory_pub = self.create_publisher(standard_messages.JointTrajectory,
                                                        conventions.TOPIC_PREDICTED_TRAJECTORY, stream_qos())
            self.arm_markers_pub = self.create_publisher(standard_messages.MarkerArray,
                                                         conventions.TOPIC_PREDICTED_ARM_MARKERS, stream_qos())
        self.status_pub = self.create_publisher(messages.DiagnosticArray, conventions.TOPIC_LEARNER_STATUS,
                                                status_qos())
        self.create_subscription(messages.JointState, conventions.TOPIC_ANGLES, self.on_angles, stream_qos())
        self.create_timer(p["status_period_s"], self.publish_status)
        self.saver = CheckpointSaver(self.checkpoint) if self.checkpoint is not None else None
        self.save_times: dict[str, float] = {}  # the last save's snapshot and write (ms), its size (MB)
        self.checkpoint_timer = None
        self.schedule_checkpoints(p["checkpoint_interval_s"])
        self.warn_about_other_name()

    def claim_checkpoint(self, path: Path) -> CheckpointLock:
        """Check the place, lock it for this node's life (a second learner on the path refuses to
        start), then remove temporary files of interrupted saves (only ours to remove once locked)."""
        try:
            check_checkpoint_place(path)
            lock = CheckpointLock(path)
        except LearningError as exc:
            raise NodeFatalError(f"parameter 'checkpoint': {exc}") from None
        removed = remove_stale_temp_files(path)
        if removed:
            self.counters.count("checkpoint.stale_temp_removed", len(removed))
            self.get_logger().info(f"removed {len(removed)} temporary files of interrupted saves: "
                                   + ", ".join(str(f) for f in removed))
        return lock

    def release_checkpoint(self) -> None:
        if self.checkpoint_lock is not None:
            self.checkpoint_lock.release()

    def schedule_checkpoints(self, interval_s: float) -> None:
        """(Re)start the periodic save; 0 (or no checkpoint path): only at shutdown."""
        if self.checkpoint_timer is not None:
            self.destroy_timer(self.checkpoint_timer)
            self.checkpoint_timer = None
        if self.checkpoint is not None and interval_s > 0:
            self.checkpoint_timer = self.create_timer(interval_s, self.save_in_background)

    def chosen_specs(self, params: dict[str, Any]) -> Sequence[ParamSpec]:
        """The chosen predictor's own settings, and only those."""
        return predictor_specs(params["predictor"])

    def other_options_parameters(self) -> set[str]:
        return {s.name for name in learner_names() for s in predictor_specs(name)}

    def on_live_parameter(self, name: str, value: object) -> None:
        """`learn` is read at every frame; a new checkpoint interval restarts the save timer."""
        if name == "checkpoint_interval_s":
            self.schedule_checkpoints(float(value))

    def create(self, settings: dict[str, Any]) -> Hierarchy | GatedPredictor | DefaultPredictor:
        try:
            return make_predictor(self.params["predictor"], settings, seed=self.params["seed"])
        except ValueError as exc:  # a setting this predictor cannot take (ParameterError and the like)
            raise ParameterError(f"predictor {self.params['predictor']!r}: {exc}") from None

    def load_or_create(self, settings: dict[str, Any]) -> Hierarchy | GatedPredictor | DefaultPredictor:
        """The checkpoint's model if there is a readable one, else a fresh one with `settings`."""
        path = self.checkpoint
        if path is None or not path.exists():
            return self.create(settings)
        try:
            model = load_predictor(self.params["predictor"], path)
        except Exception as exc:  # whatever an unreadable file raises: set it aside, start fresh
            if isinstance(exc, LearningError) and exc.kind_mismatch:  # a sound file of another predictor
                raise NodeFatalError(f"checkpoint {path} does not fit parameter predictor="
                                     f"{self.params['predictor']!r} ({exc}); set 'predictor' to match it or use "
                                     "another checkpoint path") from None
            if not (isinstance(exc, LearningError) and exc.source is not None):
                exc = LearningError(f"{path}: not a readable checkpoint: {type(exc).__name__}: {exc}", source=path)
            try:
                aside = set_aside(path)
            except OSError as move_exc:
                raise NodeFatalError(f"unreadable checkpoint {path} ({exc}) could not be moved aside: {move_exc}; "
                                     "not starting, to avoid overwriting it") from None
            self.get_logger().error(f"unreadable checkpoint moved to {aside}; starting a fresh model: {exc}")
            self.counters.count("checkpoint.corrupt_moved_aside")
            return self.create(settings)
        learner = inner_model(model)
        differ = {}
        if isinstance(learner.params, HierarchyParams):  # the hierarchy's settings are its flat parameters
            saved, given = learner.params.to_flat(), HierarchyParams.from_flat(settings).to_flat()
            differ = {k: (v, saved[k]) for k, v in given.items() if k in saved and saved[k] != v}
        if differ:
            self.get_logger().warning("the checkpoint's learning parameters are used, not these node parameters: "
                                      + ", ".join(f"{k}={a} (checkpoint {b})" for k, (a, b) in differ.items()))
        self.get_logger().info(f"loaded {path} ({self.params['predictor']}): {learner.frames_seen} "
                               f"frames seen, neurons {model.neuron_counts}")
        return model

    def on_angles(self, msg: messages.JointState) -> None:
        """One frame: bridge a short gap with missing samples or end the sequence, learn, predict, publish."""
        last = self.angles.last_stamp
        accepted = self.angles.accept(*messages.joint_state_fields(msg))
        if accepted is None:
            return
        stamp, angles = accepted
        if last is not None:
            self.handle_gap(stamp - last)
        start = time.perf_counter()
        try:
            predictions = self.model.step(angles, learn=self.params["learn"])
        except MemoryError:  # a network that cannot grow: what it learned stays, the next frame may fit
            self.counters.count("frames.out_of_memory")
            self.counters.warn_throttled("frames.out_of_memory", "out of memory while learning a frame: frame "
                                         "skipped, the model keeps what it learned (give its layers a max_neurons)")
            return
        elapsed = time.perf_counter() - start
        self.step_times.append(elapsed)
        self.step_max = max(self.step_max, elapsed)
        self.counters.count("frames.learned" if self.params["learn"] else "frames.seen")
        if predictions is None:
            return
        if self.interval_pubs is not None:  # first: a compensator using it then has it with the predictions
            self.publish_interval(stamp)
        self.pred_pub.publish(messages.predictions_msg(stamp, predictions))
        self.pred_angles_pub.publish(messages.joint_state(stamp + self.horizon * self.params["frame_period_s"],
                                                          ARM_JOINTS, predictions[-1]))
        if self.params["standard_outputs"]:
            trajectory = prediction_trajectory(predictions, self.params["frame_period_s"])
            self.trajectory_pub.publish(standard_messages.joint_trajectory(stamp, ARM_JOINTS, trajectory))
            # stamped now, not at t+h: a viewer transforms markers with the TF at their stamp
            self.arm_markers_pub.publish(standard_messages.figure_markers(
                self.now_s(), ROBOT_FRAME, "predicted_arm",
                arm_figure(predictions[-1]), (1.0, 0.5, 0.1, 0.9), lifetime_s=1.0, joint_size=0.025,
                line_width=0.015))
        self.counters.count("predictions.published")

    def make_interval_publishers(self) -> tuple[Any, ...]:
        """The interval's custom array, and its JointTrajectory twins (lower, upper) with the standard outputs."""
        pubs = [self.create_publisher(messages.Float64MultiArray, conventions.TOPIC_PREDICTION_INTERVAL, stream_qos())]
        if self.params["standard_outputs"]:
            pubs += [self.create_publisher(standard_messages.JointTrajectory, topic, stream_qos()) for topic in
                     (conventions.TOPIC_PREDICTED_TRAJECTORY_LOWER, conventions.TOPIC_PREDICTED_TRAJECTORY_UPPER)]
        return tuple(pubs)

    def publish_interval(self, stamp: float) -> None:
        """The interval the model stated with its last prediction (made at frame `stamp`)."""
        assert self.interval_pubs is not None
        stated = self.model.interval()  # type: ignore[union-attr]
        if stated is None:
            return
        self.interval_pubs[0].publish(messages.interval_msg(stamp, *stated, self.model.interval_nominal))
        for pub, bound in zip(self.interval_pubs[1:], stated, strict=False):
            trajectory = prediction_trajectory(bound, self.params["frame_period_s"])
            pub.publish(standard_messages.joint_trajectory(stamp, ARM_JOINTS, trajectory))

    def handle_gap(self, dt: float) -> None:
        """Missing frames (dt of several periods) keep the learner's step count in time; a long gap resets."""
        missing = missing_frames(dt, self.params["frame_period_s"], self.params["max_gap_s"])
        if missing is None:
            self.model.reset_sequence()
            self.counters.count("sequences.reset_on_gap")
            return
        for _ in range(missing):
            self.model.step(None)
        if missing > 0:
            self.counters.count("frames.missing", missing)

    def publish_status(self) -> None:
        """Neurons per layer, errors and step times as a DiagnosticArray (about 1 Hz)."""
        errors = self.gwr.errors()
        values: dict[str, object] = {conventions.NEURON_KEYS[k]: v for k, v in errors["neurons"].items()}
        for key in ("frames", "missing", "sequences", "predictions"):
            values[key] = errors[key]
        if "recruited" in errors:  # the default's neurons recruited for surprising pairs
            values["neurons_recruited"] = errors["recruited"]
        if "evicted" in errors:  # neurons removed at the network's bound to make room
            values["neurons_evicted"] = errors["evicted"]
        if "recognised_frames" in errors:  # the default's frames predicted by its experts ungated
            values["frames_recognised"] = errors["recognised_frames"]
        values["pe_mean_mse"] = float(errors["pe_mean"])
        values["cpe_mean_mse"] = float(errors["cpe_mean"])
        values[f"cpe_h{self.horizon}_mse"] = float(errors["cpe"][-1])
        for name, w in errors.get("mix_weights", {}).items():  # the network's local / global read-outs
            values[f"mix_weight_{name}_h{self.horizon}"] = float(w[-1])
        for name, w in errors.get("expert_weights", {}).items():  # the default's experts
            values[f"expert_weight_{name}_h{self.horizon}"] = float(w[-1])
        for name, held in errors.get("snippets", {}).items():  # the default's snippet memories
            values[f"snippets_{name}"] = held["stored"]
            values[f"snippets_replaced_{name}"] = held["replaced"]
        self.collect_saves()
        values.update(self.save_times)
        values["blas_threads"] = blas_threads()
        times = self.step_times or [0.0]
        values["step_ms_mean"] = 1e3 * float(np.mean(times))
        values["step_ms_max"] = 1e3 * self.step_max  # both since the last status
        self.step_times, self.step_max = [], 0.0
        status = messages.diagnostic_status(f"{self.get_fully_qualified_name()}/{conventions.LEARNER_STATUS_NAME}",
                                            values, "learning" if self.params["learn"] else "predicting only")
        self.status_pub.publish(messages.diagnostic_array(self.now_s(), [status]))

    def save_in_background(self) -> None:
        """The periodic save: a snapshot now, written by the saver's thread (results: `collect_saves`)."""
        assert self.saver is not None
        self.collect_saves()
        try:
            snapshot_s = self.saver.submit(self.model)
        except (LearningError, MemoryError) as exc:
            self.save_failed(exc)
            return
        self.save_times["checkpoint_snapshot_ms"] = 1e3 * snapshot_s

    def collect_saves(self) -> None:
        """Count and log the background writes finished since the last look."""
        for result in self.saver.results() if self.saver is not None else ():
            if result.error is not None:
                self.save_failed(result.error)
                continue
            self.counters.count("checkpoint.saved")
            self.save_times.update(checkpoint_write_ms=1e3 * result.write_s, checkpoint_mb=result.bytes / 2**20)
            self.error = None

    def save_failed(self, exc: BaseException) -> None:
        self.counters.count("checkpoint.save_failed")
        self.counters.warn_throttled("checkpoint", f"could not save the checkpoint: {exc}")
        self.error = f"checkpoint save failed: {exc}"

    def save_checkpoint(self) -> bool:
        """A save on this thread, after any background write has finished (the final one)."""
        if self.saver is not None:
            if not self.saver.close(timeout=SAVE_WAIT_S):
                self.get_logger().warning(f"a background save did not finish within {SAVE_WAIT_S:.0f} s; saving again")
            self.collect_saves()
        try:
            self.model.save(self.checkpoint)
        except (LearningError, OSError, MemoryError) as exc:
            self.save_failed(exc)
            return False
        self.counters.count("checkpoint.saved")
        self.error = None
        return True

    def on_shutdown(self) -> None:
        if self.checkpoint is None:
            return
        try:
            if not self.save_checkpoint():
                raise NodeFatalError(f"the final checkpoint could not be written to {self.checkpoint}")
        finally:
            self.release_checkpoint()
        self.get_logger().info(f"checkpoint saved to {self.checkpoint} (neurons {self.model.neuron_counts})")

    def warn_about_other_name(self) -> None:
        """A params file with a section for the learner's other name only: rcl applies none of it, silently."""
        for path in params_file.sections_for_other_name(sys.argv, self.get_name(), self.OTHER_NAME):
            self.get_logger().warning(f"params file {path} has a section for '{self.OTHER_NAME}' and none for "
                                      f"'{self.get_name()}': none of its settings apply to this node; name the "
                                      f"section '{self.get_name()}:' (or '/**:')")


class GwrHierarchyNode(ArmPredictorNode):
    """The learner under its old name, for one release: params-file sections, parameter calls and
    /diagnostics names of `gwr_hierarchy` go on working; the start says it is deprecated."""

    NODE_NAME = conventions.DEPRECATED_LEARNER_NODE
    OTHER_NAME = conventions.LEARNER_NODE

    def __init__(self) -> None:
        rclpy.logging.get_logger(self.NODE_NAME).warning(
            f"the executable '{self.NODE_NAME}' is deprecated and goes in the next release: run "
            f"'{self.OTHER_NAME}' (the same node, named '{self.OTHER_NAME}': rename a params file's "
            f"'{self.NODE_NAME}:' section to '{self.OTHER_NAME}:')")
        super().__init__()


def main(args: list[str] | None = None) -> int:
    return run_node(ArmPredictorNode, args)


def main_gwr_hierarchy(args: list[str] | None = None) -> int:
    """The deprecated executable `gwr_hierarchy`."""
    return run_node(GwrHierarchyNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
