"""angle_extractor: skeletons (30 fps) -> median of 3 -> the 8 Nao arm angles (10 fps) as JointState.

The paper's vision module: every 3 skeleton frames are smoothed into one by their median
(`gwr_predictor.data.smoothing.MedianOf3`), then mapped to the Nao's arm joints and clipped
(`gwr_predictor.data.extraction.frame_angles`). The JointState is stamped with the smoothed frame's
stamp (its middle frame), so downstream timing refers to when the person was in that pose.

Every accepted skeleton frame is also published as a MarkerArray on `skeleton_markers` (joints and
bones, frame `markers_frame_id`, the capture stamp) for RViz / Foxglove. With `input:=k4abt_markers`
the input is an Azure Kinect / Orbbec body-tracking MarkerArray (`body_tracking_data`) instead: the
body nearest to the sensor is mapped to the 15 joints (`gwr_predictor.data.k4abt`) and then takes
exactly the path of a skeleton message (same checks, counters and smoothing).
"""

from __future__ import annotations

import numpy as np

from gwr_predictor.data import k4abt
from gwr_predictor.data.errors import DataError
from gwr_predictor.data.extraction import frame_angles
from gwr_predictor.data.skeleton_files import MAX_PLAUSIBLE_METRES
from gwr_predictor.data.smoothing import MedianOf3
from gwr_predictor.parameters.spec import ParamSpec
from gwr_predictor.pipeline import conventions
from gwr_predictor.pipeline.conventions import SKELETON_JOINTS
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.input_rules import SkeletonReorder
from gwr_predictor.pipeline.markers import SKELETON_FRAME, skeleton_figure
from gwr_predictor.robot.nao import ARM_JOINTS

from . import messages, standard_messages
from .pipeline_node import PipelineNode
from .qos import stream_qos
from .runner import run_node

PARAMS = (
    ParamSpec("max_gap_s", conventions.MAX_GAP_S,
              "a stamp gap larger than this starts a new sequence (the smoothing group restarts)", 0.0, 3600.0),
    ParamSpec("input_reliability", "reliable", "QoS of the skeleton subscription; best_effort also matches "
              "trackers that publish best-effort", choices=("reliable", "best_effort")),
    ParamSpec("input", "skeleton", "skeleton: the labelled array on 'skeleton'; k4abt_markers: an Azure Kinect / "
              "Orbbec body-tracking MarkerArray on 'body_tracking_data' (nearest body)",
              choices=("skeleton", "k4abt_markers")),
    ParamSpec("markers", True, "also publish every accepted skeleton frame as a MarkerArray on 'skeleton_markers'"),
    ParamSpec("markers_frame_id", SKELETON_FRAME,
              "frame_id of the skeleton markers (the skeleton camera convention)"),
)


class AngleExtractorNode(PipelineNode):
    NODE_NAME = "angle_extractor"

    def __init__(self) -> None:
        super().__init__(self.NODE_NAME, PARAMS)
        self.smoother = MedianOf3()
        self.stamps = self.stamp_check()
        self.reorder = SkeletonReorder(self.counters)
        self.angles_pub = self.create_publisher(messages.JointState, conventions.TOPIC_ANGLES, stream_qos())
        self.markers_pub = (self.create_publisher(standard_messages.MarkerArray, conventions.TOPIC_SKELETON_MARKERS,
                                                  stream_qos()) if self.params["markers"] else None)
        qos = stream_qos(reliable=self.params["input_reliability"] == "reliable")
        if self.params["input"] == "k4abt_markers":
            self.create_subscription(standard_messages.MarkerArray, conventions.TOPIC_BODY_TRACKING,
                                     self.on_body_markers, qos)
        else:
            self.create_subscription(messages.Float64MultiArray, conventions.TOPIC_SKELETON, self.on_skeleton, qos)

    def on_body_markers(self, msg: standard_messages.MarkerArray) -> None:
        """Body-tracking markers -> the nearest body's skeleton, then the skeleton path (same checks)."""
        try:
            stamp, _, ids, xyz = standard_messages.read_body_markers(msg)
        except PipelineError as exc:  # only the bound on markers is checked before reading
            if exc.reason != "too_large":
                raise
            self.counters.reject("body_tracking.too_large", str(exc))
            return
        try:
            body = k4abt.nearest_body(ids, xyz)
        except DataError as exc:
            self.counters.reject("body_tracking.layout", str(exc))
            return
        if body is None:
            self.counters.count("body_tracking.no_body")
            return
        if body.unknown_markers:
            self.counters.count("body_tracking.unknown_markers_ignored", body.unknown_markers)
        if body.n_bodies > 1:
            self.counters.count("body_tracking.nearest_of_several")
        try:
            skeleton = messages.skeleton_msg(stamp, body.positions)
        except ValueError as exc:  # a stamp no skeleton can carry (negative, non-finite)
            self.counters.reject("body_tracking.stamp", str(exc))
            return
        self.on_skeleton(skeleton)

    def on_skeleton(self, msg: messages.Float64MultiArray) -> None:
        """Check the frame, smooth it; every third accepted frame gives one JointState."""
        frame = self.checked_frame(msg)
        if frame is None:
            return
        stamp, positions = frame
        previous = self.last_stamp
        if not self.check_stamp(self.stamps, "skeleton", stamp):
            return
        if previous is not None and not 0.0 < stamp - previous <= self.params["max_gap_s"]:
            self.smoother.reset()  # a gap, or a new sequence after stamps went back
            self.counters.count("sequence_gaps")
        self.counters.count("skeleton.accepted")
        if self.markers_pub is not None:
            figure = skeleton_figure(positions)
            self.markers_pub.publish(standard_messages.figure_markers(stamp, self.params["markers_frame_id"],
                                                                      "skeleton", figure, (0.1, 0.8, 0.3, 1.0)))
        smoothed = self.smoother.push(stamp, positions)
        if smoothed is not None:
            self.publish_angles(*smoothed)

    def checked_frame(self, msg: messages.Float64MultiArray) -> tuple[float, np.ndarray] | None:
        """(stamp, positions in SKELETON_JOINTS order) or None, by the rules in docs/pipeline.md."""
        try:
            stamp, names, positions = messages.read_skeleton(msg)
        except PipelineError as exc:
            self.counters.reject("skeleton.too_large" if exc.reason == "too_large" else "skeleton.layout", str(exc))
            return None
        if np.any(np.isinf(positions)):
            self.counters.reject("skeleton.non_finite", "infinite coordinates (NaN marks an untracked joint)")
            return None
        if np.nanmax(np.abs(positions), initial=0.0) > MAX_PLAUSIBLE_METRES:
            self.counters.reject("skeleton.out_of_range", f"coordinates beyond {MAX_PLAUSIBLE_METRES} m "
                                 "(millimetres instead of metres?)")
            return None
        return stamp, self.reorder(names, positions)

    @property
    def last_stamp(self) -> float | None:
        """The stamp of the last accepted skeleton (the stamp rule's memory)."""
        return self.stamps.last

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
