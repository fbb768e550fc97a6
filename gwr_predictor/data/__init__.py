"""Where the learner's frames come from: demonstrator -> skeleton files -> median of 3 -> Nao angles.

Also mocap recordings (BVH, ASF/AMC, joint positions, .pt) onto the same skeleton stream, the
angle CSV files, the memoised demonstrator data set, simulated sensor faults and the bench's
synthetic arm demonstrations. Data the package cannot use is a `DataError` (`errors.py`).
"""

from gwr_predictor._exports import lazy_exports

_EXPORTS = {
    "DataError": "errors",
    "demonstrate": "demonstrator",
    "demonstrate_one": "demonstrator",
    "default_subjects": "demonstrator",
    "SubjectProfile": "demonstrator",
    "SkeletonSequence": "skeleton_files",
    "load_skeleton": "skeleton_files",
    "save_skeleton": "skeleton_files",
    "MedianOf3": "smoothing",
    "median_of_3": "smoothing",
    "skeleton_to_angles": "angles",
    "extract_angles": "extraction",
    "frame_angles": "extraction",
    "ExtractedAngles": "extraction",
    "load_angles_csv": "angle_files",
    "save_angles_csv": "angle_files",
    "AngleSequence": "datasets",
    "demo_angle_sequences": "datasets",
    "drop_chunks": "faults",
    "joint_dropouts": "faults",
    "load_any_skeleton": "mocap",
    "load_clip": "mocap",
    "clip_to_skeleton": "mocap",
    "ImportOptions": "mocap_clip",
    "MocapClip": "mocap_clip",
    "fetch_clips": "real_motion",
    "synthetic_demonstrations": "synthetic",
    "synthetic_arm_stream": "synthetic",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
