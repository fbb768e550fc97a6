"""gwr_predictor: online sensorimotor prediction with a hierarchy of Growing When Required networks.

The library is pure Python + numpy (no rclpy). It reads top-down like the paper:
gwr -> predictive_gwr -> hierarchy for learning; demonstrator -> skeleton_io -> smoothing ->
angles -> nao (kinematics) for data; nao_sim and compensator for the robot side; bags and
experiments on top. ROS nodes live in `gwr_predictor.nodes` and only convert messages.
"""

__version__ = "0.1.0"
