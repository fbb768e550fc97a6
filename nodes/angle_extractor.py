"""angle_extractor: skeletons (30 fps) -> median of 3 -> the 8 Nao arm angles (10 fps) as JointState.

The paper's vision module: every 3 skeleton frames are smoothed into one by their median
(`gwr_predictor.data.smoothing.MedianOf3`), then mapped to the Nao's arm joints and clipped
(`gwr_predictor.data.extraction.frame_angles`). The JointState is stamped with the smoothed frame's
stamp (its middle frame), so downstream timing refers to when the person was in that pose.
"""

from __future__ import annotations

import numpy as np

from gwr_predictor.data.extraction import frame_angles
from gwr_predictor.data.skeleton_files import MAX_PLAUSIBLE_METRES
from gwr_predictor.data.smoothing import MedianOf3
from gwr_predictor.parameter_spec import ParamSpec
from gwr_predictor.pipeline import conventions
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS, LayoutError
from gwr_predictor.pipeline.gates import SkeletonReorder
from gwr_predictor.robot.nao import ARM_JOINTS

from . import messages
from .node_base import PipelineNode, run_node, stream_qos

PARAMS = (
    ParamSpec("max_gap_s", conventions.MAX_GAP_S,
          "a stamp gap larger than this starts a new sequence (the smoothing group restarts)", 0.0, 3600.0),
    ParamSpec("input_reliability", "reliable", "QoS of the skeleton subscription; best_effort also matches "
          "trackers that publish best-effort", choices=("reliable", "best_effort")),
)


class AngleExtractorNode(PipelineNode):
    NODE_NAME = "angle_extractor"

    def __init__(self) -> None:
        super().__init__(self.NODE_NAME, PARAMS)
        self.smoother = MedianOf3()
        self.last_stamp: float | None = None
        self.reorder = SkeletonReorder(self.counters)
        self.angles_pub = self.create_publisher(messages.JointState, conventions.TOPIC_ANGLES, stream_qos())
        reliable = self.params["input_reliability"] == "reliable"
        self.create_subscription(messages.Float64MultiArray, conventions.TOPIC_SKELETON, self.on_skeleton,
                                 stream_qos(reliable=reliable))

    def on_skeleton(self, msg: messages.Float64MultiArray) -> None:
        """Check the frame, smooth it; every third accepted frame gives one JointState."""
        frame = self.checked_frame(msg)
        if frame is None:
            return
        stamp, positions = frame
        if self.last_stamp is not None and stamp - self.last_stamp > self.params["max_gap_s"]:
            self.smoother.reset()
            self.counters.count("sequence_gaps")
        self.last_stamp = stamp
        self.counters.count("skeleton.accepted")
        smoothed = self.smoother.push(stamp, positions)
        if smoothed is not None:
            self.publish_angles(*smoothed)

    def checked_frame(self, msg: messages.Float64MultiArray) -> tuple[float, np.ndarray] | None:
        """(stamp, positions in SKELETON_JOINTS order) or None, by the rules in docs/pipeline.md."""
        try:
            stamp, names, positions = messages.read_skeleton(msg)
        except LayoutError as exc:
            self.counters.reject("skeleton.layout", str(exc))
            return None
        if not np.isfinite(stamp) or stamp <= 0.0 or (self.last_stamp is not None and stamp <= self.last_stamp):
            self.counters.reject("skeleton.stamp", f"stamp {stamp} not after the previous {self.last_stamp}")
            return None
        if np.any(np.isinf(positions)):
            self.counters.reject("skeleton.non_finite", "infinite coordinates (NaN marks an untracked joint)")
            return None
        if np.nanmax(np.abs(positions), initial=0.0) > MAX_PLAUSIBLE_METRES:
            self.counters.reject("skeleton.out_of_range", f"coordinates beyond {MAX_PLAUSIBLE_METRES} m "
                                 "(millimetres instead of metres?)")
            return None
        return stamp, self.reorder(names, positions)

    def publish_angles(self, stamp: float, positions: np.ndarray) -> None:
        angles, raw = frame_angles(positions, SKELETON_JOINTS)
        if not np.all(np.isfinite(raw)):
            self.counters.reject("frame.missing_joints", "a smoothed frame lacks joints the arm angles need; dropped")
            return
        if np.any(angles != raw):
            self.counters.count("angles.clipped_to_limits")
        self.angles_pub.publish(messages.joint_state(stamp, ARM_JOINTS, angles))
        self.counters.count("angles.published")


def main(args: list[str] | None = None) -> int:
    return run_node(AngleExtractorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
