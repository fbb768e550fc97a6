"""The robot side: Nao kinematics and URDF, the PyBullet simulator, the delayed arm, compensation.

Also the offline closed loop and the lag/tracking measures that score it. Its one error class is
`RobotError` (`errors.py`).
"""

from gwr_predictor._exports import lazy_exports

_EXPORTS = {
    "ARM_JOINTS": "nao",
    "forward_kinematics": "nao",
    "clip_to_limits": "nao",
    "build_nao_urdf": "urdf",
    "default_urdf_path": "urdf",
    "write_urdf": "urdf",
    "NaoSimulator": "pybullet_nao",
    "SimulatedRobot": "delayed_arm",
    "RobotParams": "delayed_arm",
    "MotorParams": "delayed_arm",
    "DelayLine": "delayed_arm",
    "RobotError": "errors",
    "DelayCompensator": "compensator",
    "CompensatorParams": "compensator",
    "CompensatorOutput": "compensator",
    "run_closed_loop": "closed_loop",
    "ClosedLoopResult": "closed_loop",
    "estimate_lag": "tracking",
    "tracking_error": "tracking",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
