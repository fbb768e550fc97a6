"""What the ROS pipeline shares without ROS: message conventions, input rules, bags, run reports, latency, plots,
videos. Its one error class is `PipelineError` (`errors.py`; `reason` tells a too-large message apart).

Bags, one module per job: `bag_messages` (the type store, message objects, CDR), `bag_qos` (offered and
replay QoS), `bag_writer`, `bag_reader` (messages and summary), `bag_recovery` (after a crash), `bag_replay`
(what the player does to a recorded message).
"""

from gwr_predictor._exports import lazy_exports

_EXPORTS = {
    "PipelineError": "errors",
    "pack_skeleton": "conventions",
    "unpack_skeleton": "conventions",
    "pack_predictions": "conventions",
    "unpack_predictions": "conventions",
    "split_stamp": "conventions",
    "stamp_seconds": "conventions",
    "select_joints": "conventions",
    "ArmAnglesCheck": "input_rules",
    "RejectionCounter": "input_rules",
    "SkeletonReorder": "input_rules",
    "missing_frames": "input_rules",
    "BagWriter": "bag_writer",
    "BagMessage": "bag_reader",
    "read_bag": "bag_reader",
    "bag_info": "bag_reader",
    "BagInfo": "bag_reader",
    "recover_bag": "bag_recovery",
    "replay_qos": "bag_qos",
    "latency_report": "message_latency",
    "LatencyReport": "message_latency",
    "compute_report": "run_report",
    "read_run": "run_report",
    "plot_run": "run_report",
    "PipelineReport": "run_report",
    "plot_angle_series": "plotting",
    "read_video_run": "video",
    "render_video": "video",
    "FrameRenderer": "video",
    "VideoWriter": "video_files",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
