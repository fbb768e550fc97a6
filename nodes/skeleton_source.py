"""skeleton_source: publishes 15-joint skeletons at the tracker's rate, from the built-in demonstrator or a file.

Stands in for the depth sensor + skeleton tracker (or stays silent with `source: none` when a bag
or a real tracker provides /skeleton). Frames are stamped with the node clock at their scheduled
time. Sequences (repetitions) are separated by a pause longer than the pipeline's `max_gap_s`,
which the downstream nodes treat as the end of a sequence. Optional fault injection reproduces the
paper's faulty sensor: whole chunks dropped (a gap in the stamps) and single joints lost (NaN).
Every frame also goes out as a `geometry_msgs/PoseArray` on `skeleton_poses` (header stamp = the frame's
stamp, one pose per joint in SKELETON_JOINTS order), for packages that read `header.stamp`.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from rclpy.publisher import Publisher

from gwr_predictor.data import demonstrator, faults
from gwr_predictor.data.mocap import load_any_skeleton
from gwr_predictor.data.mocap_clip import ImportOptions
from gwr_predictor.data.skeleton_files import SkeletonSequence
from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.parameters.spec import ParameterError, ParamSpec
from gwr_predictor.pipeline import conventions
from gwr_predictor.pipeline.markers import SKELETON_FRAME

from . import messages, standard_messages
from .exits import NodeFatalError
from .pipeline_node import PipelineNode
from .qos import stream_qos
from .runner import run_node

PARAMS = (
    ParamSpec("source", "demonstrator", "where skeletons come from", choices=("demonstrator", "file", "none")),
    ParamSpec("file", "", "skeleton file (.npz or .csv, see skeleton_io) or mocap file (.bvh, .amc, .npy/.npz "
                          "positions, .pt; mapped and resampled to 30 fps) for source 'file'"),
    ParamSpec("joint_map", "", "mocap file: JSON/YAML joint map (empty: a preset detected from the joint names)"),
    ParamSpec("mocap_units", "auto", "mocap file: length unit (auto, m, cm, mm, inch or metres per unit)"),
    ParamSpec("mocap_fps", 0.0, "mocap file: its frame rate when the file does not say it (0: from the file)",
              0.0, 10000.0),
    ParamSpec("patterns", [], "demonstrator patterns to perform (empty: all 10 of the paper)"),
    ParamSpec("subjects", 3, "number of simulated people (s1-s3 are the paper-like profiles)", 1, 100),
    ParamSpec("first_repetition", 1, "number of the first repetition performed (the pretraining uses 1..N)", 1, 10000),
    ParamSpec("repetitions", 1, "repetitions per pattern and subject", 1, 10000),
    ParamSpec("loop", False, "start again after the last sequence (otherwise the node exits)"),
    ParamSpec("rate_hz", conventions.SKELETON_FPS, "demonstrator frame rate (a file plays at its own stamps)",
              1.0, 1000.0),
    ParamSpec("seed", 0, "demonstrator and fault-injection seed", 0, 2**31 - 1),
    ParamSpec("pause_s", 1.0, "silence between sequences; must exceed max_gap_s of the downstream nodes", 0.0, 3600.0),
    ParamSpec("start_delay_s", 0.0, "wait before the first frame (s)", 0.0, 3600.0),
    ParamSpec("wait_for_subscribers", 0, "before the first frame, wait until /skeleton has this many subscribers",
          0, 1000),
    ParamSpec("drop_fraction", 0.0, "fault injection: share of frames lost in whole chunks", 0.0, 0.95),
    ParamSpec("drop_chunk_s", 1.0, "fault injection: length of one lost chunk (s); the paper used 1 s", 0.01, 60.0),
    ParamSpec("joint_dropout_rate", 0.0, "fault injection: probability per frame and joint of an untracked (NaN) joint",
          0.0, 1.0),
    ParamSpec("tick_s", 0.005, "scheduling period; frames go out at most this late (s)", 0.0005, 0.1),
    ParamSpec("standard_outputs", True, "also publish every frame as a PoseArray on 'skeleton_poses' (header "
              "stamp, SKELETON_JOINTS order) for packages that read header.stamp"),
    ParamSpec("frame_id", SKELETON_FRAME, "frame_id of skeleton_poses: the skeleton camera frame (as "
              "angle_extractor's markers_frame_id)"),
)


class SkeletonSourceNode(PipelineNode):
    NODE_NAME = "skeleton_source"

    def __init__(self) -> None:
        super().__init__(self.NODE_NAME, PARAMS)
        p = self.params
        self.rng = np.random.default_rng(p["seed"])
        self.pub = self.create_publisher(messages.Float64MultiArray, conventions.TOPIC_SKELETON, stream_qos())
        self.poses_pub = self.create_poses_publisher()
        if p["source"] == "none":
            self.get_logger().info("source 'none': publishing nothing (a bag or a tracker provides /skeleton)")
            return
        self.sequences = self.sequence_iterator()
        self.current: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # schedule s, positions, kept
        self.index = 0
        self.next_start: float | None = None  # node-clock time of the next sequence's first frame
        self.started_at: float | None = None  # the first tick (under sim time, the first /clock)
        self.create_timer(p["tick_s"], self.tick)

    def create_poses_publisher(self) -> Publisher | None:
        """The stamped twin of /skeleton, unless `standard_outputs` is off; a pose without a frame means nothing."""
        if not self.params["standard_outputs"]:
            return None
        if not self.params["frame_id"]:
            raise ParameterError("parameter 'frame_id' is empty: skeleton_poses needs the camera frame "
                                 "(or set standard_outputs: false)")
        return self.create_publisher(standard_messages.PoseArray, conventions.TOPIC_SKELETON_POSES, stream_qos())

    def sequence_iterator(self) -> Iterator[SkeletonSequence]:
        """The sequences to perform, again and again if `loop` (validated before the first frame)."""
        p = self.params
        if p["source"] == "file":
            if not p["file"]:
                raise ParameterError("parameter 'file' is empty but source is 'file'")
            try:
                options = ImportOptions(units=p["mocap_units"], fps=p["mocap_fps"], joint_map=p["joint_map"] or None)
                seqs: list[SkeletonSequence] | None = [load_any_skeleton(p["file"], options)]
            except GwrPredictorError as exc:
                raise NodeFatalError(" ".join(str(exc).split())) from None
            except MemoryError:  # within the import limits but not within this machine's memory
                raise NodeFatalError(f"{p['file']}: needs more memory than is available; refused") from None
        else:
            patterns = tuple(p["patterns"]) or demonstrator.PATTERNS
            unknown = [x for x in patterns if x not in demonstrator.PATTERNS]
            if unknown:
                raise ParameterError(f"parameter 'patterns': unknown {unknown}; allowed: "
                                     + ", ".join(demonstrator.PATTERNS))
            seqs = None
            subjects = demonstrator.default_subjects(p["subjects"], seed=p["seed"])
            reps = range(p["first_repetition"], p["first_repetition"] + p["repetitions"])
            # repetition-major order: every pattern appears early in a run
            order = [(pat, subj, rep) for rep in reps for subj in subjects for pat in patterns]

        def generate() -> Iterator[SkeletonSequence]:
            while True:
                if seqs is not None:
                    yield from seqs
                else:
                    for pat, subj, rep in order:
                        yield demonstrator.demonstrate_one(pat, subj, rep, seed=p["seed"], fps=p["rate_hz"])
                if not p["loop"]:
                    return

        return generate()

    def tick(self) -> None:
        """Publish every frame whose scheduled time has come; move on to the next sequence at the end."""
        now = self.now_s()
        if self.next_start is None:
            if not self.ready(now):
                return
            self.next_start = now
        if self.current is None and not self.next_sequence():
            self.get_logger().info(f"all sequences published ({self.counters.get('frames.published')} frames)")
            self.finish(0)
            return
        schedule, positions, keep = self.current
        while self.index < len(schedule) and schedule[self.index] <= now:
            if keep[self.index]:
                self.publish_frame(schedule[self.index], positions[self.index])
            self.index += 1
        if self.index >= len(schedule):
            self.next_start = schedule[-1] + self.params["pause_s"] + 1.0 / self.params["rate_hz"]
            self.current = None

    def publish_frame(self, stamp: float, positions: np.ndarray) -> None:
        """The labelled array the pipeline reads, then its stamped twin for other packages."""
        self.pub.publish(messages.skeleton_msg(stamp, positions))
        if self.poses_pub is not None:
            self.poses_pub.publish(standard_messages.pose_array(stamp, self.params["frame_id"], positions))
        self.counters.count("frames.published")

    def ready(self, now: float) -> bool:
        p = self.params
        if self.started_at is None:
            self.started_at = now
        if p["wait_for_subscribers"] and self.pub.get_subscription_count() < p["wait_for_subscribers"]:
            return False
        return now - self.started_at >= p["start_delay_s"]

    def next_sequence(self) -> bool:
        """Load the next sequence: schedule (node-clock stamps), positions and which frames are kept."""
        seq = next(self.sequences, None)
        if seq is None:
            return False
        p = self.params
        t = np.asarray(seq.timestamps, dtype=float)
        schedule = self.next_start + (t - t[0])
        positions = np.asarray(seq.positions, dtype=float)
        keep = np.ones(len(t), dtype=bool)
        if p["drop_fraction"] > 0.0:
            chunk = max(1, round(p["drop_chunk_s"] * p["rate_hz"]))
            keep = faults.drop_chunks(len(t), p["drop_fraction"], chunk, self.rng)
            self.counters.count("frames.dropped_by_fault_injection", int(np.sum(~keep)))
        if p["joint_dropout_rate"] > 0.0:
            positions = faults.joint_dropouts(positions, p["joint_dropout_rate"], rng=self.rng)
        self.current, self.index = (schedule, positions, keep), 0
        self.counters.count("sequences.started")
        self.get_logger().info(f"sequence {seq.name}: {len(t)} frames, {t[-1] - t[0]:.1f} s")
        return True


def main(args: list[str] | None = None) -> int:
    return run_node(SkeletonSourceNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
