"""AmbieGen-ROS: search for environments in which autonomous systems fail.

The core (``ambiegen_ros.core``, ``ambiegen_ros.problems``) imports no ROS; the ROS layer lives in
``ambiegen_ros.ros`` and ``ambiegen_ros.nodes``.
"""

__version__ = "0.1.0"
