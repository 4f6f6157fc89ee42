"""Simulation nodes: thin ROS wrappers that execute scenarios with ``ambiegen_ros.sims``."""
