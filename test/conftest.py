"""Shared fixtures: `ros` (real node processes over DDS, see ros_harness.py)."""

pytest_plugins = ["ros_harness"]
