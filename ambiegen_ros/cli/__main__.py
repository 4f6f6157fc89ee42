"""``python -m ambiegen_ros.cli``: the same as ``ambiegen`` (through the launcher's dependency check)."""
import sys

from ..entry import launch

sys.exit(launch("ambiegen"))
