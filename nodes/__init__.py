"""Thin rclpy nodes: declare parameters, convert messages, call the library, publish."""
